"""Checks shared by the mesh tests."""

from mpi4py import MPI

import dolfinx.mesh
import numpy as np

from fsi import compat, config


def boundary_vertices(submesh) -> set[tuple[float, float]]:
    """Coordinates of the vertices on the exterior facets of a submesh, gathered on all ranks."""
    tdim = submesh.topology.dim
    submesh.topology.create_connectivity(tdim - 1, tdim)
    facets = dolfinx.mesh.exterior_facet_indices(submesh.topology)
    nodes = compat.entities_to_geometry(submesh, tdim - 1, facets).ravel()
    local = [tuple(x) for x in submesh.geometry.x[nodes, :2]]
    return set().union(*submesh.comm.allgather(local))


def mesh_motion_settings(**kw) -> config.MeshMotionSettings:
    """The ``mesh_motion`` section with the keys ``kw`` (validated as in a case file)."""
    return config.from_dict({"mesh_motion": kw}).mesh_motion


def global_max(comm: MPI.Comm, a: np.ndarray) -> float:
    """max |a| over every rank's values."""
    return comm.allreduce(float(np.abs(a).max(initial=0.0)), op=MPI.MAX)
