"""The time loop of ``fsi run`` (:func:`march`): a stepper (fsi/run/steppers.py: rigid,
coupled or structure alone) advances one step and returns its metrics row; the run's files
(:class:`fsi.run.outputs.RunOutputs`) take the row and the fields; the checkpoints
(fsi/run/checkpoint.py) take the stepper's state. A step that fails is retried as two half steps
(:func:`advance`); a run that stops early raises one of fsi/run/errors.py's exceptions.
"""

from __future__ import annotations

import logging
import math
import time as wallclock
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from fsi import config
from fsi.config import boundary_data
from fsi.numerics import newton
from fsi.numerics.timestepping import SAME_TIME, AdaptiveSteps, Step, StepSizeControl, steps
from fsi.output import io
from fsi.run import checkpoint, checkpoint_checks, time_errors
from fsi.run.errors import Interrupted, OutputFailed, RunStopped, StepFailed
from fsi.run.outputs import RunOutputs
from fsi.run.state_arrays import Layout
from fsi.run.steppers import CoupledStepper, RigidStepper, Stepper, StructureStepper

log = logging.getLogger("fsi")


@dataclass
class RunResult:
    """A finished run: the steps this run took, its wall time (s) and its summary.json."""

    steps: int
    wall_time_s: float
    summary: dict


def run(
    case: config.Case,
    out: Path,
    comm: MPI.Comm = MPI.COMM_WORLD,
    restart: checkpoint.Checkpoint | None = None,
    stop_requested: Callable[[], int | None] = lambda: None,
) -> RunResult:
    """Run a case (rigid structure or coupled), writing ``out``'s files (see the README), from
    t = 0 or from the checkpoint ``restart`` (:func:`fsi.run.checkpoint.read`). ``stop_requested``
    returns the number of a signal that asks the run to stop, or None (polled after every
    step; :class:`Interrupted`).

    Raises a :class:`RunStopped` when the run stops early (the finished steps stay in
    metrics.csv, the last converged one is checkpointed), :class:`fsi.run.checkpoint.
    CheckpointError` when ``restart``'s arrays do not fit the case (before anything is
    written). Collective."""
    start = wallclock.perf_counter()
    try:
        if case.structure.mode == "rigid":
            stepper: Stepper = RigidStepper(case, comm)
        elif case.structure.interface_load != "fluid":
            stepper = StructureStepper(case, comm)
        else:
            stepper = CoupledStepper(case, comm)
    except newton.SolveFailed as e:  # before the first step (the prestress): nothing to save
        failed = StepFailed(str(e))
        failed.started = False
        raise failed from None
    return march(case, out, comm, stepper, start, restart, stop_requested)


def march(
    case: config.Case,
    out: Path,
    comm: MPI.Comm,
    stepper: Stepper,
    start: float,
    restart: checkpoint.Checkpoint | None = None,
    stop_requested: Callable[[], int | None] = lambda: None,
) -> RunResult:
    """Step ``stepper`` through ``case.time.run_schedule`` (``time.cycles`` heartbeats), from
    t = 0 or after ``restart``'s step (its arrays placed on this run's dofs and checked,
    :func:`fsi.run.checkpoint.localize`, before any file is touched): each step's row and
    fields go to the run's files (:class:`fsi.run.outputs.RunOutputs`), its state to the
    checkpoints (:func:`_record_steps`). ``start``: the wall clock (``time.perf_counter``) when
    the run began. A run that stops early raises a :class:`fsi.run.errors.RunStopped` on every
    rank (``StepFailed``, ``OutputFailed``, or ``Interrupted`` after the step during which
    ``stop_requested`` returned a signal), with the stepper's state after the last converged
    step, whose row is the last one written, checkpointed (a failed step leaves the solvers
    anywhere). Collective."""
    schedule = config.run_time(case)
    t0, first, last = _step_range(schedule, restart)
    adaptive = case.time.step_control == "adaptive"
    layouts = stepper.layouts()
    if restart is not None:  # before any file is touched
        loaded = checkpoint.localize(restart, layouts, stepper.state(), comm)
    with RunOutputs(case, out, comm, stepper, restart) as outputs:
        if restart is not None:
            stepper.load_state(loaded)
        clock = _clock(case, schedule, t0, first, restart) if adaptive else None
        before = _first_snapshot(stepper, first, t0, restart, clock)
        saved = _Checkpoints(out, comm, case, stepper, layouts, before)
        retried: list[Step] = []  # the steps that had to be split
        rejected: list[Step] | None = None if clock is None else []  # for their time error
        try:
            outputs.write_fields(t0)
            if clock is None:
                taken_steps = _scheduled_steps(stepper, schedule, t0, first, saved, retried)
            else:
                taken_steps = _adaptive_steps(stepper, clock, saved, retried, rejected)
            taken = _record_steps(
                taken_steps, outputs, saved, clock, last, schedule.end, start, stop_requested
            )
            if taken == 0:  # restarted at (or past) the end: the checkpoint goes to out as well
                saved.write_good()
            summary = outputs.write_summary(retried, saved.latest, start, rejected)
        except (RunStopped, io.OutputError) as e:
            stopped = saved.stopped(e)
            try:
                if stopped is e:
                    raise
                raise stopped from e
            finally:
                del stopped  # its traceback holds this frame: no cycle through this local
    return RunResult(taken, summary["wall_time_s"], summary)


def _first_snapshot(
    stepper: Stepper,
    first: int,
    t0: float,
    restart: checkpoint.Checkpoint | None,
    clock: AdaptiveSteps | None,
) -> _Snapshot:
    """The stepper's state at the run's start, after step ``first`` at ``t0``."""
    return _Snapshot(
        first,
        t0,
        None if restart is None else restart.dt,
        stepper.state(),
        clock.dt if clock else None,
    )


def _record_steps(
    taken_steps: Iterator[tuple[Step, dict]],
    outputs: RunOutputs,
    saved: _Checkpoints,
    clock: AdaptiveSteps | None,
    last: int,
    end: float,
    start: float,
    stop_requested: Callable[[], int | None],
) -> int:
    """Record each step ``taken_steps`` takes: its row and fields to ``outputs``, its state to
    ``saved`` (checkpointed every ``output.checkpoint_every`` steps and after the last one, step
    ``last`` or, with adaptive steps, ``clock``'s last); after each periodic checkpoint the
    solvers drop the Jacobians they keep across steps, so a restart from it repeats this run's
    arithmetic (:meth:`Stepper.forget_jacobians`); the progress towards ``end`` (s) is logged
    and a stop request honoured (:func:`_stop_if_requested`). Returns the number of steps taken.
    Collective."""
    case, comm, stepper = saved.case, saved.comm, saved.stepper
    taken = 0
    for step, row in taken_steps:
        final = step.index == last if clock is None else clock.next_step() is None
        outputs.write_step(row, final)
        saved.after(
            _Snapshot(step.index, step.t, step.dt, stepper.state(), clock.dt if clock else None),
            final,
        )
        if step.index % case.output.checkpoint_every == 0:
            stepper.forget_jacobians()  # restarts from these checkpoints stay exact
        taken += 1
        _report_progress(stepper, row, end, last if clock is None else None, start, taken)
        _stop_if_requested(comm, stop_requested, final)
    return taken


def _step_range(
    schedule: config.Time, restart: checkpoint.Checkpoint | None
) -> tuple[float, int, int]:
    """The run's start time t0, the index of the step before its first (0, or the restart's
    step) and the index of its last step in ``schedule`` (``first`` if there is none)."""
    t0 = 0.0 if restart is None else restart.t
    first = 0 if restart is None else restart.step
    last = first
    for last_step in steps(schedule, t0, first):  # counted, never stored (time.max_steps)
        last = last_step.index
    return t0, first, last


def _clock(
    case: config.Case,
    schedule: config.Time,
    t0: float,
    first: int,
    restart: checkpoint.Checkpoint | None,
) -> AdaptiveSteps:
    """The adaptive steps from step ``first`` at ``t0``: the first of ``time.adaptive.first_dt``,
    after a restart of the size the restarted run would have tried next."""
    settings = case.time.adaptive
    control = StepSizeControl(settings.tolerance, settings.min_dt)
    dt = settings.first_dt
    if restart is not None and restart.next_dt is not None:
        dt = restart.next_dt
    return AdaptiveSteps(schedule, control, case.output.report_times, t0, first, dt)


def _scheduled_steps(
    stepper: Stepper,
    schedule: config.Time,
    t0: float,
    first: int,
    saved: _Checkpoints,
    retried: list[Step],
) -> Iterator[tuple[Step, dict]]:
    """Each step of ``schedule`` after step ``first`` (at ``t0``) taken (:func:`_take_step`)
    and its row. A generator: each step is taken from ``saved``'s good state when the loop asks
    for it."""
    retries = saved.case.time.retries
    for step in steps(schedule, t0, first):
        yield step, _take_step(stepper, step, saved.good.state, retries, retried)


def _adaptive_steps(
    stepper: Stepper,
    clock: AdaptiveSteps,
    saved: _Checkpoints,
    retried: list[Step],
    rejected: list[Step],
) -> Iterator[tuple[Step, dict]]:
    """The steps ``clock`` chooses, each taken and its row: a step whose local error
    (``time_error``) is above the tolerance is undone (the stepper goes back to ``saved``'s good
    state; the step is appended to ``rejected``) and taken again as short as the error asks
    for; one that is still above it at ``time.adaptive.min_dt`` fails the run
    (:class:`StepFailed`). A generator, as :func:`_scheduled_steps`."""
    retries, control = saved.case.time.retries, clock.control
    while (step := clock.next_step()) is not None:
        while True:
            row = _take_step(stepper, step, saved.good.state, retries, retried)
            error = None if row[time_errors.COLUMN] == "" else row[time_errors.COLUMN]
            if control.accepts(error):
                break
            if step.dt <= control.min_dt * (1 + SAME_TIME):
                scales = saved.case.time.adaptive
                raise StepFailed(
                    f"step {step.index} to t = {step.t:g} s: its local time error "
                    f"{error:.3g} is above time.adaptive.tolerance = {control.tolerance:g} "
                    f"at time.adaptive.min_dt = {control.min_dt:g} s. The error is relative "
                    "to the largest each field has been, or while it is smaller to "
                    f"time.adaptive.velocity_scale = {scales.velocity_scale:g} m/s and "
                    f"displacement_scale = {scales.displacement_scale:g} m: a run from rest "
                    "needs them set to the size the fields will reach"
                )
            stepper.load_state(saved.good.state)
            rejected.append(step)
            step = clock.retry(step, error)
            log.info(
                "step %d to t = %.6g s rejected (time error %.3g > %.3g); taking dt = %.3g s",
                rejected[-1].index,
                rejected[-1].t,
                error,
                control.tolerance,
                step.dt,
            )
        clock.accept(step, error)
        yield step, row


def _stop_if_requested(
    comm: MPI.Comm, stop_requested: Callable[[], int | None], final: bool
) -> None:
    """Raise :class:`Interrupted` on every rank if ``stop_requested`` returned a signal on any
    rank, unless the step just taken was the last. Collective (an allreduce)."""
    signal = comm.allreduce(stop_requested() or 0, op=MPI.MAX)
    if signal and not final:
        raise Interrupted(signal)


def _take_step(
    stepper: Stepper, step: Step, before: dict, retries: int, retried: list[Step]
) -> dict:
    """The metrics row of ``step`` (:func:`advance`, with its wall time); a row holding a
    non-finite number fails the step (a NaN is never written)."""
    tic = wallclock.perf_counter()
    row = {
        "step": step.index,
        "t": step.t,
        "dt": step.dt,
        **advance(stepper, step, before, retries, retried),
    }
    row["wall_time_s"] = wallclock.perf_counter() - tic
    bad = [key for key, v in row.items() if isinstance(v, float) and not math.isfinite(v)]
    if bad:
        raise StepFailed(f"step {step.index} to t = {step.t:g} s gave non-finite {', '.join(bad)}")
    return row


def _report_progress(
    stepper: Stepper, row: dict, end: float, last: int | None, start: float, taken: int
) -> None:
    """Log the step just taken (the ``taken``-th of this run, which began at wall clock
    ``start``) and how far the run is: the steps left of ``last`` and their time at this run's
    pace, or with adaptive steps (``last`` None, their number unknown) the share of the time
    to ``end`` done and the wall time so far."""
    elapsed = wallclock.perf_counter() - start
    if last is None:
        where = f"step {row['step']}"
        left = f"{row['t'] / end:.0%} of {end:g} s in {elapsed:.0f} s"
    else:
        where = f"step {row['step']}/{last}"
        left = f"~{elapsed / taken * (last - row['step']):.0f} s left"
    log.info(
        "%s  t = %.5g s  dt = %.3g s  %s  %.2f s/step  %s",
        where,
        row["t"],
        row["dt"],
        stepper.describe(row),
        row["wall_time_s"],
        left,
    )


def advance(stepper: Stepper, step: Step, before: dict, retries: int, retried: list[Step]) -> dict:
    """``stepper.step(step)``; if it fails with retries left, go back to ``before`` (the
    stepper's state at the start of the step) and take the step as two of half its size, each
    retried the same way with one retry fewer. Returns the row of the step's last (sub)step;
    appends every split step to ``retried``. An inlet formula that cannot be evaluated at a time
    of the step fails it (:class:`StepFailed`, no retry: its time is the configuration's fault).
    Collective (the failure is raised on every rank)."""
    try:
        return stepper.step(step)
    except boundary_data.FormulaError as e:
        raise StepFailed(f"step {step.index} to t = {step.t:g} s: fluid.inlet: {e}") from e
    except StepFailed as e:
        if retries <= 0:
            raise
        log.warning(
            "step %d to t = %.6g s failed (%s); taking it as two steps of %.3g s",
            step.index,
            step.t,
            e,
            step.dt / 2,
        )
        retried.append(step)
        stepper.load_state(before)
        half = step.dt / 2
        advance(stepper, Step(step.index, step.t - half, half), before, retries - 1, retried)
        middle = stepper.state()
        return advance(stepper, Step(step.index, step.t, half), middle, retries - 1, retried)


@dataclass(frozen=True)
class _Snapshot:
    """The stepper's state after step ``step`` (time ``t``, step size ``dt``)."""

    step: int
    t: float
    dt: float | None
    state: dict
    next_dt: float | None = None  # adaptive steps: the size the next step will try


class _Checkpoints:
    """The run's checkpoints: ``good``, the snapshot after the last converged step, written
    every ``output.checkpoint_every`` steps, after the last step and when the run stops early;
    ``latest``, this run's latest checkpoint written (folder, step, t) or None."""

    def __init__(
        self,
        out: Path,
        comm: MPI.Comm,
        case: config.Case,
        stepper: Stepper,
        layouts: dict[str, Layout],
        good: _Snapshot,
    ):
        self.out, self.comm, self.case, self.layouts = out, comm, case, layouts
        self.stepper = stepper
        self.good = good
        self.latest: tuple[Path, int, float] | None = None

    def write_good(self) -> tuple[Path, int, float] | None:
        """Write ``good`` as ``out/checkpoint``, then the files derived from its state
        (:meth:`Stepper.write_checkpoint_files`: ``wall_indices.csv``); return (the folder,
        step, t), or if the checkpoint fails log why and return None (the previous checkpoint
        stays). Collective."""
        good, out, comm = self.good, self.out, self.comm
        try:
            folder = checkpoint.write(
                out,
                comm,
                good.state,
                self.layouts,
                checkpoint_checks.metadata(
                    self.case, comm, good.step, good.t, good.dt, good.next_dt
                ),
            )
        except checkpoint.CheckpointError as e:  # raised on every rank: said once
            if comm.rank == 0:
                log.error("fsi: no checkpoint of step %d: %s", good.step, e)
            return None
        try:  # the files derived from the checkpointed state: wall_indices.csv
            self.stepper.write_checkpoint_files(out, comm, good.state)
        except io.OutputError as e:  # raised on every rank; the checkpoint holds the values
            if comm.rank == 0:
                log.error("fsi: %s", e)
        written = folder, good.step, good.t
        self.latest = written
        return written

    def after(self, snapshot: _Snapshot, final: bool) -> None:
        """``snapshot`` is the new good state; checkpoint it when due. A failed checkpoint is
        logged and the run goes on, except after the last step."""
        self.good = snapshot
        if snapshot.step % self.case.output.checkpoint_every == 0 or final:
            if self.write_good() is None and final:
                raise io.OutputError(f"no checkpoint of the last step {snapshot.step}")

    def stopped(self, error: Exception) -> RunStopped:
        """The :class:`RunStopped` for ``error`` (an output failure becomes
        :class:`OutputFailed`), with the good state checkpointed unless it is already; if that
        fails (a full disk) the run's previous checkpoint is named."""
        stopped = error if isinstance(error, RunStopped) else OutputFailed(str(error))
        if self.latest is None or self.latest[1] != self.good.step:
            self.write_good()
        stopped.checkpoint, stopped.step, stopped.t = self.latest or (None, None, None)
        return stopped
