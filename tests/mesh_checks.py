"""Checks shared by the mesh tests."""

import dolfinx.mesh

from fsi import compat


def boundary_vertices(submesh) -> set[tuple[float, float]]:
    """Coordinates of the vertices on the exterior facets of a submesh, gathered on all ranks."""
    tdim = submesh.topology.dim
    submesh.topology.create_connectivity(tdim - 1, tdim)
    facets = dolfinx.mesh.exterior_facet_indices(submesh.topology)
    nodes = compat.entities_to_geometry(submesh, tdim - 1, facets).ravel()
    local = [tuple(x) for x in submesh.geometry.x[nodes, :2]]
    return set().union(*submesh.comm.allgather(local))
