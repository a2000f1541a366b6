"""``fsi sweep``: a case run for every combination of the values of one or more keys (the
Cartesian product of the ``--vary`` lists), one run folder each under ``--out``, then one table
and plots of each run's headline outputs.

:func:`plan` makes and validates the combinations, :func:`execute` runs them (a finished run
is skipped, a stopped one resumed: :func:`folder_state`), :func:`write_results` writes the table
(``sweep.csv``, ``sweep.md``) of the :data:`HEADLINES` and the plots (:func:`write_plots`).
"""

from __future__ import annotations

import gc
import itertools
import json
import logging
import math
import re
import shlex
import signal
import time as wallclock
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from mpi4py import MPI

import yaml

from fsi import config
from fsi.config import reader
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import io, units
from fsi.run import checkpoint

log = logging.getLogger("fsi")

MAX_RUNS = 1000
"""The largest product a sweep accepts (each run is a whole ``fsi run``)."""

EXIT_OK, EXIT_USAGE, EXIT_SOLVE_FAILED, EXIT_OUTPUT_FAILED = 0, 2, 3, 4


class SweepError(Exception):
    """A wrong ``--vary``, ``--set`` or ``--out`` (exit status 2, before any run)."""


# --------------------------------------------------------------------------------------------
# The product


@dataclass(frozen=True)
class Variation:
    """One ``--vary key=v1,v2,...``: the key and its values as typed (YAML, as ``--set``)."""

    key: str
    values: tuple[str, ...]

    @property
    def option(self) -> str:
        return f"{self.key}={','.join(self.values)}"


@dataclass(frozen=True)
class SweepRun:
    """One combination: its number (from 1), the (key, value) of each varied key in ``--vary``
    order, the validated case and the overrides that make it, and its folder."""

    index: int
    choice: tuple[tuple[str, str], ...]
    case: config.Case
    overrides: tuple[str, ...]
    folder: Path

    @property
    def label(self) -> str:
        """``key=value, key=value`` (the progress lines)."""
        return ", ".join(f"{key}={value}" for key, value in self.choice)


def split_values(text: str) -> list[str]:
    """``text`` split at its commas outside brackets, braces and quotes (so a YAML list or
    mapping is one value: ``[bottom],[bottom, top]`` → ``[bottom]``, ``[bottom, top]``), each
    stripped of surrounding blanks."""
    values, current, depth, quote = [], [], 0, ""
    for char in text:
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth = max(depth - 1, 0)
        elif char == "," and depth == 0:
            values.append("".join(current).strip())
            current = []
            continue
        current.append(char)
    values.append("".join(current).strip())
    return values


def parse_vary(items: Sequence[str]) -> list[Variation]:
    """The ``--vary`` options as :class:`Variation` s. Raises :class:`SweepError` for an item
    without ``key=``, an empty value list or value, a value given twice, a key given twice."""
    variations: list[Variation] = []
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise SweepError(f"--vary {item!r}: expected key.path=value1,value2,...")
        if any(v.key == key for v in variations):
            raise SweepError(f"--vary {key}: given twice (list all its values in one --vary)")
        if not text.strip():
            raise SweepError(f"--vary {key}: no values (expected {key}=value1,value2,...)")
        values = split_values(text)
        if "" in values:
            raise SweepError(
                f"--vary {key}: an empty value in {text!r} (expected {key}=value1,value2,...)"
            )
        twice = next((v for i, v in enumerate(values) if v in values[:i]), None)
        if twice is not None:
            raise SweepError(f"--vary {key}: the value {twice!r} is given twice")
        variations.append(Variation(key, tuple(values)))
    return variations


def _overlaps(a: str, b: str) -> bool:
    """Whether key paths ``a`` and ``b`` are the same or one holds the other."""
    return a == b or a.startswith((b + ".", b + "[")) or b.startswith((a + ".", a + "["))


def plan(
    case_file: Path, variations: Sequence[Variation], sets: Sequence[str], out: Path
) -> list[SweepRun]:
    """Every combination of the varied values (``itertools.product`` in ``--vary`` order: the
    last key changes fastest), each validated as ``fsi run`` would validate it, before any run.

    Raises :class:`SweepError`: a key both varied and ``--set`` (or one inside the other),
    more than :data:`MAX_RUNS` runs, a combination the configuration refuses (the first one:
    ``--vary key=value: <the configuration's message>``, naming the varied key it is about, or
    all the combination's values when it is about another key) or ``fsi run`` cannot run, two
    combinations that give the same case or the same folder name; and
    :class:`fsi.config.ConfigError` when the case file or ``--set`` alone is wrong."""
    _check_variations(variations, sets)
    varied = [v.key for v in variations]
    first = [f"{v.key}={v.values[0]}" for v in variations]
    load = config.loader(case_file)
    _check_base(load, sets, varied, [*sets, *first])

    runs: list[SweepRun] = []
    seen: dict[str, SweepRun] = {}
    folders: dict[str, SweepRun] = {}
    total, said = math.prod(len(v.values) for v in variations), wallclock.monotonic()
    for index, values in enumerate(itertools.product(*(v.values for v in variations)), 1):
        if index > 1 and wallclock.monotonic() - said > VALIDATION_PROGRESS_S:
            log.info("sweep: validated %d of %d runs", index - 1, total)
            said = wallclock.monotonic()
        choice = tuple(zip(varied, values, strict=True))
        overrides = (*sets, *(f"{key}={value}" for key, value in choice))
        try:
            case = load(overrides)
        except config.ConfigError as e:
            raise SweepError(str(e.from_source(_culprit(choice, e.key)))) from None
        reason = config.cannot_run(case)
        if reason is not None:
            raise SweepError(f"{_culprit(choice, '')}: {reason}")
        run = SweepRun(index, choice, case, overrides, out / folder_name(choice))
        resolved = json.dumps(config.to_dict(case), sort_keys=True)
        _check_unique(run, resolved, seen, folders)
        seen[resolved] = folders[run.folder.name] = run
        runs.append(run)
    return runs


VALIDATION_PROGRESS_S = 5.0
"""While a sweep's runs are validated, a progress line at most this often (s)."""


def _check_variations(variations: Sequence[Variation], sets: Sequence[str]) -> None:
    """Raise :class:`SweepError` if a varied key is also ``--set`` (or one holds the other) or
    the combinations are more than :data:`MAX_RUNS`."""
    set_keys = [item.partition("=")[0].strip() for item in sets]
    for variation in variations:
        clash = next((k for k in set_keys if _overlaps(k, variation.key)), None)
        if clash is not None:
            also = "" if clash == variation.key else f" (as part of {clash})"
            raise SweepError(
                f"--vary {variation.key}: also given with --set{also}: vary it or set it, not both"
            )
    count = math.prod(len(v.values) for v in variations)
    if count > MAX_RUNS:
        sizes = " x ".join(str(len(v.values)) for v in variations)
        raise SweepError(f"--vary: {sizes} = {count} runs; a sweep runs at most {MAX_RUNS}")


def _check_unique(
    run: SweepRun, resolved: str, seen: dict[str, SweepRun], folders: dict[str, SweepRun]
) -> None:
    """Raise :class:`SweepError` if ``run``'s resolved case or folder name is one of an earlier
    run's (``seen``, ``folders``), or its folder name is longer than 255 bytes."""
    if resolved in seen:
        raise SweepError(
            f"--vary: {seen[resolved].label} and {run.label} are the same "
            "case (values that mean the same, e.g. 0.5 and 0.50): give each "
            "value once"
        )
    if run.folder.name in folders:
        raise SweepError(
            f"--vary: {folders[run.folder.name].label} and {run.label} would "
            f"share the folder {run.folder}: values that differ only in "
            "characters other than letters, digits and . _ + -"
        )
    if len(run.folder.name.encode()) > 255:
        raise SweepError(
            f"--vary: the folder name of {run.label} would be longer than 255 "
            "bytes: vary fewer keys, or with shorter values"
        )


def _check_base(
    load: Callable[[Sequence[str]], config.Case],
    sets: Sequence[str],
    varied: Sequence[str],
    first: Sequence[str],
) -> None:
    """Raise the :class:`fsi.config.ConfigError` of the case file (``load``: it, with the
    overrides it is called with) with the ``--set`` overrides alone, unless it is about a
    varied key (which every run overrides) or the first combination's values (``first``: its
    overrides) remove it, as varied inlets remove the base inlet's "time.cycles needs a
    periodic inlet": each combination is then validated on its own."""
    try:
        load(sets)
    except config.ConfigError as e:
        if e.key and any(_overlaps(e.key, key) for key in varied):
            return
        try:
            load(first)
        except config.ConfigError as again:
            if again.key == e.key:
                raise e from None


def _culprit(choice: Sequence[tuple[str, str]], key: str) -> str:
    """``--vary key=value`` of the varied key that ``key`` is about, or all of the
    combination's values when it is about none of them."""
    about = [(k, v) for k, v in choice if key and _overlaps(key, k)]
    return "--vary " + ", ".join(f"{k}={v}" for k, v in (about or choice))


def folder_name(choice: Sequence[tuple[str, str]]) -> str:
    """``key=value,key=value`` in ``--vary`` order, the values as typed, with every run of
    characters other than letters, digits and ``. _ + -`` in keys and values replaced by ``_``
    (none at either end of a value: ``[bottom, top]`` → ``bottom_top``).
    """

    def clean(text: str) -> str:
        return re.sub(r"[^A-Za-z0-9._+-]+", "_", text).strip("_") or "_"

    return ",".join(f"{clean(key)}={clean(value)}" for key, value in choice)


# --------------------------------------------------------------------------------------------
# Resuming


@dataclass(frozen=True)
class FolderState:
    """What a sweep does with a run's folder: ``skip`` it (finished), ``resume`` it from its
    checkpoint, ``start`` the run in it (no earlier run there), or ``replace`` an earlier run
    there, deleting its files as ``fsi run --overwrite`` (only with ``fsi sweep
    --overwrite``: :func:`refusal`); ``why`` says so for the progress line."""

    action: Literal["skip", "resume", "start", "replace"]
    why: str


def folder_state(run: SweepRun) -> FolderState:
    """Read ``run.folder`` (rank 0 alone; writes nothing):

    - ``skip``: its ``config.yaml`` is this run's configuration and its ``summary.json`` says
      the run reached this configuration's ``time.end``;
    - ``resume``: its configuration differs from this run's at most in ``time`` (a longer
      ``time.end``, another schedule), and it has a checkpoint before ``time.end`` (a run
      stopped or failed; a finished run to be continued further), or at ``time.end`` with
      the same configuration (a run stopped before it wrote its summary.json);
    - ``start``: anything else (no earlier run, another configuration, no checkpoint).

    Keys that the stored ``config.yaml`` lacks (runs written before a key existed) are not
    compared."""
    folder = run.folder
    if not folder.is_dir() or not io.run_files(folder):
        return FolderState("start", "started")
    try:
        stored = yaml.safe_load((folder / "config.yaml").read_text())
    except (OSError, ValueError, yaml.YAMLError):
        stored = None
    if not isinstance(stored, dict):
        return FolderState("replace", "started afresh (its folder holds no readable config.yaml)")
    now = yaml.safe_load(config.to_yaml(run.case))
    different = config.differences(stored, now)
    end = config.run_time(run.case).end  # time.cycles: cycles × period
    if not different and _reached(folder / "summary.json", end):
        return FolderState("skip", "done earlier, skipped")
    reached = _covering_end(folder, different, end)
    if reached is not None:
        return FolderState(
            "skip",
            f"done earlier to t = {reached:.6g} s, which covers time.end = {end:.6g} s: "
            "skipped (its rows up to that end are tabled)",
        )
    other = [key for key in different if not _overlaps(key, "time")]
    if other:
        return FolderState(
            "replace", f"started afresh (its folder holds a run with another {other[0]})"
        )
    t = checkpoint_time(folder)
    at_end = t is not None and abs(t - end) <= SAME_TIME * end
    if t is not None and ((t < end and not at_end) or (at_end and not different)):
        return FolderState("resume", f"resumed from its checkpoint at t = {t:.6g} s")
    if t is None:
        why = "no checkpoint"
    elif at_end:
        why = "it ran to time.end with another schedule"
    else:
        why = f"its checkpoint is at t = {t:.6g} s, after time.end"
    return FolderState("replace", f"started afresh ({why})")


def _covering_end(folder: Path, different: Sequence[str], end: float) -> float | None:
    """The end a finished run in ``folder`` reached when it covers a request that differs
    from its configuration only in ``time.end`` (``different``), ending earlier: the same steps
    up to ``end``, so its rows up to ``end`` are the request's. None otherwise."""
    if list(different) != ["time.end"]:
        return None
    try:
        reached = float(json.loads((folder / "summary.json").read_text())["end_time_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return reached if reached > end * (1 + SAME_TIME) else None


def _reached(summary: Path, end: float) -> bool:
    """Whether ``summary`` is a run's complete summary.json with ``end_time_s`` = ``end``."""
    try:
        data = json.loads(summary.read_text())
        return abs(float(data["end_time_s"]) - end) <= SAME_TIME * end
    except (OSError, ValueError, KeyError, TypeError):
        return False


def checkpoint_time(folder: Path) -> float | None:
    """The time of the checkpoint of the run in ``folder`` (None: none, or unreadable)."""
    try:
        path, _ = checkpoint.locate(folder)
        return float(json.loads((path / checkpoint.METADATA).read_text())["t"])
    except (checkpoint.CheckpointError, OSError, ValueError, KeyError, TypeError):
        return None


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


# --------------------------------------------------------------------------------------------
# The table


@dataclass(frozen=True)
class Headline:
    """A column of the table: ``name``, the :mod:`fsi.output.units` quantity it is shown in, what it
    is, and where it comes from: the ``max``/``min`` over the rows of metrics.csv column
    ``source``, or (``how="summary"``) summary.json's key ``source``."""

    name: str
    label: str  # the quantity's short name on a plot's axis
    quantity: str
    meaning: str
    source: str
    how: Literal["max", "min", "summary"]
    structure: bool = False  # a structure's quantity: none for a rigid-structure run


HEADLINES = (
    Headline(
        "max_principal_cap",
        "peak cap stress (max principal)",
        "stress",
        "peak cap stress: the fibrous cap's largest principal Cauchy stress, max over the run",
        "max_principal_cap",
        "max",
        True,
    ),
    Headline(
        "max_sss",
        "max |σ₁₂| in the structure",
        "stress",
        "the structure's largest |σ₁₂| (structural shear stress), max over the run",
        "max_sss",
        "max",
        True,
    ),
    Headline(
        "min_wss",
        "min wall shear stress",
        "stress",
        "the smallest signed wall shear stress over the run (negative: reversed flow)",
        "min_wss",
        "min",
    ),
    Headline(
        "max_wss",
        "max wall shear stress",
        "stress",
        "the largest signed wall shear stress over the run",
        "max_wss",
        "max",
    ),
    Headline(
        "min_tawss",
        "min TAWSS",
        "stress",
        "the smallest time-averaged wall shear stress along the lumen's walls (summary.json)",
        "min_tawss",
        "summary",
    ),
    Headline(
        "max_osi",
        "max OSI",
        "count",
        "the largest oscillatory shear index along the lumen's walls (summary.json)",
        "max_osi",
        "summary",
    ),
    Headline(
        "max_recirculation_length",
        "max recirculation length",
        "length",
        "the longest reversed-flow zone along either wall, max over the run",
        "recirculation_length",
        "max",
    ),
    Headline(
        "peak_displacement",
        "peak displacement",
        "displacement",
        "the structure's largest |η|, max over the run",
        "peak_displacement",
        "max",
        True,
    ),
    Headline(
        "peak_inlet_flow_rate",
        "peak inlet flow rate",
        "flow_rate",
        "the largest inlet flow rate per unit depth over the run (positive downstream)",
        "inlet_flow_rate",
        "max",
    ),
)


class ResultError(Exception):
    """A finished run's summary.json or metrics.csv cannot be read."""


def headline_values(folder: Path, end: float | None = None) -> dict[str, float | None]:
    """The :data:`HEADLINES` of the finished run in ``folder``, over its rows up to ``end``
    (None: all): None for a quantity its case does not have (no such column or key, no value
    in any row; the structure's quantities of a rigid-structure run) and, when ``end`` cuts the
    run short, for those of summary.json (over the whole run). Raises :class:`ResultError`."""
    try:
        summary = json.loads((folder / "summary.json").read_text())
        rows = io.read_metrics(folder / "metrics.csv")
    except (OSError, ValueError) as e:  # io.MetricsError is a ValueError
        raise ResultError(str(e)) from e
    cut = end is not None and any(r["t"] > end * (1 + SAME_TIME) for r in rows)
    if cut:
        rows = [r for r in rows if r["t"] <= end * (1 + SAME_TIME)]
    rigid = summary.get("structure_mode") == "rigid"
    values: dict[str, float | None] = {}
    for h in HEADLINES:
        if (h.structure and rigid) or (cut and h.how == "summary"):
            value = None
        elif h.how == "summary":
            value = summary.get(h.source)
            value = float(value) if isinstance(value, (int, float)) else None
        else:
            column = [r[h.source] for r in rows if h.source in r]
            value = (max if h.how == "max" else min)(column) if column else None
        values[h.name] = value
    return values


def write_results(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    statuses: Sequence[str],
    out: Path,
    comm: MPI.Comm,
) -> tuple[list[Path], list[str]]:
    """``out/sweep.csv`` (SI units, the :data:`HEADLINES` in their columns, an empty cell where
    there is no value), ``out/sweep.md`` (the same table in readable units, ``–`` where there is
    no value, and what each column is) and :func:`write_plots`. Only runs whose status is
    ``done`` have values (a done run whose files cannot be read becomes ``failed: ...``).
    Returns the files written and the statuses. Collective (rank 0 writes; raises
    :class:`fsi.output.io.OutputError` on every rank if it cannot)."""
    keys = [v.key for v in variations]
    statuses = list(statuses)
    table: list[dict[str, float | None]] = []
    if comm.rank == 0:
        for i, run in enumerate(runs):
            values = {h.name: None for h in HEADLINES}
            if statuses[i] == "done":
                try:
                    values = headline_values(run.folder, config.run_time(run.case).end)
                except ResultError as e:
                    statuses[i] = f"failed: cannot read its results: {e}"
            table.append(values)
    csv_rows = [
        [value for _, value in run.choice]
        + [math.nan if row[h.name] is None else row[h.name] for h in HEADLINES]
        + [status]
        for run, row, status in zip(runs, table, statuses, strict=False)
    ]
    columns = keys + [h.name for h in HEADLINES] + ["status"]
    io.on_rank0(comm, lambda: out.mkdir(parents=True, exist_ok=True), out)
    io.write_table(comm, out / "sweep.csv", columns, csv_rows)
    written = [out / "sweep.csv", out / "sweep.md"]
    io.on_rank0(
        comm,
        lambda: (out / "sweep.md").write_text(markdown(runs, variations, table, statuses)),
        out / "sweep.md",
    )
    plots: list[Path] = []
    io.on_rank0(comm, lambda: plots.extend(write_plots(runs, variations, table, out)), out)
    return written + comm.bcast(plots, root=0), comm.bcast(statuses, root=0)


def markdown(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    table: Sequence[dict[str, float | None]],
    statuses: Sequence[str],
) -> str:
    """The table as markdown: one row per run, each headline in the unit that suits its values
    (:func:`fsi.output.units.choose_unit`), 4 significant digits, ``–`` where there is no value."""
    shown = {}
    for h in HEADLINES:
        values = [row[h.name] for row in table if row[h.name] is not None]
        shown[h.name] = units.choose_unit(h.quantity, values)

    def header(h: Headline) -> str:
        unit = shown[h.name].name
        return f"{h.name} ({unit})" if unit else h.name

    def cell(h: Headline, value: float | None) -> str:
        return "–" if value is None else f"{value * shown[h.name].scale:.4g}"

    def escape(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    columns = [v.key for v in variations] + [header(h) for h in HEADLINES] + ["status"]
    lines = [
        f"# Sweep of {runs[0].case.name}" if runs else "# Sweep",
        "",
        "| " + " | ".join(columns) + " |",
        "|" + "---|" * len(columns),
    ]
    for run, row, status in zip(runs, table, statuses, strict=False):
        cells = (
            [escape(value) for _, value in run.choice]
            + [cell(h, row[h.name]) for h in HEADLINES]
            + [escape(status)]
        )
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "Each run's folder is named by its varied values (e.g. "
        f"`{runs[0].folder.name if runs else ''}`); the columns:",
        "",
    ]
    lines += [f"- `{h.name}`: {h.meaning}." for h in HEADLINES]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# The plots


def _numeric(case: config.Case, key: str) -> float | None:
    """The value of ``key`` in ``case`` if it is a number (not a bool), else None."""
    node = yaml.safe_load(config.to_yaml(case))
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        return None
    return float(node)


def axis_label(case: config.Case, key: str) -> str:
    """A varied key as a quantity with its unit: the key's last part in words, after its
    section's name unless that is ``geometry`` (whose names say what they are), e.g.
    ``geometry.cap_thickness`` → "cap thickness (m)", ``fluid.inlet.amplitude`` → "inlet
    amplitude (Pa)", ``structure.cap.young_modulus`` → "cap young modulus (Pa)"."""
    parts = key.split(".")
    words = parts[-1:] if parts[0] == "geometry" or len(parts) == 1 else parts[-2:]
    text = " ".join(words).replace("_", " ")
    unit = reader.unit_of(case, key)
    return f"{text} ({unit})" if unit else text


def write_plots(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    table: Sequence[dict[str, float | None]],
    out: Path,
) -> list[Path]:
    """``out/sweep_<headline>.png`` for each headline that some run has: one panel per varied
    key with more than one value (the first key if none has), its values along x (on a number
    axis, ticked at the values, when every value is a number, else in ``--vary`` order), one
    line per combination of the other keys' values (a gap where a run has no value). A
    headline no run has gets no plot (an earlier sweep's is deleted). Rank 0 alone; returns
    the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for h in HEADLINES:
        path = out / f"sweep_{h.name}.png"
        values = [row[h.name] for row in table if row[h.name] is not None]
        if not values:
            path.unlink(missing_ok=True)
            continue
        unit = units.choose_unit(h.quantity, values)
        panels = [i for i, v in enumerate(variations) if len(v.values) > 1] or [0]
        figure, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 3.8), squeeze=False)
        for axis, panel in zip(axes[0], panels, strict=True):
            _panel(axis, panel, runs, variations, table, h.name, unit.scale)
            axis.set_xlabel(axis_label(runs[0].case, variations[panel].key))
            axis.set_ylabel(f"{h.label} ({unit.name})" if unit.name else h.label)
            axis.grid(True, alpha=0.3)
        suptitle(figure, h.meaning)
        figure.tight_layout()
        figure.savefig(path, dpi=110)
        plt.close(figure)
        written.append(path)
    return written


def suptitle(figure, text: str, fontsize: float = 9) -> None:
    """``text`` as ``figure``'s title, broken into lines that fit its width (one 84-character
    headline was cut off at both edges of a one-panel plot)."""
    import textwrap

    # ~0.55 em a character, with a margin: the characters that fit the figure's width
    per_line = int(figure.get_figwidth() * 72 / (0.55 * fontsize) * 0.9)
    figure.suptitle(textwrap.fill(text, per_line), fontsize=fontsize)


def _panel(
    axis,
    panel: int,
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    table: Sequence[dict[str, float | None]],
    name: str,
    scale: float,
) -> None:
    """Headline ``name`` against varied key number ``panel``: one line per combination of the
    other keys' values."""
    key = variations[panel].key
    order = list(variations[panel].values)
    numbers = {run.choice[panel][1]: _numeric(run.case, key) for run in runs}
    numeric = all(v is not None for v in numbers.values())
    lines: dict[tuple, list[tuple[float, float]]] = {}
    for run, row in zip(runs, table, strict=True):
        others = tuple(c for i, c in enumerate(run.choice) if i != panel)
        value = run.choice[panel][1]
        x = numbers[value] if numeric else float(order.index(value))
        y = math.nan if row[name] is None else row[name] * scale
        lines.setdefault(others, []).append((x, y))
    for others, points in lines.items():
        points.sort()
        label = ", ".join(f"{k}={v}" for k, v in others) or None
        axis.plot([p[0] for p in points], [p[1] for p in points], "o-", label=label)
    if numeric:  # a tick at each value, labelled as typed (automatic ticks crowd 5e-4 steps)
        ticks = sorted((numbers[value], value) for value in order)
        axis.set_xticks([x for x, _ in ticks], [value for _, value in ticks])
    else:
        axis.set_xticks(range(len(order)), order)
    if len(lines) > 1:
        axis.legend(fontsize=7)
