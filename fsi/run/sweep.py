"""``fsi sweep``: a case run for every combination of the values of one or more keys (the
Cartesian product of the ``--vary`` lists), one run folder each under ``--out``, then one table
and plots of each run's headline outputs.

:func:`plan` makes and validates the combinations (here), :func:`fsi.run.sweep_execution.execute`
runs them (a finished run is skipped, a stopped one resumed: :func:`folder_state`, here),
:func:`fsi.run.sweep_results.write_results` writes the table (``sweep.csv``, ``sweep.md``) of the
headline outputs and the plots.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import re
import time as wallclock
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import yaml

from fsi import config
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import io
from fsi.run import checkpoint

log = logging.getLogger("fsi")

MAX_RUNS = 1000
"""The largest product a sweep accepts (each run is a whole ``fsi run``)."""


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
