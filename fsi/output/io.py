"""Files: the mesh (XDMF with tags) and its summary, tables (CSV; metrics.csv:
fsi/output/metrics_csv.py), field time series (XDMF), ``run.log`` and what ``fsi run`` writes
into its folder (:data:`RUN_FILES`; the run owns them, fsi/run/outputs.py). Physics modules
never open files.

Most files are written by rank 0 alone. A write that fails there (a full disk, a read-only
folder) must stop every rank, not leave the others waiting in the next collective: writes go
through :func:`collectively`, which turns a failure on any rank into :class:`OutputError` on all.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import os
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from mpi4py import MPI

import dolfinx.fem
import dolfinx.io

from fsi import compat
from fsi.output import provenance
from fsi.output.metrics_csv import format_value
from fsi.physics.mesh import TaggedMesh

log = logging.getLogger("fsi")


T = TypeVar("T")


class OutputError(Exception):
    """A file of the run could not be written (raised on every rank)."""


def collectively(comm: MPI.Comm, write: Callable[[], T], path: Path | None = None) -> T:
    """Call ``write()`` on every rank and agree on the outcome: if it raised ``OSError`` (or a
    ``RuntimeError`` of the HDF5 layer) on any rank, raise :class:`OutputError` with the first
    rank's message (naming ``path``, the file written, if the error does not) on every rank.
    ``write`` must not enter a collective after a point where it can fail on one rank only
    (rank-0 writes: write, then let this call be the collective). Collective."""
    message, result = "", None
    try:
        result = write()
    except (OSError, RuntimeError) as e:
        message = _describe_error(e)
        if path is not None and str(path) not in message:
            message = f"{path}: {message}"
    _meet(comm, message)
    messages = [m for m in comm.allgather(message) if m]
    if messages:
        raise OutputError(messages[0])
    return result


AGREEMENT_TIMEOUT_S = 120.0
"""How long a rank whose write failed waits for the others to reach the agreement: a write of
the HDF5 layer can fail on one rank only while the others wait inside it (a disk filled by
another process mid-write). Then the failing rank ends the job (``MPI_Abort``, exit status 4)
with its message instead of waiting for ever."""


def _meet(comm: MPI.Comm, message: str) -> None:
    """Wait until every rank has got here; if this rank failed (``message``) and the others do
    not come within :data:`AGREEMENT_TIMEOUT_S`, abort the job with the message."""
    if comm.size == 1:
        return
    request = comm.Ibarrier()
    if not message:
        request.Wait()
        return
    deadline = time.monotonic() + AGREEMENT_TIMEOUT_S
    while not request.Test():
        if time.monotonic() > deadline:
            print(
                f"fsi: cannot write the run's files: {message} (rank {comm.rank}; the other "
                "ranks are stuck in the write: ending the job)",
                file=sys.stderr,
                flush=True,
            )
            comm.Abort(4)
        time.sleep(0.01)


def ensure_space(comm: MPI.Comm, folder: Path, needed: int, what: str) -> None:
    """Raise :class:`OutputError` on every rank unless the file system of ``folder`` has
    ``needed`` bytes free for ``what``: a write into a full disk can fail on one rank only,
    inside the HDF5 layer's collectives, so the writers look first. Collective."""
    free = shutil.disk_usage(folder).free if comm.rank == 0 else 0
    free = comm.bcast(free, root=0)
    if free < needed:
        raise OutputError(
            f"{folder}: {free} bytes free, {what} needs about {needed} (the disk is full)"
        )


def on_rank0(comm: MPI.Comm, write: Callable[[], object], path: Path | None = None) -> None:
    """``write()`` on rank 0 only, with :func:`collectively`'s agreement. Collective."""
    collectively(comm, write if comm.rank == 0 else lambda: None, path)


def _describe_error(e: Exception) -> str:
    if isinstance(e, OSError) and e.filename is not None:
        return f"{e.filename}: {e.strerror or e}"
    return str(e) or type(e).__name__


def write_json(comm: MPI.Comm, path: Path, data: dict) -> None:
    """Write ``data`` as indented JSON from rank 0; every rank returns once it is on disk
    (:class:`OutputError` on every rank if it could not be written)."""
    on_rank0(comm, lambda: path.write_text(json.dumps(data, indent=2) + "\n"))


def write_mesh(out: Path, tagged: TaggedMesh, summary: dict) -> None:
    """``out/mesh.xdmf`` (mesh, cell tags ``cell_tags``, facet tags ``facet_tags``) and
    ``out/mesh.json`` (the summary of :func:`fsi.physics.mesh.summary`). Collective."""
    comm = tagged.comm
    on_rank0(comm, lambda: out.mkdir(parents=True, exist_ok=True))
    tagged.mesh.name = "mesh"

    def write() -> None:
        with dolfinx.io.XDMFFile(comm, str(out / "mesh.xdmf"), "w") as xdmf:
            xdmf.write_mesh(tagged.mesh)
            compat.write_meshtags(xdmf, tagged.mesh, tagged.cell_tags)
            compat.write_meshtags(xdmf, tagged.mesh, tagged.facet_tags)

    collectively(comm, write)
    write_json(comm, out / "mesh.json", summary)


def field_segment(name: str, first_step: int | None) -> str:
    """The field file of a run segment: ``name`` itself for a run from t = 0, and
    ``<stem>.restart<k><suffix>`` (``fields.restart40.xdmf``) for the segment that restarts
    from the checkpoint of step k, so a restart never touches the files it continues."""
    if first_step is None:
        return name
    path = Path(name)
    return f"{path.stem}.restart{first_step}{path.suffix}"


def remove_later_segments(out: Path, names: list[str], first_step: int) -> list[Path]:
    """Delete the field files (XDMF and HDF5) of segments that restarted after step
    ``first_step`` (their steps are dropped with the metrics rows). Returns what was deleted."""
    removed = []
    for name in names:
        stem = Path(name).stem
        for path in out.glob(f"{stem}.restart*.*"):
            k = path.name[len(stem) + len(".restart") :].split(".")[0]
            if k.isdigit() and int(k) > first_step and path.suffix in (".xdmf", ".h5"):
                path.unlink()
                removed.append(path)
    return removed


class FieldWriter:
    """An XDMF time series of fields for ParaView. Lagrange fields are written as their P1
    interpolants and DG fields as DG0 (XDMF stores vertex and cell data only); on a moving mesh
    the mesh displacement is one of the fields (ParaView: Warp By Vector).

    The file is open only while a snapshot is written (opened to append, then closed): a run
    killed at any other moment (``kill -9``, a node lost) leaves an XDMF/HDF5 pair that holds
    every snapshot written before, where an HDF5 file left open is unreadable."""

    def __init__(self, comm: MPI.Comm, path: Path, mesh):
        self.path, self.comm = path, comm
        with dolfinx.io.XDMFFile(comm, str(path), "w") as xdmf:
            xdmf.write_mesh(mesh)
        self._outputs: dict[str, dolfinx.fem.Function] = {}

    def _output_for(self, f: dolfinx.fem.Function) -> dolfinx.fem.Function:
        if f.name not in self._outputs:
            discontinuous, _, shape = compat.element_info(f.function_space)
            family, degree = ("DG", 0) if discontinuous else ("Lagrange", 1)
            out = dolfinx.fem.Function(
                compat.function_space(f.function_space.mesh, family, degree, shape)
            )
            out.name = f.name
            self._outputs[f.name] = out
        return self._outputs[f.name]

    def write(self, t: float, fields: list[dolfinx.fem.Function]) -> None:
        outputs = [self._output_for(f) for f in fields]
        # Room for the values (8-byte numbers) and as much again for the HDF5 layer's metadata.
        values = sum(
            8 * f.function_space.dofmap.index_map.size_global * f.function_space.dofmap.index_map_bs
            for f in outputs
        )
        ensure_space(
            outputs[0].function_space.mesh.comm,
            self.path.parent,
            2 * values + SPACE_MARGIN,
            f"writing {self.path.name} at t = {t:g} s",
        )
        for f, out in zip(fields, outputs):
            out.interpolate(f)
        with dolfinx.io.XDMFFile(self.comm, str(self.path), "a") as xdmf:
            for out in outputs:
                xdmf.write_function(out, t)

    def close(self) -> None:
        """Nothing to do: the file is closed after every snapshot."""


def snapshot_times(xdmf: Path) -> list[float]:
    """The times of the snapshots an XDMF/HDF5 pair written by :class:`FieldWriter` holds,
    read from its HDF5 file (the first field's datasets, named by the time). Raises OSError
    (or KeyError) when the HDF5 file cannot be read, as after a run killed while writing it."""
    import h5py

    with h5py.File(Path(xdmf).with_suffix(".h5"), "r") as f:
        functions = f["Function"]
        first = functions[sorted(functions)[0]]
        return sorted(float(key.replace("_", ".")) for key in first)


SPACE_MARGIN = 64 * 1024
"""Bytes kept free beyond what a write needs (:func:`ensure_space`)."""


RUN_FILES = (
    "config.yaml",
    "metrics.csv",
    "metrics.csv.partial",
    "summary.json",
    "run.log",
    "wall_indices.csv",
    "wall_indices.csv.partial",
    "fields*.xdmf",
    "fields*.h5",
    "solid*.xdmf",
    "solid*.h5",
    "checkpoint",
    "checkpoint.partial",
    "checkpoint.previous",
)
"""What ``fsi run`` writes into its ``--out`` folder (glob patterns); ``--overwrite`` deletes
these and nothing else."""


def start_log(path: Path) -> logging.Handler:
    """Start ``path`` (``run.log``; appended to by a restart that continues the run): a line
    with the versions and the command line, then what the ``fsi`` logger says (the progress
    lines, warnings; INFO and above) until :func:`stop_log` with the handler returned. Rank 0
    alone."""
    with path.open("a", encoding="utf-8") as f:
        describe = provenance.describe()
        f.write(
            f"{time.strftime('%Y-%m-%d %H:%M:%S')} {provenance.version_line()}: "
            f"{describe['command']}\n"
        )
    handler = logging.FileHandler(path, mode="a", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(message)s", "%Y-%m-%d %H:%M:%S"))
    handler.setLevel(logging.INFO)
    log.addHandler(handler)
    return handler


def stop_log(handler: logging.Handler) -> None:
    """The end of :func:`start_log`'s logging into ``run.log``."""
    log.removeHandler(handler)
    handler.close()


def append_to_log(out: Path, lines: list[str]) -> None:
    """Add ``lines`` to ``out/run.log`` if the run wrote one (rank 0 only; a failure to write
    is ignored: the lines went to stderr too)."""
    path = out / "run.log"
    if not path.is_file():
        return
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    try:
        with path.open("a", encoding="utf-8") as f:
            f.writelines(f"{stamp} {line}\n" for line in lines)
    except OSError:
        pass


class RunFolderError(Exception):
    """``--out`` cannot take this run (exit status 2, before any computation)."""


def run_files(out: Path) -> list[Path]:
    """The files and folders of an earlier run in ``out`` (:data:`RUN_FILES`)."""
    return sorted({p for pattern in RUN_FILES for p in out.glob(pattern)})


def remove_run_files(out: Path) -> None:
    """Delete an earlier run's :data:`RUN_FILES` from ``out`` (nothing else; a symbolic link
    among them is removed itself, what it points to is left alone)."""
    for path in run_files(out):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


LOCK_FILE = "run.lock"
"""The file in ``--out`` that a run holds an exclusive lock on (flock) for its whole life, with
its process id in it. Left in place when the run ends (a run refused, failed or stopped removes
the lock file, and the folder, that it made itself)."""


class RunLock:
    """``with RunLock(comm, out):`` holds ``out/run.lock`` (:data:`LOCK_FILE`) for the block:
    rank 0 makes ``out`` and takes the lock without waiting. Raises :class:`RunFolderError` on
    every rank, naming the holder's process id, when another process holds it or the file
    cannot be made. Collective."""

    def __init__(self, comm: MPI.Comm, out: Path):
        self.comm, self.path, self._fd = comm, Path(out) / LOCK_FILE, None
        self._made: list[Path] = []  # what taking the lock created: the folder, the file

    def __enter__(self) -> RunLock:
        import fcntl

        message = ""
        if self.comm.rank == 0:
            self._made = [p for p in (self.path.parent, self.path) if not p.exists()]
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                message, fd = f"{self.path}: cannot be made ({_describe_error(e)})", None
        if self.comm.rank == 0 and fd is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                message = (
                    f"{self.path.parent} is being written by another fsi run (process {holder}, "
                    f"which holds {self.path}); wait for it, or choose another --out"
                )
            else:
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                self._fd = fd
        message = self.comm.bcast(message, root=0)
        if message:
            raise RunFolderError(message)
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if self._fd is None:
            return
        if exc_type is not None:  # refused or stopped: remove the lock file and folder it made
            for path in reversed(self._made):
                if path == self.path:
                    path.unlink(missing_ok=True)
                elif not any(path.iterdir()):
                    path.rmdir()
        os.close(self._fd)  # releases the lock
        self._fd = None


def check_folder(comm: MPI.Comm, out: Path, *, earlier_run: bool = False) -> None:
    """Check, before any computation and without writing anything, that ``out`` can take the
    output: a folder, or a path where one can be made, writable by this process (a read-only
    mount is caught, a full disk is not); unless ``earlier_run``, one that holds no earlier
    run's files (:data:`RUN_FILES`). Collective; raises :class:`RunFolderError` on every rank."""
    message = _check_folder(out, earlier_run) if comm.rank == 0 else ""
    message = comm.bcast(message, root=0)
    if message:
        raise RunFolderError(message)


def _check_folder(out: Path, earlier_run: bool) -> str:
    if out.is_symlink() and not out.exists():
        return f"{out} is a symbolic link to {os.readlink(out)}, which does not exist"
    existing = next(p for p in (out, *out.absolute().parents) if p.exists())
    if not existing.is_dir():
        return f"{existing} is a file, not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{existing}: cannot write there (read-only or no permission)"
    earlier = run_files(out) if existing == out and not earlier_run else []
    if earlier:
        names = ", ".join(p.name for p in earlier[:4]) + (", ..." if len(earlier) > 4 else "")
        return (
            f"{out} holds an earlier run ({names}): continue it with --restart {out},"
            " replace it with --overwrite, or choose another --out"
        )
    return ""


def write_table(comm: MPI.Comm, path: Path, columns: list[str], rows: list[list]) -> None:
    """A table as CSV, written by rank 0 from its ``rows`` (lists in column order; the other
    ranks' are ignored): floats with 10 significant digits (as metrics.csv), NaN as an empty
    cell, infinity as ``inf``. Written to ``<path>.partial`` and renamed, so ``path`` is always
    a complete table. Collective (:func:`on_rank0`: :class:`OutputError` on every rank if it
    cannot be written)."""

    def cell(value) -> str:
        return "" if isinstance(value, float) and math.isnan(value) else format_value(value)

    def write() -> None:
        partial = path.with_name(path.name + ".partial")
        with partial.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(columns)
            writer.writerows([cell(v) for v in row] for row in rows)
        os.replace(partial, path)

    on_rank0(comm, write, path)
