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
import logging
import os
import signal
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path

from mpi4py import MPI

from fsi import config
from fsi.output import paths
from fsi.run import launch, sweep_command
from fsi.run.errors import (
    EXIT_INTERNAL,
    EXIT_OK,
    EXIT_OUTPUT_FAILED,
    EXIT_USAGE,
)
from fsi.run.launch import say_error

log = logging.getLogger("fsi")


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
    is one the file system cannot name (:func:`fsi.output.paths.too_long`)."""
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
    why = paths.too_long(Path(text), room)
    if why:
        raise argparse.ArgumentTypeError(why)
    return Path(text)


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
        help="a field of RUN_DIR/fields.xdmf (velocity, pressure, wall_shear_stress, viscosity, "
        "shear_rate, mesh_displacement) or solid.xdmf (eta, sss, von_mises, max_principal, "
        "region); or an index of RUN_DIR/wall_indices.csv along the walls (tawss, osi, rrt)",
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
        "--fibres",
        action="store_true",
        help="draw an HGO wall's fibre families (their in-plane parts) over a structure field",
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
        help="of a 3D run's field: its section by the plane AXIS = VALUE (m), e.g. z=0 (the "
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
        return _guarded(comm, lambda: sweep_command.sweep(args))
    own = args.command == "run" and args.config is None
    try:
        if own:
            args.config = launch.own_config(args.restart)
        case = config.load(args.config, args.overrides, run_config=own)
    except launch.Refused as e:
        say_error(comm, str(e))
        return EXIT_USAGE
    except config.ConfigError as e:
        say_error(comm, str(e))
        return EXIT_USAGE
    if args.command in ("run", "check") and comm.rank == 0:
        for caution in config.cautions(case):
            log.warning("fsi: warning: %s", caution)
    command = {"run": _run, "mesh": _mesh, "check": _check}[args.command]
    return _guarded(comm, lambda: command(args, case))


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


def _run(args: argparse.Namespace, case: config.Case) -> int:
    request = launch.RunRequest(
        args.config, args.out, args.overrides, args.restart, args.overwrite, args.allow_changes
    )
    return launch.run_case(request, case).status


def _check(args: argparse.Namespace, case: config.Case) -> int:
    reason = config.cannot_run(case)
    if reason is not None:
        say_error(MPI.COMM_WORLD, f"{args.config}: {reason}")
        return EXIT_USAGE
    log.info(
        "%s: valid (case %r, geometry %s, mesh %s, structure %s)",
        args.config,
        case.name,
        case.geometry.kind,
        case.mesh.level,
        case.structure.mode,
    )
    return EXIT_OK


def _mesh(args: argparse.Namespace, case: config.Case) -> int:
    return launch.mesh_case(args.config, args.out, case)


def _report(args: argparse.Namespace) -> int:
    from fsi.output import report, report_runs

    comm = MPI.COMM_WORLD
    status = EXIT_OK
    if comm.rank == 0:  # reading and plotting a few files: rank 0 alone
        try:
            report_runs.check_times(args.times)
            report_runs.check_out(args.out)
            runs = report_runs.load_runs(args.runs)
        except report_runs.ReportError as e:
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
            ("--fibres", args.fibres or None),
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
    from fsi.output import field_files, plot, section, wall_plot

    plot.check_out(args.out)
    refused = _plot_options_refused(args)
    if refused:
        raise plot.PlotError(refused)
    if args.field in wall_plot.INDICES:
        index = wall_plot.read(args.run, args.field, args.cycle)
        return wall_plot.draw(index, args.out), None
    plane = None if args.slice is None else section.Plane.parse(args.slice)
    snapshot = field_files.read_field(
        args.run, args.field, args.time, warp=args.warp, region=args.region
    )
    if plane is not None:
        snapshot = section.cut(snapshot, plane)
    flow = plot.streamline_field(snapshot) if args.streamlines else None
    fibres = plot.fibre_fields(snapshot) if args.fibres else ()
    written = plot.draw(snapshot, args.out, component=args.component, flow=flow, fibres=fibres)
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
