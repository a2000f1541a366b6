"""Stopping a run by a signal: after the current step, with a checkpoint (:class:`StopOnSignal`;
docs/reliability.md)."""

from __future__ import annotations

import os
import signal
import sys

from mpi4py import MPI


class StopOnSignal:
    """While entered, SIGINT, SIGTERM and SIGUSR1 ask the run to stop after its current step
    (the run polls the instance, which returns the signal's number or None); a second one stops
    at once (KeyboardInterrupt). Open MPI's mpirun forwards SIGUSR1 to every rank but answers
    SIGINT and SIGTERM by killing the ranks within a second: under mpirun, stop a run with
    ``kill -USR1 <mpirun's pid>`` (docs/reliability.md)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGUSR1)

    def __init__(self) -> None:
        self.signal: int | None = None
        self._previous: dict = {}

    def __enter__(self) -> StopOnSignal:
        for s in self.SIGNALS:
            self._previous[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for s, handler in self._previous.items():
            signal.signal(s, handler)

    def __call__(self) -> int | None:
        return self.signal

    def _handle(self, signum: int, frame) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum
        if MPI.COMM_WORLD.rank == 0:  # a plain write: the handler may interrupt one to stderr
            message = (
                f"fsi: {signal.Signals(signum).name} received: stopping after this step "
                "with a checkpoint (again: stop at once)\n"
            )
            try:
                os.write(sys.stderr.fileno(), message.encode())
            except (OSError, ValueError):  # no usable stderr (closed, or captured in memory)
                pass
