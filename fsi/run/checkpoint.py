"""Checkpoints of ``fsi run``: the files. The state comes from the run's stepper
(:meth:`fsi.run.steppers.Stepper.state`) as named numpy arrays of its local dofs, with a
:class:`fsi.run.state_arrays.Layout` for each distributed array; this module writes
(:func:`write`), finds and reads (:func:`read`) and redistributes (:func:`localize`) them, and
opens nothing else. ``RUN_DIR/checkpoint/`` holds the latest complete checkpoint:
``checkpoint.json`` (:func:`fsi.run.checkpoint_checks.metadata`) and one ``rank<k>.npz`` per
rank that wrote it. What a checkpoint must agree on with the run that reads it:
fsi/run/checkpoint_checks.py.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

from mpi4py import MPI

import numpy as np
import yaml

from fsi import config
from fsi.config import reader
from fsi.output import io
from fsi.run.checkpoint_checks import (
    CheckpointError,
    check_arrays,
    check_continuation,
    check_metadata,
    check_metrics,
    check_position,
    raise_if_any,
    rank_file,
)
from fsi.run.state_arrays import Layout, layout_of

log = logging.getLogger("fsi")
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
    raise_if_any(comm, message)
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
    raise_if_any(comm, message)
    zipped = BytesIO()  # in memory: a full disk then fails one plain write
    np.savez(zipped, **arrays)
    try:
        with open(partial / rank_file(comm.rank), "wb") as f:
            f.write(zipped.getbuffer())
            f.flush()
            os.fsync(f.fileno())
    except OSError as e:
        message = f"{partial / rank_file(comm.rank)}: {e}"
    raise_if_any(comm, message)
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
    raise_if_any(comm, message)


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
    raise_if_any(comm, message)
    raise_if_any(comm, check_arrays(meta, folder, files))
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
    raise_if_any(comm, message)
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
