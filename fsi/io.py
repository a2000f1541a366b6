"""Files: the mesh (XDMF with tags) and its summary, metrics tables (CSV) and field time series
(XDMF). Physics modules never open files."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from mpi4py import MPI

import dolfinx.fem
import dolfinx.io

from fsi import compat
from fsi.mesh import TaggedMesh


def write_json(comm: MPI.Comm, path: Path, data: dict) -> None:
    """Write ``data`` as indented JSON from rank 0; every rank returns once it is on disk."""
    if comm.rank == 0:
        path.write_text(json.dumps(data, indent=2) + "\n")
    comm.barrier()


def write_mesh(out: Path, tagged: TaggedMesh, summary: dict) -> None:
    """``out/mesh.xdmf`` (mesh, cell tags ``cell_tags``, facet tags ``facet_tags``) and
    ``out/mesh.json`` (the summary of :func:`fsi.mesh.summary`). Collective."""
    comm = tagged.comm
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    comm.barrier()
    tagged.mesh.name = "mesh"
    with dolfinx.io.XDMFFile(comm, str(out / "mesh.xdmf"), "w") as xdmf:
        xdmf.write_mesh(tagged.mesh)
        compat.write_meshtags(xdmf, tagged.mesh, tagged.cell_tags)
        compat.write_meshtags(xdmf, tagged.mesh, tagged.facet_tags)
    write_json(comm, out / "mesh.json", summary)


class MetricsTable:
    """``metrics.csv``: one row per time step, written by rank 0 and flushed at every row, so a
    run that stops keeps every finished step. On restart the rows up to ``keep_until_step`` of
    ``source`` (default: ``path`` itself) are kept, the later ones dropped, and new rows are
    appended; :attr:`kept` holds the kept rows as numbers (on every rank)."""

    def __init__(self, comm: MPI.Comm, path: Path, columns: list[str],
                 keep_until_step: int | None = None, source: Path | None = None):
        self.comm, self.path, self.columns = comm, path, list(columns)
        self._file = None
        self.kept: list[dict] = []
        source = path if source is None else source
        rows: list[dict] = []
        if comm.rank == 0 and keep_until_step is not None and source.exists():
            with source.open(newline="") as f:
                rows = [r for r in csv.DictReader(f) if int(r["step"]) <= keep_until_step]
        self.kept = comm.bcast([{k: _parse(v) for k, v in r.items() if v not in ("", None)}
                                for r in rows], root=0)
        if comm.rank != 0:
            return
        self._file = path.open("w", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns, extrasaction="raise")
        self._writer.writeheader()
        for row in rows:
            self._writer.writerow({k: row.get(k, "") for k in self.columns})
        self._file.flush()

    def write(self, row: dict) -> None:
        if self._file is not None:
            self._writer.writerow({k: _format(row.get(k, "")) for k in self.columns})
            self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def _format(value) -> str:
    return f"{value:.10g}" if isinstance(value, float) else str(value)


def _parse(text: str) -> int | float | str:
    """A metrics value as written by :func:`_format`: int, float, or the text itself."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_metrics(path: Path) -> list[dict[str, float]]:
    """The rows of a ``metrics.csv`` as numbers."""
    with Path(path).open(newline="") as f:
        return [{k: float(v) for k, v in row.items() if v != ""} for row in csv.DictReader(f)]


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
            k = path.name[len(stem) + len(".restart"):].split(".")[0]
            if k.isdigit() and int(k) > first_step and path.suffix in (".xdmf", ".h5"):
                path.unlink()
                removed.append(path)
    return removed


class FieldWriter:
    """An XDMF time series of fields for ParaView. Lagrange fields are written as their P1
    interpolants and DG fields as DG0 (XDMF stores vertex and cell data only); on a moving mesh
    the mesh displacement is one of the fields (ParaView: Warp By Vector)."""

    def __init__(self, comm: MPI.Comm, path: Path, mesh):
        self._xdmf = dolfinx.io.XDMFFile(comm, str(path), "w")
        self._xdmf.write_mesh(mesh)
        self._outputs: dict[str, dolfinx.fem.Function] = {}

    def _output_for(self, f: dolfinx.fem.Function) -> dolfinx.fem.Function:
        if f.name not in self._outputs:
            discontinuous, _, shape = compat.element_info(f.function_space)
            family, degree = ("DG", 0) if discontinuous else ("Lagrange", 1)
            out = dolfinx.fem.Function(compat.function_space(f.function_space.mesh, family,
                                                             degree, shape))
            out.name = f.name
            self._outputs[f.name] = out
        return self._outputs[f.name]

    def write(self, t: float, fields: list[dolfinx.fem.Function]) -> None:
        for f in fields:
            out = self._output_for(f)
            out.interpolate(f)
            self._xdmf.write_function(out, t)

    def close(self) -> None:
        self._xdmf.close()

