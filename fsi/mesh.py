"""The case's tagged mesh: gmsh builds it on rank 0, dolfinx distributes it, and its measures.

The geometry builders (``geometry/``) add entities and physical groups to a gmsh model; this
module meshes that model at the configured level (coarse, then uniform refinements), hands it to
dolfinx, and measures the distributed mesh: cell and facet counts, region areas, the stenosis
degree and the thinnest fibrous cap. Every function here is collective.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import numpy as np
import ufl

from fsi import compat
from fsi.config import Case, ChannelGeometry, StenosisGeometry
from geometry import channel, stenosis
from geometry.tags import Boundary, Region

log = logging.getLogger(__name__)


@dataclass
class TaggedMesh:
    """The whole system's mesh (fluid and structure) with its region and boundary tags."""

    mesh: dolfinx.mesh.Mesh
    cell_tags: dolfinx.mesh.MeshTags
    facet_tags: dolfinx.mesh.MeshTags

    @property
    def comm(self) -> MPI.Comm:
        return self.mesh.comm

    def cells(self, *regions: Region) -> np.ndarray:
        """Local indices of the cells in ``regions`` (owned and ghost)."""
        mask = np.isin(self.cell_tags.values, [int(r) for r in regions])
        return self.cell_tags.indices[mask]

    def facets(self, *boundaries: Boundary) -> np.ndarray:
        """Local indices of the facets on ``boundaries``."""
        mask = np.isin(self.facet_tags.values, [int(b) for b in boundaries])
        return self.facet_tags.indices[mask]


def build(case: Case, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """Mesh the case's geometry with gmsh on rank 0 and distribute it over ``comm``."""
    error = None
    if comm.rank == 0:
        import gmsh

        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            _build_model(case)
            gmsh.model.mesh.generate(2)
            for _ in range(case.mesh.refinements):
                gmsh.model.mesh.refine()
        except Exception as e:  # reported on every rank below, before any collective
            error = f"gmsh failed to mesh the geometry: {e}"
    error = comm.bcast(error, root=0)
    if error is not None:
        if comm.rank == 0:
            gmsh.finalize()
        raise RuntimeError(error)
    try:
        mesh, cell_tags, facet_tags = compat.model_to_mesh(comm, 0, gdim=2)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    mesh.topology.create_connectivity(1, 2)
    mesh.topology.create_entities(1)
    cell_tags.name, facet_tags.name = "cell_tags", "facet_tags"
    return TaggedMesh(mesh, cell_tags, facet_tags)


def _build_model(case: Case) -> None:
    g, m = case.geometry, case.mesh
    if isinstance(g, StenosisGeometry):
        stenosis.build(g, size=m.size, local_size=m.local_size)
    elif isinstance(g, ChannelGeometry):
        channel.build(g, size=m.size)
    else:  # pragma: no cover - the config admits no other kind
        raise ValueError(f"unknown geometry kind {g.kind!r}")


def extract(tagged: TaggedMesh, *regions: Region):
    """The submesh of ``regions`` (e.g. the fluid, or wall + cap + lipid) and its parent-cell map."""
    return compat.create_submesh(tagged.mesh, tagged.mesh.topology.dim, tagged.cells(*regions))


def _owned_count(indices: np.ndarray, index_map) -> int:
    return int(np.count_nonzero(indices < index_map.size_local))


def summary(tagged: TaggedMesh, case: Case) -> dict:
    """Cell counts and areas per region, facet counts per boundary and geometric measures.

    Counts cover owned entities only, so they are the same on any number of ranks.
    """
    mesh, comm = tagged.mesh, tagged.comm
    cell_map, facet_map = mesh.topology.index_map(2), mesh.topology.index_map(1)
    dx = ufl.Measure("dx", domain=mesh, subdomain_data=tagged.cell_tags)
    one = dolfinx.fem.Constant(mesh, 1.0)

    def area(measure) -> float:
        local = dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * measure))
        return float(comm.allreduce(local, op=MPI.SUM))

    cells = {r.label: comm.allreduce(_owned_count(tagged.cells(r), cell_map)) for r in Region}
    cells["total"] = cell_map.size_global
    areas = {r.label: area(dx(int(r))) for r in Region}
    areas["total"] = area(dx)
    facets = {b.label: comm.allreduce(_owned_count(tagged.facets(b), facet_map)) for b in Boundary}
    result = {"cells": cells, "area_m2": areas, "facets": facets}
    if isinstance(case.geometry, StenosisGeometry):
        result["measures"] = stenosis_measures(tagged, case.geometry)
    return result


def facet_segments(tagged: TaggedMesh, boundary: Boundary) -> np.ndarray:
    """End points (n, 2, 2) of every facet on ``boundary``, gathered on all ranks."""
    mesh = tagged.mesh
    facets = tagged.facets(boundary)
    facets = facets[facets < mesh.topology.index_map(1).size_local]
    nodes = compat.entities_to_geometry(mesh, 1, facets).reshape(-1, 2)
    local = mesh.geometry.x[nodes][:, :, :2]
    return np.concatenate(tagged.comm.allgather(local)).reshape(-1, 2, 2)


def stenosis_measures(tagged: TaggedMesh, g: StenosisGeometry) -> dict:
    """The stenosis degree and the thinnest fibrous cap, measured on the mesh.

    Degree: the fraction of the lumen height the plaques occlude at their apex. Cap thickness:
    the smallest distance from a cap–lipid vertex to the lumen boundary (the interface facets).
    """
    interface = facet_segments(tagged, Boundary.INTERFACE)
    y = interface[:, :, 1].ravel()
    # With plaque on both sides each is lower than half the lumen; with one, all is that side's.
    split = g.height / 2 if len(g.plaque_sides) == 2 else (np.inf if "bottom" in g.plaque_sides else -np.inf)
    bottom = y[y < split].max(initial=0.0)
    top = (g.height - y[y >= split]).max(initial=0.0)
    lipid_vertices = facet_segments(tagged, Boundary.CAP_LIPID).reshape(-1, 2)
    thinnest = stenosis.distance_to_segments(lipid_vertices, interface[:, 0], interface[:, 1])
    return {
        "stenosis_degree": float((bottom + top) / g.height),
        "min_cap_thickness_m": float(thinnest.min()),
    }
