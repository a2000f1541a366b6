"""Checkpoints of ``fsi run``: the files. The state comes from the run's stepper
(:meth:`fsi.run.steppers.Stepper.state`) as named numpy arrays of its local dofs, with a
:class:`fsi.run.state_arrays.Layout` for each distributed array; this module writes
(:func:`write`), finds and reads (:func:`read`) and redistributes (:func:`localize`) them, and
opens nothing else. ``RUN_DIR/checkpoint/`` holds the latest complete checkpoint:
``checkpoint.json`` (:func:`metadata`) and one ``rank<k>.npz`` per rank that wrote it.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shutil
import time
import typing
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

from mpi4py import MPI

import dolfinx
import numpy as np
import yaml

import fsi
from fsi import config
from fsi.config import reader
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import io
from fsi.run.state_arrays import Layout, layout_of

log = logging.getLogger("fsi")

FORMAT = 1
DIRECTORY, PARTIAL, PREVIOUS = "checkpoint", "checkpoint.partial", "checkpoint.previous"
METADATA = "checkpoint.json"
VARIABLE = ("coupling.", "predictor.", "counters.", "fluid.outlet_state", "time_error.")
"""Groups of state arrays whose number and shape may change between runs (accelerations,
predictor order, counters, adaptive steps' error levels); every other array of a fresh
stepper's state must be restored."""
ADDED = ("wall_indices.",)
"""Groups of state arrays added after checkpoints were first written: a checkpoint without
them still restarts (the stepper starts those from the restart;
fsi.output.wall_outputs.FluidOutputs)."""
MATCH_TOLERANCE = 1e-9
"""Keys match within this fraction of the extent of the stored keys (they are equal bit for bit
when the mesh is the same; 1e-9 of a 2 cm artery is 20 pm, far below any mesh size)."""


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
    steps 1 to k, complete (:func:`fsi.output.io.read_rows`), and step k's ``t`` and ``dt`` (where
    both have one) are the checkpoint's (``source``) within a relative :data:`SAME_TIME`."""
    k = meta["step"]
    if k == 0:
        return
    keeps = f"a restart from step {k} keeps its rows 1 to {k}"
    if not metrics.is_file():
        raise CheckpointError(f"{metrics}: missing; {keeps}")
    try:
        rows = io.read_rows(metrics, until_step=k)
    except io.MetricsError as e:
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


def _raise_if_any(comm: MPI.Comm, message: str) -> None:
    messages = [m for m in comm.allgather(message) if m]
    if messages:
        raise CheckpointError(messages[0])


# --------------------------------------------------------------------------------------------
# Writing


def _owned_rows(a: np.ndarray, layout: Layout) -> np.ndarray:
    rows = len(layout.points)
    if a.shape[0] != rows * layout.block:
        raise ValueError(
            f"an array of layout {layout.name!r} has {a.shape[0]} entries, not "
            f"{rows} rows × {layout.block}"
        )
    return a.reshape(rows, layout.block, *a.shape[1:])[: layout.owned]


def write(
    out: Path, comm: MPI.Comm, state: dict[str, np.ndarray], layouts: dict[str, Layout], meta: dict
) -> Path:
    """Write ``out/checkpoint/`` atomically: the owned rows of this rank's distributed arrays
    (:func:`layout_of`) with their keys, the global arrays from rank 0, and ``meta`` as
    checkpoint.json. Refuses non-finite values. Collective; raises :class:`CheckpointError` on
    every rank if any rank fails (the previous checkpoint stays, the partial one is removed).

    A rank file holds each distributed array's owned rows (``<array>``, shape (owned, block, ...))
    and their keys (``keys.<layout>``: the reference coordinates of the dof's node, plus the
    component for a mixed space); rank 0's also the global values (times, counters, Aitken's ω).
    They are written into ``checkpoint.partial/``, then swapped in, the old one kept as
    ``checkpoint.previous/`` meanwhile: a run killed at any point leaves one complete checkpoint.
    """
    final, partial = out / DIRECTORY, out / PARTIAL
    bad = [k for k, v in state.items() if v.dtype.kind == "f" and not np.isfinite(v).all()]
    message = f"{out}: not writing a checkpoint: non-finite {', '.join(bad)}" if bad else ""
    _raise_if_any(comm, message)
    arrays = {}
    meta = {
        **meta,
        "layouts": {key: getattr(layout_of(key, layouts), "name", None) for key in state},
    }
    for key, value in state.items():
        layout = layout_of(key, layouts)
        if layout is not None:
            arrays[key] = _owned_rows(value, layout)
        elif comm.rank == 0:
            arrays[key] = value
    for layout in {layout.name: layout for layout in layouts.values()}.values():
        arrays[f"keys.{layout.name}"] = layout.points[: layout.owned]
    size = comm.allreduce(sum(a.nbytes for a in arrays.values()), op=MPI.SUM)
    try:
        io.ensure_space(comm, out, size + size // 10 + io.SPACE_MARGIN, "a checkpoint")
    except io.OutputError as e:
        raise CheckpointError(str(e)) from None
    try:
        _write_swap(out, comm, arrays, meta)
    except CheckpointError:
        if comm.rank == 0:  # a full disk: give back the space of the partial copy
            shutil.rmtree(partial, ignore_errors=True)
        raise
    return final


def _write_swap(out: Path, comm: MPI.Comm, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """Write the rank files and checkpoint.json into ``checkpoint.partial/``, then swap it in.
    Collective; raises :class:`CheckpointError` on every rank if any rank fails."""
    final, partial, previous = out / DIRECTORY, out / PARTIAL, out / PREVIOUS
    message = ""
    if comm.rank == 0:
        try:
            shutil.rmtree(partial, ignore_errors=True)
            partial.mkdir(parents=True)
        except OSError as e:
            message = f"{partial}: {e}"
    _raise_if_any(comm, message)
    zipped = BytesIO()  # in memory: a full disk then fails one plain write
    np.savez(zipped, **arrays)
    try:
        with open(partial / rank_file(comm.rank), "wb") as f:
            f.write(zipped.getbuffer())
            f.flush()
            os.fsync(f.fileno())
    except OSError as e:
        message = f"{partial / rank_file(comm.rank)}: {e}"
    _raise_if_any(comm, message)
    if comm.rank == 0:
        try:
            with open(partial / METADATA, "w") as f:
                f.write(json.dumps(meta, indent=2) + "\n")
                f.flush()
                os.fsync(f.fileno())
            if previous.exists() and not final.exists():  # left by a failed swap
                previous.rename(final)
            shutil.rmtree(previous, ignore_errors=True)
            if final.exists():
                final.rename(previous)
            partial.rename(final)
            shutil.rmtree(previous, ignore_errors=True)
            _fsync_directory(out)
        except OSError as e:
            message = f"{final}: {e}"
    _raise_if_any(comm, message)


def _fsync_directory(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


# --------------------------------------------------------------------------------------------
# Reading


@dataclass(frozen=True)
class Checkpoint:
    """A checkpoint read back: its folder, the run folder it belongs to, checkpoint.json and the
    arrays of every rank file (in file order), before :func:`localize` gives them to the run's
    local dofs."""

    path: Path
    run_dir: Path
    meta: dict
    files: tuple[dict[str, np.ndarray], ...]

    @property
    def step(self) -> int:
        return int(self.meta["step"])

    @property
    def t(self) -> float:
        return float(self.meta["t"])

    @property
    def dt(self) -> float | None:
        return self.meta.get("dt")

    @property
    def next_dt(self) -> float | None:
        """With adaptive steps, the size of the step the run would have tried next."""
        return self.meta.get("next_dt")

    def continues(self, out: Path) -> bool:
        """Whether a restart into ``out`` continues this checkpoint's own run folder."""
        return self.run_dir.resolve() == Path(out).resolve()

    def changed_keys(self, case: config.Case) -> list[str]:
        """The keys of ``case`` that differ from the run's own ``config.yaml`` and change its
        physics or what its outputs mean (every key but those of :data:`FREE_ON_RESTART`);
        none if that file cannot be read."""
        try:
            written = reader.parse_yaml((self.run_dir / "config.yaml").read_text())
        except (OSError, ValueError, yaml.YAMLError):
            return []
        if not isinstance(written, dict):
            return []
        changed = config.differences(written, config.to_dict(case))
        return [k for k in changed if not any(_within(k, free) for free in FREE_ON_RESTART)]

    def changed_mesh_motion(self, case: config.Case) -> list[str]:
        """The ``mesh_motion`` keys whose values in ``case`` differ from those of the run that
        wrote the checkpoint (its ``config.yaml``; none if that cannot be read). A restart may
        change them, but the fluid mesh is then re-extended at the first step and its mesh
        velocity (and so the forces of that step) carries the jump."""
        try:
            written = reader.parse_yaml((self.run_dir / "config.yaml").read_text())
            before = written["mesh_motion"]
        except (OSError, ValueError, KeyError, TypeError, yaml.YAMLError):
            return []
        now = config.to_dict(case)["mesh_motion"]
        return sorted(k for k in now if before.get(k) != now[k])


FREE_ON_RESTART = (
    "name",
    "time",
    "output",
    "coupling",
    "mesh_motion",
    "fluid.solver",
    "structure.solver",
)
"""What a restart may change without ``--allow-changes``: how far and how finely the run
goes on (the schedule, its end, ``time.cycles``), what it writes and how often, and the
solvers' and coupling's settings (their answers agree within their tolerances; the mesh
motion's change is warned of). Any other key changes the physics or the outputs' meaning."""


def _within(key: str, section: str) -> bool:
    return key == section or key.startswith(section + ".")


def own_config(path: Path) -> Path:
    """The ``config.yaml`` of the run whose checkpoint :func:`locate` finds at ``path``.
    Raises :class:`CheckpointError` if there is no checkpoint or no such file."""
    _, run_dir = locate(path)
    own = run_dir / "config.yaml"
    if not own.is_file():
        raise CheckpointError(f"{own}: missing (the run's own configuration)")
    return own


def locate(path: Path) -> tuple[Path, Path]:
    """(checkpoint folder, run folder) for ``path``, a run folder (its ``checkpoint/``, or
    ``checkpoint.previous/`` left by a run killed while swapping them) or a checkpoint folder."""
    path = Path(path)
    for folder, run_dir in ((path / DIRECTORY, path), (path, path.parent), (path / PREVIOUS, path)):
        if (folder / METADATA).is_file():
            if folder.name == PREVIOUS:
                log.warning(
                    "%s is missing: using %s (a run stopped while replacing it)",
                    path / DIRECTORY,
                    folder,
                )
            return folder, run_dir
    raise CheckpointError(
        f"{path / DIRECTORY / METADATA}: no checkpoint there (--restart takes "
        "the folder of an earlier run)"
    )


def read(path: Path, case: config.Case, comm: MPI.Comm) -> Checkpoint:
    """Find the checkpoint of ``path`` (:func:`locate`), check it against ``case``
    (:func:`check_metadata`), check its step, time and files (:func:`check_position`), that
    the run folder's metrics.csv holds the rows a restart keeps (:func:`check_metrics`) and
    that ``case`` continues the run (:func:`check_continuation`), read
    its rank files (every rank reads all of them) and check their arrays
    (:func:`check_arrays`). Writes nothing. Collective; raises :class:`CheckpointError` on every
    rank, naming the file and the key (or line), when anything is wrong."""
    meta, message, folder, run_dir = None, "", None, None
    if comm.rank == 0:
        try:
            folder, run_dir = locate(path)
            source = folder / METADATA
            try:
                meta = json.loads(source.read_text())
                check_metadata(meta, case, source)
                check_position(meta, source)
                missing = [f for f in meta["files"] if not (folder / f).is_file()]
            except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
                raise CheckpointError(f"{source}: unreadable checkpoint ({e!r})") from e
            if missing:
                raise CheckpointError(
                    f"{folder / missing[0]}: missing (the checkpoint is incomplete)"
                )
            check_metrics(meta, source, run_dir / "metrics.csv")
            check_continuation(meta, case, source, run_dir)
        except CheckpointError as e:
            message = str(e)
    message, meta, folder, run_dir = comm.bcast((message, meta, folder, run_dir), root=0)
    if message:
        raise CheckpointError(message)
    files = []
    for name in meta["files"]:
        try:
            with np.load(folder / name, allow_pickle=False) as data:
                files.append({k: data[k] for k in data.files})
        except Exception as e:  # a truncated or corrupt zip raises many kinds of errors
            message = f"{folder / name}: unreadable checkpoint ({type(e).__name__}: {e})"
            break
    _raise_if_any(comm, message)
    _raise_if_any(comm, check_arrays(meta, folder, files))
    return Checkpoint(folder, run_dir, meta, tuple(files))


def _match(stored: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each row of ``points`` the index of the stored key within
    :data:`MATCH_TOLERANCE` (−1: none, or a NaN point)."""
    from scipy.spatial import cKDTree

    index = np.full(len(points), -1, dtype=np.int64)
    valid = ~np.isnan(points).any(axis=1)
    if not len(stored) or not valid.any():
        return index
    extent = float(np.ptp(stored, axis=0).max()) or 1.0
    bound = MATCH_TOLERANCE * extent
    distance, found = cKDTree(stored).query(points[valid], distance_upper_bound=bound)
    index[np.flatnonzero(valid)] = np.where(np.isfinite(distance), found, -1)
    return index


def _check_rows(checkpoint: Checkpoint, key: str, layout: Layout) -> str:
    """'' if array ``key`` (of ``layout``) has, in every rank file, one row of ``layout.block``
    values per stored key and the same shape beyond; else what is wrong."""
    first = checkpoint.files[0][key]
    for name, arrays in zip(checkpoint.meta["files"], checkpoint.files):
        a, rows = arrays[key], len(arrays[f"keys.{layout.name}"])
        if (
            a.ndim < 2
            or len(a) != rows
            or a.shape[1] != layout.block
            or a.shape[2:] != first.shape[2:]
        ):
            return (
                f"{checkpoint.path / name}: array {key!r} has shape {a.shape}, expected "
                f"({rows}, {layout.block}, ...): a row per key of {layout.name!r} (the "
                "file is damaged)"
            )
    return ""


def localize(
    checkpoint: Checkpoint,
    layouts: dict[str, Layout],
    current: dict[str, np.ndarray],
    comm: MPI.Comm,
) -> dict[str, np.ndarray]:
    """The checkpoint's arrays on this rank's local dofs: every row (owned and ghost) of a
    distributed array takes the value stored under its key, global arrays come from rank 0's file.
    Keys, not local dof numbers, because the mesh partition differs from run to run (SCOTCH on
    several ranks), so a restart may also use another number of ranks. Checked against ``current``
    (the fresh stepper's state): each of its arrays outside :data:`VARIABLE` must be restored with
    its shape. Collective; raises :class:`CheckpointError` on every rank if the keys do not match
    (another mesh), an array is missing or a distributed array's rows do not match its keys.
    """
    state: dict[str, np.ndarray] = {}
    indices, message = _match_keys(checkpoint, layouts, comm)
    if not message:
        state, message = _restore_arrays(checkpoint, layouts, indices)
    if not message:
        message = _check_restored(state, current, checkpoint.path)
    _raise_if_any(comm, message)
    return state


def _match_keys(
    checkpoint: Checkpoint, layouts: dict[str, Layout], comm: MPI.Comm
) -> tuple[dict[str, np.ndarray], str]:
    """For each layout name, the index in the checkpoint's concatenated keys of each local dof
    (see :func:`_match`), and '' or what is wrong (the same on every rank). Collective: one or
    two allreduce per layout checked, in the order of ``layouts``, until the first problem."""
    files, source = checkpoint.files, checkpoint.path
    message = ""
    indices: dict[str, np.ndarray] = {}
    added = {layout.name for key, layout in layouts.items() if key.startswith(ADDED)}
    for name, layout in {layout.name: layout for layout in layouts.values()}.items():
        key = f"keys.{name}"
        if name in added and all(key not in f for f in files):
            continue  # written before these arrays existed
        if any(key not in f for f in files):
            message = f"{source}: no keys of {name!r} (written by another kind of run)"
            break
        stored = np.concatenate([f[key] for f in files])
        if stored.ndim != 2 or stored.shape[1] != layout.points.shape[1]:
            message = (
                f"{source}: {key}: keys of shape {stored.shape[1:]}, this run's have "
                f"{layout.points.shape[1:]} (the file is damaged)"
            )
            break
        owned = comm.allreduce(layout.owned, op=MPI.SUM)
        if len(stored) != owned:
            message = (
                f"{source}: {name}: the checkpoint has {len(stored)} rows, this run "
                f"{owned}: the mesh differs from the one the checkpoint was written on"
            )
            break
        index = _match(stored, layout.points)
        lost = int(np.count_nonzero((index < 0) & ~np.isnan(layout.points).any(axis=1)))
        if comm.allreduce(lost, op=MPI.SUM):
            message = (
                f"{source}: {name}: {comm.allreduce(lost, op=MPI.SUM)} dofs of this run "
                "are not in the checkpoint: the mesh differs from the one it was "
                "written on"
            )
            break
        indices[name] = index
    return indices, message


def _restore_arrays(
    checkpoint: Checkpoint, layouts: dict[str, Layout], indices: dict[str, np.ndarray]
) -> tuple[dict[str, np.ndarray], str]:
    """The checkpoint's arrays on this rank's local dofs (rows picked by ``indices``, global
    arrays from rank 0's file), and '' or the first array that is missing or damaged. Local."""
    files, source = checkpoint.files, checkpoint.path
    state: dict[str, np.ndarray] = {}
    message = ""
    for key in files[0]:
        if key.startswith("keys."):
            continue
        layout = layout_of(key, layouts)
        if layout is None:
            state[key] = files[0][key]
            continue
        if any(key not in f for f in files):
            message = f"{source}: array {key!r} is missing from some rank files"
            break
        message = _check_rows(checkpoint, key, layout)
        if message:
            break
        stored = np.concatenate([f[key] for f in files])
        index = indices[layout.name]
        values = np.zeros((len(index), *stored.shape[1:]), dtype=stored.dtype)
        values[index >= 0] = stored[index[index >= 0]]
        state[key] = values.reshape(-1, *stored.shape[2:])
    return state, message


def _check_restored(
    state: dict[str, np.ndarray], current: dict[str, np.ndarray], source: Path
) -> str:
    """'' if ``state`` has each array of ``current`` outside :data:`VARIABLE` with its shape (a
    number or None where it has one), those of :data:`ADDED` only if it has any of them; else
    the first that is missing or of another shape."""

    def scalar(a: np.ndarray) -> bool:  # a number, or None (an empty array)
        return a.ndim == 0 or a.shape == (0,)

    has_added = {group for group in ADDED if any(k.startswith(group) for k in state)}
    for key, value in current.items():
        if key.startswith(VARIABLE):
            continue
        if key.startswith(ADDED) and not any(key.startswith(g) for g in has_added):
            continue
        if key not in state:
            return f"{source}: array {key!r} is missing (written by another kind of run)"
        if state[key].shape != value.shape and not (scalar(value) and scalar(state[key])):
            return f"{source}: array {key!r} has shape {state[key].shape}, this run {value.shape}"
    return ""
