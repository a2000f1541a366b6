"""Resistance and three-element Windkessel (RCR) outlets (fsi/physics/outlets.py,
fsi/physics/fluid_boundary_terms.py, LumpedOutlet).

The models alone against their ODE (exact solution, order of the time scheme); the fluid with a
resistance outlet in a steady rigid channel (P = P_ref + R Q at the solution, for R up to 10⁹
Pa s/m² with Newton's quadratic convergence; the channel's own Poiseuille resistance in series);
the Windkessel driven by a constant flow rate (a velocity inlet: incompressibility makes Q at the
outlet exactly the inlet's) against the exact P_c(t), its error shrinking at the order of the
fluid's scheme; blood flowing back in through the outlet when the Windkessel discharges; a
restarted run continuing P_c like the uninterrupted one; bad settings refused with exit 2.
"""

import csv
import math
from pathlib import Path

from mpi4py import MPI

import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import pytest
import ufl

from fsi import cli, compat, config
from fsi.geometry.tags import Boundary, Region
from fsi.numerics.timestepping import bdf_weights
from fsi.output import metrics
from fsi.physics import fluid, fluid_boundaries, mesh, outlets

INLET, OUTLET, WALL = Boundary.INLET, Boundary.OUTLET, Boundary.RIGID_WALL
CHANNEL = "configs/channel_poiseuille.yaml"
LENGTH, HEIGHT, VISCOSITY = 0.02, 0.007, 0.0035  # the channel's defaults (m, m, Pa s)
SERIAL = MPI.COMM_WORLD.size == 1


def rcr_exact(t: float, model: config.WindkesselOutlet, flow_rate: float) -> float:
    """P_c(t) of C dP_c/dt = Q − (P_c − P_ref)/R_d, P_c(0) = P_0, for a constant Q:
    P_ref + Q R_d + (P_0 − P_ref − Q R_d) e^{−t/(R_d C)}."""
    steady = model.reference_pressure + flow_rate * model.distal_resistance
    decay = math.exp(-t / (model.distal_resistance * model.compliance))
    return steady + (model.initial_pressure - steady) * decay


# --------------------------------------------------------------------------------------------
# The models alone


def test_models_come_from_the_outlet_section():
    def outlet(section: dict):
        return config.from_dict({"fluid": {"outlet": section}}).fluid.outlet

    assert outlets.from_config(outlet({})) is None  # traction-free, the default
    assert outlets.from_config(
        outlet({"kind": "resistance", "resistance": 2e5, "reference_pressure": 10})
    ) == outlets.Resistance(2e5, 10)
    wk = outlets.from_config(
        outlet(
            {
                "kind": "windkessel",
                "proximal_resistance": 1e5,
                "distal_resistance": 1e6,
                "compliance": 1e-8,
                "initial_pressure": 50,
                "reference_pressure": 5,
            }
        )
    )
    assert wk == outlets.Windkessel(1e5, 1e6, 1e-8, 50, 5)


def test_steady_windkessel_is_its_two_resistances_in_series():
    wk = outlets.Windkessel(1e5, 1e6, 1e-8, initial_pressure=50.0, reference_pressure=5.0)
    base, slope = wk.pressure_law(wk.initial_state(), (0.0, 0.0, 0.0))
    assert (base, slope) == pytest.approx((5.0, 1.1e6), rel=1e-14)
    after = wk.advance(wk.initial_state(), 1e-4, (0.0, 0.0, 0.0))
    assert after[0] == pytest.approx(5.0 + 1e6 * 1e-4, rel=1e-14)  # P_c = P_ref + R_d Q


@pytest.mark.parametrize("order", [1, 2])
def test_windkessel_follows_its_ode_at_the_order_of_the_scheme(order):
    """Backward Euler / variable-step BDF2 (started by one backward Euler step) on the RCR ODE
    for a constant Q: the error at t = 2 τ halves / quarters when dt halves."""
    wk = outlets.Windkessel(0.0, 1e6, 2e-8, initial_pressure=300.0, reference_pressure=20.0)
    Q, end = 2e-4, 0.04  # τ = R_d C = 0.02 s
    errors = []
    for steps in (20, 40, 80):
        dt, state, previous = end / steps, wk.initial_state(), None
        for k in range(steps):
            weights = bdf_weights(order if k > 0 else 1, dt, previous)
            weights = (*weights, 0.0)[:3]
            state, previous = wk.advance(state, Q, weights), dt
        errors.append(abs(state[0] - rcr_exact(end, wk, Q)))
    rates = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    assert rates == pytest.approx([order, order], abs=0.1), (errors, rates)


# --------------------------------------------------------------------------------------------
# The fluid with a lumped outlet


def channel_solver(
    inlet: dict, outlet: dict, scheme: str = "steady", density: float = 1060.0, supg: bool = True
):
    """The 2 cm × 7 mm channel (1 mm cells), the given inlet and outlet sections, no-slip walls
    (SUPG as ``supg``)."""
    case = config.from_dict(
        {
            "geometry": {"kind": "channel"},
            "structure": {"mode": "rigid"},
            "mesh": {"size": 1e-3, "local_size": 1e-3},
            "fluid": {
                "density": density,
                "rheology": {"model": "newtonian", "viscosity": VISCOSITY},
                "inlet": inlet,
                "outlet": outlet,
                "supg": supg,
            },
        }
    )
    part = mesh.restrict(mesh.build(case, MPI.COMM_WORLD), Region.FLUID)
    boundaries = fluid_boundaries.boundary_conditions(
        case.fluid, (INLET, OUTLET, WALL), moving_interface=False
    )
    return fluid.FluidSolver(part.mesh, part.facet_tags, case.fluid, boundaries, scheme=scheme)


def outlet_flow_rate(solver: fluid.FluidSolver) -> float:
    return metrics.flow_rate(solver.u, solver.facet_tags, [OUTLET])


def mean_pressure(solver: fluid.FluidSolver, tag: int) -> float:
    """∫ p ds / ∫ ds over the boundary ``tag``."""
    ds = ufl.Measure("ds", domain=solver.mesh, subdomain_data=solver.facet_tags)
    one = dolfinx.fem.Constant(solver.mesh, 1.0)
    integral, length = (
        solver.comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(f)))
        for f in (solver.p * ds(tag), one * ds(tag))
    )
    return integral / length


VELOCITY_INLET = {"kind": "parabolic_velocity", "mean_velocity": 0.05, "ramp_time": 0.0}


@pytest.mark.parametrize("resistance", [1e3, 1e6, 1e9])
def test_resistance_outlet_pressure_is_reference_plus_r_times_q(resistance):
    """A velocity inlet fixes Q = Ū H; the outlet's pressure is P_ref + R Q at the converged
    solution, in as many Newton iterations for R = 10⁹ as for 10³ (the rank-one Jacobian term
    keeps Newton's convergence: a lagged Q would diverge for R above the channel's)."""
    solver = channel_solver(
        VELOCITY_INLET, {"kind": "resistance", "resistance": resistance, "reference_pressure": 10.0}
    )
    result = solver.step(0.0, 1.0)
    assert result.converged and result.iterations <= 2, result
    Q = outlet_flow_rate(solver)
    assert Q == pytest.approx(0.05 * HEIGHT, rel=1e-9)
    P = solver.outlet_values()["outlet_pressure"]
    assert P == pytest.approx(10.0 + resistance * Q, rel=1e-10)
    # The do-nothing outlet of a fully developed flow: its mean pressure is P.
    assert mean_pressure(solver, OUTLET) == pytest.approx(P, rel=1e-6, abs=1e-6)


def test_the_outlets_block_enters_a_jacobian_in_one_pass_with_the_same_entries():
    """The outlet's dense block R' b bᵀ merged into a new Jacobian in one pass
    (``fsi.numerics.dense_block``) gives the entries that inserting it entry by entry gives, on
    1 and 2 ranks; a second Jacobian into the same matrix adds it in place (the pattern holds
    it: the same number of nonzeros) with the same entries, and the matrix still assembles."""
    from petsc4py import PETSc

    solver = channel_solver(
        VELOCITY_INLET, {"kind": "resistance", "resistance": 1e9, "reference_pressure": 10.0}
    )
    assert solver.step(0.0, 1.0).converged
    problem, x = solver.problem, compat.petsc_vector(solver.U)
    (outlet,) = problem.lumped
    problem.F(x, dolfinx.fem.petsc.create_vector(problem.L))  # sets the outlet's b at x

    entry_by_entry = dolfinx.fem.petsc.create_matrix(problem.a)
    dolfinx.fem.petsc.NonlinearProblem.J(problem, x, entry_by_entry)
    b = outlet._b.copy()
    dolfinx.fem.petsc.set_bc(b, problem.bcs, None, 0.0)
    local = np.flatnonzero(b.array)
    rows = (local + b.getOwnershipRange()[0]).astype(PETSc.IntType)
    columns = np.concatenate(MPI.COMM_WORLD.allgather(rows)).astype(PETSc.IntType)
    values = np.concatenate(MPI.COMM_WORLD.allgather(b.array[local]))
    entry_by_entry.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    block = 1e9 * np.outer(b.array[local], values)
    entry_by_entry.setValues(rows, columns, block, addv=PETSc.InsertMode.ADD_VALUES)
    entry_by_entry.assemble()
    size = entry_by_entry.norm()
    assert size > 1e9 * float(np.dot(values, values)) / 2  # the block is there

    merged = dolfinx.fem.petsc.create_matrix(problem.a)
    for _ in range(2):
        problem.J(x, merged)
        difference = entry_by_entry.copy()
        difference.axpy(-1.0, merged, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        assert difference.norm() <= 1e-14 * size
        nonzeros = merged.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]
        assert nonzeros == entry_by_entry.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]


def test_resistance_adds_to_the_channels_poiseuille_resistance():
    """A pressure P_in at the inlet, P_ref + R Q at the outlet: Q = (P_in − P_ref)/(R_ch + R)
    with R_ch = 12 μ L / H³ the channel's (per unit depth), and P_in − P = R_ch Q (ρ = 1: the
    steady solve from rest of tests/test_fluid.py's pressure-driven channel)."""
    P_in, P_ref, R = 3.0, 1.0, 5000.0
    solver = channel_solver(
        {"kind": "pressure", "formula": str(P_in)},
        {"kind": "resistance", "resistance": R, "reference_pressure": P_ref},
        density=1.0,
    )
    result = solver.step(0.0, 1.0)
    assert result.converged, result
    R_channel = 12 * VISCOSITY * LENGTH / HEIGHT**3
    Q = outlet_flow_rate(solver)
    assert Q == pytest.approx((P_in - P_ref) / (R_channel + R), rel=1e-6)
    P = solver.outlet_values()["outlet_pressure"]
    assert P == pytest.approx(P_ref + R * Q, rel=1e-10)
    assert P_in - P == pytest.approx(R_channel * Q, rel=1e-6)
    assert mean_pressure(solver, OUTLET) == pytest.approx(P, rel=1e-6)


WINDKESSEL = {
    "kind": "windkessel",
    "proximal_resistance": 1e5,
    "distal_resistance": 1e6,
    "compliance": 2e-8,
    "initial_pressure": 300.0,
    "reference_pressure": 20.0,
}


def windkessel_error(scheme: str, dt: float, end: float = 0.04) -> float:
    """|P_c − exact| at ``end`` for the channel under a constant Q; checks P = P_c + R_p Q and
    Q = Ū H at every step."""
    solver = channel_solver(VELOCITY_INLET, WINDKESSEL, scheme=scheme)
    model = solver.lumped[0].model
    steps = round(end / dt)
    for k in range(1, steps + 1):
        result = solver.step(k * dt, dt)
        assert result.converged, result
        solver.advance()
        Q = outlet_flow_rate(solver)
        assert Q == pytest.approx(0.05 * HEIGHT, rel=1e-9)
        values = solver.outlet_values()
        assert values["outlet_pressure"] == pytest.approx(
            values["windkessel_pressure"] + model.proximal_resistance * Q, rel=1e-12
        )
    return abs(values["windkessel_pressure"] - rcr_exact(end, model, 0.05 * HEIGHT))


@pytest.mark.parametrize("scheme,order", [("backward_euler", 1), ("bdf2", 2)])
def test_windkessel_outlet_follows_the_ode_at_the_fluids_order(scheme, order):
    """τ = R_d C = 0.02 s, to t = 2 τ with 20 and 40 steps: P_c within the scheme's error of
    the exact solution (0.3 % and 0.003 % of P_0 − P_ref at 40 steps), the error shrinking by
    2^order (±0.15) when dt halves."""
    coarse, fine = windkessel_error(scheme, 0.002), windkessel_error(scheme, 0.001)
    scale = WINDKESSEL["initial_pressure"] - WINDKESSEL["reference_pressure"]
    assert fine < (3e-3 if order == 1 else 3e-5) * scale, (coarse, fine)
    assert math.log2(coarse / fine) == pytest.approx(order, abs=0.15), (coarse, fine)


def test_steady_windkessel_outlet_is_at_its_steady_pressure():
    solver = channel_solver(VELOCITY_INLET, WINDKESSEL)
    assert solver.step(0.0, 1.0).converged
    solver.advance()
    Q, values = 0.05 * HEIGHT, solver.outlet_values()
    assert values["windkessel_pressure"] == pytest.approx(20.0 + 1e6 * Q, rel=1e-9)
    assert values["outlet_pressure"] == pytest.approx(20.0 + 1.1e6 * Q, rel=1e-9)


def discharge(
    backflow_stabilization: float, steps: int, supg: bool = True
) -> tuple[list, list, str]:
    """The channel with its inlet at 0 Pa and a Windkessel charged to P_0 = 5 kPa, BDF2, dt 1 ms:
    P_c and Q after each step until one fails (then its message)."""
    solver = channel_solver(
        {"kind": "pressure", "formula": "0"},
        {
            **WINDKESSEL,
            "proximal_resistance": 1e4,
            "distal_resistance": 1e5,
            "compliance": 1e-7,
            "initial_pressure": 5000.0,
            "reference_pressure": 0.0,
            "backflow_stabilization": backflow_stabilization,
        },
        scheme="bdf2",
        supg=supg,
    )
    pressures, flows = [5000.0], []
    for k in range(1, steps + 1):
        result = solver.step(k * 1e-3, 1e-3)
        if not result.converged:
            return pressures, flows, result.reason
        solver.advance()
        pressures.append(solver.outlet_values()["windkessel_pressure"])
        flows.append(outlet_flow_rate(solver))
    assert np.isfinite(solver.u.x.array).all()
    return pressures, flows, ""


def test_a_discharging_windkessel_drives_backflow_stably():
    """The charged Windkessel pushes blood back in through the outlet (Q < 0, up to 1 m/s) while
    its capacitor discharges. With the backflow term (β = 1 in the ``tangential`` form, the
    default) every step converges and P_c falls (later the blood column's inertia makes it
    overshoot below P_ref: an RLC discharge), with SUPG (the default) or without; with neither
    (β = 0, no SUPG) Newton fails within the first steps (measured: step 4). SUPG alone carries
    these 12 steps too (measured), so the test keeps it off to show what the term does."""
    for supg in (True, False):
        pressures, flows, failure = discharge(1.0, 12, supg)
        assert not failure, (supg, failure)
        assert max(flows) < 0
        assert all(b < a for a, b in zip(pressures, pressures[1:], strict=False))
        assert 0 < pressures[-1] < 0.5 * pressures[0]
    _, _, failure = discharge(0.0, 10, supg=False)
    assert "did not converge" in failure, failure


# --------------------------------------------------------------------------------------------
# Runs: metrics, restarts, bad settings


WINDKESSEL_RUN = [
    "fluid.inlet.kind=parabolic_velocity",
    "fluid.inlet.mean_velocity=0.05",
    "fluid.inlet.ramp_time=0",
    "fluid.outlet.kind=windkessel",
    "fluid.outlet.proximal_resistance=1e5",
    "fluid.outlet.distal_resistance=1e6",
    "fluid.outlet.compliance=1e-8",
    "fluid.outlet.initial_pressure=100",
    "time.schedule=[{until: 0.002, dt: 0.001}, {until: 0.004, dt: 0.0005}]",
]


def fsi_run(out: Path, overrides, restart: Path | None = None, *extra: str) -> int:
    args = ["run", CHANNEL, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
    return cli.main(args + ([] if restart is None else ["--restart", str(restart)]) + list(extra))


def metrics_rows(run: Path) -> list[dict]:
    with (run / "metrics.csv").open(newline="") as f:
        return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in csv.DictReader(f)]


def test_a_restarted_windkessel_run_continues_like_the_uninterrupted_one(shared_tmp):
    """BDF2 across a change of dt: 6 steps straight, and 2 steps then a restart to step 6. The
    Windkessel's P_c^n, P_c^{n−1} are in the checkpoint: the rows are equal (1 rank; 2 ranks
    partition the mesh differently in every run: to 1e-9)."""
    straight, split = shared_tmp / "straight", shared_tmp / "split"
    assert fsi_run(straight, [*WINDKESSEL_RUN, "time.end=0.004"]) == 0
    assert fsi_run(split, [*WINDKESSEL_RUN, "time.end=0.002"]) == 0
    assert fsi_run(split, [*WINDKESSEL_RUN, "time.end=0.004"], restart=split) == 0
    a, b = metrics_rows(straight), metrics_rows(split)
    assert [r["step"] for r in b] == ["1", "2", "3", "4", "5", "6"]
    assert "outlet_pressure" in a[0] and "windkessel_pressure" in a[0]
    # P_c is charging from P_0 = 100 Pa towards P_ref + R_d Q = 450 Pa.
    charging = [float(r["windkessel_pressure"]) for r in a]
    assert all(100 < x < y < 450 for x, y in zip(charging, charging[1:], strict=False))
    if SERIAL:
        assert a == b
    else:
        for x, y in zip(a, b, strict=True):
            for key in ("outlet_pressure", "windkessel_pressure"):
                assert float(x[key]) == pytest.approx(float(y[key]), rel=1e-9), key


def test_a_windkessel_added_at_a_restart_starts_from_its_initial_pressure(shared_tmp, fsi_log):
    """A checkpoint of a traction-free run holds no Windkessel state: a restart that adds one
    (a change of the outlet: refused unless asked for with --allow-changes) starts P_c from P_0
    at the checkpoint's time, with a warning."""
    run = shared_tmp / "run"
    traction_free = [s for s in WINDKESSEL_RUN if not s.startswith("fluid.outlet")]
    assert fsi_run(run, [*traction_free, "time.end=0.002"]) == 0
    assert fsi_run(run, [*WINDKESSEL_RUN, "time.end=0.003"], restart=run) == 2
    assert fsi_run(run, [*WINDKESSEL_RUN, "time.end=0.003"], run, "--allow-changes") == 0
    rows = metrics_rows(run)
    assert [r["step"] for r in rows] == ["1", "2", "3", "4"]
    # BDF2's P_c^3 from P_c^2 = P_c^1 = P_0 = 100 Pa, towards 450 Pa.
    assert 100 < float(rows[-1]["windkessel_pressure"]) < 150
    if MPI.COMM_WORLD.rank == 0:
        assert "starts from its initial_pressure at t = 0.002 s" in fsi_log.text


@pytest.mark.parametrize(
    "setting,key,expected",
    [
        ("fluid.outlet={kind: resistance, resistance: -1}", "fluid.outlet.resistance", ">= 0"),
        ("fluid.outlet={kind: windkessel, compliance: 0}", "fluid.outlet.compliance", "positive"),
        (
            "fluid.outlet={kind: windkessel, compliance: -1e-8}",
            "fluid.outlet.compliance",
            "positive",
        ),
        (
            "fluid.outlet={kind: windkessel, distal_resistance: 0}",
            "fluid.outlet.distal_resistance",
            "positive",
        ),
        (
            "fluid.outlet={kind: windkessel, proximal_resistance: -5}",
            "fluid.outlet.proximal_resistance",
            ">= 0",
        ),
        (
            "fluid.outlet={kind: windkessel, initial_pressure: .inf}",
            "fluid.outlet.initial_pressure",
            "finite",
        ),
        ("fluid.outlet={kind: rcr}", "fluid.outlet.kind", "'windkessel'"),
        (
            "fluid.outlet={kind: resistance, compliance: 1}",
            "fluid.outlet.compliance",
            "one of the keys",
        ),
    ],
)
def test_bad_outlet_settings_exit_2_naming_the_key(setting, key, expected, capsys):
    status = cli.main(["check", CHANNEL, "--set", setting])
    err = MPI.COMM_WORLD.bcast(capsys.readouterr().err if MPI.COMM_WORLD.rank == 0 else None)
    assert status == 2
    assert f"--set: {key}: expected" in err and expected in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
