"""The time loop of ``fsi run``: builds the mesh and the solvers of a case, steps through the
schedule, and hands metrics and fields to the writers of fsi/io.py.

Rigid-structure cases (``structure.mode: rigid``) solve the fluid alone, with no-slip on every
wall and on the (then rigid) interface and obstacle. The coupled modes of the stenosis
(``fixed_wall``, ``moving_wall``; MODEL.md §4–5) solve the partitioned fluid–structure problem of
fsi/partitioned.py, Dirichlet–Neumann iterations per step. Both share one loop (:func:`march`):
a *stepper* advances one step and returns its metrics row; the loop writes the row, the fields
and the summary.
"""

from __future__ import annotations

import logging
import math
import platform
import time as wallclock
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from mpi4py import MPI

import dolfinx

from fsi import config, coupling, fluid, io, mesh, metrics, partitioned, solid
from fsi.mesh_motion import MeshQualityError
from fsi.timestepping import Step, steps
from geometry import turek_hron
from geometry.tags import Boundary, Region

log = logging.getLogger("fsi")

COLUMNS = ["step", "t", "dt", "peak_velocity", "peak_pressure", "peak_displacement", "max_sss",
           "coupling_iterations", "coupling_residual", "newton_iterations", "newton_residual",
           "wall_time_s"]
COUPLED_COLUMNS = COLUMNS + ["peak_wall_displacement", "relaxation", "solid_newton_iterations",
                             "mesh_jacobian_ratio"]
WALL_COLUMNS = ["min_wss", "max_wss", "recirculation_length"]
"""Channel-like lumens (stenosis, channel): the signed wall shear stress's extremes (Pa) and the
longest reversed-flow zone along either wall (m) (fsi.metrics.wall_shear_summary)."""
"""``peak_wall_displacement``: max |η| over the vessel wall (0 in the fixed-wall mode);
``relaxation``: Aitken's (or the constant) ω of the step's last iteration, empty for IQN-ILS;
``newton_iterations``/``solid_newton_iterations``: fluid/solid Newton iterations summed over the
step's coupling iterations; ``mesh_jacobian_ratio``: the fluid mesh's smallest J/J_ref."""


class SolveFailed(RuntimeError):
    """A sub-solver did not converge; the run stops with exit status 3."""


@dataclass
class RunResult:
    steps: int
    wall_time_s: float
    summary: dict


def unsupported(case: config.Case) -> str | None:
    """Why this case cannot run (checked before any computation), or None."""
    mode = case.structure.mode
    if mode != "rigid" and case.structure.interface_load == "fluid":
        if case.structure.degree != 2:
            return (f"structure.degree: the coupling pairs the fluid's P2 velocity nodes with "
                    f"the structure's interface nodes, so structure.mode '{mode}' needs "
                    f"structure.degree 2, got {case.structure.degree}")
    if case.output.fields == "vtx" and not hasattr(dolfinx.io, "VTXWriter"):
        return "output.fields: 'vtx' needs dolfinx built with ADIOS2 (not Debian 12's); use 'xdmf'"
    return None


def run(case: config.Case, out: Path, comm: MPI.Comm = MPI.COMM_WORLD) -> RunResult:
    """Run a case (rigid structure or coupled), writing ``out``'s files (see the README).

    Raises :class:`SolveFailed` when a step fails; the finished steps stay in metrics.csv.
    Collective."""
    start = wallclock.perf_counter()
    if case.structure.mode == "rigid":
        stepper: Stepper = RigidStepper(case, comm)
    elif case.structure.interface_load != "fluid":
        stepper = StructureStepper(case, comm)
    else:
        stepper = CoupledStepper(case, comm)
    return march(case, out, comm, stepper, start)


# --------------------------------------------------------------------------------------------
# The shared loop


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
        """Advance one step; return its metrics row (raise :class:`SolveFailed` on failure)."""

    def describe(self, row: dict) -> str:
        """The step's solver statistics for the progress log."""

    def summary(self) -> dict:
        """Totals and sizes for summary.json."""


def march(case: config.Case, out: Path, comm: MPI.Comm, stepper: Stepper,
          start: float) -> RunResult:
    """Step ``stepper`` through the schedule: ``out/config.yaml``, a metrics row per step
    (flushed at once), fields every ``output.fields_every`` steps and at the end, and
    ``out/summary.json`` once every step is done. Collective."""
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        config.dump(case, out / "config.yaml")
    comm.barrier()
    table = io.MetricsTable(comm, out / "metrics.csv", stepper.columns)
    files = stepper.field_files()
    # The writers store the mesh now, in its reference configuration (the runs start at rest).
    writers = [(io.FieldWriter(comm, out / name, m), fields) for name, (m, fields) in files.items()]
    schedule = list(steps(case.time))
    rows: list[dict] = []
    try:
        for writer, fields in writers:
            writer.write(0.0, fields)
        for k, step in enumerate(schedule):
            tic = wallclock.perf_counter()
            row = {"step": step.index, "t": step.t, "dt": step.dt, **stepper.step(step)}
            row["wall_time_s"] = wallclock.perf_counter() - tic
            bad = [key for key, v in row.items() if isinstance(v, float) and not math.isfinite(v)]
            if bad:  # never write a NaN: a step that produced one failed
                raise SolveFailed(f"step {step.index} to t = {step.t:g} s gave non-finite "
                                  f"{', '.join(bad)}")
            table.write(row)
            rows.append(row)
            if step.index % case.output.fields_every == 0 or k == len(schedule) - 1:
                for writer, fields in writers:
                    writer.write(step.t, fields)
            elapsed = wallclock.perf_counter() - start
            left = elapsed / (k + 1) * (len(schedule) - k - 1)
            log.info("step %d/%d  t = %.5g s  dt = %.3g s  %s  %.2f s/step  ~%.0f s left",
                     step.index, len(schedule), step.t, step.dt, stepper.describe(row),
                     row["wall_time_s"], left)
    finally:
        table.close()
        for writer, _ in writers:
            writer.close()
    newton = sum(r.get("newton_iterations", 0) for r in rows)
    summary = {
        "case": case.name, "structure_mode": case.structure.mode, "steps": len(schedule),
        "end_time_s": schedule[-1].t if schedule else 0,
        "wall_time_s": wallclock.perf_counter() - start,
        "mean_step_time_s": sum(r["wall_time_s"] for r in rows) / max(len(rows), 1),
        "newton_iterations": newton, "mean_newton_iterations": newton / max(len(rows), 1),
        "ranks": comm.size, "dolfinx": dolfinx.__version__, "python": platform.python_version(),
        **stepper.summary(),
    }
    io.write_json(comm, out / "summary.json", summary)
    return RunResult(len(schedule), summary["wall_time_s"], summary)


# --------------------------------------------------------------------------------------------
# Fluid outputs shared by the rigid and the coupled runs


class FluidOutputs:
    """The fluid's derived output: viscosity, shear rate and wall shear stress fields (on every
    no-slip or moving wall) and, for channel-like lumens, the WALL_COLUMNS of the metrics row."""

    def __init__(self, case: config.Case, solver: fluid.FluidSolver):
        self.solver = solver
        self.walls = [b for b in mesh.geometry_module(case).BOUNDARIES
                      if b in (Boundary.RIGID_WALL, Boundary.INTERFACE, Boundary.OBSTACLE)]
        self.lumen = not isinstance(case.geometry, config.TurekHronGeometry)
        self.columns = WALL_COLUMNS if self.lumen else []
        self.derived = metrics.FluidFields(solver.u, solver.p, solver.law, solver.facet_tags,
                                           self.walls)

    @property
    def fields(self) -> list:
        return [self.solver.u, self.solver.p, *self.derived.fields]

    def update(self) -> dict:
        """Recompute the fields for the current solution; return the row's wall columns."""
        s = self.solver
        self.derived.update()
        if not self.lumen:
            return {}
        return metrics.wall_shear_summary(metrics.wall_shear_stress(
            s.u, s.p, s.law, s.facet_tags, self.walls))


# --------------------------------------------------------------------------------------------
# Rigid structure: the fluid alone


def fluid_boundaries(case: config.Case) -> tuple:
    """Rigid structure: the configured inlet, a traction-free outlet, no-slip elsewhere."""
    walls = [b for b in mesh.geometry_module(case).BOUNDARIES
             if b in (Boundary.RIGID_WALL, Boundary.INTERFACE, Boundary.OBSTACLE)]
    return (fluid.Inflow(Boundary.INLET, case.fluid.inlet, case.fluid.inflow_stabilization),
            fluid.Outflow(Boundary.OUTLET, case.fluid.outlet.backflow_stabilization),
            fluid.NoSlip(tuple(walls)))


class RigidStepper:
    """The fluid alone on the fixed fluid mesh (Turek–Hron cases add drag and lift)."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        self.whole = mesh.build(case, comm)
        self.part = mesh.restrict(self.whole, Region.FLUID)
        self.cells = mesh.summary(self.whole, case)["cells"]
        self.solver = fluid.FluidSolver(self.part.mesh, self.part.facet_tags, case.fluid,
                                        fluid_boundaries(case), scheme=case.time.scheme)
        self.obstacle = [b for b in (Boundary.OBSTACLE, Boundary.INTERFACE)
                         if b in mesh.geometry_module(case).BOUNDARIES]
        self.turek_hron = isinstance(case.geometry, config.TurekHronGeometry)
        self.outputs = FluidOutputs(case, self.solver)
        self.columns = COLUMNS + self.outputs.columns + (["drag", "lift"] if self.turek_hron
                                                         else [])

    def field_files(self) -> dict[str, tuple[object, list]]:
        return {"fields.xdmf": (self.part.mesh, self.outputs.fields)}

    def step(self, step: Step) -> dict:
        solver = self.solver
        result = solver.step(step.t, step.dt)
        if not result.converged:
            raise SolveFailed(result.message)
        solver.advance()
        row = {"peak_velocity": metrics.peak_velocity(solver.u),
               "peak_pressure": metrics.peak_pressure(solver.p),
               "peak_displacement": 0.0, "coupling_iterations": 0,
               "newton_iterations": result.iterations, "newton_residual": result.residual,
               **self.outputs.update()}
        if self.turek_hron:
            row["drag"], row["lift"] = solver.boundary_force(self.obstacle)
        return row

    def describe(self, row: dict) -> str:
        return f"Newton {row['newton_iterations']} (residual {row['newton_residual']:.2e})"

    def summary(self) -> dict:
        W = self.solver.W
        return {"mean_coupling_iterations": 0.0,
                "fluid_dofs": global_dofs(W),
                "cells": self.cells}


# --------------------------------------------------------------------------------------------
# The coupled modes: partitioned fluid–structure interaction


class CoupledStepper:
    """Dirichlet–Neumann iterations per step (fsi/partitioned.py), then the study's metrics:
    peaks of |u| and p over the fluid, of |η| over the structure, and the largest |σ₁₂| (SSS).
    The Turek–Hron cases add the benchmark's ``drag`` and ``lift`` (N/m, over the cylinder and
    the flag, on the deformed mesh) and the displacement ``ux_A``, ``uy_A`` (m) of point A."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        self.problem = partitioned.build_coupled(case, comm)
        self.cells = mesh.summary(self.problem.whole, case)["cells"]
        self.point_a = (turek_hron.point_a(case.geometry)
                        if isinstance(case.geometry, config.TurekHronGeometry) else None)
        self.outputs = FluidOutputs(case, self.problem.fluid)
        self.columns = COUPLED_COLUMNS + self.outputs.columns + (
            ["drag", "lift", "ux_A", "uy_A"] if self.point_a else [])
        self.iterations: list[int] = []
        self.solid_newton = 0

    def field_files(self) -> dict[str, tuple[object, list]]:
        p = self.problem
        stress = p.solid.stress.fields
        return {"fields.xdmf": (p.fluid.mesh, [*self.outputs.fields, p.fluid.ale.d]),
                "solid.xdmf": (p.solid.domain.mesh, [p.solid.eta, stress["sss"],
                                                     stress["von_mises"]])}

    def step(self, step: Step) -> dict:
        p = self.problem
        try:
            result = p.step(step.index, step.t, step.dt)
        except coupling.CouplingNotConverged as e:
            raise SolveFailed(f"{e} (t = {step.t:g} s, dt = {step.dt:g} s)") from e
        except (fluid.FluidSolveError, solid.SolveFailed, MeshQualityError) as e:
            raise SolveFailed(f"step {step.index} to t = {step.t:g} s (dt = {step.dt:g} s), "
                              f"coupling iteration {p.fluid_side.solves}: {e}") from e
        p.solid.stress.update()
        fluid_last = p.fluid_side.last
        self.iterations.append(result.iterations)
        self.solid_newton += p.solid_side.newton_iterations
        omega = p.relaxation
        row = self.benchmark_values() if self.point_a else {
            "peak_wall_displacement": p.solid.max_displacement([Region.WALL])}
        return {**row, **self.outputs.update(),
                "peak_velocity": metrics.peak_velocity(p.fluid.u),
                "peak_pressure": metrics.peak_pressure(p.fluid.p),
                "peak_displacement": p.solid.max_displacement(),
                "max_sss": p.solid.stress.region_maxima()["all"].max_abs_shear,
                "coupling_iterations": result.iterations,
                "coupling_residual": result.residuals[-1],
                "newton_iterations": p.fluid_side.newton_iterations,
                "newton_residual": fluid_last.residual if fluid_last else "",
                "relaxation": "" if omega is None else omega,
                "solid_newton_iterations": p.solid_side.newton_iterations,
                "mesh_jacobian_ratio": p.fluid_side.mesh_quality}

    def benchmark_values(self) -> dict:
        """Turek–Hron: drag and lift on the cylinder + flag, the displacement of point A."""
        p = self.problem
        drag, lift = p.fluid.boundary_force((Boundary.OBSTACLE, Boundary.INTERFACE))
        ux, uy = metrics.nodal_value(p.solid.eta, self.point_a)
        return {"drag": drag, "lift": lift, "ux_A": ux, "uy_A": uy}

    def describe(self, row: dict) -> str:
        omega = row["relaxation"]
        return (f"coupling {row['coupling_iterations']} (residual "
                f"{row['coupling_residual']:.1e}{'' if omega == '' else f', ω = {omega:.3g}'})"
                f"  Newton fluid {row['newton_iterations']}, solid "
                f"{row['solid_newton_iterations']}  |η|max {row['peak_displacement']:.3g} m")

    def summary(self) -> dict:
        p, n = self.problem, len(self.iterations)
        W, V = p.fluid.W, p.solid.V
        return {"acceleration": p.settings.acceleration,
                "coupling_iterations": sum(self.iterations),
                "mean_coupling_iterations": sum(self.iterations) / max(n, 1),
                "max_coupling_iterations": max(self.iterations, default=0),
                "solid_newton_iterations": self.solid_newton,
                "fluid_dofs": global_dofs(W),
                "solid_dofs": global_dofs(V),
                "cells": self.cells}


# --------------------------------------------------------------------------------------------
# The structure alone (structure.interface_load: inlet_pressure or none)


class StructureStepper:
    """The structure alone under a prescribed interface pressure (the inlet's P(t)) or under its
    body force only; the fluid columns hold the prescribed pressure and no velocity."""

    columns = COLUMNS + ["peak_wall_displacement"]

    def __init__(self, case: config.Case, comm: MPI.Comm):
        whole = mesh.build(case, comm)
        self.cells = mesh.summary(whole, case)["cells"]
        self.pressure = (fluid.inlet_pressure(case.fluid.inlet)
                         if case.structure.interface_load == "inlet_pressure" else None)
        self.solver = solid.build(case, whole, comm, self.pressure)
        self.stenosis = isinstance(case.geometry, config.StenosisGeometry)

    def field_files(self) -> dict[str, tuple[object, list]]:
        s, stress = self.solver, self.solver.stress.fields
        return {"solid.xdmf": (s.domain.mesh, [s.eta, stress["sss"], stress["von_mises"]])}

    def step(self, step: Step) -> dict:
        s = self.solver
        result = s.step(step.t, step.dt)
        if not result.converged:
            raise SolveFailed(f"structure step {step.index} to t = {step.t:g} s failed: "
                              f"{result.reason} (residual {result.residual:.3g})")
        s.advance()
        s.stress.update()
        return {"peak_velocity": "",
                "peak_pressure": self.pressure(step.t) if self.pressure else "",
                "peak_displacement": s.max_displacement(),
                "peak_wall_displacement": (s.max_displacement([Region.WALL])
                                           if self.stenosis else ""),
                "max_sss": s.stress.region_maxima()["all"].max_abs_shear,
                "coupling_iterations": 0,
                "newton_iterations": result.iterations, "newton_residual": result.residual}

    def describe(self, row: dict) -> str:
        return (f"Newton {row['newton_iterations']} (residual {row['newton_residual']:.2e})  "
                f"|η|max {row['peak_displacement']:.3g} m  SSS {row['max_sss']:.3g} Pa")

    def summary(self) -> dict:
        V = self.solver.V
        return {"mean_coupling_iterations": 0.0,
                "solid_dofs": global_dofs(V),
                "cells": self.cells}
