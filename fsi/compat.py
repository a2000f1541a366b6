"""Differences between the supported dolfinx releases: 0.5.2 (Debian 12) and 0.9.0 (Debian 13).

Every call whose signature or return value differs between the two lives here and nowhere else.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import dolfinx.cpp
import dolfinx.io
import dolfinx.mesh
import numpy as np

DOLFINX_VERSION = tuple(int(part) for part in dolfinx.__version__.split(".")[:2])
LEGACY = DOLFINX_VERSION < (0, 6)  # dolfinx 0.5.x


def model_to_mesh(comm: MPI.Comm, rank: int, gdim: int):
    """The current gmsh model (on ``rank``) as a distributed mesh with cell and facet tags."""
    import gmsh
    from dolfinx.io import gmshio

    mesh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, rank, gdim=gdim)[:3]
    return mesh, cell_tags, facet_tags


def function_space(mesh, family: str, degree: int, shape: tuple[int, ...] = ()):
    """A Lagrange/DG function space: scalar (``shape=()``), vector (``(2,)``) or tensor."""
    if LEGACY:
        import dolfinx.fem

        if shape == ():
            return dolfinx.fem.FunctionSpace(mesh, (family, degree))
        if len(shape) == 1:
            return dolfinx.fem.VectorFunctionSpace(mesh, (family, degree), dim=shape[0])
        return dolfinx.fem.TensorFunctionSpace(mesh, (family, degree), shape=shape)
    import basix.ufl
    import dolfinx.fem

    element = basix.ufl.element(family, mesh.basix_cell(), degree, shape=shape or None)
    return dolfinx.fem.functionspace(mesh, element)


def create_submesh(mesh, dim: int, entities: np.ndarray):
    """A submesh of ``entities`` and the map from its cells to the parent's (local) cells."""
    submesh, entity_map, *_ = dolfinx.mesh.create_submesh(mesh, dim, entities)
    return submesh, np.asarray(entity_map, dtype=np.int32)


def entities_to_geometry(mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """Geometry-node indices (rows) of the given entities."""
    entities = np.asarray(entities, dtype=np.int32)
    if LEGACY:
        return dolfinx.cpp.mesh.entities_to_geometry(mesh._mesh, dim, entities, False)
    return dolfinx.mesh.entities_to_geometry(mesh, dim, entities, False)


def write_meshtags(xdmf: dolfinx.io.XDMFFile, mesh, tags) -> None:
    """Write mesh tags after the mesh in an open XDMF file."""
    if LEGACY:
        xdmf.write_meshtags(tags)
    else:
        xdmf.write_meshtags(tags, mesh.geometry)


def read_mesh_with_tags(comm: MPI.Comm, path: str):
    """Read ``mesh.xdmf`` as written by :func:`fsi.mesh.write`: the mesh, cell and facet tags."""
    with dolfinx.io.XDMFFile(comm, path, "r") as xdmf:
        mesh = xdmf.read_mesh(name="mesh")
        tdim = mesh.topology.dim
        cell_tags = xdmf.read_meshtags(mesh, name="cell_tags")
        mesh.topology.create_connectivity(tdim - 1, tdim)
        facet_tags = xdmf.read_meshtags(mesh, name="facet_tags")
    return mesh, cell_tags, facet_tags
