"""Transfer of interface data between the fluid and the solid function spaces (Γw1).

:class:`InterfaceMap` pairs the interface dofs of a source and a destination space by position
(both meshes are submeshes of one gmsh mesh). An *interface vector* is the array of a space's
owned interface dof values, shape (n_owned, block size), so each interface dof counts exactly
once in the MPI-global inner products of the coupling accelerations (:func:`norm`).
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx.fem
import numpy as np
from scipy.spatial import cKDTree

from fsi.physics.mesh import owned_facet_dofs


class InterfaceMap:
    """Pairs the owned interface dofs of ``V_src`` and ``V_dst`` (same block size) by position.

    An interface facet's fluid and solid cells may live on different ranks, so the (small) source
    interface data are gathered on every rank (:meth:`gather`) and each rank picks what its
    destination dofs need.

    Args:
        V_src, V_dst: the two spaces, e.g. the solid displacement and the fluid velocity.
        facets_src, facets_dst: local facet indices of the interface on each space's mesh.
        tolerance: largest distance between paired dof points, relative to the interface's
            extent; a dof with no partner that close raises ValueError (non-conforming meshes).
    """

    def __init__(self, V_src, facets_src, V_dst, facets_dst, tolerance: float = 1e-8):
        self.comm: MPI.Comm = V_src.mesh.comm
        self.bs = V_src.dofmap.index_map_bs
        if V_dst.dofmap.index_map_bs != self.bs:
            raise ValueError("interface spaces must have the same block size")
        self.src_dofs = owned_facet_dofs(V_src, facets_src)
        self.dst_dofs = owned_facet_dofs(V_dst, facets_dst)
        src_points = V_src.tabulate_dof_coordinates()[self.src_dofs]
        dst_points = V_dst.tabulate_dof_coordinates()[self.dst_dofs]

        # Every rank learns all source points, in rank order; gathered data follow that order.
        self._counts = np.array(self.comm.allgather(len(self.src_dofs)))
        all_src = np.concatenate(self.comm.allgather(src_points)).reshape(-1, 3)
        all_dst = np.concatenate(self.comm.allgather(dst_points)).reshape(-1, 3)
        if len(all_src) != len(all_dst):
            raise ValueError(
                f"interface dof counts differ: {len(all_src)} source, {len(all_dst)} destination"
            )
        extent = float(np.ptp(all_src, axis=0).max()) if len(all_src) else 1.0
        tree = cKDTree(all_src)
        distance, self._pick = (
            tree.query(dst_points) if len(dst_points) else (np.zeros(0), np.zeros(0, int))
        )
        bad = self.comm.allreduce(int(np.count_nonzero(distance > tolerance * extent)))
        if bad:
            raise ValueError(
                f"{bad} interface dofs have no partner within {tolerance:g} × the "
                "interface extent: the fluid and solid meshes do not conform"
            )
        self.size = len(all_src)  # interface nodes in all

    def gather(self, src_values: np.ndarray) -> np.ndarray:
        """All ranks' source interface vectors, concatenated in rank order."""
        parts = self.comm.allgather(np.asarray(src_values).reshape(-1, self.bs))
        return np.concatenate(parts).reshape(-1, self.bs)

    def transfer(self, src_values: np.ndarray) -> np.ndarray:
        """The destination interface vector carrying the source interface vector's values."""
        return self.gather(src_values)[self._pick]

    def set_dst(self, f: dolfinx.fem.Function, values: np.ndarray) -> None:
        """Write a destination interface vector into a destination-space function."""
        f.x.array.reshape(-1, self.bs)[self.dst_dofs] = values
        f.x.scatter_forward()


def norm(comm: MPI.Comm, v: np.ndarray) -> float:
    """MPI-global Euclidean norm of an interface vector."""
    return float(np.sqrt(comm.allreduce(float(np.vdot(v, v)), op=MPI.SUM)))
