"""The fluid's linearization (``fluid.solver.linearization``): ``extrapolated`` takes the
advecting velocity, the viscosity and the stabilization's τ from the extrapolation
u* = (1 + r) u^n − r u^{n−1} of the accepted steps, so each step is one linear problem. It must
keep BDF2's second order and stay beside the Newton solution of the same step size.

The flow is the study's rigid-wall Carreau stenosis (configs/stenosis_fixed_carreau.yaml,
coarse mesh, structure.mode rigid: every viscosity and advection term nonlinear) driven from
rest by the 5 ms traction pulse, with constant steps to t = 10 ms.
"""

from mpi4py import MPI

import numpy as np
import pytest
from test_newton import gathered_by_position

from fsi import cli, config
from fsi.numerics.timestepping import steps
from fsi.run import steppers

CARREAU = "configs/stenosis_fixed_carreau.yaml"
END = 0.01


def velocity_at_end(linearization: str, dt: float) -> steppers.RigidStepper:
    """The rigid Carreau stenosis marched with constant steps ``dt`` to t = 10 ms (its
    ``solver.u`` the velocity there); with the extrapolated linearization every step must take
    one Newton iteration (fresh Jacobians: ``jacobian_reuse: none``). The stepper is returned
    to be kept: a solver dropped within a test may be collected on one rank before the other,
    and PETSc destroys its objects collectively (conftest collects after every test)."""
    case = config.load(
        CARREAU,
        [
            "structure.mode=rigid",
            f"time.end={END}",
            f"time.schedule=[{{until: {END}, dt: {dt}}}]",
            f"fluid.solver.linearization={linearization}",
            "fluid.solver.jacobian_reuse=none",
        ],
    )
    stepper = steppers.RigidStepper(case, MPI.COMM_WORLD)
    for step in steps(case.time):
        row = stepper.step(step)
        if linearization == "extrapolated":
            assert row["newton_iterations"] == 1, row
    return stepper


def nodal_velocity(stepper: steppers.RigidStepper) -> np.ndarray:
    """The velocity at every node of the mesh, on every rank, ordered by the nodes'
    coordinates: comparable between runs whose meshes are the same but numbered and
    partitioned independently."""
    V = stepper.solver.V
    owned = V.dofmap.index_map.size_local
    u = stepper.solver.u.x.array.reshape(-1, 2)[:owned]
    return gathered_by_position(MPI.COMM_WORLD, V.tabulate_dof_coordinates()[:owned], u)


def distance(a: np.ndarray, b: np.ndarray) -> float:
    """The root mean square of the nodal velocity difference (m/s)."""
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def test_extrapolated_linearization_keeps_second_order():
    """Halving dt from 1 ms to 0.5 ms to 0.25 ms: the extrapolated solution's successive
    differences (RMS over the nodes of the velocity at 10 ms) fall by at least 3× (second
    order: 4×; measured 6.6e-3 → 9.7e-4 m/s, 6.8×; Newton's 7.3e-3 → 1.0e-3, 7.1×: the steps
    from rest are not yet asymptotic), and at 0.25 ms it is within a quarter of Newton's own
    time error (≈ its last difference / 3, Richardson) of the Newton solution (measured
    1.9e-5 m/s, 0.06× of it; the same on 1 and 2 ranks to 1e-15)."""
    dts = (1e-3, 5e-4, 2.5e-4)
    runs = {  # the steppers are kept: see velocity_at_end
        name: [velocity_at_end(name, dt) for dt in dts] for name in ("newton", "extrapolated")
    }
    newton, extrapolated = ([nodal_velocity(r) for r in runs[name]] for name in runs)
    changes = {
        name: [distance(u[k], u[k + 1]) for k in range(2)]
        for name, u in (("newton", newton), ("extrapolated", extrapolated))
    }
    for name, (coarse, fine) in changes.items():
        assert coarse / fine > 3.0, (name, changes)
    # Newton's time error at 0.25 ms ≈ its last change / 3 (Richardson, second order).
    gap = distance(newton[-1], extrapolated[-1])
    assert gap < 0.25 * changes["newton"][1] / 3, (gap, changes)


def test_extrapolated_linearization_needs_past_steps(capsys):
    """A steady solve has no past steps to extrapolate from: exit 2 naming the key."""
    args = ["check", CARREAU, "--set", "time.scheme=steady"]
    args += ["--set", "fluid.solver.linearization=extrapolated"]
    args += ["--set", "structure.time_integration.scheme=quasi_static"]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert "fluid.solver.linearization: expected 'newton' when time.scheme is 'steady'" in err
    with pytest.raises(
        config.ConfigError, match="structure.solver.linearization: expected one of the keys"
    ):
        config.load(CARREAU, ["structure.solver.linearization=extrapolated"])
