"""Total-Lagrangian hyperelastodynamics of the structure (../shared/MODEL.md §3).

On the structure's reference configuration Ω₀ (wall + cap + lipid of the stenosis, or the
Turek–Hron flag) find the displacement η with::

    ρ η̈ − ∇·P = ρ b               in Ω₀,     F = I + ∇η,  P = F (Σ(F) + S_v)
    η = 0 (or a given η)           on ΓD       (clamped; every wall dof in the fixed-wall mode)
    P N = t₀ + nodal forces − p J F⁻ᵀ N  on the interface Γw1
    P N = −(k_s η·N + c_s η̇·N) N   on ΓN       (tissue support; 0 and 0: traction-free)

with per-region hyperelastic laws (fsi/physics/materials.py), the per-region Kelvin–Voigt viscous
stress ``S_v = τ (λ tr Ė I + 2μ Ė)``, ``Ė = sym(Fᵀ ∇η̇)`` (relaxation time τ ≥ 0, 0 by default;
a small-amplitude mode of angular frequency ω then has the damping ratio ωτ/2), the external
tissue's spring–dashpot support of Moireau et al. (2012) on the exterior ΓN, normal direction
only (stiffness k_s, Pa/m, and damping c_s, Pa·s/m, per unit reference length; see
docs/wall-damping.md), a traction ``t₀`` per unit *reference*
length (first Piola traction; a fluid's Cauchy traction σ n on the deformed interface is
``t₀ = J σ F⁻ᵀ N``), nodal interface forces (a fluid's residual-based reaction forces) and an
optional follower pressure ``p``. Discretised with vector Lagrange elements (P2 by default) and
marched in time by the Newmark family of fsi/numerics/timestepping.py, in the energy-momentum form::

    ∫ ρ a_{n+1-αm}·δη + F_{n+1-αf} Σ_{n+1-αf} : ∇δη dx = ∫ ρ b·δη dx + ∫ t₀_{n+1-αf}·δη ds + ...

with ``Σ_{n+1-αf} = (1 − αf) Σ(F_{n+1}) + αf Σ(F_n)`` (Kuhl & Ramm's generalized
energy-momentum method): for St. Venant–Kirchhoff and αf = 1/2 (the trapezoidal rule) the
stress work equals the stored-energy increment exactly, so the discrete energy is conserved;
for linear problems this is the classical Newmark/Chung–Hulbert scheme. The damping terms
enter at the same point::

    ... + ∫ F_{n+1-αf} S_v(F̄, ∇η̇_{n+1-αf}) : ∇δη dx
        + ∫_ΓN (k_s η_{n+1-αf}·N + c_s η̇_{n+1-αf}·N)(δη·N) ds

with ``η̇_{n+1}`` the scheme's velocity of η_{n+1} (so the Jacobian holds their derivatives,
and linearised this is the Chung–Hulbert scheme for ``M a + C v + K η = f``) and the strain
rate pulled back with the mid-step ``F̄ = (F_{n+1} + F_n)/2``: whenever ``η̇_{n+1-αf}`` is the
difference quotient ``(η_{n+1} − η_n)/dt`` — the trapezoidal rule, and the quasi-static scheme,
whose velocity is that backward difference — ``sym(F̄ᵀ ∇η̇) = (E_{n+1} − E_n)/dt`` exactly, so
a rigid motion of any size makes no viscous stress and (trapezoidal rule) the viscous work of a
step, ``∫ S_v : (E_{n+1} − E_n) dx``, is ≥ 0: the energy-momentum scheme stays exact, energy
only leaves through the dampers. In the quasi-static scheme (no inertia, balance at t_{n+1})
the viscous stress is backward Euler's ``τ C : (E_{n+1} − E_n)/dt``: a creep law, negligible
when τ ≪ dt.

Newton's method is dolfinx's NonlinearProblem/NewtonSolver (options prefix ``solid_``). The
coupler drives a :class:`SolidSolver` through ``step`` / ``advance`` / ``save_state`` /
``restore_state`` and the interface vectors (owned interface dofs, shape (n, 2)).
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
from fsi.config import Case, Material, SolverSettings, StenosisGeometry
from fsi.numerics.newton import Newton, SolveFailed, SolveResult, petsc_options
from fsi.numerics.timestepping import NewmarkFamily, structural_scheme
from fsi.physics import mesh as fsi_mesh
from fsi.physics.materials import HyperelasticLaw, KelvinVoigt, cauchy, cauchy_zz, lame, make_law
from fsi.physics.mesh import TaggedMesh
from geometry.tags import STRUCTURE_REGIONS, Boundary, Region

log = logging.getLogger(__name__)

DisplacementValue = Callable[[np.ndarray, float], np.ndarray]
"""``value(x, t)``: x of shape (3, n) → displacement of shape (2, n)."""


# --------------------------------------------------------------------------------------------
# The structure's mesh: the parent's tags carried over to the submesh


def structure_regions(case: Case) -> tuple[Region, ...]:
    """The regions that make up the structure of ``case``'s geometry."""
    return STRUCTURE_REGIONS if isinstance(case.geometry, StenosisGeometry) else (Region.FLAG,)


def structure_mesh(tagged: TaggedMesh, regions: Sequence[Region]) -> TaggedMesh:
    """The submesh of ``regions`` of the whole system's mesh, with the parent's tags."""
    return fsi_mesh.restrict(tagged, *regions)


# --------------------------------------------------------------------------------------------
# Boundary conditions and loads as data


@dataclass(frozen=True)
class Clamp:
    """η = 0 on the facets of ``boundaries``."""

    boundaries: tuple[Boundary, ...] = (Boundary.CLAMPED,)


@dataclass(frozen=True)
class HoldRegions:
    """η = 0 on every dof of the cells of ``regions`` (the fixed-wall mode holds the wall)."""

    regions: tuple[Region, ...] = (Region.WALL,)


@dataclass(frozen=True)
class PrescribedDisplacement:
    """η = ``value(x, t)`` on ``boundaries`` (``None``: the whole boundary of the structure)."""

    value: DisplacementValue
    boundaries: tuple[Boundary, ...] | None = None


Dirichlet = Clamp | HoldRegions | PrescribedDisplacement


@dataclass(frozen=True)
class Support:
    """The surrounding tissue as a spring–dashpot on ``boundaries`` (a Robin condition,
    Moireau et al. 2012), normal direction only::

        P N = −(k_s η·N + c_s η̇·N) N     (first Piola traction, per reference length)

    ``stiffness`` k_s (Pa/m), ``damping`` c_s (Pa·s/m), N the reference outward normal.
    Normal only: the tissue around an artery resists its radial motion (it is compressed or
    pulled), while the wall slides along it almost freely; the axial motion is in any case
    held by the clamped ends here. It is also what svMultiPhysics' "apply along normal
    direction" Robin condition does."""

    stiffness: float = 0.0
    damping: float = 0.0
    boundaries: tuple[Boundary, ...] = (Boundary.EXTERIOR,)


@dataclass(frozen=True)
class SolidBoundaryConditions:
    """Dirichlet conditions, the interface where the fluid's loads act, and the loads.

    ``body_force``: force per unit mass (gravity), m/s². ``pressure(t)``: a follower pressure on
    the interface (Pa; its traction is ``−p J F⁻ᵀ N`` per reference length). ``source(x)``: a
    force per unit reference volume as a UFL expression of the spatial coordinate (for
    manufactured solutions). ``support``: the tissue's spring–dashpot on the exterior.
    Everything not named is traction-free.
    """

    dirichlet: tuple[Dirichlet, ...] = (Clamp(),)
    interface: tuple[Boundary, ...] = (Boundary.INTERFACE,)
    body_force: tuple[float, float] = (0.0, 0.0)
    pressure: Callable[[float], float] | None = None
    source: Callable[[ufl.SpatialCoordinate], ufl.core.expr.Expr] | None = None
    support: Support | None = None


def boundary_conditions(
    case: Case, pressure: Callable[[float], float] | None = None
) -> SolidBoundaryConditions:
    """The case's conditions: ``moving_wall`` clamps ΓD (the wall ends, or the flag's joint);
    ``fixed_wall`` also holds every dof of the vessel wall, so only the plaque moves.

    ``structure.support`` (if not 0 and 0) supports the stenosis wall's exterior ΓN; in the
    fixed-wall mode ΓN belongs to the held wall and the term has no effect. The Turek–Hron
    flag has no ΓN: there it is ignored, with a warning."""
    s = case.structure
    if s.mode == "rigid":
        raise ValueError("structure.mode 'rigid' has no structure to solve")
    dirichlet: tuple[Dirichlet, ...] = (Clamp((Boundary.CLAMPED,)),)
    stenosis = isinstance(case.geometry, StenosisGeometry)
    if s.mode == "fixed_wall" and stenosis:
        dirichlet += (HoldRegions((Region.WALL,)),)
    support = None
    if s.support.stiffness > 0 or s.support.damping > 0:
        if stenosis:
            support = Support(s.support.stiffness, s.support.damping, (Boundary.EXTERIOR,))
        else:
            log.warning(
                "structure.support is ignored: geometry.kind '%s' has no exterior boundary",
                case.geometry.kind,
            )
    return SolidBoundaryConditions(
        dirichlet=dirichlet, body_force=tuple(s.body_force), pressure=pressure, support=support
    )


def region_materials(case: Case) -> dict[Region, Material]:
    s = case.structure
    return {Region.WALL: s.wall, Region.CAP: s.cap, Region.LIPID: s.lipid, Region.FLAG: s.flag}


# --------------------------------------------------------------------------------------------
# Per-region laws


@dataclass(frozen=True)
class RegionwiseLaw:
    """Several laws on disjoint regions: ``Σ = Σ_k χ_k Σ_k(F)`` with DG0 indicators χ_k."""

    parts: tuple[tuple[object, HyperelasticLaw], ...]
    name: str = "regionwise"

    def _sum(self, method: str, F):
        return sum(chi * getattr(law, method)(F) for chi, law in self.parts)

    def strain_energy(self, F):
        return self._sum("strain_energy", F)

    def second_piola(self, F):
        return self._sum("second_piola", F)

    def second_piola_zz(self, F):
        return self._sum("second_piola_zz", F)


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
    """The residual with the interface's nodal forces subtracted (on owned, free dofs)."""

    def __init__(self, F, u, bcs, J, nodal: Callable[[], tuple[np.ndarray, np.ndarray]]):
        super().__init__(F, u, bcs, J=J)
        self._nodal = nodal
        self.residual_norm = math.nan

    def F(self, x, b):
        super().F(x, b)
        rows, values = self._nodal()
        if len(rows):
            array = b.getArray(readonly=False)
            array[rows] -= values
        self.residual_norm = b.norm()


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
        solver: Newton tolerances and the PETSc options of the linear solves.
        prefix: PETSc options prefix of the Newton's linear solver.
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
    ):
        mesh = domain.mesh
        self.domain, self.bcs_data, self.scheme, self.prefix = domain, bcs, scheme, prefix
        self.comm: MPI.Comm = mesh.comm
        tdim = mesh.topology.dim
        mesh.topology.create_connectivity(tdim - 1, tdim)
        mesh.topology.create_connectivity(tdim, tdim)  # dofs of cells (dolfinx 0.9)
        self.degree = degree
        self.V = compat.function_space(mesh, "Lagrange", degree, (mesh.geometry.dim,))
        self.t = 0.0  # time of the committed state n
        self._dt = dolfinx.fem.Constant(mesh, PETSc.ScalarType(1.0))

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

        self._build_materials(materials)
        self._build_dirichlet()
        self._build_interface()
        self._build_forms(quadrature_degree)
        self._build_newton(solver)
        self.stress = StressFields(self, self.law)
        self._jacobian = None
        self._energy_forms = None

    # -- set-up ---------------------------------------------------------------------------

    def _build_materials(self, materials: Mapping[Region, Material]) -> None:
        mesh, tags = self.domain.mesh, self.domain.cell_tags
        present = [
            int(r) for r in np.unique(np.concatenate(self.comm.allgather(np.unique(tags.values))))
        ]
        missing = [r for r in present if Region(r) not in materials]
        if missing:
            raise ValueError(f"no material for regions {[Region(r).label for r in missing]}")
        self.regions = tuple(Region(r) for r in present)
        Q = compat.function_space(mesh, "DG", 0)
        dofs = compat.cell_dofs(Q)[:, 0]

        def dg0(values_by_region: Mapping[int, float], name: str) -> dolfinx.fem.Function:
            f = dolfinx.fem.Function(Q)
            f.name = name
            f.x.array[dofs[tags.indices]] = [values_by_region.get(int(v), 0.0) for v in tags.values]
            f.x.scatter_forward()
            return f

        mats = {r: materials[Region(r)] for r in present}
        lmbda_mu = {r: lame(m.young_modulus, m.poisson_ratio) for r, m in mats.items()}
        self.rho = dg0({r: m.density for r, m in mats.items()}, "density")
        lmbda = dg0({r: lm[0] for r, lm in lmbda_mu.items()}, "lambda")
        mu = dg0({r: lm[1] for r, lm in lmbda_mu.items()}, "mu")
        laws = sorted({m.law for m in mats.values()})
        if len(laws) == 1:
            self.law: HyperelasticLaw = make_law(laws[0], lmbda, mu)
        else:
            parts = tuple(
                (
                    dg0({r: 1.0 for r, m in mats.items() if m.law == name}, f"chi_{name}"),
                    make_law(name, lmbda, mu),
                )
                for name in laws
            )
            self.law = RegionwiseLaw(parts)
        # Kelvin–Voigt, stiffness-proportional per region: λ_v = τλ, μ_v = τμ (DG0). Left out
        # of the forms when every τ is 0, so the elastic residual is unchanged bit for bit.
        tau = {r: m.viscous_relaxation_time for r, m in mats.items()}
        self.viscous: KelvinVoigt | None = None
        if any(value > 0 for value in tau.values()):
            self.viscous = KelvinVoigt.stiffness_proportional(
                dg0(tau, "viscous_relaxation_time"), lmbda, mu
            )
        self.Q0 = Q
        self._cell_region = np.full(len(dofs), -1, dtype=np.int32)
        self._cell_region[tags.indices] = tags.values

    def _facets(self, boundaries: Sequence[Boundary] | None) -> np.ndarray:
        mesh = self.domain.mesh
        if boundaries is None:
            return dolfinx.mesh.exterior_facet_indices(mesh.topology)
        return self.domain.facets(*boundaries)

    def _build_dirichlet(self) -> None:
        mesh = self.domain.mesh
        tdim = mesh.topology.dim
        self._bcs, self._prescribed = [], []
        constrained = []
        zero = np.zeros(mesh.geometry.dim, dtype=PETSc.ScalarType)
        for item in self.bcs_data.dirichlet:
            if isinstance(item, HoldRegions):
                dofs = dolfinx.fem.locate_dofs_topological(
                    self.V, tdim, self.domain.cells(*item.regions)
                )
                self._bcs.append(dolfinx.fem.dirichletbc(zero, dofs, self.V))
            elif isinstance(item, Clamp):
                dofs = dolfinx.fem.locate_dofs_topological(
                    self.V, tdim - 1, self._facets(item.boundaries)
                )
                self._bcs.append(dolfinx.fem.dirichletbc(zero, dofs, self.V))
            elif isinstance(item, PrescribedDisplacement):
                dofs = dolfinx.fem.locate_dofs_topological(
                    self.V, tdim - 1, self._facets(item.boundaries)
                )
                g = dolfinx.fem.Function(self.V)
                self._bcs.append(dolfinx.fem.dirichletbc(g, dofs))
                self._prescribed.append((item.value, g))
            else:  # pragma: no cover
                raise TypeError(f"unknown Dirichlet condition {item!r}")
            constrained.append(dofs)
        self._constrained = (
            np.unique(np.concatenate(constrained)) if constrained else np.zeros(0, dtype=np.int32)
        )
        self._homogeneous = [
            dolfinx.fem.dirichletbc(zero, bc_dofs, self.V) for bc_dofs in constrained
        ]

    def _build_interface(self) -> None:
        """The owned interface dofs (the order of every interface vector) and their points."""
        mesh = self.domain.mesh
        self.interface_facets = self.domain.facets(*self.bcs_data.interface)
        dofs = dolfinx.fem.locate_dofs_topological(
            self.V, mesh.topology.dim - 1, self.interface_facets
        )
        self.interface_dofs = dofs[dofs < self.V.dofmap.index_map.size_local]
        self.interface_points = self.V.tabulate_dof_coordinates()[self.interface_dofs, :2]
        free = ~np.isin(self.interface_dofs, self._constrained)
        bs = self.V.dofmap.index_map_bs
        self._force_rows = (self.interface_dofs[free, None] * bs + np.arange(bs)).ravel()
        self._force_free = free
        self.forces = np.zeros((len(self.interface_dofs), bs))
        self.forces_n = np.zeros_like(self.forces)

    def _build_forms(self, quadrature_degree: int) -> None:
        """The residual of the balance of momentum at n+1−αf (:attr:`residual_form`: stress,
        inertia, loads, pressure and support) and its Jacobian in η (:attr:`jacobian_form`)."""
        mesh, s = self.domain.mesh, self.scheme
        self._build_measures(quadrature_degree)
        ds_interface = self._ds_interface
        d = mesh.geometry.dim
        I = ufl.Identity(d)
        deta = ufl.TestFunction(self.V)
        af = s.alpha_f
        F_new, F_old = I + ufl.grad(self.eta), I + ufl.grad(self.eta_n)
        residual, v_alpha = self._stress_residual(F_new, F_old, deta)
        self._gravity = dolfinx.fem.Constant(
            mesh, np.asarray(self.bcs_data.body_force, dtype=PETSc.ScalarType)
        )
        residual -= self.rho * ufl.inner(self._gravity, deta) * self.dx
        if self.bcs_data.source is not None:
            residual -= ufl.inner(self.bcs_data.source(ufl.SpatialCoordinate(mesh)), deta) * self.dx
        residual -= ufl.inner(s.at(self.traction, self.traction_n, af), deta) * ds_interface
        self._pressure = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        self._pressure_n = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        if self.bcs_data.pressure is not None:
            N = ufl.FacetNormal(mesh)
            F_a = s.at(F_new, F_old, af)
            p_a = s.at(self._pressure, self._pressure_n, af)
            residual += p_a * ufl.inner(ufl.det(F_a) * ufl.inv(F_a).T * N, deta) * ds_interface
        support_term = self._support_residual(v_alpha, deta)
        if support_term is not None:
            residual += support_term
        self.residual_form = residual
        self.jacobian_form = ufl.derivative(residual, self.eta, ufl.TrialFunction(self.V))

    def _build_measures(self, quadrature_degree: int) -> None:
        """The measures :attr:`dx` and :attr:`ds` (with the cell and facet tags) and the
        interface's ``ds``, all at ``quadrature_degree``."""
        mesh = self.domain.mesh
        metadata = {"quadrature_degree": quadrature_degree}
        self.dx = ufl.Measure(
            "dx", domain=mesh, subdomain_data=self.domain.cell_tags, metadata=metadata
        )
        self.ds = ufl.Measure(
            "ds", domain=mesh, subdomain_data=self.domain.facet_tags, metadata=metadata
        )
        ds_interface = sum(
            (self.ds(int(b)) for b in self.bcs_data.interface[1:]),
            self.ds(int(self.bcs_data.interface[0])),
        )
        self._ds_interface = ds_interface

    def _stress_residual(self, F_new, F_old, deta):
        """The stress (elastic, plus Kelvin–Voigt if any) and inertia terms of the residual at
        n+1−αf, and the velocity η̇ at n+1−αf."""
        s, law = self.scheme, self.law
        af, am = s.alpha_f, s.alpha_m
        # Generalized energy-momentum stress: F at n+1-αf times the interpolated Σ.
        S_alpha = s.at(law.second_piola(F_new), law.second_piola(F_old), af)
        # η̇ at n+1-αf, with η̇_{n+1} the scheme's function of the unknown η_{n+1}.
        v_alpha = s.at(s.velocity(self.eta, self.eta_n, self.v_n, self.a_n, self._dt), self.v_n, af)
        if self.viscous is not None:
            # The rate pulled back with the mid-step F̄: Ė = (E_{n+1} − E_n)/dt exactly when
            # η̇_{n+1-αf} = (η_{n+1} − η_n)/dt (trapezoidal, quasi-static): see the docstring.
            S_alpha = S_alpha + self.viscous.second_piola(
                s.at(F_new, F_old, 0.5), ufl.grad(v_alpha)
            )
        P_alpha = s.at(F_new, F_old, af) * S_alpha
        residual = ufl.inner(P_alpha, ufl.grad(deta)) * self.dx
        if s.dynamic:
            a_new = s.acceleration(self.eta, self.eta_n, self.v_n, self.a_n, self._dt)
            residual += self.rho * ufl.inner(s.at(a_new, self.a_n, am), deta) * self.dx
        return residual, v_alpha

    def _support_residual(self, v_alpha, deta):
        """The elastic support's term of the residual, or None without a support; its
        constants, normal and measure go to :attr:`_support` (None without one)."""
        mesh, s = self.domain.mesh, self.scheme
        support = self.bcs_data.support
        self._support = None
        if support is None:
            return None
        # P N = −(k_s η·N + c_s η̇·N) N on the supported boundary, at n+1-αf.
        N = ufl.FacetNormal(mesh)
        k_s = dolfinx.fem.Constant(mesh, PETSc.ScalarType(support.stiffness))
        c_s = dolfinx.fem.Constant(mesh, PETSc.ScalarType(support.damping))
        ds_support = sum(
            (self.ds(int(b)) for b in support.boundaries[1:]),
            self.ds(int(support.boundaries[0])),
        )
        self._support = (k_s, c_s, N, ds_support)
        eta_alpha = s.at(self.eta, self.eta_n, s.alpha_f)
        return (
            (k_s * ufl.dot(eta_alpha, N) + c_s * ufl.dot(v_alpha, N))
            * ufl.dot(deta, N)
            * ds_support
        )

    def _nodal(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.scheme.at(self.forces, self.forces_n, self.scheme.alpha_f)
        return self._force_rows, f[self._force_free].ravel()

    def _build_newton(self, settings: SolverSettings) -> None:
        self.problem = _Problem(
            self.residual_form, self.eta, self._bcs, self.jacobian_form, self._nodal
        )
        # dolfinx's "residual" test divides by the first increment's norm (mixed units), so test
        # the increments: converged when |δη_k| < atol (m) or |δη_k| < rtol |δη_1|.
        self.newton = Newton(self.comm, self.problem, settings, self.prefix, "incremental")

    # -- loads ----------------------------------------------------------------------------

    def set_interface_forces(self, forces: np.ndarray) -> None:
        """Nodal forces at t_{n+1} on the owned interface dofs (an interface vector (n, 2), N/m);
        entries on clamped dofs are ignored."""
        forces = np.asarray(forces, dtype=float).reshape(self.forces.shape)
        self.forces[:] = forces

    def set_interface_traction(self, traction: np.ndarray | dolfinx.fem.Function) -> None:
        """The first Piola traction t₀ at t_{n+1}: a Function on the displacement space, or an
        interface vector (n, 2) of its values at the owned interface dofs (Pa)."""
        if isinstance(traction, dolfinx.fem.Function):
            self.traction.x.array[:] = traction.x.array
        else:
            values = self.traction.x.array.reshape(-1, self.V.dofmap.index_map_bs)
            values[self.interface_dofs] = np.asarray(traction).reshape(-1, values.shape[1])
            self.traction.x.scatter_forward()

    def set_body_force(self, g: Sequence[float]) -> None:
        """Force per unit mass (m/s²), e.g. to ramp gravity in a static solve."""
        self._gravity.value[:] = np.asarray(g, dtype=float)

    # -- stepping -------------------------------------------------------------------------

    def step(self, t: float, dt: float) -> SolveResult:
        """Solve for η_{n+1} at ``t = t_n + dt`` from the committed state n and the loads set.

        On failure (Newton not converged, a non-finite value, an inverted element or a linear
        solver error) η is put back to its value before the call and ``converged`` is False.
        """
        self._dt.value = dt
        if self.bcs_data.pressure is not None:
            self._pressure.value = self.bcs_data.pressure(t)
            self._pressure_n.value = self.bcs_data.pressure(self.t)
        for value, g in self._prescribed:
            g.interpolate(lambda x, value=value: value(x, t))
            g.x.scatter_forward()  # a ghost dof may lie in no local cell of a submesh
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
        return SolidState(
            self.t,
            *(
                f.x.array.copy()
                for f in (self.eta, self.eta_n, self.v_n, self.a_n, self.traction, self.traction_n)
            ),
            self.forces.copy(),
            self.forces_n.copy(),
        )

    def restore_state(self, state: SolidState) -> None:
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

    def set_initial_conditions(
        self, eta0: Callable | None = None, v0: Callable | None = None
    ) -> None:
        """Initial displacement and velocity (callables of x (3, n) → (2, n)); the initial
        acceleration is then made consistent with the loads: :meth:`initialize_acceleration`."""
        for f, value in ((self.eta_n, eta0), (self.v_n, v0)):
            if value is not None:
                f.interpolate(value)
                f.x.scatter_forward()
        self.eta.x.array[:] = self.eta_n.x.array
        if self.scheme.dynamic:
            self.initialize_acceleration()

    def initialize_acceleration(self) -> None:
        """Solve ``M a_n = f_ext(t_n) − f_int(η_n, η̇_n)`` (a_n = 0 on constrained dofs; f_int
        with the viscous stress and the support's force), so that the committed state satisfies
        the equation of motion (e.g. a flag released under gravity)."""
        mesh, I = self.domain.mesh, ufl.Identity(self.domain.mesh.geometry.dim)
        deta, da = ufl.TestFunction(self.V), ufl.TrialFunction(self.V)
        F = I + ufl.grad(self.eta_n)
        S = self.law.second_piola(F)
        if self.viscous is not None:
            S = S + self.viscous.second_piola(F, ufl.grad(self.v_n))
        rhs = -ufl.inner(F * S, ufl.grad(deta)) * self.dx
        if self._support is not None:
            k_s, c_s, N, ds_support = self._support
            rhs -= (
                (k_s * ufl.dot(self.eta_n, N) + c_s * ufl.dot(self.v_n, N))
                * ufl.dot(deta, N)
                * ds_support
            )
        rhs += self.rho * ufl.inner(self._gravity, deta) * self.dx
        rhs += ufl.inner(self.traction_n, deta) * self._ds_interface
        if self.bcs_data.source is not None:
            rhs += ufl.inner(self.bcs_data.source(ufl.SpatialCoordinate(mesh)), deta) * self.dx
        if self.bcs_data.pressure is not None:
            N = ufl.FacetNormal(mesh)
            self._pressure_n.value = self.bcs_data.pressure(self.t)
            rhs -= (
                self._pressure_n
                * ufl.inner(ufl.det(F) * ufl.inv(F).T * N, deta)
                * self._ds_interface
            )
        mass = self.rho * ufl.inner(da, deta) * self.dx
        a_form, L_form = dolfinx.fem.form(mass), dolfinx.fem.form(rhs)
        M = dolfinx.fem.petsc.assemble_matrix(a_form, bcs=self._homogeneous)
        M.assemble()
        b = dolfinx.fem.petsc.assemble_vector(L_form)
        array = b.getArray(readonly=False)
        f = self.forces_n[self._force_free].ravel()
        array[self._force_rows] += f
        dolfinx.fem.petsc.apply_lifting(b, [a_form], [self._homogeneous])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        dolfinx.fem.petsc.set_bc(b, self._homogeneous)
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
        """η at the owned interface dofs, (n, 2), in the order of ``interface_points``."""
        return self.eta.x.array.reshape(-1, 2)[self.interface_dofs].copy()

    def interface_velocity(self) -> np.ndarray:
        """η̇_{n+1} of the last step at the owned interface dofs, (n, 2)."""
        return self.v.x.array.reshape(-1, 2)[self.interface_dofs].copy()

    def _owned_block_values(self, f: dolfinx.fem.Function) -> np.ndarray:
        n = self.V.dofmap.index_map.size_local
        return f.x.array.reshape(-1, 2)[:n]

    def max_displacement(self, regions: Sequence[Region] | None = None) -> float:
        """max |η| over the dofs (of the cells of ``regions``), over all ranks."""
        values = self._owned_block_values(self.eta)
        if regions is not None:
            dofs = dolfinx.fem.locate_dofs_topological(
                self.V, self.domain.mesh.topology.dim, self.domain.cells(*regions)
            )
            values = values[dofs[dofs < len(values)]]
        local = float(np.sqrt((values**2).sum(axis=1)).max(initial=0.0))
        return float(self.comm.allreduce(local, op=MPI.MAX))

    def min_jacobian(self) -> float:
        """min det F at the cell midpoints (DG0 interpolation), over all ranks."""
        if self._jacobian is None:
            F = ufl.Identity(2) + ufl.grad(self.eta)
            self._jacobian = (
                dolfinx.fem.Function(self.Q0),
                dolfinx.fem.Expression(ufl.det(F), compat.interpolation_points(self.Q0)),
            )
        J, expression = self._jacobian
        J.interpolate(expression)
        n = self.Q0.dofmap.index_map.size_local
        return float(self.comm.allreduce(float(J.x.array[:n].min(initial=np.inf)), op=MPI.MIN))

    def energies(self) -> tuple[float, float]:
        """Kinetic and stored energy of the committed state n, ``½∫ρ|η̇|²`` and ``∫W(F)`` (J/m)."""
        if self._energy_forms is None:
            F = ufl.Identity(2) + ufl.grad(self.eta_n)
            self._energy_forms = [
                dolfinx.fem.form(0.5 * self.rho * ufl.inner(self.v_n, self.v_n) * self.dx),
                dolfinx.fem.form(self.law.strain_energy(F) * self.dx),
            ]
        kinetic, stored = (
            float(self.comm.allreduce(dolfinx.fem.assemble_scalar(form), op=MPI.SUM))
            for form in self._energy_forms
        )
        return kinetic, stored


class CoupledSolid:
    """The solid as the coupler's interface solver (fsi.coupled.coupling.InterfaceSolver).

    ``solve(load)`` takes the fluid's interface load at t_{n+1} as a flat interface vector
    (``"forces"``: nodal forces, N/m; ``"traction"``: first Piola traction values, Pa), solves
    the step set by :meth:`begin_step` and returns the interface displacement, flat. A failed
    solve raises :class:`SolveFailed`. ``restore_state`` goes back to the start of the step but,
    with ``warm_start``, keeps the last iterate of η as Newton's initial guess.
    """

    def __init__(self, solver: SolidSolver, load: str = "forces", warm_start: bool = True):
        if load not in ("forces", "traction"):
            raise ValueError(f"load must be 'forces' or 'traction', got {load!r}")
        self.solver, self.load, self.warm_start = solver, load, warm_start
        self.t, self.dt = math.nan, math.nan
        self.last: SolveResult | None = None
        self._checkpoint: SolidState | None = None

    def begin_step(self, t: float, dt: float) -> None:
        self.t, self.dt = t, dt

    def save_state(self) -> None:
        self._checkpoint = self.solver.save_state()

    def restore_state(self) -> None:
        if self._checkpoint is None:
            raise RuntimeError("restore_state before save_state")
        guess = self.solver.eta.x.array.copy()
        self.solver.restore_state(self._checkpoint)
        if self.warm_start:
            self.solver.eta.x.array[:] = guess

    def solve(self, interface_input: np.ndarray) -> np.ndarray:
        if not math.isfinite(self.dt):
            raise RuntimeError("call begin_step(t, dt) before solve")
        values = np.asarray(interface_input).reshape(-1, 2)
        if self.load == "forces":
            self.solver.set_interface_forces(values)
        else:
            self.solver.set_interface_traction(values)
        self.last = self.solver.step(self.t, self.dt)
        if not self.last.converged:
            raise SolveFailed(
                f"structure step to t = {self.t:g} s failed: {self.last.reason}"
                f" (residual {self.last.residual:.3g})"
            )
        return self.solver.interface_displacement().ravel()

    def velocity(self) -> np.ndarray:
        """η̇_{n+1} at the interface (flat), for the fluid's kinematic condition u = η̇."""
        return self.solver.interface_velocity().ravel()

    def advance(self) -> None:
        self.solver.advance()


# --------------------------------------------------------------------------------------------
# Stresses


@dataclass(frozen=True)
class RegionStress:
    """Maxima over one region (Pa): von Mises, largest principal, largest |σ₁₂| (the SSS)."""

    max_von_mises: float
    max_principal: float
    max_abs_shear: float


class StressFields:
    """Cauchy stress of the current η as DG fields, and their per-region maxima.

    ``σ = J⁻¹ P Fᵀ`` (in-plane) on the current configuration, plane strain with
    ``σ₃₃ = J⁻¹ Σ₃₃``; the study's structural shear stress ``σ₁₂``; von Mises
    ``sqrt(((σ₁₁−σ₂₂)² + (σ₂₂−σ₃₃)² + (σ₃₃−σ₁₁)²)/2 + 3σ₁₂²)``; the largest principal stress
    ``max((σ₁₁+σ₂₂)/2 + sqrt(((σ₁₁−σ₂₂)/2)² + σ₁₂²), σ₃₃)``. Fields are interpolated into DG
    of degree ``max(k − 1, 0)`` for P``k`` displacements (the degree of ∇η), at its points.

    :attr:`cell_fields` are what the field files hold (XDMF stores one value per cell): each
    cell's extreme of the fields above (``sss``: the value of largest magnitude, sign kept;
    ``von_mises`` and ``max_principal``: the largest), so their maxima over a region are the
    :meth:`region_maxima`; and ``region``, the cell's region tag (geometry/tags.py ``Region``).
    """

    def __init__(self, solver: SolidSolver, law: HyperelasticLaw):
        self.solver = solver
        mesh = solver.domain.mesh
        degree = max(solver.degree - 1, 0)
        self.S = compat.function_space(mesh, "DG", degree)
        self.T = compat.function_space(mesh, "DG", degree, (2, 2))
        F = ufl.Identity(2) + ufl.grad(solver.eta)
        sigma = cauchy(law, F)
        s33 = cauchy_zz(law, F)
        s11, s22, s12 = sigma[0, 0], sigma[1, 1], sigma[0, 1]
        von_mises = ufl.sqrt(
            ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2) / 2 + 3 * s12**2
        )
        in_plane = (s11 + s22) / 2 + ufl.sqrt(((s11 - s22) / 2) ** 2 + s12**2)
        principal = ufl.max_value(in_plane, s33)
        self.sigma = dolfinx.fem.Function(self.T)
        self.sigma.name = "sigma"
        self.fields = {}
        self._expressions = [
            (self.sigma, dolfinx.fem.Expression(sigma, compat.interpolation_points(self.T)))
        ]
        for name, expr in (("sss", s12), ("von_mises", von_mises), ("max_principal", principal)):
            f = dolfinx.fem.Function(self.S)
            f.name = name
            self.fields[name] = f
            self._expressions.append(
                (f, dolfinx.fem.Expression(expr, compat.interpolation_points(self.S)))
            )
        dofs = compat.cell_dofs(self.S)
        self._dof_points = self.S.tabulate_dof_coordinates()[:, :2].copy()  # reference config.
        n_owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self._all_cell_dofs = dofs
        self._cell_dofs = dofs[:n_owned]
        self._cell_region = solver._cell_region[:n_owned]
        S0 = compat.function_space(mesh, "DG", 0)
        self._cell_value = compat.cell_dofs(S0)[:, 0]  # cell → its DG0 dof
        self.cell_fields = {}
        for name in (*self.fields, "region"):
            f = dolfinx.fem.Function(S0)
            f.name = name
            self.cell_fields[name] = f
        region = self.cell_fields["region"].x.array
        region[self._cell_value] = solver._cell_region[: len(self._cell_value)]

    def update(self) -> None:
        """Interpolate the stresses of the current η; their cell extremes."""
        for f, expr in self._expressions:
            f.interpolate(expr)
        for name, f in self.fields.items():
            values = f.x.array[self._all_cell_dofs]  # (cells, dofs per cell)
            if name == "sss":  # signed: the value of largest magnitude
                extreme = np.take_along_axis(
                    values, np.abs(values).argmax(axis=1)[:, None], axis=1
                )[:, 0]
            else:
                extreme = values.max(axis=1)
            self.cell_fields[name].x.array[self._cell_value] = extreme

    def region_maxima(self) -> dict[str, RegionStress]:
        """Per region (and ``"all"``): the maxima over the region's cells on all ranks.

        Call :meth:`update` first.
        """
        out = {}
        comm = self.solver.comm
        vm = self.fields["von_mises"].x.array
        pr = self.fields["max_principal"].x.array
        sh = np.abs(self.fields["sss"].x.array)
        regions = [(r.label, [int(r)]) for r in self.solver.regions]
        regions.append(("all", [int(r) for r in self.solver.regions]))
        for label, values in regions:
            dofs = self._cell_dofs[np.isin(self._cell_region, values)].ravel()
            local = [float(a[dofs].max(initial=-np.inf)) for a in (vm, pr, sh)]
            out[label] = RegionStress(*(float(comm.allreduce(v, op=MPI.MAX)) for v in local))
        return out

    def location_of_max(self, name: str, region: int) -> tuple[float, float, float]:
        """(value, x, y): the largest value of the stress field ``name`` (``max_principal``,
        ``von_mises``) over the cells of ``region`` on all ranks (the value
        :meth:`region_maxima` reports) and where it is attained: the point (m, reference
        configuration) of the field's DG node that holds it (for P2 displacements a vertex of
        the cell, for P1 its midpoint). Ties go to the smallest x, then y, so the point does not
        depend on the partition; (NaN, NaN, NaN) for an empty region. Call :meth:`update`
        first. Collective."""
        values = self.fields[name].x.array
        dofs = self._cell_dofs[np.isin(self._cell_region, [int(region)])].ravel()
        best = (-np.inf, np.nan, np.nan)
        if len(dofs):
            top = values[dofs].max()
            points = self._dof_points[dofs[values[dofs] == top]]
            x, y = min(map(tuple, points))
            best = (float(top), float(x), float(y))
        found = [b for b in self.solver.comm.allgather(best) if b[0] > -np.inf]
        if not found:
            return (np.nan, np.nan, np.nan)
        top = max(b[0] for b in found)
        return min((b for b in found if b[0] == top), key=lambda b: (b[1], b[2]))


# --------------------------------------------------------------------------------------------
# Building from a case


def build(
    case: Case,
    tagged: TaggedMesh | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    pressure: Callable[[float], float] | None = None,
    scheme: NewmarkFamily | None = None,
) -> SolidSolver:
    """The case's structure solver (mesh from ``tagged`` or built; materials, mode, scheme)."""
    if tagged is None:
        tagged = fsi_mesh.build(case, comm)
    domain = structure_mesh(tagged, structure_regions(case))
    s = case.structure
    return SolidSolver(
        domain,
        region_materials(case),
        boundary_conditions(case, pressure),
        scheme or structural_scheme(s.time_integration),
        degree=s.degree,
        quadrature_degree=s.quadrature_degree,
        solver=s.solver,
    )
