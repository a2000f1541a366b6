"""What a checkpoint must agree on with the run that reads it (fsi/run/checkpoint.py reads and
writes the files): its metadata (:func:`metadata`: the format, the case's keys the state
depends on, the step and time), the case it continues (:func:`check_metadata`,
:func:`check_continuation`), its step against ``metrics.csv`` (:func:`check_metrics`) and its
arrays (:func:`check_arrays`). Each check raises :class:`CheckpointError` naming the file.
"""

from __future__ import annotations

import json
import math
import time
import typing
from pathlib import Path

from mpi4py import MPI

import dolfinx
import numpy as np
import yaml

import fsi
from fsi import config
from fsi.config import reader
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import metrics_csv

FORMAT = 1


class CheckpointError(Exception):
    """A checkpoint is missing, unreadable or does not fit the run (exit status 2)."""


def rank_file(rank: int) -> str:
    return f"rank{rank:04d}.npz"


# --------------------------------------------------------------------------------------------
# What a checkpoint must agree on with the run that reads it


def dependencies(case: config.Case) -> dict:
    """The configuration the arrays depend on: the geometry and mesh sections (the mesh), the
    structure's mode, interface load and degree (which solvers, which spaces)."""
    data = config.to_dict(case)
    s = data["structure"]
    mesh = {k: v for k, v in data["mesh"].items() if k != "max_cells"}  # a limit, not the mesh
    sections = {
        "geometry": data["geometry"],
        "mesh": mesh,
        "structure": {k: s[k] for k in ("mode", "interface_load", "degree")},
    }
    return json.loads(json.dumps(sections))  # as it reads back from JSON (tuples as lists)


def metadata(
    case: config.Case,
    comm: MPI.Comm,
    step: int,
    t: float,
    dt: float | None,
    next_dt: float | None = None,
) -> dict:
    """checkpoint.json's content for the state after step ``step`` (at time ``t``, of size
    ``dt``; with adaptive steps ``next_dt`` is the size the next step tries): also the number of
    ranks, the case name, the configuration the arrays depend on (:func:`dependencies`), the fsi
    and dolfinx versions and the rank files.
    """
    return {
        "format": FORMAT,
        "step": int(step),
        "t": float(t),
        "dt": None if dt is None else float(dt),
        "next_dt": None if next_dt is None else float(next_dt),
        "ranks": comm.size,
        "case": case.name,
        "config": dependencies(case),
        "versions": {"fsi": fsi.__version__, "dolfinx": dolfinx.__version__},
        "files": [rank_file(r) for r in range(comm.size)],
        "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def _first_difference(old, new, key: str = ""):
    if isinstance(old, dict) and isinstance(new, dict):
        for k in list(old) + [k for k in new if k not in old]:
            found = _first_difference(old.get(k), new.get(k), f"{key}.{k}" if key else k)
            if found:
                return found
        return None
    return None if old == new else (key, old, new)


def check_metadata(meta: dict, case: config.Case, source: Path) -> None:
    """Raise :class:`CheckpointError` (naming ``source`` and the key) unless the checkpoint
    was written for the same geometry, mesh and structure as ``case``."""
    if meta.get("format") != FORMAT:
        raise CheckpointError(f"{source}: format: expected {FORMAT}, got {meta.get('format')!r}")
    found = _first_difference(meta["config"], dependencies(case))
    if found:
        key, old, new = found
        raise CheckpointError(
            f"{source}: {key}: the checkpoint has {old!r}, the configuration {new!r}; a restart "
            "needs the same geometry, mesh and structure (mode, interface load, degree)"
        )


def check_continuation(meta: dict, case: config.Case, source: Path, run_dir: Path) -> None:
    """Raise :class:`CheckpointError` unless ``case`` continues the run: its end is not before
    the checkpoint's time (the run folder would then describe a run shorter than its data),
    and its inlet's period is the one the run used (its ``config.yaml``, when readable): a new
    period would start the heartbeats of metrics.csv's ``cycle``, summary.json's ``cycles``
    and wall_indices.csv's blocks at other times than those already written."""
    t, end = float(meta["t"]), config.run_time(case).end
    if t > end * (1 + SAME_TIME):
        raise CheckpointError(
            f"{source}: t: the checkpoint is at t = {t:.6g} s, after the configuration's end "
            f"({end:.6g} s): a restart continues a run, it cannot shorten it (raise time.end)"
        )
    try:
        written = reader.parse_yaml((run_dir / "config.yaml").read_text())
        inlet = written["fluid"]["inlet"]
        before = float(inlet.get("period", 0.0)) if isinstance(inlet, dict) else 0.0
    except (OSError, ValueError, KeyError, TypeError, yaml.YAMLError):
        return
    now = config.heartbeat_period(case)
    if abs(before - now) > 1e-12 * max(before, now):
        raise CheckpointError(
            f"{source}: fluid.inlet.period: the run being continued has {before:g} s "
            f"({run_dir / 'config.yaml'}), the configuration {now:g} s; its heartbeats "
            "(metrics.csv's cycle, summary.json's cycles, wall_indices.csv) would start at "
            "other times (start a new run instead)"
        )


def check_position(meta: dict, source: Path) -> None:
    """Raise :class:`CheckpointError` (naming ``source`` and the key) unless checkpoint.json's
    ``step`` is a whole number >= 0, ``t`` a finite number >= 0 (0 at step 0), ``dt`` and
    ``next_dt`` null (or absent) or finite numbers > 0, and ``files`` the rank files of its
    ``ranks`` (rank0000.npz, ...)."""
    step, t, ranks = (meta.get(k) for k in ("step", "t", "ranks"))
    if not _whole(step) or step < 0:
        raise CheckpointError(f"{source}: step: expected a whole number >= 0, got {step!r}")
    if not _real(t) or not math.isfinite(t) or t < 0 or (step == 0 and t != 0):
        raise CheckpointError(f"{source}: t: expected a finite time >= 0 (0 at step 0), got {t!r}")
    for key in ("dt", "next_dt"):
        dt = meta.get(key)
        if dt is not None and (not _real(dt) or not math.isfinite(dt) or dt <= 0):
            raise CheckpointError(
                f"{source}: {key}: expected null or a finite step > 0, got {dt!r}"
            )
    if not _whole(ranks) or ranks < 1:
        raise CheckpointError(f"{source}: ranks: expected a whole number >= 1, got {ranks!r}")
    expected = [rank_file(r) for r in range(ranks)]
    if meta.get("files") != expected:
        raise CheckpointError(
            f"{source}: files: expected {expected[0]} to {expected[-1]} (one "
            f"per rank, ranks: {ranks}), got {meta.get('files')!r}"
        )


def _whole(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _real(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_metrics(meta: dict, source: Path, metrics: Path) -> None:
    """Raise :class:`CheckpointError` (naming ``metrics``, the run folder's metrics.csv) unless
    it holds the rows a restart from the checkpoint's step k keeps, each once and in order:
    steps 1 to k, complete (:func:`fsi.output.metrics_csv.read_rows`), and step k's ``t`` and
    ``dt`` (where both have one) are the checkpoint's (``source``) within a relative
    :data:`SAME_TIME`."""
    k = meta["step"]
    if k == 0:
        return
    keeps = f"a restart from step {k} keeps its rows 1 to {k}"
    if not metrics.is_file():
        raise CheckpointError(f"{metrics}: missing; {keeps}")
    try:
        rows = metrics_csv.read_rows(metrics, until_step=k)
    except metrics_csv.MetricsError as e:
        raise CheckpointError(f"{e} ({keeps})") from None
    except OSError as e:
        raise CheckpointError(f"{metrics}: unreadable ({e.strerror or e})") from None
    missing = sorted(set(range(1, k + 1)) - {row.step for row in rows})
    if missing:
        noun = "steps" if len(missing) > 1 else "step"
        raise CheckpointError(
            f"{metrics}: no row of {noun} {_spans(missing)}: the table was "
            f"cut short or damaged, and {keeps}"
        )
    for expected, row in enumerate(rows, start=1):
        if row.step != expected:
            raise CheckpointError(
                f"{metrics}: line {row.line}: step {row.step} where step "
                f"{expected} belongs ({keeps}, each once and in order)"
            )
    last = rows[-1]
    for key in ("t", "dt"):
        value = meta.get(key)
        if value is not None and key in last.values and not _close(last.values[key], value):
            raise CheckpointError(
                f"{source}: {key}: the checkpoint has {value!r}, but {metrics} line {last.line} "
                f"(step {k}) has {key} = {last.text[key]}: they are not of the same step (was "
                "one of them edited?)"
            )


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= SAME_TIME * max(abs(a), abs(b))


def _spans(steps: list[int]) -> str:
    """Sorted step numbers as spans: [1, 2, 3, 7] → '1-3, 7'."""
    spans: list[list[int]] = []
    for s in steps:
        if spans and s == spans[-1][1] + 1:
            spans[-1][1] = s
        else:
            spans.append([s, s])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in spans)


def check_arrays(meta: dict, folder: Path, files: typing.Sequence[dict[str, np.ndarray]]) -> str:
    """What is wrong with the arrays of the rank files, '' if nothing: every array must be of
    numbers (or booleans), every float finite, every ``counters.*`` of whole numbers >= 0, and the
    state's times (``fluid.time``, ``solid.t``, in rank 0's file) the checkpoint's ``t``."""
    for name, arrays in zip(meta["files"], files):
        for key, a in arrays.items():
            if a.dtype.kind not in "biuf":
                return f"{folder / name}: {key}: expected numbers, got {a.dtype} values"
            if a.dtype.kind == "f" and not np.isfinite(a).all():
                return f"{folder / name}: {key}: non-finite values (NaN or inf)"
            if key.startswith("counters.") and (a.dtype.kind not in "iu" or (a < 0).any()):
                return f"{folder / name}: {key}: expected whole numbers >= 0"
    for key in ("fluid.time", "solid.t"):
        a = files[0].get(key)
        if a is not None and (a.shape != () or not _close(float(a), meta["t"])):
            value = float(a) if a.shape == () else f"an array of shape {a.shape}"
            return (
                f"{folder / meta['files'][0]}: {key}: {value}, but checkpoint.json's t is "
                f"{meta['t']!r}"
            )
    return ""


def raise_if_any(comm: MPI.Comm, message: str) -> None:
    messages = [m for m in comm.allgather(message) if m]
    if messages:
        raise CheckpointError(messages[0])
