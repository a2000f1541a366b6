"""The axisymmetric fluid (issue #28; docs/axisymmetric.md) against the exact pipe flows.

The rigid tube (``geometry.kind: tube``, ``structure.mode: rigid``) is the meridian half-plane
of a circular pipe: x the axis z, y the radius r. Its fluid has the hoop terms (u_r/r in the
divergence, the strain rate, the viscous term and SUPG's strong residual) and every integral
weighted by 2π r, so its flow rate is in m³/s. Poiseuille's flow is a discrete solution of P2/P1
(quadratic u, linear p, and SUPG's strong residual zero for it), so it is met to round-off;
Womersley's (Bessel functions) to the discretisation's error. The plane answers are unchanged
bit for bit (the plane tests; test_plane_forms_are_unchanged here).
"""

from mpi4py import MPI

import numpy as np
import pytest
import scipy.integrate
import scipy.special
import support_physics
from test_open_boundaries import (
    WOMERSLEY_PERIOD,
    WOMERSLEY_PRESSURE,
    march_womersley,
    study_fluid,
)

from fsi import config
from fsi.geometry.tags import Boundary, Region
from fsi.output import metrics
from fsi.physics import fluid, fluid_case, inflow_profiles, mesh
from fsi.run import steppers

L, R = 0.02, 0.004  # the pipe: length, radius (m)


def pipe(size: float, fluid_section: dict, comm: MPI.Comm = MPI.COMM_WORLD, **geometry):
    """The rigid tube case (2 cm × 4 mm radius), its fluid solver's mesh and facet tags."""
    case = config.from_dict(
        {
            "geometry": {"kind": "tube", "length": L, "radius": R, **geometry},
            "structure": {"mode": "rigid"},
            "mesh": {"size": size, "local_size": size},
            "fluid": fluid_section,
        }
    )
    part = mesh.restrict(mesh.build(case, comm), Region.FLUID)
    return case, part.mesh, part.facet_tags


def solver_of(case, submesh, tags, scheme: str) -> fluid.FluidSolver:
    return fluid.FluidSolver(
        submesh,
        tags,
        case.fluid,
        fluid_case.fluid_conditions(case),
        scheme=scheme,
        axisymmetric=config.is_axisymmetric(case.geometry),
    )


def test_poiseuille_pipe_flow_is_exact():
    """The pipe under a pressure drop G L (G = 300 Pa/m, μ = 0.0035 Pa s, steady, SUPG on, ρ = 1
    for a steady solve from rest) with the study's open-boundary settings: u_z = G (R² − r²)/(4μ),
    u_r = 0 and p = G (L − z) at every node to 1e-10 of the peak, so Q = π R⁴ G / (8 μ) (the
    issue asks 0.5 %; met to round-off) through the inlet and the outlet, in m³/s, and the wall
    shear stress G R / 2 (the output's field and columns)."""
    G, mu = 300.0, 0.0035
    section = study_fluid(
        "newtonian", supg=True, density=1.0, inlet={"kind": "pressure", "formula": repr(G * L)}
    )
    case, submesh, tags = pipe(1e-3, section)
    solver = solver_of(case, submesh, tags, "steady")
    result = solver.step(1.0, 1.0)
    assert result.converged and result.iterations >= 1, result
    x = solver.V.tabulate_dof_coordinates()
    u = solver.u.x.array.reshape(-1, 2)
    peak = G * R**2 / (4 * mu)
    assert np.abs(u[:, 0] - G * (R**2 - x[:, 1] ** 2) / (4 * mu)).max() < 1e-10 * peak
    assert np.abs(u[:, 1]).max() < 1e-10 * peak
    xp = solver.Q.tabulate_dof_coordinates()
    assert np.abs(solver.p.x.array - G * (L - xp[:, 0])).max() < 1e-10 * G * L

    exact = np.pi * R**4 * G / (8 * mu)
    coords = solver.coordinates
    q_in = metrics.flow_rate(solver.u, tags, [Boundary.INLET], -1.0, coordinates=coords)
    q_out = metrics.flow_rate(solver.u, tags, [Boundary.OUTLET], coordinates=coords)
    assert abs(q_in / exact - 1) < 1e-9 and abs(q_out / exact - 1) < 1e-9, (q_in, q_out, exact)
    outputs = steppers.FluidOutputs(case, solver)
    row = outputs.update()
    assert abs(row["inlet_flow_rate"] / exact - 1) < 1e-9, row
    assert abs(row["max_wss"] / (G * R / 2) - 1) < 1e-8, row
    assert abs(row["mean_inlet_pressure"] / (G * L) - 1) < 1e-9, row


def test_the_axis_holds_only_the_radial_velocity():
    """On the axis u_r = 0 and u_z is free: the Poiseuille solution's centreline speed
    G R²/(4 μ) is reached there (not held at 0 as on a wall), on 1 and 2 ranks alike."""
    G, mu = 300.0, 0.0035
    section = study_fluid(
        "newtonian", density=1.0, inlet={"kind": "pressure", "formula": repr(G * L)}
    )
    case, submesh, tags = pipe(1e-3, section)
    solver = solver_of(case, submesh, tags, "steady")
    assert solver.step(1.0, 1.0).converged
    owned = solver.V.dofmap.index_map.size_local
    x = solver.V.tabulate_dof_coordinates()[:owned]
    on_axis = np.isclose(x[:, 1], 0.0)
    u = solver.u.x.array.reshape(-1, 2)[:owned][on_axis]
    found = solver.comm.allreduce(len(u))
    assert found > 0
    centre = G * R**2 / (4 * mu)
    worst = solver.comm.allreduce(np.abs(u[:, 0] - centre).max(initial=0.0), op=MPI.MAX)
    assert worst < 1e-10 * centre, worst
    assert solver.comm.allreduce(np.abs(u[:, 1]).max(initial=0.0), op=MPI.MAX) == 0.0


def pipe_womersley(r: np.ndarray, rho: float, mu: float) -> tuple[np.ndarray, complex]:
    """Womersley's pipe flow under the pressure drop P cos(ωt) over L
    (:func:`support_physics.womersley_pipe`)."""
    return support_physics.womersley_pipe(r, R, WOMERSLEY_PRESSURE / L, WOMERSLEY_PERIOD, rho, mu)


def womersley_errors(size: float) -> tuple[float, float]:
    """The pipe driven by P cos(2πt/T) at its inlet with the study's fluid settings (as the
    plane channel's Womersley test, test_open_boundaries), started from the exact periodic
    state and marched for 1.5 periods (BDF2, dt 5 ms): the largest errors over the last
    period of the peak velocity and of the outlet flow rate, relative to their amplitudes.
    The flow reverses completely twice a period."""
    formula = f"{WOMERSLEY_PRESSURE} * cos(2 * pi * t / {WOMERSLEY_PERIOD})"
    section = study_fluid("newtonian", inlet={"kind": "pressure", "formula": formula})
    case, submesh, tags = pipe(size, section)
    solver = solver_of(case, submesh, tags, "bdf2")
    rho, mu = case.fluid.density, case.fluid.rheology.viscosity
    u_hat, q_hat = pipe_womersley(np.linspace(0, R, 801), rho, mu)
    return march_womersley(solver, tags, lambda r: pipe_womersley(r, rho, mu)[0], u_hat, q_hat)


def test_womersley_pipe_flow_within_one_percent():
    """Womersley flow in the rigid pipe (300 Pa/m amplitude, T = 0.5 s, Womersley number
    R sqrt(ωρ/μ) = 7.8): over the last period the peak velocity and the outlet flow rate
    within 1 % of their amplitudes (the issue's tolerance) on 0.25 mm cells, the full reversal
    through the study's open boundaries included (measured: see docs/axisymmetric.md)."""
    peak, flow = womersley_errors(2.5e-4)
    assert peak < 1e-2 and flow < 1e-2, (peak, flow)


@pytest.mark.parametrize("axisymmetric", [False])
def test_plane_forms_are_unchanged(axisymmetric):
    """A plane solver's residual is the UFL it was before the coordinates existed: the
    weak form's measures are the plain ones (no 2π r), the divergence ufl.div."""
    section = study_fluid("newtonian", inlet={"kind": "pressure", "formula": "1"})
    case, submesh, tags = pipe(1e-3, section, axisymmetric=axisymmetric)
    solver = solver_of(case, submesh, tags, "bdf2")
    assert not solver.coordinates.axisymmetric
    text = str(solver.residual_form)
    assert "x[1]" not in text and "6.28" not in text


def test_the_pipe_womersley_inlet_profile_is_the_exact_one():
    """The flow-rate inlet's pipe profile of one harmonic (fsi.physics.inflow_profiles, scaled
    Bessel functions) equals Womersley's solution above (plain Bessel functions) per unit
    flux, û/Q̂, to 1e-9 of its peak, at the test's ω and at ten times it; and it carries unit
    flux (∫ φ 2π r dr = 1 to 1e-9, Simpson's rule on 4001 points)."""
    rho, mu = 1060.0, 0.0035
    r = np.linspace(0, R, 4001)
    omega = 2 * np.pi / WOMERSLEY_PERIOD
    u_hat, q_hat = pipe_womersley(r, rho, mu)
    phi = inflow_profiles.pipe_womersley(r, R, omega, rho, mu)
    assert np.abs(phi - u_hat / q_hat).max() < 1e-9 * np.abs(phi).max()
    for w in (omega, 10 * omega):
        phi = inflow_profiles.pipe_womersley(r, R, w, rho, mu)
        assert abs(scipy.integrate.simpson(phi * 2 * np.pi * r, x=r) - 1) < 1e-9


def test_a_flow_rate_inlet_carries_its_flow_rate_through_the_pipe():
    """A steady parabolic flow-rate inlet of Q = 2e-6 m³/s (a carotid's mean) in the rigid pipe
    (ρ = 1, steady): the velocity everywhere is the pipe's Poiseuille flow 2 Q/(π R²) (1 − r²/R²)
    to 1e-10 of its peak, and the outlet's flow rate is Q (m³/s) to 1e-9."""
    Q = 2e-6
    section = study_fluid(
        "newtonian",
        density=1.0,
        inlet={"kind": "flow_rate", "formula": repr(Q)},
        inlet_open_boundary="same",
    )
    case, submesh, tags = pipe(1e-3, section)
    solver = solver_of(case, submesh, tags, "steady")
    assert solver.step(1.0, 1.0).converged
    x = solver.V.tabulate_dof_coordinates()
    u = solver.u.x.array.reshape(-1, 2)
    peak = 2 * Q / (np.pi * R**2)
    assert np.abs(u[:, 0] - peak * (1 - (x[:, 1] / R) ** 2)).max() < 1e-10 * peak
    assert np.abs(u[:, 1]).max() < 1e-10 * peak
    q_out = metrics.flow_rate(solver.u, tags, [Boundary.OUTLET], coordinates=solver.coordinates)
    assert abs(q_out / Q - 1) < 1e-9, q_out
