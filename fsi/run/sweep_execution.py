"""``fsi sweep``'s runs, one after the other (:func:`execute`): each planned run
(fsi/run/sweep.py) skipped when finished, resumed when stopped, or started; its line in the log;
then the table and plots (fsi/run/sweep_results.py). Also the plan as ``--dry-run`` prints it
(:func:`describe_plan`) and why ``--out`` refuses it (:func:`refusal`).
"""

from __future__ import annotations

import gc
import logging
import shlex
import signal
import time as wallclock
from collections.abc import Callable, Sequence
from pathlib import Path

from mpi4py import MPI

from fsi.output import io
from fsi.run.errors import EXIT_OK, EXIT_OUTPUT_FAILED, EXIT_SOLVE_FAILED
from fsi.run.sweep import FolderState, SweepRun, Variation, folder_state
from fsi.run.sweep_results import write_results

log = logging.getLogger("fsi")


# --------------------------------------------------------------------------------------------
# Running


RunOne = Callable[[SweepRun, bool, bool], tuple[int, str]]
"""Runs a :class:`SweepRun` as ``fsi run`` (``resume``: ``--restart`` its folder;
``overwrite``: ``--overwrite``); returns the exit status and, unless 0, why in one line."""


def execute(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    out: Path,
    run_one: RunOne,
    stop_requested: Callable[[], int | None],
    resume: Sequence[str],
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> int:
    """Run ``runs`` one after the other (:func:`folder_state` says which to skip, resume or
    start afresh), with a progress line before and after each, then write the table and the
    plots (:func:`write_results`, also after a stop). A failed run (any exit status other than
    0 and 128 + a signal) is recorded and the next one started. A stop (a run stopped by a
    signal, or ``stop_requested`` returning one between runs) ends the sweep; the message
    gives ``resume``, the command that continues it.

    Returns 0 when every run is done, 3 when one failed, 128 + the signal when stopped, 4 when
    the table cannot be written. Collective."""
    statuses = ["pending"] * len(runs)
    stopped_by = 0
    try:
        for i, run in enumerate(runs):
            stopped_by = comm.allreduce(stop_requested() or 0, op=MPI.MAX)
            if stopped_by:
                break
            statuses[i], stopped_by = advance(run, len(runs), run_one, comm)
            if stopped_by:
                break
    except KeyboardInterrupt:  # a second signal between runs
        stopped_by = signal.SIGINT
    try:
        written, statuses = write_results(runs, variations, statuses, out, comm)
    except io.OutputError as e:
        if comm.rank == 0:
            log.error("fsi: cannot write the sweep's table: %s", e)
        return EXIT_OUTPUT_FAILED
    log.info(
        "sweep: %d of %d runs done; wrote %s",
        statuses.count("done"),
        len(runs),
        ", ".join(str(p) for p in written),
    )
    if stopped_by:
        if comm.rank == 0:  # the other ranks log errors too
            log.error(
                "fsi: sweep stopped by signal %d (%s). To resume it, run\n  %s",
                stopped_by,
                signal.Signals(stopped_by).name,
                shlex.join(resume),
            )
        return 128 + stopped_by
    return EXIT_SOLVE_FAILED if any(s.startswith("failed") for s in statuses) else EXIT_OK


def advance(run: SweepRun, total: int, run_one: RunOne, comm: MPI.Comm) -> tuple[str, int]:
    """Skip ``run``, resume it or start it afresh (:func:`folder_state`), with a progress line
    before and after (``total``: the sweep's number of runs). Returns its status (done,
    stopped or ``failed: <why>``) and the signal that stopped it, or 0. Collective."""
    state = comm.bcast(folder_state(run) if comm.rank == 0 else None, root=0)
    head = f"sweep {run.index}/{total}: {run.label}"
    log.info("%s: %s", head, state.why)
    if state.action == "skip":
        return "done", 0
    return _run_and_log(run, state, head, run_one, comm)


def _run_and_log(
    run: SweepRun, state: FolderState, head: str, run_one: RunOne, comm: MPI.Comm
) -> tuple[str, int]:
    """Run ``run`` (resumed or started afresh as ``state`` says) and log its outcome after
    ``head``; returns its status (done, stopped or ``failed: <why>``) and the signal that
    stopped it, or 0. Collective (garbage collection and a barrier after the run)."""
    tic = wallclock.perf_counter()
    status, reason = run_one(run, state.action == "resume", state.action == "replace")
    # Free the run's dolfinx/PETSc objects on every rank at this point: their
    # destructors are collective, and a failed run leaves them in reference cycles
    # that the garbage collector would free at different moments on each rank.
    gc.collect()
    comm.barrier()
    took = f"{wallclock.perf_counter() - tic:.0f} s"
    if status == EXIT_OK:
        log.info("%s: done in %s", head, took)
        return "done", 0
    if status > 128:
        log.info("%s: stopped after %s", head, took)
        return "stopped", status - 128
    log.info("%s: failed after %s (exit status %d): %s", head, took, status, reason)
    return f"failed: {reason}", 0


def describe_plan(runs: Sequence[SweepRun], overwrite: bool = False) -> list[str]:
    """One line per run saying what a sweep would do with it (``--dry-run``; rank 0), and
    what it refuses (:func:`refusal`)."""
    lines = []
    for run in runs:
        if run.folder.is_symlink():
            what = "refused: " + _linked(run)
        else:
            state = folder_state(run)
            what = "done, would be skipped" if state.action == "skip" else "would be " + state.why
            if state.action == "replace" and not overwrite:
                what += ", deleting its earlier run: refused without --overwrite"
        lines.append(f"sweep {run.index}/{len(runs)}: {run.label}: {what} ({run.folder})")
    return lines


def _linked(run: SweepRun) -> str:
    return (
        f"{run.folder} is a symbolic link (to {run.folder.readlink()}): a sweep writes only "
        "into its own folders"
    )


def refusal(runs: Sequence[SweepRun], overwrite: bool) -> str:
    """Why the sweep must not start (rank 0; "" if it may): a run's folder is a symbolic link
    (never followed, with or without ``--overwrite``), or, without ``overwrite``, runs would
    replace earlier runs' results (another configuration, schedule or end in their folders):
    it names how many and the first, with why."""
    linked = next((run for run in runs if run.folder.is_symlink()), None)
    if linked is not None:
        return f"{linked.label}: {_linked(linked)}"
    if overwrite:
        return ""
    replaced = [(run, state) for run in runs if (state := folder_state(run)).action == "replace"]
    if not replaced:
        return ""
    run, state = replaced[0]
    return (
        f"{len(replaced)} of the {len(runs)} runs would delete an earlier run's results, e.g. "
        f"{run.label}: {state.why.replace('started afresh', 'its folder would be replaced')}: "
        "add --overwrite to replace them (--dry-run lists them), or choose another --out"
    )
