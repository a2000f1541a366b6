"""``fsi sweep --scheduler slurm``: a sweep's unfinished runs as the tasks of one Slurm job array.

:func:`submit` writes ``DIR/sweep.json`` (the sweep's definition), each run folder's
``submitted.yaml`` (its resolved configuration) and ``DIR/sweep.sbatch`` (task *i* runs
``fsi sweep ... --task i`` under ``srun``: :func:`run_task`, the resume rules of
:func:`fsi.run.sweep_execution.advance`) and submits it with ``sbatch``; :func:`collect` writes the
table of the finished runs (``fsi sweep DIR --collect``), with why each other run is not done.
"""

from __future__ import annotations

import json
import logging
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

from mpi4py import MPI

from fsi import config
from fsi.output import io
from fsi.run import errors, sweep, sweep_execution, sweep_results

log = logging.getLogger("fsi")

SCRIPT, DEFINITION, TASKS = "sweep.sbatch", "sweep.json", "slurm"
"""The batch script, the sweep's definition and the folder of the tasks' logs (in DIR)."""

SUBMITTED, OUTCOME = "submitted.yaml", "slurm-task.status"
"""In each run folder: its resolved configuration as submitted, and how its last array task
ended (done, stopped, ``failed: <why>``)."""

DEFAULT_OPTIONS = {"job-name": "fsi-sweep", "signal": "USR1@120"}
"""``#SBATCH`` options written unless ``--slurm-option`` gives them: USR1 two minutes before
the time limit stops a run with a checkpoint (as ``fsi run``'s SIGUSR1)."""

RESERVED = ("array", "ntasks", "output", "chdir")
"""Options the sweep sets itself (the runs to do, ``--ranks-per-run``, the logs' folder)."""

METACHARACTERS = frozenset(" \t\n\r|&;<>()$`\\\"'")
"""Characters refused in a ``--slurm-option`` (blanks, newlines, the shell's operators,
quotes and expansions)."""

TIMEOUT = 60
"""Seconds ``sbatch`` and ``squeue`` may take."""


class SlurmError(Exception):
    """A wrong ``--slurm-option``, no ``sbatch``, a refused submission, no sweep to collect
    (exit status 2, one line)."""


@dataclass(frozen=True)
class SlurmSweep:
    """A sweep for Slurm: the case file and ``--out`` (absolute), the ``--vary`` and ``--set``
    options, the ranks of each run, the ``#SBATCH`` options, and the array task that last
    took each run (run folder's name → ``<job>_<run number>``)."""

    case: str
    out: str
    vary: tuple[str, ...]
    sets: tuple[str, ...]
    ranks: int = 1
    options: Mapping[str, str] = field(default_factory=dict)
    jobs: Mapping[str, str] = field(default_factory=dict)


def parse_options(items: Sequence[str]) -> dict[str, str]:
    """The ``--slurm-option KEY=VALUE`` (or ``KEY`` alone, a flag: value ``""``) as a mapping,
    :data:`DEFAULT_OPTIONS` included. Raises :class:`SlurmError` for a malformed key, a
    :data:`RESERVED` key, or a newline or a :data:`METACHARACTERS` character."""
    options = dict(DEFAULT_OPTIONS)
    for item in items:
        key, _, value = item.partition("=")
        key = key.strip().lstrip("-")
        bad = sorted(set(item) & METACHARACTERS)
        if bad:
            raise SlurmError(
                f"--slurm-option {item!r}: {bad[0]!r} is not allowed (no blanks, newlines, "
                "quotes or shell metacharacters)"
            )
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_-]*", key):
            raise SlurmError(f"--slurm-option {item!r}: expected KEY=VALUE (e.g. time=02:00:00)")
        if key in RESERVED:
            raise SlurmError(
                f"--slurm-option {key}: set by the sweep (the runs to do, --ranks-per-run, "
                f"the logs in DIR/{TASKS}/)"
            )
        options[key] = value
    return options


def prepare(
    case: Path,
    out: Path,
    options: tuple[Sequence[str], Sequence[str]],
    ranks: int,
    slurm_options: Sequence[str],
    dry_run: bool,
    comm: MPI.Comm,
) -> SlurmSweep:
    """The :class:`SlurmSweep` of ``fsi sweep CASE --out OUT --vary ... --set ...`` (``options``:
    the ``--vary`` and the ``--set`` items) ``--scheduler slurm --ranks-per-run RANKS
    --slurm-option ...``, with the jobs of an earlier submission into ``out``. Raises
    :class:`SlurmError` for a wrong option or, unless ``dry_run``, no ``sbatch``."""
    if ranks < 1:
        raise SlurmError(f"--ranks-per-run {ranks}: expected a positive whole number")
    checked = parse_options(slurm_options)
    if not dry_run and shutil.which("sbatch") is None:
        raise SlurmError("--scheduler slurm: sbatch not found (is Slurm's client on the PATH?)")
    earlier = comm.bcast(_earlier_jobs(out) if comm.rank == 0 else None, root=0)
    vary, sets = options
    return SlurmSweep(
        str(case.absolute()),
        str(out.absolute()),
        tuple(vary),
        tuple(sets),
        ranks,
        checked,
        earlier,
    )


def _earlier_jobs(out: Path) -> dict[str, str]:
    """The array tasks of a sweep submitted earlier into ``out`` (:attr:`SlurmSweep.jobs`)."""
    try:
        return dict(load(out).jobs)
    except SlurmError:
        return {}


# --------------------------------------------------------------------------------------------
# The files


def load(out: Path) -> SlurmSweep:
    """The :class:`SlurmSweep` of ``out/sweep.json``; :class:`SlurmError` if there is none."""
    try:
        data = json.loads((out / DEFINITION).read_text())
        data.update(vary=tuple(data["vary"]), sets=tuple(data["sets"]), out=str(out.absolute()))
        return SlurmSweep(**data)
    except (OSError, ValueError, TypeError, KeyError) as e:
        raise SlurmError(
            f"--collect: {out} holds no readable {DEFINITION} (a sweep submitted with "
            f"--scheduler slurm): {e}"
        ) from None


def save(definition: SlurmSweep) -> None:
    """Write ``out/sweep.json`` (rank 0)."""
    text = json.dumps(asdict(definition), indent=1) + "\n"
    (Path(definition.out) / DEFINITION).write_text(text)


def task_command(definition: SlurmSweep) -> list[str]:
    """``python -m fsi sweep CASE --out DIR --vary ... --set ... --task`` (the task's index
    follows), with this Python's absolute path."""
    return [
        sys.executable,
        "-m",
        "fsi",
        "sweep",
        definition.case,
        "--out",
        definition.out,
        *[a for v in definition.vary for a in ("--vary", v)],
        *[a for s in definition.sets for a in ("--set", s)],
        "--task",
    ]


def script(definition: SlurmSweep, runs: Sequence[sweep.SweepRun]) -> str:
    """The batch script: a job array of ``runs``, each task ``srun -n <ranks>`` running its run
    (every word shell-quoted); a task that ends without writing its outcome gets ``failed:
    ...`` with its exit status."""
    options = {
        "array": ",".join(str(run.index) for run in runs),
        "ntasks": str(definition.ranks),
        "output": f"{TASKS}/%A_%a.log",
        **definition.options,
    }
    folders = " ".join(f"[{run.index}]={shlex.quote(run.folder.name)}" for run in runs)
    outcome = f'{shlex.quote(definition.out)}/"${{folders[$SLURM_ARRAY_TASK_ID]}}"/{OUTCOME}'
    lines = [
        "#!/bin/bash",
        "# fsi sweep --scheduler slurm: one array task per run to do. Submit again with the",
        f"# same fsi sweep command (or sbatch {SCRIPT} from this folder).",
        *[f"#SBATCH --{k}={shlex.quote(v)}" if v else f"#SBATCH --{k}" for k, v in options.items()],
        "export SLURM_MPI_TYPE=${SLURM_MPI_TYPE:-pmix}  # srun starts the MPI ranks",
        "export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1",
        f"folders=({folders})",
        f"outcome={outcome}",
        'rm -f "$outcome"',
        f'srun -n {definition.ranks} {shlex.join(task_command(definition))} "$SLURM_ARRAY_TASK_ID"',
        "status=$?",
        'if [ ! -s "$outcome" ]; then',
        '    echo "failed: its task ended with exit status $status without an outcome (see '
        f'{TASKS}/${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}.log)" > "$outcome"',
        "fi",
        'exit "$status"',
    ]
    return "\n".join(lines) + "\n"


def write(definition: SlurmSweep, runs: Sequence[sweep.SweepRun], todo: Sequence[int]) -> Path:
    """Write each run folder's ``submitted.yaml`` (the earlier outcomes of the runs numbered
    ``todo`` deleted), ``DIR/slurm/``, ``DIR/sweep.json`` and the batch script of ``todo``;
    returns the script's path. Rank 0; raises OSError."""
    out = Path(definition.out)
    (out / TASKS).mkdir(parents=True, exist_ok=True)
    for run in runs:
        run.folder.mkdir(exist_ok=True)
        (run.folder / SUBMITTED).write_text(config.to_yaml(run.case))
    chosen = [run for run in runs if run.index in todo]
    for run in chosen:
        (run.folder / OUTCOME).unlink(missing_ok=True)
    save(definition)
    path = out / SCRIPT
    path.write_text(script(definition, chosen))
    path.chmod(0o755)
    return path


# --------------------------------------------------------------------------------------------
# Slurm's commands


def sbatch(out: Path) -> str:
    """Submit ``out/sweep.sbatch`` from ``out``; the job id. Raises :class:`SlurmError`."""
    try:
        done = subprocess.run(
            ["sbatch", "--parsable", SCRIPT],
            cwd=out,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as e:
        raise SlurmError(f"sbatch: {e}") from None
    if done.returncode != 0:
        why = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        raise SlurmError(f"sbatch refused {out / SCRIPT}: {why}")
    job = done.stdout.strip().split(";")[0]
    if not re.fullmatch(r"[0-9]+", job):  # --parsable prints "<id>" or "<id>;<cluster>"
        raise SlurmError(
            f"sbatch printed {_shown(done.stdout)}, not a job id: {out / SCRIPT} may have been "
            "submitted all the same; see squeue before submitting the sweep again"
        )
    return job


def _shown(text: str) -> str:
    """Program output for a message: its first line, bounded, quoted."""
    first = (text.strip().splitlines() or [""])[0]
    return repr(first if len(first) <= 60 else first[:60] + "...")


JOB_STATE = re.compile(r"([0-9]+(?:_[0-9]+)?) ([A-Z]+)")
"""A line of ``squeue -h -r -o '%i %t'``: an array task (``<job>_<n>``) and its state code."""


def queued(jobs: Mapping[str, str]) -> tuple[dict[str, str], dict[str, str]]:
    """The array tasks of ``jobs`` (:attr:`SlurmSweep.jobs`) still in Slurm's queue:
    ``<job>_<number>`` → ``queued (job J)`` or ``running (job J)``, from ``squeue``; and the
    jobs whose state ``squeue`` could not tell (job → why: no squeue, a timeout, an error
    other than Slurm no longer knowing the job, output that is not a list of tasks). A job
    that left the queue is in neither."""
    found: dict[str, str] = {}
    unknown: dict[str, str] = {}
    for job in sorted({task.partition("_")[0] for task in jobs.values()}):
        try:
            done = subprocess.run(
                ["squeue", "-h", "-r", "-j", job, "-o", "%i %t"],
                capture_output=True,
                text=True,
                timeout=TIMEOUT,
                check=False,
            )
        except FileNotFoundError:
            unknown[job] = "squeue not found (is Slurm's client on the PATH?)"
            continue
        except (OSError, subprocess.TimeoutExpired) as e:
            unknown[job] = f"squeue: {e}"
            continue
        if done.returncode != 0:
            why = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
            if "invalid job id" not in why.lower():  # that one: Slurm forgot the ended job
                unknown[job] = f"squeue failed: {why}"
            continue
        lines = [JOB_STATE.fullmatch(line.strip()) for line in done.stdout.strip().splitlines()]
        if not all(lines):
            unknown[job] = f"squeue printed {_shown(done.stdout)}, not a list of tasks"
            continue
        for line in lines:
            task, state = line.groups()
            found[task] = f"{'running' if state == 'R' else 'queued'} (job {job})"
    return found, unknown


# --------------------------------------------------------------------------------------------
# Collecting, submitting, running a task


def statuses(definition: SlurmSweep, runs: Sequence[sweep.SweepRun]) -> list[str]:
    """Each run's status for the table: ``done`` (:func:`fsi.run.sweep.folder_state` would skip
    it), ``pending: queued/running (job J)``, its task's outcome (``failed: <why>``,
    ``stopped``), ``pending: unknown, ...`` for a task whose state ``squeue`` cannot tell
    (missing, failing), ``failed: ...`` for a task that left the queue without one, else
    ``pending: not submitted``. Rank 0."""
    in_queue, unknown = queued(definition.jobs)
    found = []
    for run in runs:
        outcome = run.folder / OUTCOME
        task = definition.jobs.get(run.folder.name, "")
        job = task.partition("_")[0]
        if sweep.folder_state(run).action == "skip":
            status = "done"
        elif task in in_queue:
            status = f"pending: {in_queue[task]}"
        elif outcome.is_file():  # done: to another configuration or time.end than now
            told = (outcome.read_text().strip().splitlines() or [""])[0]
            status = told if told.startswith(("failed", "stopped")) else "pending: not submitted"
        elif job in unknown:  # neither failed nor to be submitted again: it may be queued
            status = (
                f"pending: unknown, the state of its array task {task} cannot be read "
                f"({unknown[job]}); not submitted again until it can"
            )
        elif task:
            status = (
                f"failed: its array task {task} ended without an outcome (cancelled, or "
                f"killed at the time limit?): see {Path(definition.out) / TASKS}/{task}.log"
            )
        else:
            status = "pending: not submitted"
        found.append(status)
    return found


def collect(
    definition: SlurmSweep,
    runs: Sequence[sweep.SweepRun],
    variations: Sequence[sweep.Variation],
    comm: MPI.Comm,
    listing: bool = True,
) -> list[str]:
    """Write the table and the plots of the finished runs
    (:func:`fsi.run.sweep_results.write_results`) and (``listing``) log every run that is not done
    with why; returns the statuses.
    Collective; raises :class:`fsi.output.io.OutputError`."""
    found = comm.bcast(statuses(definition, runs) if comm.rank == 0 else None, root=0)
    written, found = sweep_results.write_results(
        runs, variations, found, Path(definition.out), comm
    )
    for run, status in zip(runs, found, strict=True):
        if listing and status != "done":
            log.info("sweep %d/%d: %s: %s", run.index, len(runs), run.label, status)
    log.info(
        "sweep: %d of %d runs done; wrote %s",
        found.count("done"),
        len(runs),
        ", ".join(str(p) for p in written),
    )
    return found


def submit(
    definition: SlurmSweep, runs: Sequence[sweep.SweepRun], found: Sequence[str], dry_run: bool
) -> str | None:
    """Write the files of :func:`write` for the runs neither done nor in the queue (``found``:
    their statuses) and, unless ``dry_run``, submit the script and record its job in
    ``DIR/sweep.json``; returns the job id (None: nothing to do, or a dry run). Rank 0; raises
    :class:`SlurmError` and OSError."""
    waiting = ("pending: queued", "pending: running", "pending: unknown")
    todo = [
        run.index
        for run, status in zip(runs, found, strict=True)
        if status != "done" and not status.startswith(waiting)
    ]
    unknown = sum(status.startswith("pending: unknown") for status in found)
    if unknown:
        log.warning(
            "fsi: warning: %d run%s submitted earlier not submitted again: squeue cannot tell "
            "whether %s still queued (see the table)",
            unknown,
            "s" if unknown > 1 else "",
            "they are" if unknown > 1 else "it is",
        )
    if not todo:
        log.info("sweep: every run is done or in Slurm's queue: nothing to submit")
        return None
    path = write(definition, runs, todo)
    if dry_run:
        log.info("wrote %s (not submitted: --dry-run) for runs %s", path, _ranges(todo))
        return None
    job = sbatch(Path(definition.out))
    taken = {run.folder.name: f"{job}_{run.index}" for run in runs if run.index in todo}
    jobs = {**definition.jobs, **taken}
    save(SlurmSweep(**{**asdict(definition), "jobs": jobs}))
    log.info("submitted %s as job %s: runs %s", path, job, _ranges(todo))
    return job


def submit_or_collect(
    definition: SlurmSweep,
    runs: Sequence[sweep.SweepRun],
    variations: Sequence[sweep.Variation],
    dry_run: bool,
    collect_only: bool,
    comm: MPI.Comm,
) -> tuple[int, str, str | None]:
    """``fsi sweep --scheduler slurm``: the table so far (:func:`collect`; not for a dry run),
    then the runs to do written and submitted (:func:`submit`); ``collect_only``: the table
    alone. Returns the exit status (0; 3 when ``collect_only`` finds a failed run; 2 when
    Slurm refuses; 4 when a file cannot be written), the error message and the job id.
    Collective."""
    try:
        if dry_run:
            found = comm.bcast(statuses(definition, runs) if comm.rank == 0 else None, root=0)
        else:
            found = collect(definition, runs, variations, comm, listing=collect_only)
    except io.OutputError as e:
        return errors.EXIT_OUTPUT_FAILED, f"cannot write the sweep's table: {e}", None
    if collect_only:
        failed = any(s.startswith("failed") for s in found)
        return (errors.EXIT_SOLVE_FAILED if failed else errors.EXIT_OK), "", None
    outcome: tuple[int, str, str | None] = (errors.EXIT_OK, "", None)
    if comm.rank == 0:
        try:
            outcome = (errors.EXIT_OK, "", submit(definition, runs, found, dry_run))
        except SlurmError as e:
            outcome = (errors.EXIT_USAGE, str(e), None)
        except OSError as e:
            outcome = (errors.EXIT_OUTPUT_FAILED, f"--out: {e.filename}: {e.strerror or e}", None)
    return comm.bcast(outcome, root=0)


def _ranges(indices: Sequence[int]) -> str:
    """``1, 3, 4`` (the runs' numbers, for the messages)."""
    return ", ".join(str(i) for i in indices)


def run_task(
    runs: Sequence[sweep.SweepRun], index: int, run_one: sweep_execution.RunOne, comm: MPI.Comm
) -> tuple[int, str, None]:
    """One array task: run number ``index`` skipped, resumed or started as a local sweep would
    (:func:`fsi.run.sweep_execution.advance`), or refused when its case no longer resolves to the
    submitted configuration; its outcome written to its folder's :data:`OUTCOME`. Returns
    the exit status (0 done, 3 failed, 128 + the signal that stopped it, 2 no such run, 4 the
    outcome not written), the error message and no job id. Collective."""
    if not 1 <= index <= len(runs):
        return (
            errors.EXIT_USAGE,
            f"--task {index}: expected a run number from 1 to {len(runs)}",
            None,
        )
    run = runs[index - 1]
    submitted = run.folder / SUBMITTED
    changed = comm.bcast(
        submitted.is_file() and submitted.read_text() != config.to_yaml(run.case)
        if comm.rank == 0
        else None,
        root=0,
    )
    if changed:
        status, stopped_by = (
            "failed: the case resolves to another configuration than the one submitted (was "
            "the case file changed?): submit the sweep again",
            0,
        )
    else:
        status, stopped_by = sweep_execution.advance(run, len(runs), run_one, comm)
    outcome = run.folder / OUTCOME
    try:
        io.on_rank0(
            comm,
            lambda: (
                outcome.parent.mkdir(parents=True, exist_ok=True),
                outcome.write_text(status + "\n"),
            ),
            outcome,
        )
    except io.OutputError as e:
        return errors.EXIT_OUTPUT_FAILED, f"cannot write the task's outcome: {e}", None
    if stopped_by:
        return 128 + stopped_by, "", None
    return (errors.EXIT_SOLVE_FAILED if status.startswith("failed") else errors.EXIT_OK), "", None
