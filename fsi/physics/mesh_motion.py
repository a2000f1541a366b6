"""ALE mesh motion of the fluid domain (docs/model.md, Mesh motion). :class:`MeshMotion` extends
the interface displacement g into the fluid as ``d`` (vector P1) on the reference domain Ω̂f:

    harmonic:    −∇·(k ∇d) = 0,
    elastic:     −∇·(k σ(d)) = 0,   σ(d) = 2 ε(d) + λ' tr(ε(d)) I,   ε(d) = sym ∇d,
    biharmonic:  Δ²d = 0, as the minimiser of ∫ k |∇∇d|² dx (:func:`biharmonic_operator`),

with ``d = g`` on the moving boundaries and ``d = 0`` on the fixed ones; :class:`AleMesh` moves
the mesh to x = X + d and keeps d^n, d^{n−1} and the mesh velocity ``w = Σ_k a_k d^{n+1−k}``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import scipy.spatial
import ufl

from fsi import compat, config
from fsi.geometry.stenosis import distance_to_segments
from fsi.geometry.tags import Boundary
from fsi.numerics.newton import petsc_options
from fsi.numerics.nullspace import rigid_body_modes
from fsi.numerics.timestepping import BdfHistory
from fsi.physics.mesh import TaggedMesh, bounding_plane_dofs, owned_facet_dofs

PREFIX = "mesh_"


class MeshQualityError(RuntimeError):
    """A fluid cell shrank below the allowed fraction of its reference area (volume in 3D), or
    inverted.

    Attributes: ``ratio`` the smallest J/J_ref, ``where`` that cell's centroid (deformed, m),
    ``threshold`` the configured ``min_jacobian_ratio``.
    """

    def __init__(self, ratio: float, where: np.ndarray, threshold: float):
        self.ratio, self.where, self.threshold = ratio, np.asarray(where), threshold
        what = "inverted" if ratio <= 0 else "collapsed"
        measure = "volume" if len(self.where) == 3 else "area"
        at = ", ".join(f"{c:.6g}" for c in self.where)
        super().__init__(
            f"fluid mesh {what}: a cell's {measure} ratio J/J_ref = {ratio:.4g} at "
            f"({at}) m is below the threshold "
            f"mesh_motion.min_jacobian_ratio = {threshold:g}"
        )


def signed_areas(x: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Signed areas ½ (x₁ − x₀) × (x₂ − x₀) of triangles with vertex rows ``nodes`` (n, 3), or
    signed volumes (x₁ − x₀)·((x₂ − x₀) × (x₃ − x₀))/6 of tetrahedra (``nodes`` (n, 4))."""
    if nodes.shape[1] == 4:
        a, b, c = (x[nodes[:, k]] - x[nodes[:, 0]] for k in (1, 2, 3))
        return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    a = x[nodes[:, 1], :2] - x[nodes[:, 0], :2]
    b = x[nodes[:, 2], :2] - x[nodes[:, 0], :2]
    return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def geometry_node_dofs(V: dolfinx.fem.FunctionSpace) -> tuple[np.ndarray, np.ndarray]:
    """The geometry nodes of the local cells, each once, and the dof of the vector P1 space
    ``V`` at each (both follow each cell's vertex order). A submesh may hold a geometry node
    that no local cell uses (dolfinx 0.5 on several ranks): it is not listed, so it is never
    moved, and it plays no part in any cell. Raises if the geometry is not affine (P1), and on
    every rank if a node and its dof are apart. Collective (an allreduce)."""
    mesh = V.mesh
    cells, dofs = compat.geometry_dofmap(mesh), compat.cell_dofs(V)
    if cells.shape != dofs.shape:
        raise ValueError("the mesh motion needs an affine (P1) geometry")
    nodes, first = np.unique(cells.ravel(), return_index=True)
    node_dofs = dofs.ravel()[first]
    gdim, x = mesh.geometry.dim, mesh.geometry.x
    points = V.tabulate_dof_coordinates()[node_dofs, :gdim]
    scale = 1.0 + np.abs(x).max(initial=0.0)
    local_ok = np.allclose(points, x[nodes, :gdim], rtol=0, atol=1e-12 * scale)
    if not mesh.comm.allreduce(bool(local_ok), op=MPI.LAND):
        raise RuntimeError("mesh motion: P1 dofs and geometry nodes do not coincide")
    return nodes, node_dofs


def biharmonic_operator(V: dolfinx.fem.FunctionSpace, k) -> PETSc.Mat:
    """A₀ = Σ_ij B_ijᵀ W B_ij: the discrete energy ∫ k |∇∇d|² of the biharmonic method, on the
    vector P1 space ``V`` with the stiffening ``k`` (a DG0 Function or a Constant).

    The auxiliary field is the Hessian H = ∇∇d in P1, defined weakly (mixed form) by
    ``∫ H_ij·φ dx = −∫ ∂_j d·∂_i φ dx + ∫_∂Ω ∂_j d·φ n_i ds`` for every P1 φ, i.e.
    ``M H_ij = B_ij d`` (the boundary term keeps it consistent up to the boundary: an affine
    d gives H = 0 exactly). With the lumped mass M ≈ diag(m_a), m_a = ∫ φ_a at node a, the
    energy ∫ k |H|² ≈ Σ_a (∫ k φ_a) |H(a)|² = dᵀ (Σ_ij B_ijᵀ W B_ij) d with
    W = diag(∫ k φ_a / m_a²): H is eliminated and one sparse symmetric matrix remains.
    Minimising it with d = g on the Dirichlet boundaries gives Δ²d = 0 in Ω with the
    natural condition ∂²d/∂n² = 0 there (and on free boundaries the second natural one)."""
    mesh, gdim = V.mesh, V.mesh.geometry.dim
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1})
    ds = ufl.Measure("ds", domain=mesh, metadata={"quadrature_degree": 1})
    n = ufl.FacetNormal(mesh)
    ones = ufl.as_vector([1.0] * gdim)

    def lumped(weight):
        vec = dolfinx.fem.petsc.assemble_vector(dolfinx.fem.form(weight * ufl.inner(ones, v) * dx))
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return vec

    W = lumped(k)
    mass = lumped(1.0)
    W.pointwiseDivide(W, mass)
    W.pointwiseDivide(W, mass)
    A0 = None
    for i in range(gdim):
        for j in range(gdim):  # H_ij = ∂_i ∂_j d
            b_ij = -ufl.inner(u.dx(j), v.dx(i)) * dx + ufl.inner(u.dx(j), v) * n[i] * ds
            B = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(b_ij))
            B.assemble()
            WB = B.copy()
            WB.diagonalScale(L=W)
            term = B.transposeMatMult(WB)
            if A0 is None:
                A0 = term
            else:
                A0.axpy(1.0, term, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    return A0


class MeshMotion:
    """The harmonic, elastic or biharmonic extension of a boundary displacement into the fluid
    mesh: boundary data (:meth:`set_boundary_function`) →
    :meth:`solve` → d, and the quality of X + d (:meth:`check_quality`). It never moves the
    mesh (:class:`AleMesh` does), and keeps no time levels.

    Args:
        tagged: the fluid (sub)mesh with its facet tags, in its reference configuration.
        settings: method, stiffening, quality threshold and PETSc options (prefix ``mesh_``).
        moving: boundaries whose displacement is given (:attr:`g` at :attr:`interface_dofs`).
        fixed: boundaries held at d = 0; ``None`` = every other tagged boundary of the mesh.
            Boundaries in neither set are free (zero flux / zero traction). A dof on both a
            moving and a fixed boundary takes the moving value (the interface must conform).
        quadrature_degree: of the harmonic/elastic operator (its integrand is constant per cell:
            0 is exact); the biharmonic's forms are integrated exactly whatever it is.
        symmetry_planes: axes c of the mirror planes x_c = 0 (a quarter tube's untagged cuts):
            d_c = 0 on them, the mesh slides along them.
    """

    def __init__(
        self,
        tagged: TaggedMesh,
        settings: config.MeshMotionSettings | None = None,
        moving: Sequence[Boundary] = (Boundary.INTERFACE,),
        fixed: Sequence[Boundary] | None = None,
        quadrature_degree: int = 1,
        symmetry_planes: Sequence[int] = (),
    ):
        settings = settings or config.MeshMotionSettings()
        self.symmetry_planes = tuple(symmetry_planes)
        self.settings = settings
        self.mesh = mesh = tagged.mesh
        self.comm: MPI.Comm = mesh.comm
        simplices = (dolfinx.mesh.CellType.triangle, dolfinx.mesh.CellType.tetrahedron)
        if mesh.topology.cell_type not in simplices:
            raise ValueError("MeshMotion supports affine triangle and tetrahedron meshes only")
        self.gdim = mesh.geometry.dim
        self._choose_boundaries(tagged, moving, fixed)

        self.V = compat.function_space(mesh, "Lagrange", 1, (self.gdim,))
        self.d = dolfinx.fem.Function(self.V, name="mesh_displacement")
        self.g = dolfinx.fem.Function(self.V, name="mesh_boundary_displacement")

        self._map_reference_geometry()
        self._locate_boundary_dofs(tagged)

        self.k = self._stiffness(tagged)
        self.quadrature_degree = quadrature_degree
        self.assemblies = 0
        self._A0, self._A = self._assemble()
        self._b = self._A.createVecLeft()
        self._ksp = self._make_solver()

    # ---- setup

    def _choose_boundaries(
        self,
        tagged: TaggedMesh,
        moving: Sequence[Boundary],
        fixed: Sequence[Boundary] | None,
    ) -> None:
        """``self.moving`` and ``self.fixed`` (default: every other boundary tagged on any rank;
        a boundary in both is moving). Collective (an allgather)."""
        present = set(np.concatenate(self.comm.allgather(np.unique(tagged.facet_tags.values))))
        self.moving = tuple(Boundary(b) for b in moving)
        if fixed is None:
            fixed = [Boundary(int(b)) for b in sorted(present) if int(b) not in self.moving]
        self.fixed = tuple(Boundary(b) for b in fixed if b not in self.moving)

    def _map_reference_geometry(self) -> None:
        """The reference geometry X, its cells, the P1 dof of each geometry node
        (:func:`geometry_node_dofs`), the dofs' reference points and the cells' reference
        areas; raises (on every rank) if a node and its dof are apart or a cell is degenerate.
        Collective (two allreduce)."""
        mesh = self.mesh
        self.reference = mesh.geometry.x.copy()
        self._cells = compat.geometry_dofmap(mesh)
        self._nodes, self._node_dofs = geometry_node_dofs(self.V)
        # Reference coordinates X of the P1 dofs (local: owned, then ghost).
        self.dof_points = self.V.tabulate_dof_coordinates()[:, : self.gdim].copy()
        self._n_owned_cells = mesh.topology.index_map(mesh.topology.dim).size_local
        self.reference_areas = signed_areas(self.reference, self._cells)
        degenerate = bool(np.any(self.reference_areas[: self._n_owned_cells] == 0))
        if self.comm.allreduce(degenerate, op=MPI.LOR):
            raise ValueError("MeshMotion: the reference mesh has a degenerate cell")

    def _locate_boundary_dofs(self, tagged: TaggedMesh) -> None:
        """The moving-boundary facets and dofs, the owned interface dofs and the owned
        Dirichlet rows (local and global); raises (on every rank) if no facet is moving.
        Collective (an allreduce)."""
        mesh = self.mesh
        tdim = mesh.topology.dim
        # Dirichlet dofs (block indices, owned and ghost; locate_dofs_topological finds those on
        # facets another rank holds too).
        fdim = tdim - 1
        mesh.topology.create_connectivity(fdim, tdim)
        self._moving_facets = tagged.facets(*self.moving)
        self._moving_dofs = dolfinx.fem.locate_dofs_topological(self.V, fdim, self._moving_facets)
        fixed_dofs = dolfinx.fem.locate_dofs_topological(self.V, fdim, tagged.facets(*self.fixed))
        # Owned moving-boundary dofs: the rows of an interface vector (as in fsi.coupled.interface).
        self.interface_dofs = owned_facet_dofs(self.V, self._moving_facets)
        n_moving = self.comm.allreduce(len(self.interface_dofs), op=MPI.SUM)
        if n_moving == 0:
            raise ValueError(
                "MeshMotion: no facet carries a moving boundary tag "
                f"{[b.label for b in self.moving]}"
            )
        bs = self.V.dofmap.index_map_bs
        n_owned = self.V.dofmap.index_map.size_local
        bc = np.union1d(self._moving_dofs, fixed_dofs)
        bc = bc[bc < n_owned]
        rows = [(bc[:, None] * bs + np.arange(bs)).ravel()]
        for c in self.symmetry_planes:  # one component: unrolled rows of V
            plane = bounding_plane_dofs(mesh, self.V.sub(c), c)
            rows.append(plane[plane < n_owned * bs])
        self._bc_local = np.unique(np.concatenate(rows)).astype(np.int32)
        start = self.V.dofmap.index_map.local_range[0]
        self._bc_rows = (self._bc_local + start * bs).astype(PETSc.IntType)

    def _stiffness(self, tagged: TaggedMesh):
        """The cell-wise stiffening k (a DG0 Function, or the Constant 1): ``none`` 1, ``jacobian``
        ``(J_max/J)^e`` with ``J`` the reference cell area, ``distance`` ``(δ_max/δ)^e`` with ``δ``
        the distance of the cell's centroid to the moving boundary.
        """
        s = self.settings
        if s.stiffening == "none":
            return dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(1.0))
        Q = compat.function_space(self.mesh, "DG", 0)
        k = dolfinx.fem.Function(Q, name="mesh_stiffening")
        owned = slice(0, self._n_owned_cells)
        if s.stiffening == "jacobian":
            size = np.abs(self.reference_areas)
        else:  # distance of each cell's centroid to the moving boundary
            size = self._distance_to_moving_boundary()
        largest = self.comm.allreduce(float(size[owned].max(initial=0.0)), op=MPI.MAX)
        cell_dofs = compat.cell_dofs(Q)[:, 0]
        k.x.array[cell_dofs] = (largest / size) ** s.stiffening_exponent
        return k

    def _distance_to_moving_boundary(self) -> np.ndarray:
        """The distance of each local cell's reference centroid to the moving boundary: to its
        segments in 2D; in 3D to the nearest of its triangles' vertices and centroids (within
        the largest facet's size of the exact distance, which is what a stiffening needs).
        Collective (an allgather)."""
        fdim = self.mesh.topology.dim - 1
        facets = self._moving_facets
        facets = facets[facets < self.mesh.topology.index_map(fdim).size_local]
        corners = fdim + 1
        nodes = compat.entities_to_geometry(self.mesh, fdim, facets).reshape(-1, corners)
        gdim = self.gdim
        local = self.reference[nodes][:, :, :gdim].reshape(-1, corners, gdim)
        facets_xyz = np.concatenate(self.comm.allgather(local)).reshape(-1, corners, gdim)
        centroids = self.reference[self._cells][:, :, :gdim].mean(axis=1)
        if gdim == 2:
            return distance_to_segments(centroids, facets_xyz[:, 0], facets_xyz[:, 1])
        points = np.vstack([facets_xyz.reshape(-1, 3), facets_xyz.mean(axis=1)])
        return scipy.spatial.cKDTree(points).query(centroids)[0]

    def _forms(self):
        """The bilinear form of the harmonic or elastic extension."""
        u, v = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        dx = ufl.Measure(
            "dx", domain=self.mesh, metadata={"quadrature_degree": self.quadrature_degree}
        )
        if self.settings.method == "harmonic":
            return self.k * ufl.inner(ufl.grad(u), ufl.grad(v)) * dx
        nu = self.settings.poisson_ratio
        lam = 2 * nu / (1 - 2 * nu)  # λ/μ with μ = 1

        def eps(z):
            return ufl.sym(ufl.grad(z))

        sigma = 2 * eps(u) + lam * ufl.tr(eps(u)) * ufl.Identity(self.gdim)
        return self.k * ufl.inner(sigma, eps(v)) * dx

    def _assemble(self):
        """A₀ (no boundary conditions) and A (Dirichlet rows and columns → identity)."""
        self.assemblies += 1
        if self.settings.method == "biharmonic":
            A0 = biharmonic_operator(self.V, self.k)
        else:
            A0 = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(self._forms()))
        A0.assemble()
        A = A0.duplicate(copy=True)
        A.zeroRowsColumns(self._bc_rows, diag=1.0)
        A.setOptionsPrefix(PREFIX)
        A.setNearNullSpace(rigid_body_modes(self.V))  # for a GAMG preset; LU ignores it
        return A0, A

    def _make_solver(self) -> PETSc.KSP:
        """The KSP (prefix ``mesh_``), set up (factorised, for LU) once, here. The config's
        options are in the options database only while they are read (the factorisation reads
        the solver package's own, e.g. ``mat_mumps_icntl_*``), so nothing leaks to others."""
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix(PREFIX)
        ksp.setOperators(self._A)
        with petsc_options(PREFIX, self.settings.petsc_options):
            ksp.setFromOptions()
            ksp.setUp()
        return ksp

    # ---- boundary data

    def set_boundary_function(self, f: dolfinx.fem.Function | Callable) -> None:
        """Set d on the moving boundary to ``f`` (a Function on this mesh, or x ↦ values as for
        ``Function.interpolate``), interpolated into P1."""
        tmp = dolfinx.fem.Function(self.V)
        tmp.interpolate(f)
        tmp.x.scatter_forward()
        view, source = self.g.x.array.reshape(-1, self.gdim), tmp.x.array.reshape(-1, self.gdim)
        view[self._moving_dofs] = source[self._moving_dofs]
        self.g.x.scatter_forward()

    @property
    def interface_points(self) -> np.ndarray:
        """Reference coordinates (n, gdim) of the owned moving-boundary dofs, in the order of an
        interface vector."""
        return self.dof_points[self.interface_dofs]

    # ---- solve

    def solve(self) -> dolfinx.fem.Function:
        """d: the extension of the boundary data. Solves A d = −A₀ g (Dirichlet rows: d = g)
        with the factorisation kept from the first call."""
        g_vec, d_vec = compat.petsc_vector(self.g), compat.petsc_vector(self.d)
        self._A0.mult(g_vec, self._b)
        self._b.scale(-1.0)
        g_owned = self.g.x.array[self._bc_local]
        self._b.array[self._bc_local] = g_owned
        self._ksp.solve(self._b, d_vec)
        reason = self._ksp.getConvergedReason()
        if reason < 0:
            raise RuntimeError(f"mesh motion: the linear solve failed (KSP reason {reason})")
        self.d.x.array[self._bc_local] = g_owned  # boundary values exactly, not to round-off
        self.d.x.scatter_forward()
        return self.d

    # ---- quality

    def jacobian_ratios(self) -> np.ndarray:
        """J(X + d)/J(X) of the owned cells: signed area (volume) over its reference value (≤ 0:
        inverted)."""
        owned = self._cells[: self._n_owned_cells]
        return signed_areas(self._deformed(), owned) / self.reference_areas[: self._n_owned_cells]

    def min_jacobian_ratio(self) -> tuple[float, np.ndarray]:
        """The smallest J/J_ref over all ranks' cells, and that cell's centroid in X + d."""
        ratios = self.jacobian_ratios()
        if len(ratios):
            i = int(np.argmin(ratios))
            local = (float(ratios[i]), self._deformed()[self._cells[i], : self.gdim].mean(axis=0))
        else:
            local = (np.inf, np.full(self.gdim, np.nan))
        candidates = self.comm.allgather(local)
        ratio, where = min(candidates, key=lambda c: c[0])  # first rank wins a tie
        return ratio, where

    def check_quality(self) -> float:
        """Raise :class:`MeshQualityError` if min J/J_ref of X + d (the mesh :class:`AleMesh`
        would make of d; judged without moving the mesh) is below ``min_jacobian_ratio``;
        return the ratio. Collective."""
        ratio, where = self.min_jacobian_ratio()
        if not ratio >= self.settings.min_jacobian_ratio:  # also catches NaN
            raise MeshQualityError(ratio, where, self.settings.min_jacobian_ratio)
        return ratio

    def _deformed(self) -> np.ndarray:
        x = self.reference.copy()
        x[self._nodes, : self.gdim] += self.d.x.array.reshape(-1, self.gdim)[self._node_dofs]
        return x


class AleMesh:
    """The moving fluid mesh x = X + d(X), d a vector P1 displacement: the one object that
    writes the mesh's coordinates.

    Keeps the reference coordinates X, the displacement ``d`` (a Function on :attr:`space`),
    its accepted levels d^n, d^{n−1} (:attr:`history`) and the mesh velocity ``w``. Build it
    before the mesh first moves. Collective (construction).
    """

    def __init__(self, mesh: dolfinx.mesh.Mesh):
        gdim = mesh.geometry.dim
        self.mesh = mesh
        self.space = compat.function_space(mesh, "Lagrange", 1, (gdim,))
        self.d = dolfinx.fem.Function(self.space, name="mesh_displacement")
        self.w = dolfinx.fem.Function(self.space, name="mesh_velocity")
        self.history = BdfHistory(self.d.x.array)
        self.reference = mesh.geometry.x.copy()
        self._nodes, self._dofs = geometry_node_dofs(self.space)

    def move(self, d: dolfinx.fem.Function | None = None) -> None:
        """Set the displacement (interpolated into P1 if it lives elsewhere) and move the mesh
        to x = X + d; without ``d``, move it to X + (the current) d."""
        if d is not None and d is not self.d:
            if d.function_space == self.space:
                self.d.x.array[:] = d.x.array
            else:
                self.d.interpolate(d)
        self.d.x.scatter_forward()
        gdim = self.mesh.geometry.dim
        values = self.d.x.array.reshape(-1, gdim)
        self.mesh.geometry.x[self._nodes, :gdim] = (
            self.reference[self._nodes, :gdim] + values[self._dofs]
        )

    def set_velocity(self, weights: Sequence[float]) -> None:
        """w = Σ_k a_k d^{n+1−k} (the mesh velocity consistent with the fluid's time scheme)."""
        self.w.x.array[:] = self.history.derivative(weights)

    def advance(self) -> None:
        """Accept the step: d^{n−1} ← d^n, d^n ← d."""
        self.history.advance()

    def save(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Copies of (d, d^n, d^{n−1}, w) (local arrays, owned and ghost entries)."""
        return (self.d.x.array.copy(), *self.history.save(), self.w.x.array.copy())

    def restore(self, d: np.ndarray, d_n: np.ndarray, d_nm1: np.ndarray, w: np.ndarray) -> None:
        """Return to a :meth:`save`'s (d, d^n, d^{n−1}, w) and move the mesh to X + d."""
        self.d.x.array[:] = d
        self.history.restore(d_n, d_nm1)
        self.w.x.array[:] = w
        self.move()
