"""The rigid-body modes of a vector displacement space as PETSc's near-nullspace: what an
algebraic multigrid preconditioner (GAMG) of the structure or of the elastic mesh motion needs
to coarsen elasticity well (docs/3d.md, the solver presets). A direct solver ignores it.
"""

from __future__ import annotations

from petsc4py import PETSc

import dolfinx.fem
import numpy as np

from fsi import compat


def rigid_body_modes(V: dolfinx.fem.FunctionSpace) -> PETSc.NullSpace:
    """The translations and infinitesimal rotations of the vector space ``V`` (2D: 2 + 1, 3D:
    3 + 3), orthonormalised, as a PETSc NullSpace for ``Mat.setNearNullSpace``. Collective."""
    gdim = V.mesh.geometry.dim
    x = V.tabulate_dof_coordinates()[:, :gdim]
    modes = []
    for axis in range(gdim):  # translations
        values = np.zeros_like(x)
        values[:, axis] = 1.0
        modes.append(values)
    pairs = [(0, 1)] if gdim == 2 else [(0, 1), (1, 2), (2, 0)]
    for i, j in pairs:  # rotations in the (i, j) plane: u_i = −x_j, u_j = x_i
        values = np.zeros_like(x)
        values[:, i], values[:, j] = -x[:, j], x[:, i]
        modes.append(values)
    vectors = []
    for values in modes:
        f = dolfinx.fem.Function(V)
        f.x.array[:] = values.ravel()
        vector = compat.petsc_vector(f).copy()
        for previous in vectors:  # Gram–Schmidt
            vector.axpy(-vector.dot(previous), previous)
        vector.normalize()
        vectors.append(vector)
    return PETSc.NullSpace().create(vectors=vectors, comm=V.mesh.comm)
