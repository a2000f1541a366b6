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
``restore_state`` and the interface vectors (owned interface dofs, shape (n, 2)). The solver
is built from the materials as cell fields (:func:`material_fields`), the
:class:`DirichletConditions` and the :class:`SolidResidual`, the weak form above term by term.
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
# Per-region laws and material fields


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


@dataclass(frozen=True)
class MaterialFields:
    """The materials of a structure's regions as fields on its cells.

    ``regions``: the regions present on any rank; ``rho``: the density (DG0, kg/m³); ``law``:
    the hyperelastic law with DG0 Lamé parameters (a :class:`RegionwiseLaw` where the regions'
    laws differ); ``viscous``: the stiffness-proportional Kelvin–Voigt stress, None when every
    relaxation time is 0 (then no viscous term is built at all); ``cells``: the DG0 space;
    ``cell_region``: each local cell's region tag (−1 for an untagged cell).
    """

    regions: tuple[Region, ...]
    rho: dolfinx.fem.Function
    law: HyperelasticLaw
    viscous: KelvinVoigt | None
    cells: dolfinx.fem.FunctionSpace
    cell_region: np.ndarray


def material_fields(domain: TaggedMesh, materials: Mapping[Region, Material]) -> MaterialFields:
    """The :class:`MaterialFields` of ``materials`` on ``domain``'s cell tags. Collective; a
    ValueError names the regions present without a material."""
    mesh, tags = domain.mesh, domain.cell_tags
    present = [
        int(r) for r in np.unique(np.concatenate(mesh.comm.allgather(np.unique(tags.values))))
    ]
    missing = [r for r in present if Region(r) not in materials]
    if missing:
        raise ValueError(f"no material for regions {[Region(r).label for r in missing]}")
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
    rho = dg0({r: m.density for r, m in mats.items()}, "density")
    lmbda = dg0({r: lm[0] for r, lm in lmbda_mu.items()}, "lambda")
    mu = dg0({r: lm[1] for r, lm in lmbda_mu.items()}, "mu")
    laws = sorted({m.law for m in mats.values()})
    if len(laws) == 1:
        law: HyperelasticLaw = make_law(laws[0], lmbda, mu)
    else:
        law = RegionwiseLaw(
            tuple(
                (
                    dg0({r: 1.0 for r, m in mats.items() if m.law == name}, f"chi_{name}"),
                    make_law(name, lmbda, mu),
                )
                for name in laws
            )
        )
    # Kelvin–Voigt, stiffness-proportional per region: λ_v = τλ, μ_v = τμ (DG0). Left out
    # of the forms when every τ is 0, so the elastic residual is unchanged bit for bit.
    tau = {r: m.viscous_relaxation_time for r, m in mats.items()}
    viscous = None
    if any(value > 0 for value in tau.values()):
        viscous = KelvinVoigt.stiffness_proportional(dg0(tau, "viscous_relaxation_time"), lmbda, mu)
    cell_region = np.full(len(dofs), -1, dtype=np.int32)
    cell_region[tags.indices] = tags.values
    return MaterialFields(tuple(Region(r) for r in present), rho, law, viscous, Q, cell_region)


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
# Dirichlet conditions on the displacement space


def _facets(domain: TaggedMesh, boundaries: Sequence[Boundary] | None) -> np.ndarray:
    """The local facets of ``boundaries`` (``None``: the whole boundary of the mesh)."""
    if boundaries is None:
        return dolfinx.mesh.exterior_facet_indices(domain.mesh.topology)
    return domain.facets(*boundaries)


class DirichletConditions:
    """The structure's :data:`Dirichlet` conditions on the displacement space ``V``.

    :attr:`bcs`: as Newton solves with them (η = 0, or the prescribed value that
    :meth:`update` sets); :attr:`homogeneous`: the same dofs held at 0 (the initial
    acceleration's mass matrix); :attr:`constrained`: every constrained dof (local block
    index), sorted.
    """

    def __init__(
        self, domain: TaggedMesh, V: dolfinx.fem.FunctionSpace, conditions: Sequence[Dirichlet]
    ):
        tdim = domain.mesh.topology.dim
        self.bcs, self._prescribed = [], []
        constrained = []
        zero = np.zeros(domain.mesh.geometry.dim, dtype=PETSc.ScalarType)
        for item in conditions:
            if isinstance(item, HoldRegions):
                dofs = dolfinx.fem.locate_dofs_topological(V, tdim, domain.cells(*item.regions))
                self.bcs.append(dolfinx.fem.dirichletbc(zero, dofs, V))
            elif isinstance(item, Clamp):
                dofs = dolfinx.fem.locate_dofs_topological(
                    V, tdim - 1, _facets(domain, item.boundaries)
                )
                self.bcs.append(dolfinx.fem.dirichletbc(zero, dofs, V))
            elif isinstance(item, PrescribedDisplacement):
                dofs = dolfinx.fem.locate_dofs_topological(
                    V, tdim - 1, _facets(domain, item.boundaries)
                )
                g = dolfinx.fem.Function(V)
                self.bcs.append(dolfinx.fem.dirichletbc(g, dofs))
                self._prescribed.append((item.value, g))
            else:  # pragma: no cover
                raise TypeError(f"unknown Dirichlet condition {item!r}")
            constrained.append(dofs)
        self.constrained = (
            np.unique(np.concatenate(constrained)) if constrained else np.zeros(0, dtype=np.int32)
        )
        self.homogeneous = [dolfinx.fem.dirichletbc(zero, dofs, V) for dofs in constrained]

    def update(self, t: float) -> None:
        """The prescribed displacements at time ``t``."""
        for value, g in self._prescribed:
            g.interpolate(lambda x, value=value: value(x, t))
            g.x.scatter_forward()  # a ghost dof may lie in no local cell of a submesh


# --------------------------------------------------------------------------------------------
# The residual, term by term


class SolidResidual:
    """The balance of momentum of a :class:`SolidSolver` (the module docstring's weak form) as
    a sum of named terms: :attr:`form`, the residual at n+1−αf, and :attr:`jacobian`, its
    derivative in η; :meth:`initial_acceleration_forms`, the same balance at the committed
    state n. A term whose data is absent (no source, no follower pressure, no support, no
    inertia in the quasi-static scheme, no viscous stress when every τ is 0) is not built.

    It reads the solver's functions (η, η_n, η̇_n, η̈_n, the tractions), materials (ρ, the law,
    the viscous stress), time step ``dt`` and boundary data, and owns what the terms add: the
    measures :attr:`dx` and :attr:`ds` (with the cell and facet tags) and
    :attr:`ds_interface`, all at ``quadrature_degree``; the body force :attr:`gravity`
    (m/s²); the follower pressure at t_{n+1} and t_n, :attr:`pressure` and
    :attr:`pressure_n` (Pa); and the support's ``(k_s, c_s, ds)``, :attr:`support` (None
    without one).
    """

    def __init__(self, solver: SolidSolver, quadrature_degree: int):
        self.solver = solver
        mesh, bcs = solver.domain.mesh, solver.bcs_data
        metadata = {"quadrature_degree": quadrature_degree}
        cell_tags, facet_tags = solver.domain.cell_tags, solver.domain.facet_tags
        self.dx = ufl.Measure("dx", domain=mesh, subdomain_data=cell_tags, metadata=metadata)
        self.ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags, metadata=metadata)
        self.ds_interface = self._ds(bcs.interface)
        self.gravity = dolfinx.fem.Constant(
            mesh, np.asarray(bcs.body_force, dtype=PETSc.ScalarType)
        )
        self.pressure = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        self.pressure_n = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        self.support = None
        if bcs.support is not None:
            self.support = (
                dolfinx.fem.Constant(mesh, PETSc.ScalarType(bcs.support.stiffness)),
                dolfinx.fem.Constant(mesh, PETSc.ScalarType(bcs.support.damping)),
                self._ds(bcs.support.boundaries),
            )
        self.form = self._residual()
        self.jacobian = ufl.derivative(self.form, solver.eta, ufl.TrialFunction(solver.V))

    def _ds(self, boundaries: Sequence[Boundary]) -> ufl.Measure:
        return sum((self.ds(int(b)) for b in boundaries[1:]), self.ds(int(boundaries[0])))

    def _residual(self) -> ufl.Form:
        """stress + inertia − body force − source − interface traction + follower pressure
        + support, each at n+1−αf."""
        s, scheme = self.solver, self.solver.scheme
        af = scheme.alpha_f
        deta = ufl.TestFunction(s.V)
        I = ufl.Identity(s.domain.mesh.geometry.dim)
        F_new, F_old = I + ufl.grad(s.eta), I + ufl.grad(s.eta_n)
        S_alpha, v_alpha = self._second_piola_alpha(F_new, F_old)
        residual = self._stress(scheme.at(F_new, F_old, af), S_alpha, deta)
        if scheme.dynamic:
            residual += self._inertia(deta)
        residual -= self._body_force(deta)
        if s.bcs_data.source is not None:
            residual -= self._source(deta)
        residual -= self._traction(scheme.at(s.traction, s.traction_n, af), deta)
        if s.bcs_data.pressure is not None:
            p_alpha = scheme.at(self.pressure, self.pressure_n, af)
            residual += self._follower_pressure(p_alpha, scheme.at(F_new, F_old, af), deta)
        if self.support is not None:
            residual += self._support(scheme.at(s.eta, s.eta_n, af), v_alpha, deta)
        return residual

    def initial_acceleration_forms(self) -> tuple[ufl.Form, ufl.Form]:
        """The mass form ``∫ ρ a·δη dx`` (bilinear in the acceleration a) and the force
        ``f_ext(t_n) − f_int(η_n, η̇_n)`` of the committed state n (the follower pressure at
        :attr:`pressure_n`): the balance ``M a_n = f`` that the acceleration a_n satisfies."""
        s = self.solver
        deta, da = ufl.TestFunction(s.V), ufl.TrialFunction(s.V)
        F = ufl.Identity(s.domain.mesh.geometry.dim) + ufl.grad(s.eta_n)
        S = s.law.second_piola(F)
        if s.viscous is not None:
            S = S + s.viscous.second_piola(F, ufl.grad(s.v_n))
        force = -self._stress(F, S, deta)
        if self.support is not None:
            force -= self._support(s.eta_n, s.v_n, deta)
        force += self._body_force(deta)
        force += self._traction(s.traction_n, deta)
        if s.bcs_data.source is not None:
            force += self._source(deta)
        if s.bcs_data.pressure is not None:
            force -= self._follower_pressure(self.pressure_n, F, deta)
        return s.rho * ufl.inner(da, deta) * self.dx, force

    # -- the terms

    def _second_piola_alpha(self, F_new, F_old):
        """The generalized energy-momentum stress ``Σ_{n+1-αf} = (1 − αf) Σ(F_{n+1}) + αf Σ(F_n)``
        plus the Kelvin–Voigt stress of η̇_{n+1-αf} (if any); and η̇_{n+1-αf}."""
        s, scheme = self.solver, self.solver.scheme
        af = scheme.alpha_f
        S_alpha = scheme.at(s.law.second_piola(F_new), s.law.second_piola(F_old), af)
        # η̇ at n+1-αf, with η̇_{n+1} the scheme's function of the unknown η_{n+1}.
        v_alpha = scheme.at(scheme.velocity(s.eta, s.eta_n, s.v_n, s.a_n, s._dt), s.v_n, af)
        if s.viscous is not None:
            # The rate pulled back with the mid-step F̄: Ė = (E_{n+1} − E_n)/dt exactly when
            # η̇_{n+1-αf} = (η_{n+1} − η_n)/dt (trapezoidal, quasi-static): see the docstring.
            S_alpha = S_alpha + s.viscous.second_piola(
                scheme.at(F_new, F_old, 0.5), ufl.grad(v_alpha)
            )
        return S_alpha, v_alpha

    def _stress(self, F, S, deta):
        """``∫ F S : ∇δη dx``, the first Piola stress ``F S`` tested."""
        return ufl.inner(F * S, ufl.grad(deta)) * self.dx

    def _inertia(self, deta):
        """``∫ ρ a_{n+1-αm}·δη dx``."""
        s, scheme = self.solver, self.solver.scheme
        a_new = scheme.acceleration(s.eta, s.eta_n, s.v_n, s.a_n, s._dt)
        return s.rho * ufl.inner(scheme.at(a_new, s.a_n, scheme.alpha_m), deta) * self.dx

    def _body_force(self, deta):
        """``∫ ρ b·δη dx``."""
        return self.solver.rho * ufl.inner(self.gravity, deta) * self.dx

    def _source(self, deta):
        """``∫ f(x)·δη dx`` (a manufactured solution's force per reference volume)."""
        x = ufl.SpatialCoordinate(self.solver.domain.mesh)
        return ufl.inner(self.solver.bcs_data.source(x), deta) * self.dx

    def _traction(self, t0, deta):
        """``∫ t₀·δη ds`` over the interface."""
        return ufl.inner(t0, deta) * self.ds_interface

    def _follower_pressure(self, p, F, deta):
        """``∫ p J F⁻ᵀ N·δη ds`` over the interface (the pressure's traction is its negative)."""
        N = ufl.FacetNormal(self.solver.domain.mesh)
        return p * ufl.inner(ufl.det(F) * ufl.inv(F).T * N, deta) * self.ds_interface

    def _support(self, eta, v, deta):
        """``∫ (k_s η·N + c_s η̇·N)(δη·N) ds`` over the supported boundary."""
        k_s, c_s, ds_support = self.support
        N = ufl.FacetNormal(self.solver.domain.mesh)
        return (k_s * ufl.dot(eta, N) + c_s * ufl.dot(v, N)) * ufl.dot(deta, N) * ds_support


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

    Its parts: the materials as cell fields (:func:`material_fields`: ``regions``, ``rho``,
    ``law``, ``viscous``), the :class:`DirichletConditions` (``dirichlet``), the interface dofs
    and their loads, the :class:`SolidResidual` (``residual``), Newton (``newton``) and the
    :class:`StressFields` (``stress``).
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

        m = material_fields(domain, materials)
        self.regions, self.rho, self.law, self.viscous = m.regions, m.rho, m.law, m.viscous
        self.Q0, self._cell_region = m.cells, m.cell_region
        self.dirichlet = DirichletConditions(domain, self.V, bcs.dirichlet)
        self._build_interface()
        self.residual = SolidResidual(self, quadrature_degree)
        self.problem = _Problem(
            self.residual.form, self.eta, self.dirichlet.bcs, self.residual.jacobian, self._nodal
        )
        # dolfinx's "residual" test divides by the first increment's norm (mixed units), so test
        # the increments: converged when |δη_k| < atol (m) or |δη_k| < rtol |δη_1|.
        self.newton = Newton(self.comm, self.problem, solver, self.prefix, "incremental")
        self.stress = StressFields(self, self.law)
        self._det_F = None
        self._energy_forms = None

    def _build_interface(self) -> None:
        """The owned interface dofs (the order of every interface vector) and their points."""
        mesh = self.domain.mesh
        self.interface_facets = self.domain.facets(*self.bcs_data.interface)
        dofs = dolfinx.fem.locate_dofs_topological(
            self.V, mesh.topology.dim - 1, self.interface_facets
        )
        self.interface_dofs = dofs[dofs < self.V.dofmap.index_map.size_local]
        self.interface_points = self.V.tabulate_dof_coordinates()[self.interface_dofs, :2]
        free = ~np.isin(self.interface_dofs, self.dirichlet.constrained)
        bs = self.V.dofmap.index_map_bs
        self._force_rows = (self.interface_dofs[free, None] * bs + np.arange(bs)).ravel()
        self._force_free = free
        self.forces = np.zeros((len(self.interface_dofs), bs))
        self.forces_n = np.zeros_like(self.forces)

    def _nodal(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.scheme.at(self.forces, self.forces_n, self.scheme.alpha_f)
        return self._force_rows, f[self._force_free].ravel()

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
        self.residual.gravity.value[:] = np.asarray(g, dtype=float)

    # -- stepping -------------------------------------------------------------------------

    def step(self, t: float, dt: float) -> SolveResult:
        """Solve for η_{n+1} at ``t = t_n + dt`` from the committed state n and the loads set.

        On failure (Newton not converged, a non-finite value, an inverted element or a linear
        solver error) η is put back to its value before the call and ``converged`` is False.
        """
        self._dt.value = dt
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
        if self._det_F is None:
            F = ufl.Identity(2) + ufl.grad(self.eta)
            self._det_F = (
                dolfinx.fem.Function(self.Q0),
                dolfinx.fem.Expression(ufl.det(F), compat.interpolation_points(self.Q0)),
            )
        J, expression = self._det_F
        J.interpolate(expression)
        n = self.Q0.dofmap.index_map.size_local
        return float(self.comm.allreduce(float(J.x.array[:n].min(initial=np.inf)), op=MPI.MIN))

    def energies(self) -> tuple[float, float]:
        """Kinetic and stored energy of the committed state n, ``½∫ρ|η̇|²`` and ``∫W(F)`` (J/m)."""
        if self._energy_forms is None:
            F = ufl.Identity(2) + ufl.grad(self.eta_n)
            self._energy_forms = [
                dolfinx.fem.form(0.5 * self.rho * ufl.inner(self.v_n, self.v_n) * self.residual.dx),
                dolfinx.fem.form(self.law.strain_energy(F) * self.residual.dx),
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
