"""The command line: ``fsi run``, ``fsi sweep``, ``fsi mesh``, ``fsi check``, ``fsi report``,
``fsi plot`` (``python -m fsi`` is the same).

Exit status (docs/reliability.md): 0 done; 1 an internal error (a bug: a traceback); 2 the
configuration, the command line, ``--out`` or the checkpoint to restart from is wrong (nothing is
computed or written); 3 a step failed (the last converged step is checkpointed); 4 a file could
not be written (disk full, folder read-only; the last checkpoint that could be written is kept);
130 / 143 / 138 stopped by SIGINT / SIGTERM / SIGUSR1 after the current step (checkpointed).
"""

from __future__ import annotations

import argparse
import gc
import logging
import os
import shlex
import signal
import sys
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from fsi import config

log = logging.getLogger("fsi")

EXIT_OK, EXIT_INTERNAL, EXIT_USAGE, EXIT_SOLVE_FAILED, EXIT_OUTPUT_FAILED = 0, 1, 2, 3, 4


def _parser() -> argparse.ArgumentParser:
    """The argument parser of ``fsi``: ``--version`` and the sub-commands run, sweep, mesh,
    check, report and plot, in that order."""
    parser = argparse.ArgumentParser(prog="fsi", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--version",
        action=_Version,
        nargs=0,
        help="show the versions of fsi (and its git revision), dolfinx, Python",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    commands = {  # name: (what it does, its arguments)
        "run": (
            "run a case: DIR/metrics.csv, summary.json, fields.xdmf, checkpoint/",
            _add_run_arguments,
        ),
        "sweep": (
            "run a case for every combination of the --vary values (a folder each, resuming), "
            "then DIR/sweep.csv, sweep.md and sweep_<quantity>.png",
            _add_sweep_arguments,
        ),
        "mesh": ("build the case's mesh: DIR/mesh.xdmf and DIR/mesh.json", _add_mesh_arguments),
        "check": ("validate a case without running it", _add_config_arguments),
        "report": (
            "the study's tables (peaks at the report times, solver effort) and plots from run "
            "folders",
            _add_report_arguments,
        ),
        "plot": (
            "a picture (PNG) of one field of a run at one time: filled contours, colour bar "
            "with units, axes in mm",
            _add_plot_arguments,
        ),
    }
    for name, (summary, add_arguments) in commands.items():
        add_arguments(sub.add_parser(name, help=summary))
    return parser


def _add_config_arguments(p: argparse.ArgumentParser, optional: bool = False) -> None:
    """The case file argument and ``--set`` overrides, shared by the commands that read a case
    (``optional``: ``fsi run --restart`` takes the run's own configuration without one)."""
    if optional:
        p.add_argument(
            "config",
            type=Path,
            nargs="?",
            help="YAML case file (with --restart: leave it out to continue the run's own "
            "DIR/config.yaml)",
        )
    else:
        p.add_argument("config", type=Path, help="YAML case file")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="override a configuration value (repeatable)",
    )


def _add_out(
    p: argparse.ArgumentParser,
    help: str | None = None,
    *,
    required: bool = True,
    metavar: str = "DIR",
) -> None:
    """``--out``: where the command writes (a folder unless ``metavar`` says otherwise)."""
    p.add_argument("--out", type=_out_path, required=required, metavar=metavar, help=help)


def _path(text: str) -> Path:
    """A path argument; an empty one is refused (it would mean the current directory), and so
    is one the file system cannot name (:func:`_too_long`)."""
    return _named_path(text, room=0)


def _out_path(text: str) -> Path:
    """``--out``: :func:`_path`, with room below it for the files a command writes there."""
    return _named_path(text, room=OUT_PATH_ROOM)


OUT_PATH_ROOM = 64
"""Bytes an ``--out`` path leaves below ``PATH_MAX`` for what is written inside it (a sweep's
run folders are checked on their own; ``checkpoint.partial/rank0000.npz`` is 29)."""


def _named_path(text: str, room: int) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a path, not an empty string")
    why = _too_long(Path(text), room)
    if why:
        raise argparse.ArgumentTypeError(why)
    return Path(text)


def _is_dir(path: Path) -> bool:
    """``path.is_dir()``, False where the path itself is too long to look up."""
    try:
        return path.is_dir()
    except OSError:
        return False


def _too_long(path: Path, room: int = 0) -> str | None:
    """Why the file system would refuse ``path`` with ENAMETOOLONG (a name in it longer than
    ``NAME_MAX``, or, as an absolute path with ``room`` bytes more, longer than ``PATH_MAX``),
    or None. The limits are those of the nearest folder of ``path`` that exists (255 and
    4096 bytes where it cannot say): each command then refuses it as a wrong argument, where
    opening it raised OSError, a traceback, exit 1."""
    absolute = Path(os.path.abspath(path))
    existing = next((p for p in (absolute, *absolute.parents) if _is_dir(p)), Path("/"))
    try:
        name_max = os.pathconf(existing, "PC_NAME_MAX")
        path_max = os.pathconf(existing, "PC_PATH_MAX")
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    for name in path.parts:
        size = len(os.fsencode(name))
        if size > name_max:
            shown = name if len(name) <= 24 else f"{name[:12]}...{name[-8:]}"
            return (
                f"the name {shown!r} in the path is {size} bytes long, longer than the "
                f"{name_max} bytes a file name may have"
            )
    size = len(os.fsencode(str(absolute)))
    if size + room >= path_max:
        inside = f", less {room} for the files written inside it" if room else ""
        return (
            f"the path is {size} bytes long as an absolute path, longer than the "
            f"{path_max - 1 - room} bytes allowed (PATH_MAX {path_max}{inside})"
        )
    return None


def _add_run_arguments(p: argparse.ArgumentParser) -> None:
    """``fsi run``: a case, ``--out``, ``--restart``, ``--allow-changes``, ``--overwrite``."""
    _add_config_arguments(p, optional=True)
    _add_out(p)
    p.add_argument(
        "--restart",
        type=_path,
        metavar="DIR",
        help="continue from the checkpoint of an earlier run in DIR (DIR/checkpoint) with "
        "DIR/config.yaml, or the case file given, --set applied; any number of ranks; the "
        "schedule, outputs, coupling and solver settings may change, other keys only with "
        "--allow-changes",
    )
    p.add_argument(
        "--allow-changes",
        action="store_true",
        help="with --restart: let the case change keys that alter the physics or the "
        "outputs' meaning (the inlet, the outlet, the rheology, ...); refused otherwise",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an earlier run's files in DIR (otherwise a DIR holding a run is "
        "refused unless --restart continues it)",
    )


def _add_mesh_arguments(p: argparse.ArgumentParser) -> None:
    """``fsi mesh``: a case and ``--out``."""
    _add_config_arguments(p)
    _add_out(p)


def _add_report_arguments(p: argparse.ArgumentParser) -> None:
    """``fsi report``: run folders, ``--out``, ``--format``, ``--times``."""
    p.add_argument("runs", type=_path, nargs="+", metavar="RUN_DIR")
    _add_out(
        p, "write DIR/report.md and the plots (default: print the tables only)", required=False
    )
    p.add_argument(
        "--format",
        choices=["png", "pdf", "svg"],
        default="png",
        help="the plots' file format (default png; pdf and svg for papers)",
    )
    p.add_argument(
        "--times",
        type=float,
        nargs="+",
        metavar="T",
        help="report times in s (default: the first run's output.report_times)",
    )


def _add_plot_arguments(p: argparse.ArgumentParser) -> None:
    """``fsi plot``: a run folder, the field, time, view options and ``--out``."""
    p.add_argument("run", type=_path, metavar="RUN_DIR")
    p.add_argument(
        "--field",
        required=True,
        metavar="NAME",
        help="a field of RUN_DIR/fields.xdmf (fluid: velocity, pressure, "
        "wall_shear_stress, viscosity, shear_rate, mesh_displacement) or "
        "solid.xdmf (structure: eta, sss, von_mises, max_principal, region); or an index of "
        "RUN_DIR/wall_indices.csv along the walls (tawss, osi, rrt)",
    )
    p.add_argument(
        "--time",
        type=float,
        metavar="T",
        help="time in s: the stored time nearest to T (restarted runs: in the segment holding "
        "it); required for a field",
    )
    p.add_argument(
        "--cycle",
        type=int,
        metavar="K",
        help="for tawss, osi, rrt with a periodic inlet: over heartbeat K (default: the last "
        "in the file)",
    )
    p.add_argument(
        "--warp",
        type=float,
        metavar="S",
        help="draw on the nodes moved by S x the displacement (default: 1 for the "
        "fluid of a coupled run, its current mesh; 0 for the structure, its "
        "reference shape)",
    )
    p.add_argument(
        "--streamlines",
        action="store_true",
        help="draw the fluid velocity's streamlines over a fluid field",
    )
    p.add_argument(
        "--region",
        choices=["fluid", "wall", "cap", "lipid", "flag"],
        help="only the cells of this region (default: the field's whole mesh)",
    )
    p.add_argument(
        "--component",
        choices=["x", "y", "z", "magnitude"],
        help="of a vector field (default: magnitude; z in 3D)",
    )
    p.add_argument(
        "--slice",
        metavar="AXIS=VALUE",
        help="of a 3D run's field: its section by the plane AXIS = VALUE (m), e.g. y=0 (the "
        "meridian plane through the plaque's middle), x=0.01 (a cross-section)",
    )
    _add_out(p, "the picture: FILE.png, FILE.pdf or FILE.svg", metavar="FILE")


def _add_sweep_arguments(p: argparse.ArgumentParser) -> None:
    """``fsi sweep``: a case, ``--vary``, ``--out``, ``--dry-run``, ``--overwrite``, and the
    Slurm options."""
    _add_config_arguments(p)
    p.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="KEY.PATH=V1,V2,...",
        help="a key (as --set takes it) and its values, comma-separated (commas "
        "inside [...] or {...} belong to the value); repeatable: the runs are "
        "the product of the lists (required, except with --collect)",
    )
    _add_out(p, "DIR/<key=value,...>/ for each run, DIR/sweep.csv and sweep.md", required=False)
    p.add_argument(
        "-n",
        "--dry-run",
        action="store_true",
        help="validate every run and list what the sweep would do with each (skip, "
        "resume, start, replace); run and write nothing (with --scheduler slurm: write the "
        "batch script, do not submit it)",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="let runs replace earlier runs' results in their folders (another "
        "configuration, schedule or end); refused otherwise",
    )
    _add_slurm_arguments(p)


def _add_slurm_arguments(p: argparse.ArgumentParser) -> None:
    """``fsi sweep``'s ``--scheduler``, ``--ranks-per-run``, ``--slurm-option``, ``--collect``
    and the hidden ``--task`` (one array task)."""
    p.add_argument(
        "--scheduler",
        default="local",
        metavar="{local,slurm}",
        help="local: the runs one after the other in this process (default); slurm: "
        "DIR/sweep.sbatch, a Slurm job array of the runs not yet done, submitted with sbatch "
        "(the job id printed)",
    )
    p.add_argument(
        "--ranks-per-run",
        type=int,
        default=1,
        metavar="N",
        help="with --scheduler slurm: each run on N MPI ranks (srun -n N; default 1)",
    )
    p.add_argument(
        "--slurm-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="with --scheduler slurm: an #SBATCH --KEY=VALUE line (e.g. time=04:00:00, "
        "partition=compute; KEY alone for a flag); repeatable. Default: --signal=USR1@120 "
        "(a run stops with a checkpoint 2 minutes before the time limit)",
    )
    p.add_argument(
        "--collect",
        action="store_true",
        help="config is the folder of a sweep submitted to Slurm: write its table of the "
        "finished runs (sweep.csv, sweep.md, plots) and list the others with why",
    )
    p.add_argument("--task", type=int, metavar="INDEX", help=argparse.SUPPRESS)


class _Version(argparse.Action):
    """``--version``: looks the git revision up only when asked."""

    def __call__(self, parser, namespace, values, option_string=None):
        from fsi.output import provenance

        print(provenance.version_line())
        parser.exit()


def _setup_logging(comm: MPI.Comm) -> None:
    """Progress on rank 0 only; other ranks report warnings and errors."""
    logger = logging.getLogger("fsi")
    if not any(isinstance(h, _Stderr) for h in logger.handlers):
        handler = _Stderr()
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
        logger.propagate = False
    logger.setLevel(logging.INFO if comm.rank == 0 else logging.WARNING)
    # The JIT compiler's build steps (setuptools, which also raises the root logger's level and
    # adds a handler while it compiles) log at INFO through the root logger: keep them quiet.
    root = logging.getLogger()
    root.setLevel(logging.WARNING)
    if not any(isinstance(f, _WarningsOnly) for f in root.filters):
        root.addFilter(_WarningsOnly())


class _Stderr(logging.StreamHandler):
    """A handler writing to whatever ``sys.stderr`` is when a record comes (main() may be
    called several times in one process, e.g. by tests that capture stderr)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


class _WarningsOnly(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.WARNING


def main(argv: Sequence[str] | None = None) -> int:
    """``fsi``'s entry point: parse ``argv`` (default: the command line), run the command and
    return its exit status (the module docstring lists them)."""
    comm = MPI.COMM_WORLD
    _setup_logging(comm)
    if argv is None:
        argv = sys.argv[1:]
    try:
        args = _parser().parse_args(_joined_option_values(argv))
    except SystemExit as e:  # argparse has printed the message; --help exits 0
        return int(e.code or 0)
    try:
        return _command(args, comm)
    except KeyboardInterrupt:  # Ctrl-C outside a run's steps (those stop at a step's end)
        print("fsi: interrupted", file=sys.stderr, flush=True)
        return 128 + signal.SIGINT


DASHED_VALUES = ("--slurm-option",)
"""Options whose value may itself start with a dash (``--slurm-option --time=1``, as sbatch
spells it), which argparse would take for another option ("expected one argument")."""


def _joined_option_values(argv: Sequence[str]) -> list[str]:
    """``argv`` with ``--slurm-option VALUE`` written ``--slurm-option=VALUE`` where VALUE
    starts with a dash, so that argparse reads it as the value."""
    joined: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] in DASHED_VALUES and i + 1 < len(argv) and argv[i + 1].startswith("-"):
            joined.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            joined.append(argv[i])
            i += 1
    return joined


def _command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    """Run the parsed command; its exit status."""
    if args.command == "report":
        return _report(args)
    if args.command == "plot":
        return _plot(args)
    if args.command == "sweep":
        return _guarded(comm, lambda: _sweep(args))
    own = args.command == "run" and args.config is None
    try:
        if own:
            args.config = _own_config(args)
        case = config.load(args.config, args.overrides, run_config=own)
    except _Refused as e:
        _error(comm, str(e))
        return EXIT_USAGE
    except config.ConfigError as e:
        _error(comm, str(e))
        return EXIT_USAGE
    if args.command in ("run", "check") and comm.rank == 0:
        for caution in config.cautions(case):
            log.warning("fsi: warning: %s", caution)
    command = {"run": _run, "mesh": _mesh, "check": _check}[args.command]
    return _guarded(comm, lambda: command(args, case))


def _own_config(args: argparse.Namespace) -> Path:
    """``fsi run`` without a case file: the ``config.yaml`` of the run ``--restart`` names;
    :class:`_Refused` without ``--restart`` or without that file."""
    from fsi.run import checkpoint

    if args.restart is None:
        raise _Refused(
            "fsi run: a case file is needed, or --restart DIR to continue DIR's run with its "
            "own configuration"
        )
    try:
        return checkpoint.own_config(args.restart)
    except checkpoint.CheckpointError as e:
        raise _Refused(f"--restart: {e}") from None


def _guarded(comm: MPI.Comm, command: Callable[[], int]) -> int:
    """``command()``; on several ranks, an exception (a bug) ends every rank with its
    traceback, since the other ranks may wait in a collective."""
    if comm.size == 1:
        return command()
    try:
        return command()
    except Exception:  # a bug: the other ranks may wait in a collective, so end them all
        print(
            f"fsi: internal error on rank {comm.rank} of {comm.size}:\n{traceback.format_exc()}",
            file=sys.stderr,
            flush=True,
        )
        comm.Abort(EXIT_INTERNAL)
        raise  # not reached


def _error(comm: MPI.Comm, message: str) -> None:
    """One ``fsi: error:`` line on stderr (rank 0; every rank has the same message)."""
    if comm.rank == 0:
        print(f"fsi: error: {message}", file=sys.stderr, flush=True)


def _check(args: argparse.Namespace, case: config.Case) -> int:
    log.info(
        "%s: valid (case %r, geometry %s, mesh %s, structure %s)",
        args.config,
        case.name,
        case.geometry.kind,
        case.mesh.level,
        case.structure.mode,
    )
    return EXIT_OK


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


def _run(args: argparse.Namespace, case: config.Case) -> int:
    request = RunRequest(
        args.config, args.out, args.overrides, args.restart, args.overwrite, args.allow_changes
    )
    return run_case(request, case).status


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
    except _Refused as e:
        return _refused(comm, str(e))
    _warn_before_run(case, restart, comm)
    return _run_checked(request, case, restart, comm)


class _Refused(Exception):
    """A run refused before any computation (its ``fsi: error:`` message)."""


def _checked_start(request: RunRequest, case: config.Case, comm: MPI.Comm):
    """The checks before any computation: the case is supported, ``--restart``'s checkpoint is
    read (returned, or None without one) and ``--out`` may be written; :class:`_Refused` if
    one fails."""
    from fsi.output import io
    from fsi.run import checkpoint, simulation

    reason = simulation.unsupported(case)
    if reason is not None:
        raise _Refused(f"{request.config}: {reason}")
    restart = None
    try:
        if request.restart is not None:
            restart = checkpoint.read(request.restart, case, comm)
    except checkpoint.CheckpointError as e:
        raise _Refused(f"--restart: {e}") from e
    changed = restart.changed_keys(case) if restart is not None else []
    if changed and not request.allow_changes:
        shown = ", ".join(changed[:6]) + (", ..." if len(changed) > 6 else "")
        raise _Refused(
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
        raise _Refused(f"--out: {e}") from e
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
    """The run itself, once checked, under :class:`_StopOnSignal`; its outcome."""
    from fsi.output import io
    from fsi.run import checkpoint, errors, simulation

    at_once = False  # a second interrupt: the ranks may be anywhere, no collective after it
    try:
        with io.RunLock(comm, request.out), _StopOnSignal() as stop:
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
    _error(comm, message)
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


class _StopOnSignal:
    """While entered, SIGINT, SIGTERM and SIGUSR1 ask the run to stop after its current step
    (the run polls the instance, which returns the signal's number or None); a second one stops
    at once (KeyboardInterrupt). Open MPI's mpirun forwards SIGUSR1 to every rank but answers
    SIGINT and SIGTERM by killing the ranks within a second: under mpirun, stop a run with
    ``kill -USR1 <mpirun's pid>`` (docs/reliability.md)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGUSR1)

    def __init__(self) -> None:
        self.signal: int | None = None
        self._previous: dict = {}

    def __enter__(self) -> _StopOnSignal:
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


def _sweep(args: argparse.Namespace) -> int:
    """``fsi sweep``: every run validated (and ``--out`` checked) before the first starts; then
    the runs one after the other in this process, each as ``fsi run`` (:func:`run_case`), and
    the table (fsi/run/sweep.py); or, with ``--scheduler slurm``, the runs to do submitted as a
    Slurm job array, whose tasks (``--task``) run them, and ``--collect`` for the table
    (fsi/run/slurm.py). A stop signal stops the current run as ``fsi run`` and the sweep after
    it."""
    from fsi.run import sweep

    comm = MPI.COMM_WORLD
    try:
        definition = _slurm_sweep(args, comm)
        variations, runs = _sweep_plan(args, comm)
    except _Refused as e:
        _error(comm, str(e))
        return EXIT_USAGE
    if not args.dry_run and args.task is None and not args.collect:
        refused = comm.bcast(sweep.refusal(runs, args.overwrite) if comm.rank == 0 else "")
        if refused:
            _error(comm, f"--out {args.out}: {refused}")
            return EXIT_USAGE
    if definition is not None or args.task is not None:
        return _sweep_slurm(args, definition, variations, runs, comm)
    if args.dry_run:
        lines = sweep.describe_plan(runs, args.overwrite) if comm.rank == 0 else []
        if comm.rank == 0:
            print("\n".join(lines), flush=True)
        return EXIT_OK
    resume = [
        "fsi",
        "sweep",
        str(args.config),
        "--out",
        str(args.out),
        *[a for v in variations for a in ("--vary", v.option)],
        *[a for s in args.overrides for a in ("--set", s)],
    ]
    with _StopOnSignal() as stop:
        return sweep.execute(runs, variations, args.out, _sweep_run_one(args), stop, resume, comm)


def _sweep_plan(args: argparse.Namespace, comm: MPI.Comm):
    """The sweep's variations and validated runs, ``--out`` checked; :class:`_Refused`."""
    from fsi.output import io
    from fsi.run import sweep

    try:
        variations = sweep.parse_vary(args.vary)
        runs = sweep.plan(args.config, variations, args.overrides, args.out)
        io.check_folder(comm, args.out, earlier_run=True)
    except (sweep.SweepError, config.ConfigError) as e:
        raise _Refused(str(e)) from None
    except io.RunFolderError as e:
        raise _Refused(f"--out: {e}") from None
    return variations, runs


def _slurm_sweep(args: argparse.Namespace, comm: MPI.Comm):
    """The checked :class:`fsi.run.slurm.SlurmSweep` of ``--scheduler slurm``, or of
    ``--collect`` (DIR/sweep.json, whose case, ``--vary``, ``--set`` and folder then replace
    ``args``'); None for a local sweep or a task. :class:`_Refused`."""
    from fsi.run import slurm

    if args.scheduler not in ("local", "slurm"):
        raise _Refused(f"--scheduler {args.scheduler}: expected local or slurm")
    try:
        if args.collect:
            if args.vary or args.overrides or args.out or args.scheduler != "local":
                raise _Refused(
                    "--collect takes the sweep's folder alone (DIR/sweep.json has the rest)"
                )
            definition = slurm.load(args.config)
            args.config, args.out = Path(definition.case), Path(definition.out)
            args.vary, args.overrides = list(definition.vary), list(definition.sets)
            return definition
        if not args.vary or args.out is None:
            raise _Refused(
                f"the following arguments are required: {'--out' if args.vary else '--vary'}"
            )
        if args.scheduler == "local" or args.task is not None:
            if args.ranks_per_run != 1 or args.slurm_option:
                raise _Refused("--ranks-per-run and --slurm-option go with --scheduler slurm")
            return None
        return slurm.prepare(
            args.config,
            args.out,
            (args.vary, args.overrides),
            args.ranks_per_run,
            args.slurm_option,
            args.dry_run,
            comm,
        )
    except slurm.SlurmError as e:
        raise _Refused(str(e)) from None


def _sweep_run_one(args: argparse.Namespace):
    """The function that runs one of the sweep's runs as ``fsi run`` (:func:`run_case`)."""
    from fsi.run import sweep

    def run_one(run: sweep.SweepRun, resume: bool, overwrite: bool) -> tuple[int, str]:
        request = RunRequest(
            args.config, run.folder, run.overrides, run.folder if resume else None, overwrite
        )
        outcome = run_case(request, run.case)
        return outcome.status, outcome.reason

    return run_one


def _sweep_slurm(args: argparse.Namespace, definition, variations, runs, comm: MPI.Comm) -> int:
    """``--task INDEX`` (one array task: run INDEX as a local sweep would), ``--scheduler
    slurm`` (the table so far, then the runs to do submitted and the job id printed;
    ``--dry-run``: the batch script written, not submitted) or ``--collect``."""
    from fsi.run import slurm

    if args.task is not None:
        with _StopOnSignal():
            status, message, job = slurm.run_task(runs, args.task, _sweep_run_one(args), comm)
    else:
        status, message, job = slurm.submit_or_collect(
            definition, runs, variations, args.dry_run, args.collect, comm
        )
    if message:
        _error(comm, message)
    elif job is not None and comm.rank == 0:
        print(job, flush=True)
    return status


def _mesh(args: argparse.Namespace, case: config.Case) -> int:
    from fsi.output import io
    from fsi.physics import mesh

    comm = MPI.COMM_WORLD
    try:
        io.check_folder(comm, args.out, earlier_run=True)
    except io.RunFolderError as e:
        _error(comm, f"--out: {e}")
        return EXIT_USAGE
    tagged = mesh.build(case, comm)
    summary = mesh.summary(tagged, case)
    try:
        io.write_mesh(args.out, tagged, summary)
    except io.OutputError as e:
        _error(comm, f"cannot write the mesh: {e}")
        return EXIT_OUTPUT_FAILED
    cells = summary["cells"]
    log.info(
        "mesh of %s (%s): %d %s (%s)",
        args.config,
        case.mesh.level,
        cells["total"],
        "tetrahedra" if config.dimension(case.geometry) == 3 else "triangles",
        ", ".join(f"{k} {v}" for k, v in cells.items() if k != "total"),
    )
    for name, value in summary.get("measures", {}).items():
        log.info("  %s: %.6g", name, value)
    log.info("wrote %s and %s", args.out / "mesh.xdmf", args.out / "mesh.json")
    return EXIT_OK


def _report(args: argparse.Namespace) -> int:
    from fsi.output import report

    comm = MPI.COMM_WORLD
    status = EXIT_OK
    if comm.rank == 0:  # reading and plotting a few files: rank 0 alone
        try:
            report.check_times(args.times)
            report.check_out(args.out)
            runs = report.load_runs(args.runs)
        except report.ReportError as e:
            print(f"fsi: error: {e}", file=sys.stderr)
            status = EXIT_USAGE
        else:
            print(report.markdown(runs, args.times))
            if args.out is not None:
                try:
                    written = report.write(runs, args.out, args.times, args.format)
                except OSError as e:
                    print(f"fsi: error: --out: {e}", file=sys.stderr)
                    status = EXIT_OUTPUT_FAILED
                else:
                    log.info("wrote %s", ", ".join(str(p) for p in written))
    return comm.bcast(status, root=0)


def _plot_options_refused(args: argparse.Namespace) -> str | None:
    """The first option given that ``--field`` cannot take, with why (None: all fit)."""
    from fsi.output import wall_plot

    if args.field in wall_plot.INDICES:
        for option, value in (
            ("--time", args.time),
            ("--warp", args.warp),
            ("--streamlines", args.streamlines or None),
            ("--region", args.region),
            ("--component", args.component),
            ("--slice", args.slice),
        ):
            if value is not None:
                return (
                    f"{option}: not for --field {args.field}, an average along the walls "
                    "(over the run, or over heartbeat --cycle K)"
                )
        return None
    if args.time is None:
        return f"--time: required for --field {args.field}"
    if args.cycle is not None:
        return f"--cycle: only for the wall indices (tawss, osi, rrt), not --field {args.field}"
    return None


def _draw_plot(args: argparse.Namespace) -> tuple[Path, str | None]:
    """The picture ``fsi plot`` asks for, written to ``--out``; and a note for stdout, or
    None. Raises PlotError, OSError."""
    from fsi.output import plot, section, wall_plot

    plot.check_out(args.out)
    refused = _plot_options_refused(args)
    if refused:
        raise plot.PlotError(refused)
    if args.field in wall_plot.INDICES:
        index = wall_plot.read(args.run, args.field, args.cycle)
        return wall_plot.draw(index, args.out), None
    plane = None if args.slice is None else section.Plane.parse(args.slice)
    snapshot = plot.read_field(args.run, args.field, args.time, warp=args.warp, region=args.region)
    if plane is not None:
        snapshot = section.cut(snapshot, plane)
    flow = plot.streamline_field(snapshot) if args.streamlines else None
    written = plot.draw(snapshot, args.out, component=args.component, flow=flow)
    note = None
    if snapshot.time_differs:
        note = (
            f"{args.run}: {args.field} is stored at t = {snapshot.time:.6g} s, the "
            f"nearest to --time {args.time:g}"
        )
    return written, note


def _plot(args: argparse.Namespace) -> int:
    from fsi.output import plot

    comm = MPI.COMM_WORLD
    status = EXIT_OK
    if comm.rank == 0:  # reading two files and drawing one picture: rank 0 alone
        try:
            written, note = _draw_plot(args)
        except plot.PlotError as e:
            print(f"fsi: error: {e}", file=sys.stderr, flush=True)
            status = EXIT_USAGE
        except OSError as e:
            print(
                f"fsi: error: --out: cannot write {args.out} ({e.strerror or e})",
                file=sys.stderr,
                flush=True,
            )
            status = EXIT_OUTPUT_FAILED
        else:
            if note:
                print(note, flush=True)
            log.info("wrote %s", written)
    return comm.bcast(status, root=0)


def run_console() -> None:
    """Console-script entry point. After a failed file write (exit status 4) the process leaves
    without running destructors: dolfinx's XDMF writer retries closing a file that failed to
    close in its destructor, and the exception it throws there would abort the process."""
    status = main()
    if status == EXIT_OUTPUT_FAILED:
        sys.stdout.flush()
        sys.stderr.flush()
        MPI.COMM_WORLD.barrier()
        MPI.Finalize()
        os._exit(status)
    sys.exit(status)
