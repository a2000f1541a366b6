"""How a run stops before the end of its schedule: :class:`RunStopped` and its three kinds,
one per exit status of ``fsi run`` (fsi/cli.py). A stepper raises :class:`StepFailed`; the time
loop (:func:`fsi.run.simulation.march`) raises each of them on every rank, after checkpointing
the last converged step."""

from __future__ import annotations

from pathlib import Path

EXIT_OK, EXIT_INTERNAL, EXIT_USAGE, EXIT_SOLVE_FAILED, EXIT_OUTPUT_FAILED = 0, 1, 2, 3, 4
"""Done; an internal error (a bug: a traceback); the configuration, the command line, ``--out``
or the checkpoint is wrong (nothing computed or written); a step failed (checkpointed); a file
could not be written. A stop by a signal exits with 128 + its number."""


class RunStopped(Exception):
    """The run stopped before the end of its schedule. :func:`fsi.run.simulation.march` sets
    ``checkpoint`` (the folder it wrote, or None if it could not: then an earlier checkpoint, if
    any, is still there) and ``step``, ``t`` (the last converged step, whose state that
    checkpoint holds)."""

    checkpoint: Path | None = None
    step: int | None = None
    t: float | None = None
    started: bool = True  # False: it stopped while it was being set up, before any step


class StepFailed(RunStopped):
    """A sub-solver did not converge, or a step's data (the inlet formula) could not be
    evaluated; the CLI's exit status 3."""


class OutputFailed(RunStopped):
    """A file of the run could not be written (a full disk, a folder made read-only); exit
    status 4."""


class Interrupted(RunStopped):
    """SIGINT, SIGTERM or SIGUSR1 asked the run to stop (:func:`fsi.run.simulation.march`
    finishes the step first); exit status 128 + ``signal``."""

    def __init__(self, signal: int):
        super().__init__(f"stopped by signal {signal}")
        self.signal = signal
