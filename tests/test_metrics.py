"""Flow rates (fsi.output.metrics.flow_rate) on Poiseuille flow: exact at the inlet and the outlet,
positive downstream, on the mesh as it is now; 1 rank = 2 ranks (the suite runs on both)."""

import dolfinx.fem
import numpy as np
import pytest
from test_fluid import INLET, OUTLET, channel, pressure_driven

from fsi import compat
from fsi.output import metrics

H = 0.007  # the height of test_fluid.channel


def poiseuille(U: float, size: float = 1e-3):
    """u = (6 U y (H − y)/H², 0) interpolated into P2 on the channel: exact, since P2 holds
    the parabola; its flow rate per unit depth is Q = ∫₀^H u_x dy = U H. Returns u and the
    channel's facet tags."""
    _, submesh, tags = channel(size, {})
    u = dolfinx.fem.Function(compat.function_space(submesh, "Lagrange", 2, shape=(2,)))
    u.interpolate(lambda x: np.stack([6 * U * x[1] * (H - x[1]) / H**2, 0 * x[0]]))
    return u, tags


@pytest.mark.parametrize("U", [0.1, -0.1])
def test_poiseuille_flow_rate_is_exact_and_positive_downstream(U):
    u, tags = poiseuille(U)
    exact = U * H
    q_in = metrics.flow_rate(u, tags, [INLET], sign=-1.0)
    q_out = metrics.flow_rate(u, tags, [OUTLET])
    # measured: ≤ 1.1e-16 relative, net 1.5e-16 (1 and 2 ranks)
    assert abs(q_in / exact - 1) < 1e-13 and abs(q_out / exact - 1) < 1e-13
    # Both boundaries at once with the outward sign: the net outflow, zero for a solenoidal u.
    assert abs(metrics.flow_rate(u, tags, [INLET, OUTLET])) < 1e-13 * abs(exact)
    # The same value on every rank (reduced, not a local sum).
    assert u.function_space.mesh.comm.allgather(q_in) == [q_in] * u.function_space.mesh.comm.size


def test_flow_rate_is_taken_on_the_moved_mesh():
    """Stretching the channel to twice its height (the nodal values stay) doubles the flux:
    the forms read the mesh's current coordinates, as after an ALE move."""
    U = 0.1
    u, tags = poiseuille(U)
    mesh = u.function_space.mesh
    mesh.geometry.x[:, 1] *= 2.0
    assert metrics.flow_rate(u, tags, [INLET], sign=-1.0) == pytest.approx(2 * U * H, rel=1e-13)
    assert metrics.flow_rate(u, tags, [OUTLET]) == pytest.approx(2 * U * H, rel=1e-13)


def test_solved_poiseuille_flow_rate_is_g_h3_over_12_mu():
    """The steady P2/P1 solution of a pressure-driven channel (test_fluid.pressure_driven) is
    Poiseuille's to the LU solve's round-off, so its flow rate is Q = G H³/(12 μ) to that."""
    G = 1.0
    _, solver = pressure_driven(1e-3, {"model": "newtonian"}, G)
    exact = G * H**3 / (12 * solver.law.viscosity)
    q_in = metrics.flow_rate(solver.u, solver.facet_tags, [INLET], sign=-1.0)
    q_out = metrics.flow_rate(solver.u, solver.facet_tags, [OUTLET])
    # measured: ≤ 2e-15 relative (1 and 2 ranks); 1e-10 as test_fluid's Poiseuille test allows
    assert abs(q_in / exact - 1) < 1e-10 and abs(q_out / exact - 1) < 1e-10
