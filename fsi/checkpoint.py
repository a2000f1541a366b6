"""Checkpoints of ``fsi run``: the files. The state itself comes from the run's stepper
(:meth:`fsi.simulation.Stepper.state`) as named numpy arrays of its local dofs, with a
:class:`Layout` for each distributed array; this module writes, finds, reads and redistributes
them, and opens nothing else.

``RUN_DIR/checkpoint/`` holds the latest complete checkpoint::

    checkpoint.json   step, t, dt of the last step, number of ranks, case name, the
                      configuration sections the arrays depend on (geometry, mesh, the
                      structure's mode/load/degree), fsi and dolfinx versions, the rank files
    rank0000.npz ...  one per MPI rank that wrote it: the rows of each distributed array that
                      rank owned (``<array>``, shape (owned, block, ...)) and their keys
                      (``keys.<layout>``: the reference coordinates of the dof's node, plus the
                      component for a mixed space); rank 0's file also holds the global values
                      (times, counters, Aitken's ω)

Keys instead of local dof numbers because the mesh partition is not reproducible: SCOTCH gives
another one in every run on several ranks. A restart reads every rank file and gives each local
row (owned and ghost) the value stored under its key, so it may run on another number of ranks;
a key without a stored value means another mesh, and stops the restart (:class:`CheckpointError`).

A checkpoint is written into ``checkpoint.partial/`` and then renamed: the old one goes to
``checkpoint.previous/`` for the moment of the swap, so a run killed at any point leaves one
complete checkpoint (``checkpoint/``, else ``checkpoint.previous/``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import time
import typing
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

import dolfinx
import numpy as np

import fsi
from fsi import compat, config

log = logging.getLogger("fsi")

FORMAT = 1
DIRECTORY, PARTIAL, PREVIOUS = "checkpoint", "checkpoint.partial", "checkpoint.previous"
METADATA = "checkpoint.json"
VARIABLE = ("coupling.", "predictor.", "counters.")
"""Groups of state arrays whose number and shape may change between runs (accelerations,
predictor order, counters); every other array of a fresh stepper's state must be restored."""
MATCH_TOLERANCE = 1e-9
"""Keys match within this fraction of the extent of the stored keys (they are equal bit for bit
when the mesh is the same; 1e-9 of a 2 cm artery is 20 pm, far below any mesh size)."""


class CheckpointError(Exception):
    """A checkpoint is missing, unreadable or does not fit the run (exit status 2)."""


def rank_file(rank: int) -> str:
    return f"rank{rank:04d}.npz"


# --------------------------------------------------------------------------------------------
# Layouts: where the rows of a distributed array live


@dataclass(frozen=True)
class Layout:
    """The local rows of distributed arrays (a Function's values, or an interface vector):
    ``points`` a key per local row (owned rows first; NaN for a ghost row on no local cell),
    ``owned`` the number of owned rows, ``block`` the values per row. An array of this layout
    has shape (rows · block, ...) (extra axes: e.g. columns of interface vectors)."""

    name: str
    points: np.ndarray
    owned: int
    block: int


def space_layout(name: str, V) -> Layout:
    """The layout of the values of a (blocked) Lagrange space: one row per node, keyed by the
    node's coordinates. Call it while the mesh is in its reference configuration."""
    gdim = V.mesh.geometry.dim
    points = V.tabulate_dof_coordinates()[:, :gdim].copy()
    used = np.zeros(len(points), dtype=bool)
    used[np.unique(compat.cell_dofs(V))] = True
    points[~used] = np.nan  # a submesh's orphan ghost (dolfinx 0.5): never read
    return Layout(name, points, V.dofmap.index_map.size_local, V.dofmap.index_map_bs)


def mixed_layout(name: str, W, parts: typing.Sequence[tuple[np.ndarray, Layout]]) -> Layout:
    """The layout of a mixed space's values (one value per row), keyed by the node coordinates
    and the component number over the parts: ``parts`` pairs each sub-space's layout with the
    mixed dof behind each of its (unrolled) dofs (−1: none)."""
    index_map = W.dofmap.index_map
    size = (index_map.size_local + index_map.num_ghosts) * W.dofmap.index_map_bs
    gdim = parts[0][1].points.shape[1]
    points = np.full((size, gdim + 1), np.nan)
    component = 0
    for to_mixed, layout in parts:
        for c in range(layout.block):
            dofs = to_mixed[c::layout.block]
            ok = dofs >= 0
            points[dofs[ok], :gdim] = layout.points[ok]
            points[dofs[ok], gdim] = component
            component += 1
    return Layout(name, points, index_map.size_local * W.dofmap.index_map_bs, 1)


def interface_layout(name: str, points: np.ndarray, block: int) -> Layout:
    """Owned entries only, ``block`` values (a flat interface vector: gdim) at each of
    ``points`` (n, gdim)."""
    return Layout(name, np.asarray(points, dtype=float), len(points), block)


def layout_of(key: str, layouts: dict[str, Layout]) -> Layout | None:
    """The layout of array ``key``: ``layouts[name]`` for ``key == name`` or ``key`` starting
    with ``name + "."`` (e.g. ``coupling.iqn.V`` for ``coupling.iqn.V.0``); None: global."""
    for name, layout in layouts.items():
        if key == name or key.startswith(name + "."):
            return layout
    return None


# --------------------------------------------------------------------------------------------
# State dataclasses <-> named arrays


def to_arrays(prefix: str, state) -> dict[str, np.ndarray]:
    """The fields of a state dataclass (e.g. :class:`fsi.fluid.FluidState`) as arrays named
    ``prefix + field``; ``None`` becomes an empty array."""
    return {prefix + f.name: (np.zeros(0) if (v := getattr(state, f.name)) is None
                              else np.array(v, copy=True))
            for f in dataclasses.fields(state)}


def from_arrays(cls, prefix: str, arrays: dict[str, np.ndarray]):
    """The state dataclass ``cls`` from :func:`to_arrays`'s arrays (0-d arrays become Python
    scalars, an empty array ``None`` where the field allows it)."""
    hints = typing.get_type_hints(cls)
    values = {}
    for f in dataclasses.fields(cls):
        a = arrays[prefix + f.name]
        optional = type(None) in typing.get_args(hints[f.name])
        if optional and a.size == 0:
            values[f.name] = None
        elif a.ndim == 0:
            values[f.name] = a.item()
        else:
            values[f.name] = a.copy()
    return cls(**values)


def subset(prefix: str, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays named ``prefix...``, with the prefix removed."""
    return {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)}


# --------------------------------------------------------------------------------------------
# What a checkpoint must agree on with the run that reads it


def dependencies(case: config.Case) -> dict:
    """The configuration the arrays depend on: the geometry and mesh sections (the mesh), the
    structure's mode, interface load and degree (which solvers, which spaces)."""
    data = config.to_dict(case)
    s = data["structure"]
    sections = {"geometry": data["geometry"], "mesh": data["mesh"],
                "structure": {k: s[k] for k in ("mode", "interface_load", "degree")}}
    return json.loads(json.dumps(sections))  # as it reads back from JSON (tuples as lists)


def metadata(case: config.Case, comm: MPI.Comm, step: int, t: float,
             dt: float | None) -> dict:
    """checkpoint.json's content for the state after step ``step`` (at time ``t``)."""
    return {"format": FORMAT, "step": int(step), "t": float(t),
            "dt": None if dt is None else float(dt), "ranks": comm.size, "case": case.name,
            "config": dependencies(case),
            "versions": {"fsi": fsi.__version__, "dolfinx": dolfinx.__version__},
            "files": [rank_file(r) for r in range(comm.size)],
            "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}


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
            "needs the same geometry, mesh and structure (mode, interface load, degree)")


def _raise_if_any(comm: MPI.Comm, message: str) -> None:
    messages = [m for m in comm.allgather(message) if m]
    if messages:
        raise CheckpointError(messages[0])


# --------------------------------------------------------------------------------------------
# Writing


def _owned_rows(a: np.ndarray, layout: Layout) -> np.ndarray:
    rows = len(layout.points)
    if a.shape[0] != rows * layout.block:
        raise ValueError(f"an array of layout {layout.name!r} has {a.shape[0]} entries, not "
                         f"{rows} rows × {layout.block}")
    return a.reshape(rows, layout.block, *a.shape[1:])[: layout.owned]


def write(out: Path, comm: MPI.Comm, state: dict[str, np.ndarray], layouts: dict[str, Layout],
          meta: dict) -> Path:
    """Write ``out/checkpoint/`` atomically (see the module docstring): the owned rows of this
    rank's distributed arrays (:func:`layout_of`) with their keys, the global arrays from rank
    0, and ``meta`` as checkpoint.json. Refuses non-finite values. Collective; raises
    :class:`CheckpointError` on every rank if any rank fails (the previous checkpoint stays)."""
    final, partial, previous = out / DIRECTORY, out / PARTIAL, out / PREVIOUS
    bad = [k for k, v in state.items() if v.dtype.kind == "f" and not np.isfinite(v).all()]
    message = f"{out}: not writing a checkpoint: non-finite {', '.join(bad)}" if bad else ""
    _raise_if_any(comm, message)
    arrays = {}
    meta = {**meta, "layouts": {key: getattr(layout_of(key, layouts), "name", None)
                                for key in state}}
    for key, value in state.items():
        layout = layout_of(key, layouts)
        if layout is not None:
            arrays[key] = _owned_rows(value, layout)
        elif comm.rank == 0:
            arrays[key] = value
    for layout in {layout.name: layout for layout in layouts.values()}.values():
        arrays[f"keys.{layout.name}"] = layout.points[: layout.owned]
    if comm.rank == 0:
        try:
            shutil.rmtree(partial, ignore_errors=True)
            partial.mkdir(parents=True)
        except OSError as e:
            message = f"{partial}: {e}"
    _raise_if_any(comm, message)
    try:
        with open(partial / rank_file(comm.rank), "wb") as f:
            np.savez(f, **arrays)
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
            shutil.rmtree(previous, ignore_errors=True)
            if final.exists():
                final.rename(previous)
            partial.rename(final)
            shutil.rmtree(previous, ignore_errors=True)
            _fsync_directory(out)
        except OSError as e:
            message = f"{final}: {e}"
    _raise_if_any(comm, message)
    return final


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


def locate(path: Path) -> tuple[Path, Path]:
    """(checkpoint folder, run folder) for ``path``, a run folder (its ``checkpoint/``, or
    ``checkpoint.previous/`` left by a run killed while swapping them) or a checkpoint folder."""
    path = Path(path)
    for folder, run_dir in ((path / DIRECTORY, path), (path, path.parent),
                            (path / PREVIOUS, path)):
        if (folder / METADATA).is_file():
            if folder.name == PREVIOUS:
                log.warning("%s is missing: using %s (a run stopped while replacing it)",
                            path / DIRECTORY, folder)
            return folder, run_dir
    raise CheckpointError(f"{path / DIRECTORY / METADATA}: no checkpoint there (--restart takes "
                          "the folder of an earlier run)")


def read(path: Path, case: config.Case, comm: MPI.Comm) -> Checkpoint:
    """Find the checkpoint of ``path`` (:func:`locate`), check it against ``case``
    (:func:`check_metadata`) and read its rank files (every rank reads all of them). Collective;
    raises :class:`CheckpointError` on every rank, naming the file, when anything is wrong."""
    meta, message, folder, run_dir = None, "", None, None
    if comm.rank == 0:
        try:
            folder, run_dir = locate(path)
            source = folder / METADATA
            try:
                meta = json.loads(source.read_text())
                check_metadata(meta, case, source)
                missing = [f for f in meta["files"] if not (folder / f).is_file()]
            except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
                raise CheckpointError(f"{source}: unreadable checkpoint ({e!r})") from e
            if missing:
                raise CheckpointError(f"{folder / missing[0]}: missing (the checkpoint is "
                                      "incomplete)")
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


def localize(checkpoint: Checkpoint, layouts: dict[str, Layout], current: dict[str, np.ndarray],
             comm: MPI.Comm) -> dict[str, np.ndarray]:
    """The checkpoint's arrays on this rank's local dofs: every row of a distributed array takes
    the value stored under its key, global arrays come from rank 0's file. Checked against
    ``current`` (the fresh stepper's state): each of its arrays outside :data:`VARIABLE` must be
    restored with its shape. Collective; raises :class:`CheckpointError` on every rank if the
    keys do not match (another mesh) or an array is missing."""
    files, source = checkpoint.files, checkpoint.path
    state: dict[str, np.ndarray] = {}
    message = ""
    indices: dict[str, np.ndarray] = {}
    for name, layout in {layout.name: layout for layout in layouts.values()}.items():
        key = f"keys.{name}"
        if any(key not in f for f in files):
            message = f"{source}: no keys of {name!r} (written by another kind of run)"
            break
        stored = np.concatenate([f[key] for f in files])
        owned = comm.allreduce(layout.owned, op=MPI.SUM)
        if len(stored) != owned:
            message = (f"{source}: {name}: the checkpoint has {len(stored)} rows, this run "
                       f"{owned}: the mesh differs from the one the checkpoint was written on")
            break
        index = _match(stored, layout.points)
        lost = int(np.count_nonzero((index < 0) & ~np.isnan(layout.points).any(axis=1)))
        if comm.allreduce(lost, op=MPI.SUM):
            message = (f"{source}: {name}: {comm.allreduce(lost, op=MPI.SUM)} dofs of this run "
                       "are not in the checkpoint: the mesh differs from the one it was "
                       "written on")
            break
        indices[name] = index
    if not message:
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
            stored = np.concatenate([f[key] for f in files])
            index = indices[layout.name]
            values = np.zeros((len(index), *stored.shape[1:]), dtype=stored.dtype)
            values[index >= 0] = stored[index[index >= 0]]
            state[key] = values.reshape(-1, *stored.shape[2:])
        def scalar(a: np.ndarray) -> bool:  # a number, or None (an empty array)
            return a.ndim == 0 or a.shape == (0,)

        for key, value in current.items():
            if key.startswith(VARIABLE):
                continue
            if key not in state:
                message = f"{source}: array {key!r} is missing (written by another kind of run)"
            elif state[key].shape != value.shape and not (scalar(value) and scalar(state[key])):
                message = (f"{source}: array {key!r} has shape {state[key].shape}, this run "
                           f"{value.shape}")
    _raise_if_any(comm, message)
    return state
