"""``fsi sweep``'s dispatch (:func:`sweep`): the plan checked, then the runs here one after
the other (fsi/run/sweep.py), or submitted as a Slurm job array, one of its tasks run, or its
table collected (fsi/run/slurm.py). Each run is ``fsi run``'s (:func:`fsi.run.launch.run_case`).
The options are ``fsi sweep``'s command line (docs/sweep.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mpi4py import MPI

from fsi import config
from fsi.run import sweep_execution
from fsi.run.errors import EXIT_OK, EXIT_USAGE
from fsi.run.launch import Refused, RunRequest, run_case, say_error
from fsi.run.signals import StopOnSignal


def sweep(args: argparse.Namespace) -> int:
    """``fsi sweep``: every run validated (and ``--out`` checked) before the first starts; then
    the runs one after the other in this process, each as ``fsi run`` (:func:`run_case`), and
    the table (fsi/run/sweep.py); or, with ``--scheduler slurm``, the runs to do submitted as a
    Slurm job array, whose tasks (``--task``) run them, and ``--collect`` for the table
    (fsi/run/slurm.py). A stop signal stops the current run as ``fsi run`` and the sweep after
    it."""

    comm = MPI.COMM_WORLD
    try:
        definition = _slurm_sweep(args, comm)
        variations, runs = _sweep_plan(args, comm)
    except Refused as e:
        say_error(comm, str(e))
        return EXIT_USAGE
    if not args.dry_run and args.task is None and not args.collect:
        refused = comm.bcast(
            sweep_execution.refusal(runs, args.overwrite) if comm.rank == 0 else ""
        )
        if refused:
            say_error(comm, f"--out {args.out}: {refused}")
            return EXIT_USAGE
    if definition is not None or args.task is not None:
        return _sweep_slurm(args, definition, variations, runs, comm)
    if args.dry_run:
        lines = sweep_execution.describe_plan(runs, args.overwrite) if comm.rank == 0 else []
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
    with StopOnSignal() as stop:
        return sweep_execution.execute(
            runs, variations, args.out, _sweep_run_one(args), stop, resume, comm
        )


def _sweep_plan(args: argparse.Namespace, comm: MPI.Comm):
    """The sweep's variations and validated runs, ``--out`` checked; :class:`Refused`."""
    from fsi.output import io
    from fsi.run import sweep

    try:
        variations = sweep.parse_vary(args.vary)
        runs = sweep.plan(args.config, variations, args.overrides, args.out)
        io.check_folder(comm, args.out, earlier_run=True)
    except (sweep.SweepError, config.ConfigError) as e:
        raise Refused(str(e)) from None
    except io.RunFolderError as e:
        raise Refused(f"--out: {e}") from None
    return variations, runs


def _slurm_sweep(args: argparse.Namespace, comm: MPI.Comm):
    """The checked :class:`fsi.run.slurm.SlurmSweep` of ``--scheduler slurm``, or of
    ``--collect`` (DIR/sweep.json, whose case, ``--vary``, ``--set`` and folder then replace
    ``args``'); None for a local sweep or a task. :class:`Refused`."""
    from fsi.run import slurm

    if args.scheduler not in ("local", "slurm"):
        raise Refused(f"--scheduler {args.scheduler}: expected local or slurm")
    try:
        if args.collect:
            if args.vary or args.overrides or args.out or args.scheduler != "local":
                raise Refused(
                    "--collect takes the sweep's folder alone (DIR/sweep.json has the rest)"
                )
            definition = slurm.load(args.config)
            args.config, args.out = Path(definition.case), Path(definition.out)
            args.vary, args.overrides = list(definition.vary), list(definition.sets)
            return definition
        if not args.vary or args.out is None:
            raise Refused(
                f"the following arguments are required: {'--out' if args.vary else '--vary'}"
            )
        if args.scheduler == "local" or args.task is not None:
            if args.ranks_per_run != 1 or args.slurm_option:
                raise Refused("--ranks-per-run and --slurm-option go with --scheduler slurm")
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
        raise Refused(str(e)) from None


def _sweep_run_one(args: argparse.Namespace):
    """The function that runs one of the sweep's runs as ``fsi run`` (:func:`run_case`)."""

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
        with StopOnSignal():
            status, message, job = slurm.run_task(runs, args.task, _sweep_run_one(args), comm)
    else:
        status, message, job = slurm.submit_or_collect(
            definition, runs, variations, args.dry_run, args.collect, comm
        )
    if message:
        say_error(comm, message)
    elif job is not None and comm.rank == 0:
        print(job, flush=True)
    return status
