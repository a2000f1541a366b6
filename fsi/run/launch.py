"""``fsi run``'s run of one case, as the command line and ``fsi sweep`` call it
(:func:`run_case`): the checks before any computation (the case is supported, ``--restart``'s
checkpoint, ``--out``), the run under :class:`~fsi.run.signals.StopOnSignal`, and the messages
and exit status of each ending (docs/reliability.md).

Exit status: 0 done; 1 an internal error (a bug: a traceback); 2 the configuration, the command
line, ``--out`` or the checkpoint to restart from is wrong (nothing is computed or written); 3 a
step failed (the last converged step is checkpointed); 4 a file could not be written; 128 + the
signal's number when stopped by SIGINT / SIGTERM / SIGUSR1 after the current step.
"""

from __future__ import annotations

import gc
import logging
import shlex
import signal
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from fsi import config
from fsi.run.errors import EXIT_OK, EXIT_OUTPUT_FAILED, EXIT_SOLVE_FAILED, EXIT_USAGE
from fsi.run.signals import StopOnSignal

log = logging.getLogger("fsi")


class Refused(Exception):
    """A run refused before any computation (its ``fsi: error:`` message)."""


def say_error(comm: MPI.Comm, message: str) -> None:
    """One ``fsi: error:`` line on stderr (rank 0; every rank has the same message)."""
    if comm.rank == 0:
        print(f"fsi: error: {message}", file=sys.stderr, flush=True)


def own_config(restart: Path | None) -> Path:
    """``fsi run`` without a case file: the ``config.yaml`` of the run ``restart`` (``--restart``)
    names; :class:`Refused` without ``--restart`` or without that file."""
    from fsi.run import checkpoint

    if restart is None:
        raise Refused(
            "fsi run: a case file is needed, or --restart DIR to continue DIR's run with its "
            "own configuration"
        )
    try:
        return checkpoint.own_config(restart)
    except checkpoint.CheckpointError as e:
        raise Refused(f"--restart: {e}") from None


@dataclass(frozen=True)
class RunRequest:
    """What ``fsi run`` is asked to do: the case file and its ``--set`` overrides (for the
    messages), ``--out``, ``--restart`` and ``--overwrite``."""

    config: Path
    out: Path
    overrides: Sequence[str] = ()
    restart: Path | None = None
    overwrite: bool = False
    allow_changes: bool = False


@dataclass(frozen=True)
class RunOutcome:
    """How a run ended: its exit status and, unless it is done (0), why, in one line."""

    status: int
    reason: str = ""


def run_case(request: RunRequest, case: config.Case) -> RunOutcome:
    """Run ``case`` as ``fsi run`` does (the same checks, messages, files and stops; SIGINT,
    SIGTERM and SIGUSR1 stop it after the current step).

    Args:
        request: the command line's case file, ``--out``, ``--set``, ``--restart`` and
            ``--overwrite``.
        case: the resolved case.

    Returns:
        The exit status and, unless the run is done, why it ended. Collective.
    """
    comm = MPI.COMM_WORLD
    try:
        restart = _checked_start(request, case, comm)
    except Refused as e:
        return _refused(comm, str(e))
    _warn_before_run(case, restart, comm)
    return _run_checked(request, case, restart, comm)


def _checked_start(request: RunRequest, case: config.Case, comm: MPI.Comm):
    """The checks before any computation: the case is supported, ``--restart``'s checkpoint is
    read (returned, or None without one) and ``--out`` may be written; :class:`Refused` if
    one fails."""
    from fsi.output import io
    from fsi.run import checkpoint

    reason = config.cannot_run(case)
    if reason is not None:
        raise Refused(f"{request.config}: {reason}")
    restart = None
    try:
        if request.restart is not None:
            restart = checkpoint.read(request.restart, case, comm)
    except checkpoint.CheckpointError as e:
        raise Refused(f"--restart: {e}") from e
    changed = restart.changed_keys(case) if restart is not None else []
    if changed and not request.allow_changes:
        shown = ", ".join(changed[:6]) + (", ..." if len(changed) > 6 else "")
        raise Refused(
            f"--restart: {request.config}{' (with --set)' if request.overrides else ''} "
            "differs from the run being continued "
            f"({restart.run_dir / 'config.yaml'}) in {shown}: a restart continues that run. "
            f"Leave out the case file to continue it as it was (fsi run --restart "
            f"{request.restart} --out {request.out}), or add --allow-changes"
        )
    continuing = restart is not None and restart.continues(request.out)
    try:
        io.check_folder(comm, request.out, earlier_run=continuing or request.overwrite)
    except io.RunFolderError as e:
        raise Refused(f"--out: {e}") from e
    return restart


def _warn_before_run(case: config.Case, restart, comm: MPI.Comm) -> None:
    """Log where a restart starts (and the mesh motion settings it changes), and warn of a
    reference BLAS under MUMPS."""
    from fsi.output import provenance

    if restart is not None:
        log.info("restarting from %s: step %d, t = %.6g s", restart.path, restart.step, restart.t)
        changed = restart.changed_mesh_motion(case) if case.structure.mode != "rigid" else []
        if changed:
            log.warning(
                "fsi: warning: %s differ from the run being continued: the fluid mesh is "
                "re-extended at the first step, whose mesh velocity and forces jump",
                ", ".join(f"mesh_motion.{k}" for k in changed),
            )
    if comm.rank == 0 and provenance.blas_name(provenance.blas_library()) == "reference":
        log.warning(
            "fsi: warning: MUMPS runs on Debian's reference BLAS, its LU factorisations ~3.6x "
            "slower than on OpenBLAS (fine mesh); `make setup` installs libopenblas0-serial"
        )


def _run_checked(request: RunRequest, case: config.Case, restart, comm: MPI.Comm) -> RunOutcome:
    """The run itself, once checked, under :class:`StopOnSignal`; its outcome."""
    from fsi.output import io
    from fsi.run import checkpoint, errors, simulation

    at_once = False  # a second interrupt: the ranks may be anywhere, no collective after it
    try:
        with io.RunLock(comm, request.out), StopOnSignal() as stop:
            result = simulation.run(case, request.out, comm, restart, stop)
    except io.RunFolderError as e:  # another run holds --out
        return _refused(comm, f"--out: {e}")
    except checkpoint.CheckpointError as e:
        return _refused(comm, f"--restart: {e}")
    except errors.RunStopped as e:
        return _stopped(request, e)
    except KeyboardInterrupt:  # a second interrupt: at once, without a checkpoint
        at_once = True
        log.error(
            "fsi: stopped at once; the last periodic checkpoint is in %s",
            request.out / checkpoint.DIRECTORY,
        )
        return RunOutcome(128 + signal.SIGINT, "stopped at once (a second interrupt)")
    finally:
        # Free the run's dolfinx/PETSc objects here, on every rank at once: their destructors
        # are collective (MUMPS), and a run that stopped leaves them in reference cycles
        # (through its exception's traceback) that each rank's garbage collector would free at
        # a different moment, hanging the ranks (seen in tests/test_faults.py on 2 ranks).
        # petsc4py only stashes a collected parallel object: garbage_cleanup destroys them.
        if not at_once:
            from petsc4py import PETSc

            gc.collect()
            PETSc.garbage_cleanup(comm)
            comm.barrier()
    done = f"done: {result.steps} steps in {result.wall_time_s:.1f} s; wrote {request.out}"
    log.info(done)
    if comm.rank == 0:
        io.append_to_log(request.out, [done])
    return RunOutcome(EXIT_OK)


def _refused(comm: MPI.Comm, message: str) -> RunOutcome:
    """A run refused before any computation: exit status 2 and its ``fsi: error:`` line."""
    say_error(comm, message)
    return RunOutcome(EXIT_USAGE, message)


def _stopped(request: RunRequest, e: Exception) -> RunOutcome:
    """Say why a run stopped early and where its checkpoint is (rank 0: every rank has the
    same exception; also into DIR/run.log); return the exit status and why, in one line."""
    from fsi.output import io
    from fsi.run import errors

    if isinstance(e, errors.Interrupted):
        status = 128 + e.signal
        reason = f"stopped by signal {e.signal} ({signal.Signals(e.signal).name})"
        lines = [f"fsi: {reason}."]
    elif isinstance(e, errors.OutputFailed):
        status = EXIT_OUTPUT_FAILED
        reason = f"cannot write the run's files: {e}"
        lines = [f"fsi: {reason}"]
    else:
        status = EXIT_SOLVE_FAILED
        reason = f"solve failed: {e}"
        where = (
            "before the first step"
            if not e.started
            else f"the finished steps are in {request.out / 'metrics.csv'}"
        )
        lines = [f"fsi: {reason} ({where})"]
    if e.checkpoint is None:
        lines.append("fsi: no checkpoint could be written.")
    else:
        change = (
            " with what failed changed (e.g. a smaller time step with --set "
            "'time.schedule=[...]', or the coupling or solver settings)"
            if status == EXIT_SOLVE_FAILED
            else ""
        )
        command = [
            "fsi",
            "run",
            str(request.config),
            "--out",
            str(request.out),
            "--restart",
            str(request.out),
            *[a for s in request.overrides for a in ("--set", s)],
        ]
        lines.append(
            f"fsi: the state after step {e.step} (t = {e.t:.6g} s) is checkpointed in "
            f"{e.checkpoint}. To continue from it{change}, run\n  "
            f"{shlex.join(command)}"
        )
    if MPI.COMM_WORLD.rank == 0:
        for line in lines:
            log.error(line)
        io.append_to_log(request.out, lines)
    return RunOutcome(status, reason)


def mesh_case(config_path: Path, out: Path, case: config.Case) -> int:
    """``fsi mesh``: build the case's mesh and write ``out``/mesh.xdmf and mesh.json (the mesh's
    cell and facet counts, areas and measures); the exit status. Collective."""
    from fsi.output import io
    from fsi.physics import mesh

    comm = MPI.COMM_WORLD
    try:
        io.check_folder(comm, out, earlier_run=True)
    except io.RunFolderError as e:
        say_error(comm, f"--out: {e}")
        return EXIT_USAGE
    tagged = mesh.build(case, comm)
    summary = mesh.summary(tagged, case)
    try:
        io.write_mesh(out, tagged, summary)
    except io.OutputError as e:
        say_error(comm, f"cannot write the mesh: {e}")
        return EXIT_OUTPUT_FAILED
    cells = summary["cells"]
    log.info(
        "mesh of %s (%s): %d %s (%s)",
        config_path,
        case.mesh.level,
        cells["total"],
        "tetrahedra" if config.dimension(case.geometry) == 3 else "triangles",
        ", ".join(f"{k} {v}" for k, v in cells.items() if k != "total"),
    )
    for name, value in summary.get("measures", {}).items():
        log.info("  %s: %.6g", name, value)
    log.info("wrote %s and %s", out / "mesh.xdmf", out / "mesh.json")
    return EXIT_OK
