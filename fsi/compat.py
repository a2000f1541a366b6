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


def element_info(V) -> tuple[bool, int, tuple[int, ...]]:
    """(discontinuous?, degree, value shape) of a (non-mixed) function space's element."""
    e = V.ufl_element()
    if LEGACY:
        return "Discontinuous" in e.family(), e.degree(), tuple(e.value_shape())
    return e.discontinuous, e.degree, tuple(e.reference_value_shape)


def create_submesh(mesh, dim: int, entities: np.ndarray):
    """A submesh of ``entities`` and the map from its cells to the parent's (local) cells."""
    submesh, entity_map, *_ = dolfinx.mesh.create_submesh(mesh, dim, entities)
    return submesh, np.asarray(entity_map, dtype=np.int32)


def entities_to_geometry(mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """Geometry-node indices (rows) of the given entities."""
    entities = np.asarray(entities, dtype=np.int32)
    if entities.size == 0:
        # dolfinx 0.9 divides by zero (SIGFPE) on an empty list, e.g. on a rank that holds no
        # facet of a boundary: ask for entity 0 (every rank has one) to get the row shape.
        return entities_to_geometry(mesh, dim, np.zeros(1, dtype=np.int32))[:0]
    if LEGACY:
        return dolfinx.cpp.mesh.entities_to_geometry(mesh._mesh, dim, entities, False)
    return dolfinx.mesh.entities_to_geometry(mesh, dim, entities, False)


def write_meshtags(xdmf: dolfinx.io.XDMFFile, mesh, tags) -> None:
    """Write mesh tags after the mesh in an open XDMF file."""
    if LEGACY:
        xdmf.write_meshtags(tags)
    else:
        xdmf.write_meshtags(tags, mesh.geometry)


# --------------------------------------------------------------------------------------------
# Dof layouts and PETSc vectors


def interpolation_points(V) -> np.ndarray:
    """Reference points of ``V``'s element for interpolating a :class:`dolfinx.fem.Expression`."""
    points = V.element.interpolation_points
    return points() if callable(points) else points  # a method in 0.5 and 0.9, later a property


def cell_dofs(V) -> np.ndarray:
    """The dofmap as an array (cells, dofs per cell) of local (block) dof indices."""
    dofs = V.dofmap.list
    return dofs.array.reshape(-1, V.dofmap.dof_layout.num_dofs) if LEGACY else np.asarray(dofs)


def petsc_vector(u):
    """The PETSc vector that wraps a :class:`dolfinx.fem.Function`'s values."""
    return u.vector if LEGACY else u.x.petsc_vec


# --------------------------------------------------------------------------------------------
# Mixed spaces and their subspaces' dofs (in place of 0.5.2's collapse()), expressions and the
# geometry dofmap (added for fsi.physics.fluid and fsi.output.metrics)


def mixed_space(mesh, parts):
    """A mixed space of ``parts``, ``(family, degree, shape)`` triples with ``shape`` () for a
    scalar, e.g. Taylor–Hood ``[("Lagrange", 2, (2,)), ("Lagrange", 1, ())]``."""
    import dolfinx.fem

    if LEGACY:
        import ufl

        cell = mesh.ufl_cell()
        elements = [
            ufl.FiniteElement(f, cell, d) if not s else ufl.VectorElement(f, cell, d, dim=s[0])
            for f, d, s in parts
        ]
        return dolfinx.fem.FunctionSpace(mesh, ufl.MixedElement(elements))
    import basix.ufl

    cell = mesh.topology.cell_name()
    elements = [basix.ufl.element(f, cell, d, shape=s if s else None) for f, d, s in parts]
    return dolfinx.fem.functionspace(mesh, basix.ufl.mixed_element(elements))


def subspace_map(W, i: int, V) -> np.ndarray:
    """The local dof of ``W`` behind each local (unrolled) dof of ``V``, a standalone space with
    the element of ``W.sub(i)`` (what ``W.sub(i).collapse()`` gives), from the cell dofmaps.

    A blocked sub-element lists its dofs node by node (x0, y0, x1, y1, ...), as V unrolls its
    blocks. −1 marks a ghost dof on no local cell (dolfinx 0.5.2's submeshes have such orphan
    ghosts in parallel, where its ``collapse()`` corrupts the heap, hence this map). Copy owned
    values and scatter forward.
    """
    V_cells = cell_dofs(V)
    W_cells = cell_dofs(W.sub(i)).reshape(len(V_cells), -1)
    bs = V.dofmap.index_map_bs
    unrolled = (V_cells[:, :, None] * bs + np.arange(bs)).reshape(len(V_cells), -1)
    index_map = V.dofmap.index_map
    V_to_W = np.full((index_map.size_local + index_map.num_ghosts) * bs, -1, dtype=np.int32)
    V_to_W[unrolled.ravel()] = W_cells.ravel()
    if (V_to_W[: index_map.size_local * bs] < 0).any():
        raise RuntimeError("an owned dof of the subspace lies on no local cell")
    return V_to_W


def eval_expression(expression, mesh, cells: np.ndarray) -> np.ndarray:
    """Values of a ``dolfinx.fem.Expression`` at its reference points on ``cells``, shape
    (len(cells), num_points * value_size)."""
    cells = np.asarray(cells, dtype=np.int32)
    if len(cells) == 0:
        return np.zeros((0, 0))
    values = expression.eval(cells) if LEGACY else expression.eval(mesh, cells)
    return np.asarray(values).reshape(len(cells), -1)


def quadrature_space(mesh, degree: int):
    """A scalar space of values at the points of the default quadrature rule of ``degree`` on
    each cell (the points of ``dx`` with that quadrature degree), and those reference points,
    shape (points, tdim): a coefficient of this space enters a form of that degree as its
    values there."""
    import dolfinx.fem

    if LEGACY:
        import basix
        import ufl

        element = ufl.FiniteElement("Quadrature", mesh.ufl_cell(), degree, quad_scheme="default")
        cell = basix.cell.string_to_type(mesh.ufl_cell().cellname())
        points, _ = basix.make_quadrature(basix.QuadratureType.Default, cell, degree)
        return dolfinx.fem.FunctionSpace(mesh, element), points
    import basix.ufl

    element = basix.ufl.quadrature_element(
        mesh.topology.cell_name(), value_shape=(), scheme="default", degree=degree
    )
    points, _ = element.custom_quadrature()
    return dolfinx.fem.functionspace(mesh, element), points


def geometry_dofmap(mesh) -> np.ndarray:
    """Geometry-node indices per local cell, shape (num_cells, nodes_per_cell)."""
    dofmap = mesh.geometry.dofmap
    if LEGACY:
        return dofmap.array.reshape(dofmap.num_nodes, -1)
    return np.asarray(dofmap)
