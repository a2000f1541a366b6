"""The time loop of ``fsi run``: builds the mesh and the solvers of a case, steps through the
schedule, and hands metrics and fields to the writers of fsi/io.py.

Rigid-structure cases (``structure.mode: rigid``) solve the fluid alone, with no-slip on every
wall and on the (then rigid) interface and obstacle. The coupled modes (``fixed_wall``,
``moving_wall``) need the partitioned coupling of issue 5 and are refused before any work.
"""

from __future__ import annotations

import logging
import platform
import time as wallclock
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

import dolfinx

from fsi import config, fluid, io, mesh, metrics
from fsi.timestepping import steps
from geometry.tags import Boundary, Region

log = logging.getLogger("fsi")

COLUMNS = ["step", "t", "dt", "peak_velocity", "peak_pressure", "peak_displacement", "max_sss",
           "coupling_iterations", "coupling_residual", "newton_iterations", "newton_residual",
           "wall_time_s"]


class SolveFailed(RuntimeError):
    """A sub-solver did not converge; the run stops with exit status 3."""


@dataclass
class RunResult:
    steps: int
    wall_time_s: float
    summary: dict


def unsupported(case: config.Case) -> str | None:
    """Why this case cannot run yet (checked before any computation), or None."""
    if case.structure.mode != "rigid":
        return (f"structure.mode: '{case.structure.mode}' needs the partitioned fluid–structure "
                "coupling, which is not available yet; run the rigid-structure case with "
                "--set structure.mode=rigid")
    if case.output.fields == "vtx" and not hasattr(dolfinx.io, "VTXWriter"):
        return "output.fields: 'vtx' needs dolfinx built with ADIOS2 (not Debian 12's); use 'xdmf'"
    return None


def fluid_boundaries(case: config.Case) -> tuple:
    """Rigid structure: the configured inlet, a traction-free outlet, no-slip elsewhere."""
    walls = [b for b in mesh.geometry_module(case).BOUNDARIES
             if b in (Boundary.RIGID_WALL, Boundary.INTERFACE, Boundary.OBSTACLE)]
    return (fluid.Inflow(Boundary.INLET, case.fluid.inlet),
            fluid.Outflow(Boundary.OUTLET, case.fluid.outlet.backflow_stabilization),
            fluid.NoSlip(tuple(walls)))


def run(case: config.Case, out: Path, comm: MPI.Comm = MPI.COMM_WORLD) -> RunResult:
    """Run a rigid-structure case, writing ``out``'s files (see the README). Collective."""
    start = wallclock.perf_counter()
    whole = mesh.build(case, comm)
    part = mesh.restrict(whole, Region.FLUID)
    solver = fluid.FluidSolver(part.mesh, part.facet_tags, case.fluid, fluid_boundaries(case),
                               scheme=case.time.scheme)
    obstacle = [b for b in (Boundary.OBSTACLE, Boundary.INTERFACE)
                if b in mesh.geometry_module(case).BOUNDARIES]
    turek_hron = isinstance(case.geometry, config.TurekHronGeometry)
    columns = COLUMNS + (["drag", "lift"] if turek_hron else [])
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        config.dump(case, out / "config.yaml")
    comm.barrier()
    table = io.MetricsTable(comm, out / "metrics.csv", columns)
    fields = io.FieldWriter(comm, out / "fields.xdmf", part.mesh)
    schedule = list(steps(case.time))
    totals = {"newton_iterations": 0}
    fields.write(0.0, [solver.u, solver.p])
    try:
        for k, step in enumerate(schedule):
            tic = wallclock.perf_counter()
            result = solver.step(step.t, step.dt)
            if not result.converged:
                raise SolveFailed(result.message)
            solver.advance()
            row = {"step": step.index, "t": step.t, "dt": step.dt,
                   "peak_velocity": metrics.peak_velocity(solver.u),
                   "peak_pressure": metrics.peak_pressure(solver.p),
                   "peak_displacement": 0.0, "coupling_iterations": 0,
                   "newton_iterations": result.iterations, "newton_residual": result.residual}
            if turek_hron:
                row["drag"], row["lift"] = solver.boundary_force(obstacle)
            row["wall_time_s"] = wallclock.perf_counter() - tic
            table.write(row)
            totals["newton_iterations"] += result.iterations
            if step.index % case.output.fields_every == 0 or k == len(schedule) - 1:
                fields.write(step.t, [solver.u, solver.p])
            elapsed = wallclock.perf_counter() - start
            left = elapsed / (k + 1) * (len(schedule) - k - 1)
            log.info("step %d/%d  t = %.5g s  dt = %.3g s  Newton %d (residual %.2e)  "
                     "%.2f s/step  ~%.0f s left", step.index, len(schedule), step.t, step.dt,
                     result.iterations, result.residual, row["wall_time_s"], left)
    finally:
        table.close()
        fields.close()
    summary = {
        "case": case.name, "steps": len(schedule), "end_time_s": schedule[-1].t if schedule else 0,
        "wall_time_s": wallclock.perf_counter() - start,
        "newton_iterations": totals["newton_iterations"],
        "mean_newton_iterations": totals["newton_iterations"] / max(len(schedule), 1),
        "mean_coupling_iterations": 0.0,
        "ranks": comm.size, "dolfinx": dolfinx.__version__, "python": platform.python_version(),
        "fluid_dofs": solver.W.dofmap.index_map.size_global * solver.W.dofmap.index_map_bs,
        "cells": mesh.summary(whole, case)["cells"],
    }
    io.write_json(comm, out / "summary.json", summary)
    return RunResult(len(schedule), summary["wall_time_s"], summary)
