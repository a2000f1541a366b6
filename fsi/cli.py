"""The command line: ``fsi run``, ``fsi mesh``, ``fsi check``, ``fsi report`` (``python -m fsi``
is the same).

Exit status: 0 done; 2 the configuration, the command line or the checkpoint to restart from is
wrong (nothing is written); 3 the solve failed (the last converged step is checkpointed).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Sequence

from mpi4py import MPI

from fsi import config

log = logging.getLogger("fsi")

EXIT_OK, EXIT_USAGE, EXIT_SOLVE_FAILED = 0, 2, 3


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fsi", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    def with_config(p: argparse.ArgumentParser) -> None:
        p.add_argument("config", type=Path, help="YAML case file")
        p.add_argument("--set", dest="overrides", action="append", default=[],
                       metavar="KEY.PATH=VALUE", help="override a configuration value (repeatable)")

    p = sub.add_parser("run", help="run a case: DIR/metrics.csv, summary.json, fields.xdmf, "
                                   "checkpoint/")
    with_config(p)
    p.add_argument("--out", type=Path, required=True, metavar="DIR")
    p.add_argument("--restart", type=Path, metavar="DIR",
                   help="continue from the checkpoint of an earlier run in DIR (DIR/checkpoint; "
                        "same mesh and structure, any number of ranks; the schedule, the "
                        "coupling and the solver settings may change)")
    p = sub.add_parser("mesh", help="build the case's mesh: DIR/mesh.xdmf and DIR/mesh.json")
    with_config(p)
    p.add_argument("--out", type=Path, required=True, metavar="DIR")
    p = sub.add_parser("check", help="validate a case without running it")
    with_config(p)
    p = sub.add_parser("report", help="the study's tables (peaks at the report times, solver "
                                      "effort) and plots from run folders")
    p.add_argument("runs", type=Path, nargs="+", metavar="RUN_DIR")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="write DIR/report.md and PNG plots (default: print the tables only)")
    p.add_argument("--times", type=float, nargs="+", metavar="T",
                   help="report times in s (default: the first run's output.report_times)")
    return parser


def _setup_logging(comm: MPI.Comm) -> None:
    """Progress on rank 0 only; other ranks report warnings and errors."""
    logger = logging.getLogger("fsi")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
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


class _WarningsOnly(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.WARNING


def main(argv: Sequence[str] | None = None) -> int:
    comm = MPI.COMM_WORLD
    _setup_logging(comm)
    try:
        args = _parser().parse_args(argv)
    except SystemExit as e:  # argparse has printed the message; --help exits 0
        return int(e.code or 0)
    if args.command == "report":
        return _report(args)
    try:
        case = config.load(args.config, args.overrides)
    except config.ConfigError as e:
        if comm.rank == 0:
            print(f"fsi: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    return {"run": _run, "mesh": _mesh, "check": _check}[args.command](args, case)


def _check(args: argparse.Namespace, case: config.Case) -> int:
    log.info("%s: valid (case %r, geometry %s, mesh %s, structure %s)", args.config, case.name,
             case.geometry.kind, case.mesh.level, case.structure.mode)
    return EXIT_OK


def _run(args: argparse.Namespace, case: config.Case) -> int:
    from fsi import simulation

    reason = simulation.unsupported(case)
    if reason is not None:
        if MPI.COMM_WORLD.rank == 0:
            print(f"fsi: error: {args.config}: {reason}", file=sys.stderr)
        return EXIT_USAGE
    from fsi import checkpoint

    restart = None
    try:
        if args.restart is not None:
            restart = checkpoint.read(args.restart, case, MPI.COMM_WORLD)
            log.info("restarting from %s: step %d, t = %.6g s", restart.path, restart.step,
                     restart.t)
        result = simulation.run(case, args.out, MPI.COMM_WORLD, restart)
    except checkpoint.CheckpointError as e:
        if MPI.COMM_WORLD.rank == 0:
            print(f"fsi: error: --restart: {e}", file=sys.stderr)
        return EXIT_USAGE
    except simulation.SolveFailed as e:
        log.error("fsi: solve failed: %s (the finished steps are in %s)", e,
                  args.out / "metrics.csv")
        if e.checkpoint is not None:
            log.error("fsi: the state after step %d (t = %.6g s), the last converged one, is "
                      "checkpointed in %s."
                      " To continue from it, change what failed (e.g. a smaller time step with"
                      " --set 'time.schedule=[...]', or the coupling or solver settings) and run"
                      "\n  fsi run %s --out %s --restart %s --set ...", e.step, e.t,
                      e.checkpoint, args.config, args.out, args.out)
        return EXIT_SOLVE_FAILED
    log.info("done: %d steps in %.1f s; wrote %s", result.steps, result.wall_time_s, args.out)
    return EXIT_OK


def _mesh(args: argparse.Namespace, case: config.Case) -> int:
    from fsi import io, mesh

    tagged = mesh.build(case, MPI.COMM_WORLD)
    summary = mesh.summary(tagged, case)
    io.write_mesh(args.out, tagged, summary)
    cells = summary["cells"]
    log.info("mesh of %s (%s): %d triangles (%s)", args.config, case.mesh.level, cells["total"],
             ", ".join(f"{k} {v}" for k, v in cells.items() if k != "total"))
    for name, value in summary.get("measures", {}).items():
        log.info("  %s: %.6g", name, value)
    log.info("wrote %s and %s", args.out / "mesh.xdmf", args.out / "mesh.json")
    return EXIT_OK


def _report(args: argparse.Namespace) -> int:
    from fsi import report

    comm = MPI.COMM_WORLD
    status = EXIT_OK
    if comm.rank == 0:  # reading and plotting a few files: rank 0 alone
        try:
            runs = [report.load_run(path) for path in args.runs]
        except report.ReportError as e:
            print(f"fsi: error: {e}", file=sys.stderr)
            status = EXIT_USAGE
        else:
            print(report.markdown(runs, args.times))
            if args.out is not None:
                written = report.write(runs, args.out, args.times)
                log.info("wrote %s", ", ".join(str(p) for p in written))
    return comm.bcast(status, root=0)


def run_console() -> None:
    """Console-script entry point."""
    sys.exit(main())
