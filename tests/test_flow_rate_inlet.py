"""Flow-rate inlets (``flow_rate``, ``flow_rate_table``, ``flow_rate_file``): the prescribed Q(t)
through the inlet at every step (P2 holds the parabola exactly), mass conservation, Poiseuille's
profile, heartbeats, the CSV file as the table, the Womersley profile against its equation and
against a pulsating channel flow, and the inputs refused (exit 2, naming the key).

The runs are the straight channel (configs/channel_poiseuille.yaml: 2 cm × 7 mm, Newtonian
μ = 3.5 mPa s, ρ = 1060 kg/m³, 0.5 mm cells)."""

import logging
import math

from mpi4py import MPI

import numpy as np
import pytest

from fsi import cli, config
from fsi.config import boundary_data, reader
from fsi.geometry.tags import Boundary, Region
from fsi.output import metrics, metrics_csv
from fsi.physics import fluid, fluid_boundaries, inflow_profiles, mesh

CHANNEL = "configs/channel_poiseuille.yaml"
H, MU, RHO = 0.007, 0.0035, 1060.0
Q0 = 1.0e-4  # m²/s: mean velocity 14 mm/s, Re = ρ Q/μ = 30
PERIOD = 0.004
ROWS = ((0.0, 1.0e-4), (0.0007, 1.6e-4), (0.0025, 0.4e-4), (0.0031, 0.9e-4), (0.004, 1.0e-4))


def write(path, text):
    """``text`` into ``path`` by rank 0, seen by every rank after the barrier."""
    if MPI.COMM_WORLD.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(text if isinstance(text, bytes) else text.encode())
    MPI.COMM_WORLD.barrier()


def table(rows) -> str:
    return "[" + ", ".join(f"[{t!r}, {q!r}]" for t, q in rows) + "]"


def run(out, overrides) -> list[dict]:
    """``fsi run`` of the channel with ``overrides``; its metrics.csv rows."""
    args = ["run", CHANNEL, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
    assert cli.main(args) == 0
    return metrics_csv.read_metrics(out / "metrics.csv")


def schedule(dt: float, end: float) -> list[str]:
    return [f"time.end={end}", f"time.schedule=[{{until: {end}, dt: {dt}}}]"]


# --------------------------------------------------------------------------------------------
# Q(t) through the inlet


def test_a_constant_flow_rate_goes_in_and_out_at_every_step(shared_tmp):
    """Q = 1e-4 m²/s ramped over 4 ms (BDF2, 1 ms steps): inlet_flow_rate is the ramped Q to
    1e-10 at every step (P2 holds the parabola) and outlet_flow_rate equals it (the P1 pressure
    holds ∫ ∇·u = 0) to the Newton tolerance."""
    rows = run(
        shared_tmp / "run",
        [f"fluid.inlet={{kind: flow_rate, formula: '{Q0!r}', ramp_time: 0.004}}"]
        + schedule(0.001, 0.006),
    )
    assert len(rows) == 6
    for row in rows:
        expected = Q0 * fluid_boundaries.inflow_ramp(row["t"], 0.004)
        assert row["inlet_flow_rate"] == pytest.approx(expected, rel=1e-10, abs=0)
        assert row["outlet_flow_rate"] == pytest.approx(expected, rel=1e-8, abs=0)
    assert rows[0]["inlet_flow_rate"] < 0.2 * Q0  # ramped


def channel_solver(inlet: dict, length: float = 0.02, scheme: str = "steady"):
    """A fluid solver on the channel of ``length`` with the ``inlet`` (a do-nothing outlet)."""
    case = config.from_dict(
        {
            "geometry": {"kind": "channel", "length": length},
            "structure": {"mode": "rigid"},
            "mesh": {"size": 5e-4, "local_size": 5e-4},
            "fluid": {"inlet": inlet, "outlet": {"backflow_stabilization": 0.0}},
        }
    )
    part = mesh.restrict(mesh.build(case, MPI.COMM_WORLD), Region.FLUID)
    boundaries = fluid_boundaries.boundary_conditions(case.fluid, [Boundary.RIGID_WALL], False)
    solver = fluid.FluidSolver(part.mesh, part.facet_tags, case.fluid, boundaries, scheme=scheme)
    return case, solver


def test_a_constant_flow_rate_gives_poiseuille_flow():
    """The steady solve: u = 6 Q y (H − y)/H³ at every velocity node (exact in P2)."""
    _, solver = channel_solver({"kind": "flow_rate", "formula": repr(Q0)})
    result = solver.step(1.0, 1.0)
    assert result.converged, result
    x = solver.V.tabulate_dof_coordinates()
    u = solver.u.x.array.reshape(-1, 2)
    exact = 6 * Q0 * x[:, 1] * (H - x[:, 1]) / H**3
    error = MPI.COMM_WORLD.allreduce(np.abs(u[:, 0] - exact).max(initial=0), op=MPI.MAX)
    across = MPI.COMM_WORLD.allreduce(np.abs(u[:, 1]).max(initial=0), op=MPI.MAX)
    assert error < 1e-8 * 1.5 * Q0 / H and across < 1e-8 * 1.5 * Q0 / H, (error, across)
    inlet = -metrics.flow_rate(solver.u, solver.facet_tags, [Boundary.INLET])
    assert inlet == pytest.approx(Q0, rel=1e-12)


def test_a_periodic_table_runs_heartbeats_and_is_interpolated(shared_tmp):
    """A flow_rate_table of period 4 ms, ``time.cycles: 2`` (4 steps of 1 ms per heartbeat):
    the cycle column, and Q(t) = Q_table(t mod T) linear between rows, to 1e-10."""
    rows = run(
        shared_tmp / "run",
        [
            f"fluid.inlet={{kind: flow_rate_table, table: {table(ROWS)}, period: {PERIOD}}}",
            "time.cycles=2",
            *schedule(0.001, PERIOD),
        ],
    )
    assert [r["cycle"] for r in rows] == [1] * 4 + [2] * 4
    law = boundary_data.table_function(ROWS, PERIOD)
    assert rows[1]["inlet_flow_rate"] == pytest.approx(
        1.6e-4 + (0.002 - 0.0007) / (0.0025 - 0.0007) * (0.4e-4 - 1.6e-4), rel=1e-10
    )
    for row in rows:
        assert row["inlet_flow_rate"] == pytest.approx(law(row["t"]), rel=1e-10, abs=0)


def test_the_csv_file_gives_the_tables_run_and_is_written_as_the_table(shared_tmp):
    """The same rows from a CSV file: the same metrics (bit for bit on one rank); config.yaml
    holds them as a flow_rate_table (with the period, profile and ramp)."""
    write(shared_tmp / "q.csv", "t,Q\n" + "".join(f"{t!r},{q!r}\n" for t, q in ROWS))
    keys = f"period: {PERIOD}, ramp_time: 0.002"
    inlets = {
        "table": f"{{kind: flow_rate_table, table: {table(ROWS)}, {keys}}}",
        "file": f"{{kind: flow_rate_file, file: '{shared_tmp / 'q.csv'}', {keys}}}",
    }
    found = {
        name: run(shared_tmp / name, [f"fluid.inlet={inlet}", *schedule(0.001, PERIOD)])
        for name, inlet in inlets.items()
    }
    for a, b in zip(found["file"], found["table"], strict=True):
        for column in set(a) - {"wall_time_s"}:
            if MPI.COMM_WORLD.size == 1:
                assert a[column] == b[column], column
            else:  # MUMPS's parallel LU does not add in the same order every run
                assert a[column] == pytest.approx(b[column], rel=1e-12, abs=1e-14), column
    written = config.load(shared_tmp / "file" / "config.yaml").fluid.inlet
    assert written == config.InletFlowRateTable(table=ROWS, period=PERIOD, ramp_time=0.002)


# --------------------------------------------------------------------------------------------
# The Womersley profile


def womersley_number(omega: float) -> float:
    """α = H/2 sqrt(ω ρ/μ) of the channel."""
    return H / 2 * math.sqrt(omega * RHO / MU)


@pytest.mark.parametrize("alpha", [0.1, 1.0, 4.0, 20.0, 2000.0])
def test_the_womersley_profile_has_unit_flux_and_solves_its_equation(alpha):
    """∫ φ ds = 1 (Gauss–Legendre, 1e-10), φ = 0 at the walls, and i ω ρ φ − μ φ'' is constant
    across the channel (central differences, h = H/4000: their error (h α')²/12 ≤ 2e-6 for
    α ≤ 20); α = 2000 (cosh(α) overflows a float) stays finite."""
    omega = (2 * alpha / H) ** 2 * MU / RHO
    nodes, weights = np.polynomial.legendre.leggauss(400)
    s = (nodes + 1) * H / 2
    phi = inflow_profiles.womersley(s, H, omega, RHO, MU)
    assert np.all(np.isfinite(phi))
    assert abs(np.sum(weights * phi) * H / 2 - 1) < 1e-10
    walls = inflow_profiles.womersley(np.array([0.0, H]), H, omega, RHO, MU)
    assert np.abs(walls).max() < 1e-12 * np.abs(phi).max()
    if alpha > 100:
        return
    h = H / 4000
    s = np.linspace(h, H - h, 3999)
    phi, left, right = (inflow_profiles.womersley(x, H, omega, RHO, MU) for x in (s, s - h, s + h))
    residual = 1j * omega * RHO * phi - MU * (left - 2 * phi + right) / h**2
    assert np.ptp(residual.real) + np.ptp(residual.imag) < 2e-5 * np.abs(residual).mean()


def test_the_womersley_profile_tends_to_the_parabola_as_omega_vanishes():
    s = np.linspace(0, H, 101)
    parabola = 6 * s * (H - s) / H**3
    for alpha, tolerance in ((1e-2, 1e-5), (1e-3, 1e-6), (1e-5, 1e-12)):
        omega = (2 * alpha / H) ** 2 * MU / RHO
        phi = inflow_profiles.womersley(s, H, omega, RHO, MU)
        assert np.abs(phi - parabola).max() < tolerance * parabola.max(), alpha


@pytest.mark.parametrize("period, warned", [(0.01, True), (0.8, False)])
def test_a_womersley_inlet_whose_flux_the_mesh_cannot_carry_is_warned_of(fsi_log, period, warned):
    """At period 0.01 s (α = 48) the boundary layers (0.07 mm) are far thinner than the 0.5 mm
    cells: the P2 interpolant of the profile carried 0.5 % less than Q without a word, where
    docs/boundary-conditions.md says its flux is Q. Now a warning names the error, the
    Womersley number and the cells (the flux error is measured as the warning says); at 0.8 s
    (α = 5.4) the mesh carries Q to 10⁻⁵ and nothing is said."""
    inlet = {
        "kind": "flow_rate",
        "formula": f"1e-3*(1 + sin(2*pi*t/{period}))",
        "period": period,
        "profile": "womersley",
    }
    with fsi_log.at_level(logging.WARNING, logger="fsi"):
        _, solver = channel_solver(inlet, length=0.004)
    # The flux the warning measures is the one the velocity nodes carry (a steady solve at
    # the peak of Q, 2e-3 m^2/s, holds them).
    assert solver.step(0.25 * period, 1.0).converged
    inflow = -metrics.flow_rate(solver.u, solver.facet_tags, [Boundary.INLET])
    assert (abs(inflow - 2e-3) > 2e-6) == warned, inflow
    said = [r.getMessage() for r in fsi_log.records if "fluid.inlet.profile womersley" in r.message]
    said = MPI.COMM_WORLD.bcast(said, root=0)  # rank 0 warns: every rank judges its words
    assert bool(said) == warned, said
    if warned:
        assert "(0.51 % of the peak |Q|) off Q" in said[0], said
        assert "Womersley number 48.3, 0.072 mm thick" in said[0] and "(0.5 mm)" in said[0]


def test_a_sinusoidal_flow_rate_gives_the_womersley_flow():
    """Q = Q0 sin(ωt) with α = 4 (T = 1.457 s), the Womersley inlet, a 1.4 cm channel, BDF2
    with dt = T/40, from rest for 1.5 periods: the velocity at every node of the middle half
    matches the periodic Womersley solution Re(−i Q0 φ_1(y) e^{iωt}) within 1 % of its
    amplitude (the start from rest decays as e^{−20 ω t/α²})."""
    alpha = 4.0
    omega = (2 * alpha / H) ** 2 * MU / RHO
    period = 2 * math.pi / omega
    inlet = {
        "kind": "flow_rate",
        "formula": f"{Q0!r}*sin(2*pi*t/{period!r})",
        "period": period,
        "profile": "womersley",
    }
    _, solver = channel_solver(inlet, length=0.014, scheme="bdf2")
    steps = 60
    dt = 1.5 * period / steps
    for k in range(1, steps + 1):
        result = solver.step(k * dt, dt)
        assert result.converged, result
        solver.advance()
    t = steps * dt
    x = solver.V.tabulate_dof_coordinates()
    middle = (x[:, 0] > 0.0035) & (x[:, 0] < 0.0105)
    phi = inflow_profiles.womersley(x[middle, 1], H, omega, RHO, MU)
    exact = (-1j * Q0 * phi * np.exp(1j * omega * t)).real
    amplitude = Q0 * np.abs(inflow_profiles.womersley(np.linspace(0, H, 201), H, omega, RHO, MU))
    u = solver.u.x.array.reshape(-1, 2)[middle]
    error = MPI.COMM_WORLD.allreduce(np.abs(u[:, 0] - exact).max(initial=0), op=MPI.MAX)
    print(f"Womersley: max error {error / amplitude.max():.3e} of the amplitude")
    assert error < 0.01 * amplitude.max()
    inflow = -metrics.flow_rate(solver.u, solver.facet_tags, [Boundary.INLET])
    print(f"Womersley: inlet flow rate error {abs(inflow - Q0 * math.sin(omega * t)) / Q0:.2e} Q0")
    assert inflow == pytest.approx(Q0 * math.sin(omega * t), abs=1e-4 * Q0)


# --------------------------------------------------------------------------------------------
# Refused inputs: exit 2, one line naming the case file and the key, before any computation

BAD_FILES = [  # (CSV bytes, None: no file, "dir": a folder; the message after "case.yaml: ")
    (None, "fluid.inlet.file: cannot read {dir}/q.csv (No such file or directory)"),
    ("dir", "fluid.inlet.file: {dir}/q.csv: not a regular file"),
    (b"", "fluid.inlet.file: {dir}/q.csv: 0 rows of t, Q; at least 2 are needed"),
    (b"t,Q\n0,1\n", "fluid.inlet.file: {dir}/q.csv: 1 row of t, Q; at least 2 are needed"),
    (b"0,0\n0.1,abc\n", "fluid.inlet.file: {dir}/q.csv: line 2: 'abc' is not a number"),
    (
        b"0,0\n0.2,1\n0.1,2\n",
        "fluid.inlet.file: {dir}/q.csv: line 3: t = 0.1 is not after the previous row's t = 0.2",
    ),
    (b"0,0\n0.1,nan\n", "fluid.inlet.file: {dir}/q.csv: line 2: Q = nan is not a finite number"),
    (b"0,0\n0.1,1,2\n", "fluid.inlet.file: {dir}/q.csv: line 2: expected 2 columns t, Q, got 3"),
    (b"0,0\n0.5,\xff\n", "fluid.inlet.file: {dir}/q.csv: not UTF-8 text (byte 0xff at offset 8)"),
    (b"#" * (1 << 20) + b"\n", "fluid.inlet.file: {dir}/q.csv: larger than 1048576 bytes"),
]


@pytest.mark.parametrize("text,message", BAD_FILES)
def test_a_bad_flow_rate_file_exits_2_naming_the_file_and_key(shared_tmp, capsys, text, message):
    if text == "dir":
        if MPI.COMM_WORLD.rank == 0:
            (shared_tmp / "q.csv").mkdir()
        MPI.COMM_WORLD.barrier()
    elif text is not None:
        write(shared_tmp / "q.csv", text)
    case = shared_tmp / "case.yaml"
    write(case, "fluid:\n  inlet: {kind: flow_rate_file, file: q.csv}\n")
    assert cli.main(["check", str(case)]) == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert err.startswith(f"fsi: error: {case}: " + message.format(dir=shared_tmp)), err
        assert err.count("\n") == 1 and "Traceback" not in err


BAD_INLETS = [  # (fluid.inlet, other keys, the key named, words of the message)
    ("{kind: flow_rate, formula: '1', profile: plug}", "", "fluid.inlet.profile", "'womersley'"),
    ("{kind: flow_rate, formula: '1', profile: womersley}", "", "fluid.inlet.profile", "period"),
    (
        "{kind: flow_rate_table, table: [[0, 1], [1, 2]], profile: womersley}",
        "",
        "fluid.inlet.profile",
        "period > 0",
    ),
    (
        "{kind: flow_rate, formula: '1', period: 1, profile: womersley}",
        "  rheology: {model: power_law}\n",
        "fluid.inlet.profile",
        "'power_law'",
    ),
    (
        "{kind: flow_rate, formula: '1', period: 1, profile: womersley}",
        "  rheology: {model: casson}\n",
        "fluid.inlet.profile",
        "'casson'",
    ),
    ("{kind: flow_rate, formula: '1/(t - 0.4)'}", "", "fluid.inlet.formula", "division by zero"),
    (
        "{kind: flow_rate, formula: 'log(t - 0.1)', period: 0.2, profile: womersley}",
        "",
        "fluid.inlet.formula",
        "evaluation fails at t = 0",  # a sample of the harmonics, not a step time
    ),
    ("{kind: flow_rate, formula: 'x'}", "", "fluid.inlet.formula", "unknown name 'x'"),
    ("{kind: flow_rate, ramp_time: -1}", "", "fluid.inlet.ramp_time", ">= 0"),
    (
        "{kind: flow_rate_table, table: [[0, 1], [0.5, 2]], period: 0.8}",
        "",
        "fluid.inlet.period",
        "fluid.inlet.table cover t in [0, 0.5] s",
    ),
    ("{kind: flow_rate_table, table: [[0, 1], [0, 2]]}", "", "fluid.inlet.table", "[t, Q] pairs"),
    (
        "{kind: flow_rate_file, file: q.csv, table: [[0, 1]]}",
        "",
        "fluid.inlet.table",
        "not a key of kind 'flow_rate_file' (its rows come from fluid.inlet.file; use kind "
        "'flow_rate_table'",
    ),
    ("{kind: flow_rate_file}", "", "fluid.inlet.file", "CSV file of rows t, Q"),
    ("{kind: flow_rate, formula: '1'}", "time: {cycles: 2}\n", "time.cycles", "flow_rate_file"),
    (
        "{kind: flow_rate, formula: '1'}",
        "structure: {interface_load: inlet_pressure}\n",
        "structure.interface_load",
        "velocity inlet",
    ),
]


@pytest.mark.parametrize("inlet,more,key,words", BAD_INLETS)
def test_a_bad_flow_rate_inlet_is_refused_naming_the_key(inlet, more, key, words):
    fluid_keys = more if more.startswith("  ") else ""
    other = "" if fluid_keys else more
    text = f"fluid:\n  inlet: {inlet}\n{fluid_keys}{other}"
    with pytest.raises(config.ConfigError) as error:
        config.from_dict(reader.parse_yaml(text), "case.yaml")
    assert error.value.key == key and words in str(error.value), str(error.value)
    assert str(error.value).startswith(f"case.yaml: {key}: ")
