"""The steppers of ``fsi run``, one per kind of run: each builds the mesh and the solvers of a
case, advances one step and returns the step's metrics row, and hands the time loop
(:func:`fsi.run.simulation.march`) its columns, field files, summary and checkpoint state.

:class:`RigidStepper` (``structure.mode: rigid``) solves the fluid alone, with no-slip on every
wall and on the (then rigid) interface and obstacle. :class:`CoupledStepper` (the coupled modes
``fixed_wall``, ``moving_wall``; docs/model.md, Coupling) solves the partitioned fluid–structure
problem of fsi/coupled/partitioned.py. :class:`StructureStepper` solves the structure alone
(``structure.interface_load``: ``inlet_pressure`` or ``none``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Protocol

from mpi4py import MPI

import numpy as np

from fsi import config
from fsi.coupled import coupling, partitioned
from fsi.geometry import tube, turek_hron, vessel_3d
from fsi.geometry.tags import Boundary, Region
from fsi.numerics import newton
from fsi.numerics.timestepping import Step
from fsi.output import metrics
from fsi.output.columns import COLUMNS, COUPLED_COLUMNS, stress_columns, stress_row
from fsi.output.wall_outputs import FluidOutputs
from fsi.physics import fluid_case, mesh, solid
from fsi.physics.fluid_boundaries import inlet_pressure
from fsi.physics.mesh_motion import MeshQualityError
from fsi.run import state_arrays, time_errors
from fsi.run.errors import StepFailed
from fsi.run.state_arrays import (
    Layout,
    fluid_layouts,
    fluid_state,
    load_solid,
    structure_layouts,
    wall_index_layouts,
)

# --------------------------------------------------------------------------------------------
# What a stepper is


def global_dofs(V) -> int:
    """Number of degrees of freedom of a function space over all ranks."""
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


class Stepper(Protocol):
    """One kind of run: its columns, its field files and how it advances one step."""

    columns: list[str]

    def field_files(self) -> dict[str, tuple[object, list]]:
        """File name → (mesh, fields) of each field time series (the fields are Functions
        whose values change in place)."""

    def step(self, step: Step) -> dict:
        """Advance one step; return its metrics row (raise :class:`StepFailed` on failure)."""

    def describe(self, row: dict) -> str:
        """The step's solver statistics for the progress log."""

    def summary(self) -> dict:
        """Totals and sizes for summary.json."""

    def state(self) -> dict[str, np.ndarray]:
        """Everything the next steps depend on, as named local arrays (a checkpoint): the
        solvers' state and history, the coupling's memory, the counters of :meth:`summary`."""

    def layouts(self) -> dict[str, Layout]:
        """Where the rows of the distributed arrays of :meth:`state` live (array name or name
        prefix → layout; the others are global), taken from the reference configuration when
        the stepper is built."""

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Continue from :meth:`state`'s arrays (on this run's dofs, :func:`fsi.run.checkpoint.
        localize`); the output fields are brought up to date."""

    def forget_jacobians(self) -> None:
        """Drop the Jacobians the solvers keep across steps (``solver.jacobian_reuse: run``), so
        the next step goes on as one restarted from :meth:`state` would."""

    def write_checkpoint_files(
        self, out: Path, comm: MPI.Comm, state: dict[str, np.ndarray]
    ) -> None:
        """Write into ``out`` the files derived from a checkpointed :meth:`state` (the fluid's
        ``wall_indices.csv``; nothing for the structure alone). Collective."""


def _forget_jacobians(*solvers) -> None:
    """Drop the Jacobians the Newton solvers of ``solvers`` keep across steps."""
    for solver in solvers:
        solver.newton.callbacks.forget()


def _solve(
    solver,
    step: Step,
    failure: Callable[[newton.SolveResult], str],
    measure: Callable[[], dict] | None = None,
) -> tuple[newton.SolveResult, dict]:
    """``solver``'s step to ``step.t``, committed (``advance``), and what ``measure()`` gives
    just before it is (``{}`` without one); if it did not converge, :class:`StepFailed` with the
    message ``failure(result)``."""
    result = solver.step(step.t, step.dt)
    if not result.converged:
        raise StepFailed(failure(result))
    measured = measure() if measure is not None else {}
    solver.advance()
    return result, measured


class _Checkpointed:
    """What the steppers give their checkpoints alike: :meth:`Stepper.layouts` (the solvers'
    and the wall indices', ``_layouts``, then the time errors') and
    :meth:`Stepper.write_checkpoint_files` (the fluid outputs', ``outputs``, if any)."""

    _layouts: dict[str, Layout]
    time_errors: time_errors.TimeErrors
    outputs: FluidOutputs | None = None

    def layouts(self) -> dict[str, Layout]:
        return {**self._layouts, **self.time_errors.layouts()}

    def write_checkpoint_files(
        self, out: Path, comm: MPI.Comm, state: dict[str, np.ndarray]
    ) -> None:
        if self.outputs is not None:
            self.outputs.write_checkpoint_files(out, comm, state)


# --------------------------------------------------------------------------------------------
# Rigid structure: the fluid alone


class RigidStepper(_Checkpointed):
    """The fluid alone on the fixed fluid mesh (Turek–Hron cases add drag and lift)."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        self.whole = mesh.build(case, comm)
        self.part = mesh.restrict(self.whole, Region.FLUID)
        self.cells = mesh.summary(self.whole, case)["cells"]
        self.solver = fluid_case.fluid_solver(case, self.part)
        self.obstacle = [
            b for b in (Boundary.OBSTACLE, Boundary.INTERFACE) if b in mesh.boundaries(case)
        ]
        self.turek_hron = isinstance(case.geometry, config.TurekHronGeometry)
        self.outputs = FluidOutputs(case, self.solver)
        self._layouts = {**fluid_layouts(self.solver), **wall_index_layouts(self.outputs)}
        self.time_errors = time_errors.build(case, comm, {"fluid": (self.solver.u, self._layouts)})
        self.columns = (
            COLUMNS
            + self.outputs.columns
            + (["drag", "lift"] if self.turek_hron else [])
            + self.time_errors.columns
        )

    def field_files(self) -> dict[str, tuple[object, list]]:
        return {"fields.xdmf": (self.part.mesh, self.outputs.fields)}

    def forget_jacobians(self) -> None:
        _forget_jacobians(self.solver)

    def step(self, step: Step) -> dict:
        solver = self.solver
        # Turek–Hron's forces before the step is accepted: its residual needs its time history.
        forces = (
            (lambda: dict(zip(("drag", "lift"), solver.boundary_force(self.obstacle))))
            if self.turek_hron
            else None
        )
        result, measured = _solve(solver, step, lambda failed: failed.reason, measure=forces)
        row = {
            "peak_velocity": metrics.peak_velocity(solver.u),
            "peak_pressure": metrics.peak_pressure(solver.p),
            "peak_displacement": 0.0,
            "coupling_iterations": 0,
            "newton_iterations": result.iterations,
            "newton_residual": result.residual,
            **self.outputs.update(),
            **self.time_errors.after_step(step.t),
            **measured,
        }
        return row

    def describe(self, row: dict) -> str:
        return f"Newton {row['newton_iterations']} (residual {row['newton_residual']:.2e})"

    def summary(self) -> dict:
        W = self.solver.W
        return {
            "mean_coupling_iterations": 0.0,
            "fluid_dofs": global_dofs(W),
            "cells": self.cells,
            **self.outputs.summary(),
        }

    def state(self) -> dict[str, np.ndarray]:
        return {
            **state_arrays.to_arrays("fluid.", self.solver.save_state()),
            **self.outputs.state(),
            **self.time_errors.state(),
        }

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        self.solver.restore_state(fluid_state(self.solver, state))
        self.outputs.load_state(state)
        self.outputs.update()
        self.time_errors.load_state(state, self.solver.time)


# --------------------------------------------------------------------------------------------
# The coupled modes: partitioned fluid–structure interaction


def displacement_point(case: config.Case) -> tuple[tuple[str, str], tuple[float, float]] | None:
    """The benchmark point whose displacement a structure's rows carry, with its two column
    names: Turek–Hron's point A (``ux_A``, ``uy_A``), a tube's inner wall at mid-length
    (``uz_A``, ``ur_A``: the elastic-tube benchmarks' point A); None for other geometries."""
    g = case.geometry
    if isinstance(g, config.TurekHronGeometry):
        return ("ux_A", "uy_A"), turek_hron.point_a(g)
    if isinstance(g, config.TubeGeometry):
        if config.dimension(g) == 3:  # on the lumen at mid-length on +y: u_x axial, u_y radial
            return ("uz_A", "ur_A"), vessel_3d.point_a(g)
        return ("uz_A", "ur_A"), tube.point_a(g)
    return None


def displacement_row(eta, point) -> dict:
    """The row's displacement of :func:`displacement_point` ``point`` (m), or nothing."""
    if point is None:
        return {}
    names, xy = point
    return dict(zip(names, (float(v) for v in metrics.nodal_value(eta, xy))))


class CoupledStepper(_Checkpointed):
    """Dirichlet–Neumann iterations per step (fsi/coupled/partitioned.py), then the study's metrics:
    peaks of |u| and p over the fluid, of |η| over the structure, and the largest |σ₁₂| (SSS).
    The Turek–Hron cases add the benchmark's ``drag`` and ``lift`` (N/m, over the cylinder and
    the flag, on the deformed mesh) and the displacement ``ux_A``, ``uy_A`` (m) of point A; a
    tube the axial and radial displacement ``uz_A``, ``ur_A`` (m) of its inner wall at
    mid-length (the elastic-tube benchmarks' point A)."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        self.problem = partitioned.build_coupled(case, comm)
        self.cells = mesh.summary(self.problem.whole, case)["cells"]
        self.turek_hron = isinstance(case.geometry, config.TurekHronGeometry)
        self.point = displacement_point(case)
        self.outputs = FluidOutputs(case, self.problem.fluid)
        # Before the mesh ever moves: the checkpoint keys are reference coordinates.
        problem = self.problem
        points = problem.solid.interface_points
        interface = state_arrays.interface_layout("interface", points, problem.unknown.block)
        self._layouts = {
            **fluid_layouts(problem.fluid),
            **structure_layouts(problem.solid),
            "coupling.iqn.V": interface,
            "coupling.iqn.W": interface,
            "predictor.values": interface,
            **wall_index_layouts(self.outputs),
        }
        self.time_errors = time_errors.build(
            case,
            comm,
            {
                "fluid": (problem.fluid.u, self._layouts),
                "structure": (problem.solid.eta, self._layouts),
            },
        )
        self.columns = (
            COUPLED_COLUMNS
            + stress_columns(problem.solid)
            + self.outputs.columns
            + (["drag", "lift"] if self.turek_hron else [])
            + (list(self.point[0]) if self.point else [])
            + self.time_errors.columns
        )
        self.iterations: list[int] = []
        self.solid_newton = 0

    def field_files(self) -> dict[str, tuple[object, list]]:
        problem = self.problem
        return {
            "fields.xdmf": (problem.fluid.mesh, [*self.outputs.fields, problem.fluid.ale.d]),
            "solid.xdmf": (
                problem.solid.domain.mesh,
                [problem.solid.eta, *problem.solid.stress.cell_fields.values()],
            ),
        }

    def forget_jacobians(self) -> None:
        _forget_jacobians(self.problem.fluid, self.problem.solid)

    def step(self, step: Step) -> dict:
        problem = self.problem
        try:
            result = problem.step(step.index, step.t, step.dt)
        except coupling.CouplingNotConverged as e:
            raise StepFailed(f"{e} (t = {step.t:g} s, dt = {step.dt:g} s)") from e
        except (newton.SolveFailed, MeshQualityError) as e:
            raise StepFailed(
                f"step {step.index} to t = {step.t:g} s (dt = {step.dt:g} s), "
                f"coupling iteration {problem.fluid_side.solves}: {e}"
            ) from e
        problem.solid.stress.update()
        fluid_last = problem.fluid_side.last
        self.iterations.append(result.iterations)
        self.solid_newton += problem.solid_side.newton_iterations
        omega = problem.relaxation
        row = (
            self.forces()
            if self.turek_hron
            else {"peak_wall_displacement": problem.solid.max_displacement([Region.WALL])}
        )
        row.update(displacement_row(problem.solid.eta, self.point))
        return {
            **row,
            **self.outputs.update(),
            "peak_velocity": metrics.peak_velocity(problem.fluid.u),
            "peak_pressure": metrics.peak_pressure(problem.fluid.p),
            "peak_displacement": problem.solid.max_displacement(),
            **stress_row(problem.solid),
            "coupling_iterations": result.iterations,
            "coupling_residual": result.residuals[-1],
            "newton_iterations": problem.fluid_side.newton_iterations,
            "newton_residual": fluid_last.residual if fluid_last else "",
            "relaxation": "" if omega is None else omega,
            "solid_newton_iterations": problem.solid_side.newton_iterations,
            "mesh_jacobian_ratio": problem.fluid_side.mesh_quality,
            **self.time_errors.after_step(step.t),
        }

    def forces(self) -> dict:
        """Turek–Hron: drag and lift on the cylinder + flag."""
        drag, lift = self.problem.fluid.boundary_force((Boundary.OBSTACLE, Boundary.INTERFACE))
        return {"drag": drag, "lift": lift}

    def describe(self, row: dict) -> str:
        omega = row["relaxation"]
        return (
            f"coupling {row['coupling_iterations']} (residual "
            f"{row['coupling_residual']:.1e}{'' if omega == '' else f', ω = {omega:.3g}'})"
            f"  Newton fluid {row['newton_iterations']}, solid "
            f"{row['solid_newton_iterations']}  |η|max {row['peak_displacement']:.3g} m"
        )

    def summary(self) -> dict:
        problem, n = self.problem, len(self.iterations)
        W, V = problem.fluid.W, problem.solid.V
        return {
            "acceleration": problem.settings.acceleration,
            "coupling_iterations": sum(self.iterations),
            "mean_coupling_iterations": sum(self.iterations) / max(n, 1),
            "max_coupling_iterations": max(self.iterations, default=0),
            "solid_newton_iterations": self.solid_newton,
            "fluid_dofs": global_dofs(W),
            "solid_dofs": global_dofs(V),
            "cells": self.cells,
            **self.outputs.summary(),
        }

    def state(self) -> dict[str, np.ndarray]:
        """The fluid's (solution, BDF history, mesh displacement history, step counter) and the
        solid's (η, Newmark/generalized-α history, loads) states, the acceleration's memory
        (Aitken's ω, IQN-ILS's columns of past steps), the predictor's history, the counters,
        the wall indices' accumulators (:meth:`FluidOutputs.state`)."""
        problem = self.problem
        return {
            **state_arrays.to_arrays("fluid.", problem.fluid.save_state()),
            **self.outputs.state(),
            **state_arrays.solid_arrays(problem.solid),
            **{f"coupling.{k}": v for k, v in problem.acceleration.state().items()},
            **{f"predictor.{k}": v for k, v in problem.predictor.state().items()},
            "counters.coupling_iterations": np.array(self.iterations, dtype=np.int64),
            "counters.solid_newton_iterations": np.array(self.solid_newton),
            **self.time_errors.state(),
        }

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        problem = self.problem
        problem.fluid.restore_state(fluid_state(problem.fluid, state))
        load_solid(problem.solid, state)
        problem.acceleration.load_state(state_arrays.subset("coupling.", state))
        problem.predictor.load_state(state_arrays.subset("predictor.", state))
        self.iterations = [int(n) for n in state["counters.coupling_iterations"]]
        self.solid_newton = int(state["counters.solid_newton_iterations"])
        self.outputs.load_state(state)
        self.outputs.update()
        self.time_errors.load_state(state, problem.fluid.time)


# --------------------------------------------------------------------------------------------
# The structure alone (structure.interface_load: inlet_pressure or none)


class StructureStepper(_Checkpointed):
    """The structure alone under a prescribed interface pressure (the inlet's P(t)) or under its
    body force only; the fluid columns hold the prescribed pressure and no velocity. The
    Turek–Hron cases (CSM1–3) add the displacement ``ux_A``, ``uy_A`` (m) of point A and a tube
    ``uz_A``, ``ur_A``, as the coupled runs do (:func:`displacement_point`)."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        whole = mesh.build(case, comm)
        self.cells = mesh.summary(whole, case)["cells"]
        self.pressure = (
            inlet_pressure(case.fluid.inlet)
            if case.structure.interface_load == "inlet_pressure"
            else None
        )
        self.solver = solid.build(case, whole, comm, self.pressure)
        self.stenosis = isinstance(case.geometry, config.StenosisGeometry)
        self.point = displacement_point(case)
        self.columns = (
            COLUMNS
            + ["peak_wall_displacement"]
            + stress_columns(self.solver)
            + (list(self.point[0]) if self.point else [])
        )
        self._layouts = structure_layouts(self.solver)
        self.time_errors = time_errors.build(
            case, comm, {"structure": (self.solver.eta, self._layouts)}
        )
        self.columns += self.time_errors.columns

    def field_files(self) -> dict[str, tuple[object, list]]:
        s = self.solver
        return {"solid.xdmf": (s.domain.mesh, [s.eta, *s.stress.cell_fields.values()])}

    def forget_jacobians(self) -> None:
        _forget_jacobians(self.solver)

    def step(self, step: Step) -> dict:
        s = self.solver
        result, _ = _solve(
            s,
            step,
            lambda failed: (
                f"structure step {step.index} to t = {step.t:g} s failed: "
                f"{failed.reason} (residual {failed.residual:.3g})"
            ),
        )
        s.stress.update()
        row = {
            "peak_velocity": "",
            "peak_pressure": self.pressure(step.t) if self.pressure else "",
            "peak_displacement": s.max_displacement(),
            "peak_wall_displacement": (s.max_displacement([Region.WALL]) if self.stenosis else ""),
            **stress_row(s),
            "coupling_iterations": 0,
            "newton_iterations": result.iterations,
            "newton_residual": result.residual,
            **self.time_errors.after_step(step.t),
        }
        row.update(displacement_row(s.eta, self.point))
        return row

    def describe(self, row: dict) -> str:
        return (
            f"Newton {row['newton_iterations']} (residual {row['newton_residual']:.2e})  "
            f"|η|max {row['peak_displacement']:.3g} m  SSS {row['max_sss']:.3g} Pa"
        )

    def summary(self) -> dict:
        V = self.solver.V
        return {"mean_coupling_iterations": 0.0, "solid_dofs": global_dofs(V), "cells": self.cells}

    def state(self) -> dict[str, np.ndarray]:
        return {
            **state_arrays.solid_arrays(self.solver),
            **self.time_errors.state(),
        }

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        load_solid(self.solver, state)
        self.time_errors.load_state(state, self.solver.t)
