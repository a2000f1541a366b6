"""The structure solver: total-Lagrangian hyperelastodynamics on Ω₀ (docs/model.md, Structure).

    ρ η̈ − ∇·P = ρ b   in Ω₀,   F = I + ∇η,  P = F (Σ(F) + S_v)   (fsi/physics/materials.py)
    η = 0 (or given) on ΓD,   P N = t₀ (Pa) + nodal forces (N/m) − p J F⁻ᵀ N on Γw1,
    P N = −(k_s η·N + c_s η̇·N) N on ΓN (tissue support,
    :class:`fsi.physics.solid_boundaries.Support`)

in the plane (plane strain, per unit depth) or, ``axisymmetric``, on the meridian half-plane of
a body of revolution (x = z, y = r; F is 3×3 with the hoop stretch 1 + η_r/r, the integrals are
over the whole body and the nodal forces are in N; fsi/physics/solid_residual.py).

:class:`SolidSolver` owns η, its time state, its boundary conditions and Newton (options prefix
``solid_``); the weak form is fsi/physics/solid_residual.py, the stresses
fsi/physics/solid_stress.py, the boundary conditions and loads as data
fsi/physics/solid_boundaries.py.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc
import numpy as np
import ufl

from fsi import compat
from fsi.config import (
    Case,
    Material,
    SolverSettings,
    StenosisGeometry,
    TubeGeometry,
    is_axisymmetric,
)
from fsi.geometry.tags import STRUCTURE_REGIONS, Region
from fsi.numerics.newton import DirichletLifting, Newton, SolveFailed, SolveResult, petsc_options
from fsi.numerics.nullspace import rigid_body_modes
from fsi.numerics.timestepping import NewmarkFamily, structural_scheme
from fsi.physics import mesh as fsi_mesh
from fsi.physics.coordinates import Coordinates
from fsi.physics.mesh import TaggedMesh
from fsi.physics.prestress import StressFreeReference, solve_reference
from fsi.physics.solid_boundaries import (
    DirichletConditions,
    SolidBoundaryConditions,
    boundary_conditions,
    region_materials,
)
from fsi.physics.solid_residual import SolidResidual, material_fields
from fsi.physics.solid_stress import StressFields

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# The structure's mesh: the parent's tags carried over to the submesh


def structure_regions(case: Case) -> tuple[Region, ...]:
    """The regions that make up the structure of ``case``'s geometry."""
    if isinstance(case.geometry, StenosisGeometry):
        return STRUCTURE_REGIONS
    return (Region.WALL,) if isinstance(case.geometry, TubeGeometry) else (Region.FLAG,)


def structure_mesh(tagged: TaggedMesh, regions: Sequence[Region]) -> TaggedMesh:
    """The submesh of ``regions`` of the whole system's mesh, with the parent's tags."""
    return fsi_mesh.restrict(tagged, *regions)


# --------------------------------------------------------------------------------------------
# Results and state


@dataclass
class SolidState:
    """Plain arrays (local, with ghosts) of everything a step depends on: a checkpoint."""

    t: float
    eta: np.ndarray
    eta_n: np.ndarray
    v_n: np.ndarray
    a_n: np.ndarray
    traction: np.ndarray
    traction_n: np.ndarray
    forces: np.ndarray
    forces_n: np.ndarray


class _Problem(dolfinx.fem.petsc.NonlinearProblem):
    """The residual with the interface's nodal forces subtracted (on owned, free dofs); its
    Dirichlet rows as dolfinx's, lifted with the Jacobian's columns only when the iterate is not
    already at the prescribed values (:class:`fsi.numerics.newton.DirichletLifting`)."""

    def __init__(self, F, u, bcs, J, nodal: Callable[[], tuple[np.ndarray, np.ndarray]]):
        super().__init__(F, u, bcs, J=J)
        self._nodal = nodal
        self.residual_norm = math.nan
        self.dirichlet = DirichletLifting(self.a, self.bcs)

    def F(self, x, b):
        with b.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, self.L)
        self.dirichlet.apply(b, x)
        rows, values = self._nodal()
        if len(rows):
            array = b.getArray(readonly=False)
            array[rows] -= values
        self.residual_norm = b.norm()

    def J(self, x, A):
        self.dirichlet.jacobian(A)  # dolfinx's, and the lifting's columns kept


# --------------------------------------------------------------------------------------------
# The solver


DEFAULT_SOLVER = SolverSettings()
"""The structure's Newton settings when none are given (the configuration's defaults)."""


class SolidSolver:
    """Hyperelastodynamics on a tagged structure mesh (see the module docstring).

    Args:
        domain: the structure's mesh with its cell tags (regions) and facet tags (boundaries).
        materials: the material of each region present (density, E, ν, law and the
            Kelvin–Voigt relaxation time τ; the viscous stress is left out when every τ is 0).
        bcs: Dirichlet conditions, interface and loads.
        scheme: the time scheme (newmark, generalized-α or quasi-static).
        degree: Lagrange degree of η (2: P1 locks in bending).
        quadrature_degree: of every integral (4 integrates the P2 SVK residual exactly).
        solver, prefix: Newton tolerances, PETSc options of the linear solves and their prefix.
        axisymmetric: the mesh is the meridian half-plane (x = z, y = r) of a body of
            revolution (fsi/physics/coordinates.py): 3×3 F with the hoop stretch, integrals
            weighted by 2πR; False (the default): plane strain per unit depth.
        prestressed: the mesh is drawn under load, from a stress-free reference
            (``prestress``, fsi/physics/prestress.py; U₀ = 0 until it is computed).

    Parts: ``coordinates`` (:class:`~fsi.physics.coordinates.Coordinates`), ``rho``, ``law``,
    ``viscous`` (:func:`material_fields`), ``dirichlet`` (:class:`DirichletConditions`),
    ``residual`` (:class:`SolidResidual`), ``newton``, ``stress``.
    """

    def __init__(
        self,
        domain: TaggedMesh,
        materials: Mapping[Region, Material],
        bcs: SolidBoundaryConditions,
        scheme: NewmarkFamily,
        *,
        degree: int = 2,
        quadrature_degree: int = 4,
        solver: SolverSettings = DEFAULT_SOLVER,
        prefix: str = "solid_",
        axisymmetric: bool = False,
        prestressed: bool = False,
    ):
        mesh = domain.mesh
        self.domain, self.bcs_data, self.scheme, self.prefix = domain, bcs, scheme, prefix
        self.coordinates = Coordinates(mesh, axisymmetric)
        self.comm: MPI.Comm = mesh.comm
        tdim = mesh.topology.dim
        mesh.topology.create_connectivity(tdim - 1, tdim)
        mesh.topology.create_connectivity(tdim, tdim)  # dofs of cells (dolfinx 0.9)
        self.degree = degree
        self.V = compat.function_space(mesh, "Lagrange", degree, (mesh.geometry.dim,))
        self.t = 0.0  # time of the committed state n
        self.dt = dolfinx.fem.Constant(mesh, PETSc.ScalarType(1.0))

        def function(name: str) -> dolfinx.fem.Function:
            f = dolfinx.fem.Function(self.V)
            f.name = name
            return f

        self.eta = function("eta")  # η_{n+1}, the unknown
        self.eta_n = function("eta_n")
        self.v_n = function("v_n")
        self.a_n = function("a_n")
        self.v = function("v")  # η̇_{n+1}, after a step
        self.a = function("a")  # η̈_{n+1}, after a step
        self.traction = function("traction")  # t₀ at t_{n+1} (first Piola, on the interface)
        self.traction_n = function("traction_n")

        m = material_fields(domain, materials, axisymmetric)
        self.regions, self.rho, self.law, self.viscous = m.regions, m.rho, m.law, m.viscous
        self.Q0, self.cell_region = m.cells, m.cell_region
        self.dirichlet = DirichletConditions(domain, self.V, bcs.dirichlet)
        self._build_interface()
        # The stress-free reference of a geometry drawn under load (U₀ = 0 until computed).
        self.prestress = StressFreeReference(self.V, self.coordinates) if prestressed else None
        self.residual = SolidResidual(self, quadrature_degree)
        self.problem = _Problem(
            self.residual.form, self.eta, self.dirichlet.bcs, self.residual.jacobian, self._nodal
        )
        self.newton = self._newton(solver)
        self.stress = StressFields(self, self.law, self.prestress)
        self._det_F = None

    def _newton(self, settings) -> Newton:
        """The Newton solver of the structure. dolfinx's "residual" test divides by the first
        increment's norm (mixed units), so it tests the increments: converged when
        |δη_k| < atol (m) or |δη_k| < rtol |δη_1|. The Jacobian carries the rigid-body modes as
        its near-nullspace (for a GAMG preset, docs/3d.md)."""
        modes = rigid_body_modes(self.V)
        return Newton(
            self.comm, self.problem, settings, self.prefix, "incremental", near_nullspace=modes
        )

    def _build_interface(self) -> None:
        """The owned interface dofs (the order of every interface vector) and their points."""
        mesh = self.domain.mesh
        self.interface_facets = self.domain.facets(*self.bcs_data.interface)
        dofs = dolfinx.fem.locate_dofs_topological(
            self.V, mesh.topology.dim - 1, self.interface_facets
        )
        self.interface_dofs = dofs[dofs < self.V.dofmap.index_map.size_local]
        gdim = mesh.geometry.dim
        self.interface_points = self.V.tabulate_dof_coordinates()[self.interface_dofs, :gdim]
        bs = self.V.dofmap.index_map_bs
        rows = self.interface_dofs[:, None] * bs + np.arange(bs)
        free = ~np.isin(rows, self.dirichlet.constrained)  # (n, bs): the free components
        self._force_rows = rows[free]
        self._force_free = free
        self.forces = np.zeros((len(self.interface_dofs), bs))
        self.forces_n = np.zeros_like(self.forces)

    def _nodal(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.scheme.at(self.forces, self.forces_n, self.scheme.alpha_f)
        return self._force_rows, f[self._force_free].ravel()

    # -- loads ----------------------------------------------------------------------------

    def set_interface_forces(self, forces: np.ndarray) -> None:
        """Nodal forces at t_{n+1} on the owned interface dofs (an interface vector (n, 2); N/m
        in the plane, N on a whole ring when axisymmetric, as the residual's integrals); entries
        on constrained components are ignored."""
        forces = np.asarray(forces, dtype=float).reshape(self.forces.shape)
        self.forces[:] = forces

    # -- stepping -------------------------------------------------------------------------

    def step(self, t: float, dt: float) -> SolveResult:
        """Solve for η_{n+1} at ``t = t_n + dt`` from the committed state n and the loads set.

        On failure (Newton not converged, a non-finite value, an inverted element or a linear
        solver error) η is put back to its value before the call and ``converged`` is False.
        """
        self.dt.value = dt
        if self.bcs_data.pressure is not None:
            self.residual.pressure.value = self.bcs_data.pressure(t)
            self.residual.pressure_n.value = self.bcs_data.pressure(self.t)
        self.dirichlet.update(t)
        guess = self.eta.x.array.copy()
        result = self.newton.solve(self.eta, lambda: self.problem.residual_norm, step=self.t)
        if result.converged:
            j_min = self.min_jacobian()
            if j_min <= 0:
                self.eta.x.array[:] = guess
                result = replace(
                    result, converged=False, reason=f"inverted element (min det F = {j_min:.3g})"
                )
        if not result.converged:
            log.warning("solid step to t = %g failed: %s", t, result.reason)
        self._update_rates(dt)
        self._t_new = t
        return result

    def _update_rates(self, dt: float) -> None:
        s = self.scheme
        args = (self.eta.x.array, self.eta_n.x.array, self.v_n.x.array, self.a_n.x.array, dt)
        self.v.x.array[:] = s.velocity(*args)
        self.a.x.array[:] = s.acceleration(*args)

    def advance(self) -> None:
        """Commit the last step: state n ← n+1 (η, η̇, η̈, the interface loads, the time)."""
        for new, old in (
            (self.eta, self.eta_n),
            (self.v, self.v_n),
            (self.a, self.a_n),
            (self.traction, self.traction_n),
        ):
            old.x.array[:] = new.x.array
        self.forces_n[:] = self.forces
        self.t = self._t_new

    def save_state(self) -> SolidState:
        """Snapshot of the committed state, the unknown η and the interface loads."""
        return SolidState(
            self.t,
            *(
                f.x.array.copy()
                for f in (self.eta, self.eta_n, self.v_n, self.a_n, self.traction, self.traction_n)
            ),
            self.forces.copy(),
            self.forces_n.copy(),
        )

    def restore_state(self, state: SolidState, warm_start: bool = False) -> None:
        """Return to ``state``. With ``warm_start`` the current η stays as Newton's initial
        guess of the next :meth:`step` (the committed state n is the state's)."""
        guess = self.eta.x.array.copy() if warm_start else None
        self.t = state.t
        for f, values in (
            (self.eta, state.eta),
            (self.eta_n, state.eta_n),
            (self.v_n, state.v_n),
            (self.a_n, state.a_n),
            (self.traction, state.traction),
            (self.traction_n, state.traction_n),
        ):
            f.x.array[:] = values
        self.forces[:] = state.forces
        self.forces_n[:] = state.forces_n
        if guess is not None:
            self.eta.x.array[:] = guess

    def initialize_acceleration(self) -> None:
        """Solve ``M a_n = f_ext(t_n) − f_int(η_n, η̇_n)`` (a_n = 0 on constrained dofs; f_int
        with the viscous stress and the support's force), so that the committed state satisfies
        the equation of motion (e.g. a flag released under gravity)."""
        if self.bcs_data.pressure is not None:
            self.residual.pressure_n.value = self.bcs_data.pressure(self.t)
        mass, force = self.residual.initial_acceleration_forms()
        a_form, L_form = dolfinx.fem.form(mass), dolfinx.fem.form(force)
        homogeneous = self.dirichlet.homogeneous
        M = dolfinx.fem.petsc.assemble_matrix(a_form, bcs=homogeneous)
        M.assemble()
        b = dolfinx.fem.petsc.assemble_vector(L_form)
        array = b.getArray(readonly=False)
        array[self._force_rows] += self.forces_n[self._force_free].ravel()
        dolfinx.fem.petsc.apply_lifting(b, [a_form], [homogeneous])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        dolfinx.fem.petsc.set_bc(b, homogeneous)
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOperators(M)
        ksp.setOptionsPrefix(self.prefix + "mass_")
        with petsc_options(self.prefix + "mass_", self.newton.options):
            ksp.setFromOptions()
            ksp.solve(b, compat.petsc_vector(self.a_n))
        self.a_n.x.scatter_forward()
        for obj in (ksp, M, b):
            obj.destroy()

    # -- outputs --------------------------------------------------------------------------

    def interface_displacement(self) -> np.ndarray:
        """η at the owned interface dofs, (n, dimension), in the order of ``interface_points``."""
        bs = self.V.dofmap.index_map_bs
        return self.eta.x.array.reshape(-1, bs)[self.interface_dofs].copy()

    def _owned_block_values(self, f: dolfinx.fem.Function) -> np.ndarray:
        n = self.V.dofmap.index_map.size_local
        return f.x.array.reshape(-1, self.V.dofmap.index_map_bs)[:n]

    def max_displacement(self, regions: Sequence[Region] | None = None) -> float:
        """max |η| over the dofs (of the cells of ``regions``), over all ranks."""
        return self.max_norm(self.eta, regions)

    def max_norm(self, f: dolfinx.fem.Function, regions: Sequence[Region] | None = None) -> float:
        """max |f| over the dofs (of the cells of ``regions``) of a function of the
        displacement space (η, or the prestress's U₀), over all ranks."""
        values = self._owned_block_values(f)
        if regions is not None:
            dofs = dolfinx.fem.locate_dofs_topological(
                self.V, self.domain.mesh.topology.dim, self.domain.cells(*regions)
            )
            values = values[dofs[dofs < len(values)]]
        local = float(np.sqrt((values**2).sum(axis=1)).max(initial=0.0))
        return float(self.comm.allreduce(local, op=MPI.MAX))

    def min_jacobian(self) -> float:
        """min det F at the cell midpoints (DG0 interpolation; axisymmetric with the hoop
        stretch), over all ranks."""
        if self._det_F is None:
            F = self.residual.deformation_gradient(self.eta)
            self._det_F = (
                dolfinx.fem.Function(self.Q0),
                dolfinx.fem.Expression(ufl.det(F), compat.interpolation_points(self.Q0)),
            )
        J, expression = self._det_F
        J.interpolate(expression)
        n = self.Q0.dofmap.index_map.size_local
        return float(self.comm.allreduce(float(J.x.array[:n].min(initial=np.inf)), op=MPI.MIN))


# --------------------------------------------------------------------------------------------
# Building from a case


def build(
    case: Case,
    tagged: TaggedMesh | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    pressure: Callable[[float], float] | None = None,
    scheme: NewmarkFamily | None = None,
    bcs: SolidBoundaryConditions | None = None,
) -> SolidSolver:
    """The case's structure solver (mesh from ``tagged`` or built; materials, mode, scheme);
    ``bcs`` in place of the case's :func:`boundary_conditions` (a verification case's exact
    data)."""
    if tagged is None:
        tagged = fsi_mesh.build(case, comm)
    domain = structure_mesh(tagged, structure_regions(case))
    s = case.structure
    bcs = bcs or boundary_conditions(case, pressure)

    def solver(bcs: SolidBoundaryConditions, scheme: NewmarkFamily) -> SolidSolver:
        return SolidSolver(
            domain,
            region_materials(case),
            bcs,
            scheme,
            degree=s.degree,
            quadrature_degree=s.quadrature_degree,
            solver=s.solver,
            axisymmetric=is_axisymmetric(case.geometry),
            prestressed=s.prestress is not None,
        )

    structure = solver(bcs, scheme or structural_scheme(s.time_integration))
    if s.prestress is not None:
        # The stress-free reference under the prestress pressure alone, quasi-static.
        reference_pressure = s.prestress.pressure
        loaded = solver(
            replace(bcs, pressure=lambda t: reference_pressure * t), NewmarkFamily.quasi_static()
        )
        result = solve_reference(loaded, s.prestress.load_steps)
        if not result.converged:
            raise SolveFailed(
                f"structure.prestress: no stress-free reference found for "
                f"{reference_pressure:g} Pa (the solve failed at {result.iterations} of "
                f"{s.prestress.load_steps} load steps; try more load_steps)"
            )
        structure.prestress.offset.x.array[:] = loaded.prestress.offset.x.array
        log.info(
            "structure.prestress: the stress-free reference of %g Pa is %.3g m from the drawn "
            "geometry at most",
            reference_pressure,
            result.mismatch,
        )
    structure.stress.update()  # the start's stresses (a prestressed wall's), for t = 0's output
    return structure
