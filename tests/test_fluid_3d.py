"""The fluid in 3D (issue #44; docs/3d.md) against the exact pipe flows: the rigid tube as
tetrahedra (``geometry.dimension: 3``, ``structure.mode: rigid``), its axis the x axis.

Unlike the axisymmetric pipe, whose P2/P1 Poiseuille solution is exact to round-off, the 3D
lumen is the inscribed polygonal prism of the circle: its cross-section is smaller by about
h²/(6R²) of the area, and the flow rate under a given pressure drop (∝ R⁴ for a circle) by about
twice that. That, not the fluid's forms, sets the tolerances here (measured beside each test).
"""

from __future__ import annotations

from dataclasses import replace

from mpi4py import MPI

import numpy as np
import pytest
import support_physics

from fsi import config
from fsi.geometry.tags import Boundary, Region
from fsi.output import metrics
from fsi.output.wall_outputs import FluidOutputs
from fsi.physics import fluid, fluid_case, inflow_profiles, mesh
from fsi.physics.fluid_boundaries import DiskInlet, inlet_flow_rate

L, R = 0.004, 0.002  # the pipe: length, radius (m)
MU, RHO = 0.0035, 1060.0


def pipe(
    size: float,
    fluid_section: dict,
    length: float = L,
    density: float = RHO,
    comm: MPI.Comm = MPI.COMM_WORLD,
):
    """The rigid 3D pipe case (radius 2 mm), its fluid solver's mesh and facet tags."""
    case = config.from_dict(
        {
            "geometry": {
                "kind": "tube",
                "dimension": 3,
                "axisymmetric": False,
                "length": length,
                "radius": R,
                "wall_thickness": 5e-4,
            },
            "structure": {"mode": "rigid"},
            "mesh": {"size": size, "local_size": size},
            "fluid": {
                "density": density,
                "rheology": {"model": "newtonian", "viscosity": MU},
                # Newton to its absolute tolerance (dolfinx 0.5's relative test divides by the
                # first update's norm, not the first residual's).
                "solver": {"rtol": 1e-20, "atol": 1e-12},
                **fluid_section,
            },
        }
    )
    part = mesh.restrict(mesh.build(case, comm), Region.FLUID)
    return case, part.mesh, part.facet_tags


def solver_of(case, submesh, tags, scheme: str) -> fluid.FluidSolver:
    return fluid.FluidSolver(
        submesh, tags, case.fluid, fluid_case.fluid_conditions(case), scheme=scheme
    )


def test_poiseuille_flow_rate_and_wall_shear_stress():
    """A steady pressure drop G L (G = 2,500 Pa/m) across the pipe (0.3 mm tetrahedra, SUPG on,
    the study's open boundaries; ρ = 1, as the axisymmetric test, so that the discretisation's
    small departure from a parallel flow is not convected at Re ~ 10³): the flow rate through
    the inlet and the outlet within 1 % of π R⁴ G/(8 μ) (the issue's tolerance; the polygon's
    deficit: −1.5 % on 0.5 mm cells), the same through both; the wall shear stress G R/2 on
    average over the wall's samples within 3 % (the traction's tangential part, its axial sign
    positive everywhere, within 0.95 of the axis' direction)."""
    G = 2500.0
    inlet = {"inlet": {"kind": "pressure", "formula": repr(G * L)}}
    case, submesh, tags = pipe(3e-4, inlet, density=1.0)
    solver = solver_of(case, submesh, tags, "steady")
    result = solver.step(1.0, 1.0)
    assert result.converged and result.iterations >= 1, result
    exact = np.pi * R**4 * G / (8 * MU)
    outputs = FluidOutputs(case, solver)
    row = outputs.update()
    q_in, q_out = row["inlet_flow_rate"], row["outlet_flow_rate"]
    assert abs(q_in / exact - 1) < 1e-2 and abs(q_out / exact - 1) < 1e-2, (q_in, q_out, exact)
    assert abs(q_in / q_out - 1) < 1e-10  # the discrete velocity is solenoidal
    samples = outputs.sampler.gather()
    wall = G * R / 2
    assert abs(samples.tau.mean() / wall - 1) < 3e-2, (samples.tau.mean(), wall)
    assert samples.tau.min() > 0
    along = np.abs(samples.vector[:, 0]) / np.linalg.norm(samples.vector, axis=1)
    assert along.min() > 0.95, along.min()
    assert abs(row["max_wss"] / wall - 1) < 0.2 and row["recirculation_length"] == 0.0, row
    assert np.allclose(samples.vector[:, 0], samples.tau, rtol=0, atol=0.05 * wall)


def test_a_flow_rate_inlet_carries_its_flow_rate():
    """A steady parabolic flow-rate inlet of Q = 2·10⁻⁷ m³/s: the pipe's profile 2 Ū (1 − r²/R²)
    on the inlet's nodes, r from the disk's centre (the peak 2 Ū on the axis), whose flux on
    the polygonal inlet is Q within the polygon's area deficit (1 %)."""
    Q = 2e-7
    section = {"inlet": {"kind": "flow_rate", "profile": "parabolic", "formula": repr(Q)}}
    case, submesh, tags = pipe(5e-4, section)
    solver = solver_of(case, submesh, tags, "steady")
    assert solver.step(1.0, 1.0).converged
    q = metrics.flow_rate(solver.u, tags, [Boundary.OUTLET])
    assert abs(q / Q - 1) < 1e-2, q
    peak = 2 * Q / (np.pi * R**2)
    assert abs(metrics.peak_velocity(solver.u) / peak - 1) < 1e-2


def test_a_3d_inlet_is_a_flat_disk():
    """The inlet's frame: its centre, inward normal and radius from its vertices; a warped one
    is refused."""
    angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    points = np.column_stack([np.zeros_like(angles), R * np.cos(angles), R * np.sin(angles)])

    class Mesh:  # the mesh's nodes: only their centroid is read
        class geometry:
            x = np.array([[L, 0.0, 0.0], [L / 2, 0.0, 0.0]])

    frame = DiskInlet.of(points, Mesh, MPI.COMM_SELF)
    assert np.allclose(frame.centre, 0, atol=1e-15) and np.allclose(frame.normal, [1, 0, 0])
    assert abs(frame.width - R) < 1e-15
    assert np.allclose(frame.radius(np.array([[0.0, 0.001, 0.0], [1.0, 0.0, 0.003]])), [1e-3, R])
    points[0, 0] = 1e-6
    with pytest.raises(ValueError, match="must be flat"):
        DiskInlet.of(points, Mesh, MPI.COMM_SELF)


PERIOD, AMPLITUDE, SLICE = 0.2, 10.0, 0.002  # s; Pa over the pipe's length; its length (m)


def pipe_womersley(r: np.ndarray) -> tuple[np.ndarray, complex]:
    """Womersley's pipe flow under the pressure drop P cos(ωt) over the slice
    (:func:`support_physics.womersley_pipe`)."""
    return support_physics.womersley_pipe(r, R, AMPLITUDE / SLICE, PERIOD, RHO, MU)


def test_womersley_flow_rate_within_two_percent():
    """Womersley flow in the rigid pipe (Womersley number R √(ωρ/μ) = 5.5, T = 0.2 s, 0.4 mm
    tetrahedra, a 2 mm slice of pipe): started from the exact periodic state and marched for
    0.6 of a period (BDF2, dt 5 ms), through the flow's reversal, the outlet flow rate stays
    within 2 % of Q̂'s amplitude (the issue's tolerance; measured over 1.25 periods 0.95 % with
    dt 4 ms, the polygon's share ~1 %) and reverses with it. The outlet's backflow term is
    ``tangential_velocity``: the shipped ``tangential`` adds ℓ² ∇_Γu : ∇_Γv, which on
    re-entering flow resists the profile itself, a boundary term whose share of the flow's
    balance goes as 1/L: on this 2 mm slice it holds the reversed flow 16 % below Q̂
    (measured; the plane channel's test, 20 mm long, 0.4–1.6 %)."""
    formula = f"{AMPLITUDE} * cos(2 * pi * t / {PERIOD})"
    section = {
        "inlet": {"kind": "pressure", "formula": formula},
        "outlet": {"kind": "traction_free", "backflow_form": "tangential_velocity"},
    }
    case, submesh, tags = pipe(4e-4, section, length=SLICE)
    solver = solver_of(case, submesh, tags, "bdf2")

    def initial(x):
        r = np.sqrt(x[1] ** 2 + x[2] ** 2)
        return np.vstack([pipe_womersley(np.minimum(r, R))[0].real, 0 * r, 0 * r])

    solver.set_initial_state(initial)
    q_hat = pipe_womersley(np.zeros(1))[1]
    omega, dt, errors, flows = 2 * np.pi / PERIOD, 5e-3, [], []
    for k in range(1, int(round(0.6 * PERIOD / dt)) + 1):
        t = k * dt
        result = solver.step(t, dt)
        assert result.converged, (t, result.reason)
        solver.advance()
        if t > 0.1 * PERIOD:
            q = metrics.flow_rate(solver.u, tags, [Boundary.OUTLET])
            errors.append(abs(q - (q_hat * np.exp(1j * omega * t)).real))
            flows.append(q)
    assert min(flows) < 0 < max(flows)  # the flow reversed
    assert max(errors) / abs(q_hat) < 2e-2, max(errors) / abs(q_hat)


def test_a_womersley_flow_rate_inlet_on_a_disk():
    """A pulsatile flow-rate inlet with the pipe's Womersley profiles (Q = Q₀(1 + ½ sin ωt),
    T = 0.2 s, α 5.5) on the 3D pipe's disk, r from its centre: at every step the inlet's flux
    is Q(t) within 2 % (the polygon's deficit and the boundary layer's 0.36 mm on 0.4 mm
    cells; measured below 1 %) and its velocity on the axis is the profile's centre value to
    1e-10."""
    Q0, period = 2e-7, PERIOD
    inlet = {
        "kind": "flow_rate",
        "formula": f"{Q0!r} * (1 + 0.5 * sin(2 * pi * t / {period!r}))",
        "period": period,
        "profile": "womersley",
    }
    case, submesh, tags = pipe(4e-4, {"inlet": inlet}, length=SLICE)
    solver = solver_of(case, submesh, tags, "bdf2")
    dt = 0.01
    for k in range(1, 6):
        t = k * dt
        assert solver.step(t, dt).converged
        solver.advance()
        q = metrics.flow_rate(solver.u, tags, [Boundary.INLET], -1.0)
        exact = Q0 * (1 + 0.5 * np.sin(2 * np.pi * t / period))
        assert abs(q / exact - 1) < 2e-2, (t, q, exact)
    owned = solver.V.dofmap.index_map.size_local
    x = solver.V.tabulate_dof_coordinates()[:owned]
    on_axis = (np.abs(x[:, 0]) < 1e-12) & (np.hypot(x[:, 1], x[:, 2]) < 1e-12)
    values = solver.u.x.array.reshape(-1, 3)[:owned][on_axis, 0]
    centre = solver.comm.allreduce([float(v) for v in values], op=MPI.SUM)
    profile = inflow_profiles.FlowRateProfile(
        inlet_flow_rate(case.fluid.inlet), np.zeros(1), R, period, RHO, MU, axisymmetric=True
    )
    assert centre and np.allclose(centre, profile(t)[0], rtol=1e-10, atol=0), (centre, profile(t))


FIELDSPLIT = {
    "ksp_type": "fgmres",
    "ksp_rtol": 1e-10,
    "ksp_max_it": 400,
    "ksp_gmres_restart": 200,
    "pc_type": "fieldsplit",
    "pc_fieldsplit_type": "schur",
    "pc_fieldsplit_schur_fact_type": "lower",
    "pc_fieldsplit_schur_precondition": "selfp",
    "fieldsplit_u_ksp_type": "preonly",
    "fieldsplit_u_pc_type": "hypre",
    "fieldsplit_p_ksp_type": "preonly",
    "fieldsplit_p_pc_type": "hypre",
}
"""The fluid's iterative preset of docs/3d.md: FGMRES with a block-triangular Schur
preconditioner, its fields ``u`` and ``p`` the solver's (fsi.physics.fluid._owned_rows)."""


def test_the_fieldsplit_preset_gives_the_direct_solvers_flow():
    """Five BDF2 steps of blood (ρ 1,060) driven by 2,500 Pa/m through the pipe (0.5 mm): the
    fieldsplit preset's velocity equals MUMPS's to 1e-9 of its peak, each linear solve within
    60 iterations (measured 19–20), and its fields split the owned rows of the matrix."""
    section = {
        "inlet": {"kind": "pressure", "formula": repr(2500.0 * L)},
        "solver": {"rtol": 1e-20, "atol": 1e-10},
    }
    # One mesh for both solvers: two builds may be partitioned apart on several ranks.
    case, submesh, tags = pipe(5e-4, section, density=1060.0)
    velocities, iterations = {}, {}
    direct = case.fluid.solver.petsc_options  # the default: MUMPS's LU
    assert direct["pc_type"] == "lu"
    for name, options in (("lu", direct), ("fieldsplit", FIELDSPLIT)):
        settings = replace(case.fluid, solver=replace(case.fluid.solver, petsc_options=options))
        conditions = fluid_case.fluid_conditions(case)
        solver = fluid.FluidSolver(submesh, tags, settings, conditions, scheme="bdf2")
        ksp = solver.newton.solver.krylov_solver
        counts = []
        for k in range(1, 6):
            assert solver.step(k * 1e-3, 1e-3).converged
            counts.append(ksp.getIterationNumber())
            solver.advance()
        velocities[name], iterations[name] = solver.u.x.array.copy(), counts
        fields = solver.newton.fields
        rows = np.concatenate([fields["u"].getIndices(), fields["p"].getIndices()])
        start, end = ksp.getOperators()[0].getOwnershipRange()
        assert np.array_equal(np.sort(rows), np.arange(start, end))
    assert iterations["lu"] == [1] * 5 and 1 < max(iterations["fieldsplit"]) <= 60, iterations
    peak = MPI.COMM_WORLD.allreduce(np.abs(velocities["lu"]).max(), op=MPI.MAX)
    difference = np.abs(velocities["fieldsplit"] - velocities["lu"]).max()
    assert MPI.COMM_WORLD.allreduce(difference, op=MPI.MAX) < 1e-9 * peak
