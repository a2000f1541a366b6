"""Files: the mesh (XDMF with tags) and its summary (JSON). Physics modules never open files."""

from __future__ import annotations

import json
from pathlib import Path

from mpi4py import MPI

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
