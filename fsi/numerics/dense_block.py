"""A dense block added to a PETSc matrix whose sparsity pattern lacks it (a lumped outlet's
R' b bᵀ in the fluid's Jacobian: fsi/physics/fluid_boundary_terms.py, ``LumpedOutlet``).

Inserted entry by entry into a matrix without room for them, PETSc grows each row a few
entries at a time and copies the whole matrix at each growth: 70 s for the first Jacobian of the
3D carotid heartbeat (8.8·10⁶ entries, a block among ~200 outlet dofs; docs/3d.md). So the
first time a matrix meets a block it comes in as a preallocated matrix of its own, merged in one
pass (``MatAXPY`` with a different pattern: 0.4 s there), and the matrix is marked with the
block's name; later, into the same matrix, the entries are added in place.
"""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np


def add_dense_block(
    A: PETSc.Mat, rows: np.ndarray, columns: np.ndarray, values: np.ndarray, name: str
) -> None:
    """``A[rows, columns] += values`` and ``A`` assembled. ``rows``: this rank's owned rows
    (global indices); ``columns``: every rank's (global), the same on all ranks; ``values``:
    len(rows) × len(columns). The rows and columns must be the same at every call with the same
    ``name``. Collective."""
    if A.query(name) is None:
        _merge(A, rows, columns, values)
        A.compose(name, PETSc.Vec().createSeq(0, comm=PETSc.COMM_SELF))  # the mark
    else:
        A.setValues(rows, columns, values, addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()


def _merge(A: PETSc.Mat, rows, columns, values) -> None:
    """A += the block, A's pattern grown to hold it in one pass."""
    (local_rows, _), _ = A.getSizes()
    first, last = A.getOwnershipRangeColumn()
    inside = np.count_nonzero((columns >= first) & (columns < last))
    diagonal = np.zeros(local_rows, dtype=PETSc.IntType)
    off_diagonal = np.zeros(local_rows, dtype=PETSc.IntType)
    local = rows - A.getOwnershipRange()[0]
    diagonal[local], off_diagonal[local] = inside, len(columns) - inside
    block = PETSc.Mat().createAIJ(A.getSizes(), nnz=(diagonal, off_diagonal), comm=A.getComm())
    block.setValues(rows, columns, values, addv=PETSc.InsertMode.ADD_VALUES)
    block.assemble()
    row_map, column_map = A.getLGMap()  # dolfinx assembles through it; MatAXPY drops it
    A.axpy(1.0, block, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    A.setLGMap(row_map, column_map)
    block.destroy()
