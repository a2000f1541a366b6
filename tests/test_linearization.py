"""The fluid's linearization (``fluid.solver.linearization``): ``extrapolated`` takes the
advecting velocity, the viscosity and the stabilization's τ from the extrapolation
u* = (1 + r) u^n − r u^{n−1} of the accepted steps, so each step is one linear problem. It must
keep BDF2's second order and stay beside the Newton solution of the same step size.

The flow is the study's rigid-wall Carreau stenosis (configs/stenosis_fixed_carreau.yaml,
coarse mesh, structure.mode rigid: every viscosity and advection term nonlinear) driven from
rest by the 5 ms traction pulse, with constant steps to t = 10 ms.
"""

from mpi4py import MPI

import dolfinx.fem
import numpy as np
import pytest
import ufl

from fsi import cli, config
from fsi.numerics.timestepping import steps
from fsi.run import steppers

CARREAU = "configs/stenosis_fixed_carreau.yaml"
END = 0.01


def velocity_at_end(linearization: str, dt: float) -> dolfinx.fem.Function:
    """The velocity at t = 10 ms of the rigid Carreau stenosis with constant steps ``dt``; with
    the extrapolated linearization every step must take one Newton iteration (fresh Jacobians:
    ``jacobian_reuse: none``)."""
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
    return stepper.solver.u


def distance(a: dolfinx.fem.Function, b: dolfinx.fem.Function) -> float:
    """‖a − b‖_L2 (m/s · m) over the fluid (the same mesh and space)."""
    form = dolfinx.fem.form(ufl.inner(a - b, a - b) * ufl.dx(a.function_space.mesh))
    local = dolfinx.fem.assemble_scalar(form)
    return float(np.sqrt(a.function_space.mesh.comm.allreduce(local, op=MPI.SUM)))


def test_extrapolated_linearization_keeps_second_order():
    """Halving dt from 1 ms to 0.5 ms to 0.25 ms: the extrapolated solution's successive
    differences (L2 norm of the velocity at 10 ms) fall by at least 3× (second order: 4×;
    measured 7.5e-5 → 1.1e-5 m²/s, 6.8×; Newton's 8.2e-5 → 1.2e-5, 7.1×: the step from rest is
    not yet asymptotic), and at 0.25 ms it is within a quarter of Newton's own time error
    (≈ its last difference / 3, Richardson) of the Newton solution (measured 1.7e-7 m²/s,
    0.04× of it)."""
    dts = (1e-3, 5e-4, 2.5e-4)
    newton = [velocity_at_end("newton", dt) for dt in dts]
    extrapolated = [velocity_at_end("extrapolated", dt) for dt in dts]
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
