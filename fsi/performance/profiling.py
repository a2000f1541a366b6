"""Pieces shared by the speed benchmarks of fsi/performance/: an exclusive-time profiler of solver
methods (with PETSc's LU events), the hooks that attach it to a coupled or rigid-wall stepper,
and small helpers."""

from __future__ import annotations

import functools
import time
from collections import defaultdict

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from fsi import config
from fsi.numerics.timestepping import steps
from fsi.run import steppers

LU_EVENTS = ("MatLUFactorNum", "MatLUFactorSym", "MatSolve")


class Profiler:
    """Exclusive wall time (this rank) of wrapped methods: a call's time minus the time of the
    wrapped calls made inside it, so nested pieces add up to the outermost one."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._children: list[float] = []

    def wrap(self, obj, name: str, label: str, lu: str | None = None) -> None:
        """Replace ``obj.name`` (a bound method) by a timed one. With ``lu``, PETSc's LU events
        during the call are booked as ``lu + " LU factorisation"`` / ``lu + " LU solves"``
        (taken out of ``label``'s time) and counted."""
        f = getattr(obj, name)

        @functools.wraps(f)
        def timed(*args, **kwargs):
            self._children.append(0.0)
            before = _lu_events() if lu else None
            tic = time.perf_counter()
            try:
                return f(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - tic
                inner = self._children.pop()
                if lu:
                    after = _lu_events()
                    factor = sum(after[e][1] - before[e][1] for e in LU_EVENTS[:2])
                    solve = after["MatSolve"][1] - before["MatSolve"][1]
                    self.seconds[f"{lu} LU factorisation"] += factor
                    self.seconds[f"{lu} LU solves"] += solve
                    self.calls[f"{lu} factorisations"] += (
                        after["MatLUFactorNum"][0] - before["MatLUFactorNum"][0]
                    )
                    inner += factor + solve
                self.seconds[label] += elapsed - inner
                self.calls[label] += 1
                if self._children:
                    self._children[-1] += elapsed

        setattr(obj, name, timed)


def _lu_events() -> dict[str, tuple[int, float]]:
    """(count, time) of PETSc's LU events on this rank so far."""
    out = {}
    for e in LU_EVENTS:
        info = PETSc.Log.Event(e).getPerfInfo()
        out[e] = (int(info["count"]), float(info["time"]))
    return out


def attach_coupled(stepper: steppers.CoupledStepper, profiler: Profiler) -> None:
    """Time the pieces of a coupled step (see the module docstring)."""
    p = stepper.problem
    wrap = profiler.wrap
    wrap(p.fluid.problem, "J", "fluid Jacobian assembly")
    wrap(p.fluid.problem, "F", "fluid residual assembly")
    wrap(p.fluid, "step", "fluid Newton (rest)", lu="fluid")
    wrap(p.fluid, "interface_force", "fluid interface forces")
    wrap(p.solid.problem, "J", "solid Jacobian assembly")
    wrap(p.solid.problem, "F", "solid residual assembly")
    wrap(p.solid, "step", "solid Newton (rest)", lu="solid")
    wrap(p.motion, "solve", "mesh motion solve")
    wrap(p.motion, "check_quality", "mesh quality check")
    wrap(p.fluid_side, "move_mesh", "mesh move + w (rest)")
    if hasattr(p.fluid_side, "hold_mesh"):  # coupling.geometry: explicit
        wrap(p.fluid_side, "hold_mesh", "mesh move + w (rest)")
    for m in (p.fluid_side.to_fluid, p.fluid_side.to_solid):
        wrap(m, "transfer", "interface transfers")
    wrap(p.motion, "set_boundary_function", "interface transfers")
    for side in (p.fluid_side, p.solid_side):
        wrap(side, "save_state", "save/restore state")
        wrap(side, "restore_state", "save/restore state")
    wrap(p.fluid_side, "solve", "fluid side (rest)")
    wrap(p.solid_side, "solve", "solid side (rest)")
    wrap(p.acceleration, "next_input", "acceleration")
    wrap(p, "step", "coupling loop (rest)")


def attach_rigid(stepper: steppers.RigidStepper, profiler: Profiler) -> None:
    s = stepper.solver
    profiler.wrap(s.problem, "J", "fluid Jacobian assembly")
    profiler.wrap(s.problem, "F", "fluid residual assembly")
    profiler.wrap(s, "step", "fluid Newton (rest)", lu="fluid")


def newton_counters(solver) -> tuple[int, int]:
    """(Jacobian assemblies, residual evaluations) so far."""
    c = solver.newton.callbacks
    return c.jacobian_assemblies, c.residual_evaluations


def wall(comm: MPI.Comm, f, repeats: int) -> np.ndarray:
    """Wall times (slowest rank) of ``repeats`` calls of ``f``."""
    times = []
    for _ in range(repeats):
        comm.barrier()
        tic = time.perf_counter()
        f()
        comm.barrier()
        times.append(comm.allreduce(time.perf_counter() - tic, op=MPI.MAX))
    return np.array(times)


def window(case: config.Case, n: int) -> float:
    """The end time of the schedule's n-th step."""
    schedule = list(steps(case.time))
    return schedule[min(n, len(schedule)) - 1].t


def mean_warm(values: np.ndarray) -> float:
    """Mean over steps 2..N (step 1 holds the symbolic factorisations)."""
    return float(values[1:].mean()) if len(values) > 1 else float("nan")
