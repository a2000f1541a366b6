"""Equal-order P1–P1 (``fluid.element: p1p1``, docs/boundary-conditions.md §7): linear velocity
and pressure held together by the stabilized form's PSPG and LSIC terms.

P1–P1 fails the inf-sup condition, so only the stabilized form has a solution; what must hold
is that it converges to the exact one and stays stable where the Galerkin form is not. Linear
velocities have no strong viscous term, so the residual R the stabilization uses is not zero
on the exact solution (Poiseuille's R = ∇p − μΔu loses −μΔu): the method is consistent only to
O(h), which the pressure shows. The option is refused where it cannot run (exit 2, naming the
key): without ``supg`` (no PSPG) and with a structure (the interface pairs P2 nodes).
"""

from mpi4py import MPI

import numpy as np
import pytest
from test_fluid import channel
from test_open_boundaries import H, L, march_channel, study_fluid

from fsi import cli, config
from fsi.geometry.tags import Boundary
from fsi.output import metrics
from fsi.physics import fluid, fluid_case

G, MU = 300.0, 0.0035  # Pa/m, Pa s: the 300 Pa/m channel of test_open_boundaries


def poiseuille_errors(size: float) -> tuple[float, float, float]:
    """The steady P1–P1 channel under 300 Pa/m (ρ = 1: Re ≈ 1, a solve from rest) on ``size``
    cells, against Poiseuille: the largest velocity error at the nodes over the peak velocity,
    the largest pressure error over the pressure drop, the flow rate's relative error."""
    case, submesh, tags = channel(
        size,
        study_fluid(
            "newtonian",
            element="p1p1",
            density=1.0,
            inlet={"kind": "pressure", "formula": repr(G * L)},
        ),
    )
    solver = fluid.FluidSolver(
        submesh, tags, case.fluid, fluid_case.fluid_conditions(case), scheme="steady"
    )
    result = solver.step(1.0, 1.0)
    assert result.converged, result
    comm = solver.comm
    x, u = solver.V.tabulate_dof_coordinates(), solver.u.x.array.reshape(-1, 2)
    peak = G * H**2 / (8 * MU)
    velocity = np.abs(u[:, 0] - G / (2 * MU) * x[:, 1] * (H - x[:, 1])).max(initial=0.0)
    xp = solver.Q.tabulate_dof_coordinates()
    pressure = np.abs(solver.p.x.array - G * (L - xp[:, 0])).max(initial=0.0)
    q = metrics.flow_rate(solver.u, tags, [Boundary.OUTLET])
    return (
        comm.allreduce(velocity, op=max) / peak,
        comm.allreduce(pressure, op=max) / (G * L),
        abs(q / (G * H**3 / (12 * MU)) - 1),
    )


def test_p1p1_converges_to_poiseuille_flow():
    """Halving the cells from 1 mm to 0.5 mm to 0.25 mm: the nodal velocity error falls at
    least 2.5× per halving (measured 6.2 % → 1.5 % → 0.57 %: 4.0×, 2.7×), the flow rate's too
    (5.2 % → 1.5 % → 0.52 %: 3.5×, 2.9×), and the pressure's at least 1.8× (4.9 % → 2.5 % →
    1.2 %: 1.9×, 2.1×, first order: the O(h) inconsistency of the residual without its viscous
    term). On 0.25 mm cells the flow rate is within 1 % of Poiseuille's. P2–P1 with the same
    stabilization is exact here (test_open_boundaries::test_supg_leaves_poiseuille_flow_exact)."""
    errors = np.array([poiseuille_errors(size) for size in (1e-3, 5e-4, 2.5e-4)])
    ratios = errors[:-1] / errors[1:]
    assert (ratios[:, 0] > 2.5).all() and (ratios[:, 2] > 2.5).all(), errors
    assert (ratios[:, 1] > 1.8).all(), errors
    assert errors[-1, 2] < 1e-2, errors


def test_p1p1_holds_the_fast_channel_the_galerkin_form_cannot():
    """The 300 Pa/m channel from rest (Newtonian, ρ = 1060: Poiseuille peak 0.525 m/s, cell
    Reynolds number ≈ 80 on the 0.5 mm cells, where the Galerkin form fails at t ≈ 1.5 s) with
    the study's fluid settings on P1–P1, BDF2, dt 0.02 s, to 10 s: every step converges, in
    ≤ 4 Newton iterations on average (measured 3.1), and the flow settles (its last 10 % move by
    < 0.1 %, measured 0.05 %) within 10 % of Poiseuille's flow rate: P1's error on 0.5 mm cells
    (measured −9.0 %; −16.9 % on 1 mm, −2.2 % on 0.25 mm cells; P2–P1 −0.000 %)."""
    _, late, newton = march_channel(study_fluid("newtonian", element="p1p1"), G, 0.02, 9.0, 10.0)
    assert np.abs(late).max() < 0.1, np.abs(late).max()
    assert np.ptp(late[:, 1]) < 1e-3, np.ptp(late[:, 1])
    assert newton <= 4, newton


@pytest.mark.parametrize(
    "overrides, reason",
    [
        (["structure.mode=rigid", "fluid.supg=false"], "fluid.supg is false"),
        ([], "structure.mode is not 'rigid'"),
    ],
)
def test_p1p1_is_refused_where_it_cannot_run(shared_tmp, capsys, overrides, reason):
    """Without the stabilization P1–P1 has no pressure; with a structure the interface maps
    would pair P1 fluid nodes with P2 solid ones: both exit 2 at ``fsi check``, naming the key
    and the reason, before anything is computed."""
    args = ["check", "configs/stenosis_fixed_newtonian.yaml", "--set", "fluid.element=p1p1"]
    for item in overrides:
        args += ["--set", item]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:  # rank 0 prints the error
        assert "fluid.element" in err and reason in err, err
    with pytest.raises(config.ConfigError, match="fluid.element: expected one of"):
        config.load("configs/stenosis_fixed_newtonian.yaml", ["fluid.element=q2q1"])
