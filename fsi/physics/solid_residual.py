"""The structure's residual: the balance of momentum in the Newmark family's energy-momentum
form, term by term, and the materials of the regions as cell fields (docs/model.md, Structure).

On Ω₀, with ``F = I + ∇η``, the per-region law Σ(F) (fsi/physics/materials.py) and the
Kelvin–Voigt stress ``S_v = τ (λ tr Ė I + 2μ Ė)``, ``Ė = sym(Fᵀ ∇η̇)``::

    ∫ ρ a_{n+1-αm}·δη + F_{n+1-αf} Σ_{n+1-αf} : ∇δη dx
        + ∫ F_{n+1-αf} S_v(F̄, ∇η̇_{n+1-αf}) : ∇δη dx
        + ∫_ΓN (k_s η_{n+1-αf}·N + c_s η̇_{n+1-αf}·N)(δη·N) ds
      = ∫ ρ b·δη dx + ∫ f·δη dx + ∫_Γ t₀_{n+1-αf}·δη ds − ∫_Γ p_{n+1-αf} J F⁻ᵀ N·δη ds

with ``Σ_{n+1-αf} = (1 − αf) Σ(F_{n+1}) + αf Σ(F_n)`` (Kuhl & Ramm's energy-momentum method,
energy-conserving for St. Venant–Kirchhoff and αf = 1/2) and ``F̄ = (F_{n+1} + F_n)/2``, so that
a rigid motion makes no viscous stress and a step's viscous work is ≥ 0.

Plane or axisymmetric (fsi/physics/coordinates.py): plane, ``F = I + ∇η`` is 2×2 (plane strain)
and the integrals are per unit depth. Axisymmetric (x = z, y = r, η = (η_z, η_r), no swirl), the
gradients are the 3×3 ones of :meth:`~fsi.physics.coordinates.Coordinates.grad`::

    F = [[1 + ∂η_z/∂z, ∂η_z/∂r, 0], [∂η_r/∂z, 1 + ∂η_r/∂r, 0], [0, 0, 1 + η_r/r]],

the hoop stretch ``F_θθ = 1 + η_r/r`` = r/R, the laws take this F as it is (3D), the stress
term is ``F Σ : ∇δη`` with the 3×3 ∇δη (its hoop part δη_r/r), the Kelvin–Voigt rate uses the
3×3 ∇η̇, and every ``dx`` and ``ds`` carries the weight 2πR (R the reference radius), so the
integrals are over the whole body of revolution (forces in N, energies in J). The follower
pressure's ``J F⁻ᵀ N`` is :meth:`SolidResidual.area_normal`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import numpy as np
import ufl

from fsi import compat
from fsi.config import Material
from fsi.geometry.tags import Boundary, Region
from fsi.physics.coordinates import Coordinates
from fsi.physics.materials import (
    HyperelasticLaw,
    KelvinVoigt,
    axisymmetric_fibres,
    cylindrical_fibres,
    has_volumetric_stress,
    lame,
    make_law,
)
from fsi.physics.mesh import TaggedMesh

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

    @property
    def nearly_incompressible(self) -> bool:
        return any(has_volumetric_stress(law) for _, law in self.parts)

    def volumetric_stress(self, F):
        """The volumetric Cauchy stress of the nearly incompressible laws in their regions."""
        return sum(
            chi * law.volumetric_stress(F) for chi, law in self.parts if has_volumetric_stress(law)
        )


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


def _fibre_fields(dg0, mats: Mapping[int, Material], mesh, axisymmetric: bool) -> dict[str, Any]:
    """The HGO law's fibre parameters as DG0 fields (k₁, k₂, κ, the directions of ±β: in the
    axisymmetric frame, or in 3D about the vessel's axis x, :func:`cylindrical_fibres`); in
    the regions of other laws k₁ = 0 (no fibre energy) and k₂ = 1 (no 0/0)."""
    if not axisymmetric and mesh.geometry.dim != 3:
        raise ValueError("the HGO law needs an axisymmetric or a 3D structure")
    fibres = {r: m.fibres for r, m in mats.items() if m.law == "hgo"}
    angle = {r: math.radians(f.angle) for r, f in fibres.items()}
    sin_angle = dg0({r: math.sin(a) for r, a in angle.items()}, "fibre_sin")
    cos_angle = dg0({r: math.cos(a) for r, a in angle.items()}, "fibre_cos")
    directions = (
        axisymmetric_fibres(sin_angle, cos_angle)
        if axisymmetric
        else cylindrical_fibres(ufl.SpatialCoordinate(mesh), sin_angle, cos_angle)
    )
    return {
        "k1": dg0({r: f.k1 for r, f in fibres.items()}, "fibre_k1"),
        "k2": dg0({r: fibres[r].k2 if r in fibres else 1.0 for r in mats}, "fibre_k2"),
        "dispersion": dg0({r: f.dispersion for r, f in fibres.items()}, "fibre_dispersion"),
        "fibres": directions,
    }


def material_fields(
    domain: TaggedMesh, materials: Mapping[Region, Material], axisymmetric: bool = False
) -> MaterialFields:
    """The :class:`MaterialFields` of ``materials`` on ``domain``'s cell tags (``axisymmetric``:
    the fibres of an HGO material in the axisymmetric frame). Collective; a ValueError names
    the regions present without a material."""
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
    parameters = {name: {} for name in laws}
    if "hgo" in laws:
        parameters["hgo"] = _fibre_fields(dg0, mats, mesh, axisymmetric)
    if len(laws) == 1:
        law: HyperelasticLaw = make_law(laws[0], lmbda, mu, **parameters[laws[0]])
    else:
        law = RegionwiseLaw(
            tuple(
                (
                    dg0({r: 1.0 for r, m in mats.items() if m.law == name}, f"chi_{name}"),
                    make_law(name, lmbda, mu, **parameters[name]),
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
# The residual, term by term


class SolidUnknowns(Protocol):
    """What the residual reads from its solver (fsi.physics.solid.SolidSolver): the tagged
    mesh, its coordinates (plane or axisymmetric) and boundary data, the time scheme, the space
    V with η, η_n, v_n, a_n and the interface tractions (now and at t_n), the step dt, and the
    material (ρ, law, viscosity)."""

    domain: TaggedMesh
    coordinates: Coordinates
    bcs_data: Any
    scheme: Any
    V: dolfinx.fem.FunctionSpace
    eta: dolfinx.fem.Function
    eta_n: dolfinx.fem.Function
    v_n: dolfinx.fem.Function
    a_n: dolfinx.fem.Function
    traction: dolfinx.fem.Function
    traction_n: dolfinx.fem.Function
    dt: dolfinx.fem.Constant
    rho: Any
    law: Any
    viscous: Any


class SolidResidual:
    """The balance of momentum of a solid solver (:class:`SolidUnknowns`; the module docstring's
    weak form) as a sum of named terms: :attr:`form`, the residual at n+1−αf, and :attr:`jacobian`,
    its derivative in η; :meth:`initial_acceleration_forms`, the same balance at the committed state
    n. A term whose data is absent (no source, no follower pressure, no support, no inertia in the
    quasi-static scheme, no viscous stress when every τ is 0) is not built.

    It reads the solver's functions (η, η_n, η̇_n, η̈_n, the tractions), materials (ρ, the law,
    the viscous stress), coordinates, time step ``dt`` and boundary data, and owns what the
    terms add: the measures :attr:`dx` and :attr:`ds` (with the cell and facet tags) and
    :attr:`ds_interface`, all at ``quadrature_degree`` and weighted by the coordinates (2πR
    when axisymmetric, the plain measures in the plane); the body force :attr:`gravity`
    (m/s²); the follower pressure at t_{n+1} and t_n, :attr:`pressure` and
    :attr:`pressure_n` (Pa); and the support's ``(k_s, c_s, ds)``, :attr:`support` (None
    without one).
    """

    def __init__(self, solver: SolidUnknowns, quadrature_degree: int):
        self.solver = solver
        mesh, bcs = solver.domain.mesh, solver.bcs_data
        self.coordinates = solver.coordinates
        metadata = {"quadrature_degree": quadrature_degree}
        cell_tags, facet_tags = solver.domain.cell_tags, solver.domain.facet_tags
        self.dx = self.coordinates.measure(
            ufl.Measure("dx", domain=mesh, subdomain_data=cell_tags, metadata=metadata)
        )
        self.ds = self.coordinates.measure(
            ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags, metadata=metadata)
        )
        self.ds_interface = self._ds(bcs.interface)
        # The body force's components in the mesh's dimension (a 3D mesh: g_z = 0).
        gravity = np.zeros(mesh.geometry.dim, dtype=PETSc.ScalarType)
        gravity[: len(bcs.body_force)] = bcs.body_force
        self.gravity = dolfinx.fem.Constant(mesh, gravity)
        self.pressure = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        self.pressure_n = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        self.support = None
        if bcs.support is not None:
            self.support = (
                dolfinx.fem.Constant(mesh, PETSc.ScalarType(bcs.support.stiffness)),
                dolfinx.fem.Constant(mesh, PETSc.ScalarType(bcs.support.damping)),
                self._ds(bcs.support.boundaries),
            )
        self.prestress = getattr(solver, "prestress", None)
        self.form = self._residual()
        self.jacobian = ufl.derivative(self.form, solver.eta, ufl.TrialFunction(solver.V))

    def _ds(self, boundaries: Sequence[Boundary]) -> ufl.Measure:
        return sum((self.ds(int(b)) for b in boundaries[1:]), self.ds(int(boundaries[0])))

    def deformation_gradient(self, eta):
        """``F = I + ∇η``: 2×2, or 3×3 with the hoop stretch ``1 + η_r/r`` (axisymmetric)."""
        return self.coordinates.identity() + self.coordinates.grad(eta)

    def _residual(self) -> ufl.Form:
        """stress + inertia − body force − source − interface traction + follower pressure
        + support, each at n+1−αf."""
        s, scheme = self.solver, self.solver.scheme
        af = scheme.alpha_f
        deta = ufl.TestFunction(s.V)
        F_new, F_old = self.deformation_gradient(s.eta), self.deformation_gradient(s.eta_n)
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
        F = self.deformation_gradient(s.eta_n)
        S = s.law.second_piola(self._elastic(F))
        if s.viscous is not None:
            S = S + self._viscous(s.viscous.second_piola(F, self.coordinates.grad(s.v_n)))
        force = -self._stress(F, S, deta)
        if self.support is not None:
            force -= self._support(s.eta_n, s.v_n, deta)
        force += self._body_force(deta)
        force += self._traction(s.traction_n, deta)
        if s.bcs_data.source is not None:
            force += self._source(deta)
        if s.bcs_data.pressure is not None:
            force -= self._follower_pressure(self.pressure_n, F, deta)
        return self._density() * ufl.inner(da, deta) * self.dx, force

    # -- the terms

    def _second_piola_alpha(self, F_new, F_old):
        """The generalized energy-momentum stress ``Σ_{n+1-αf} = (1 − αf) Σ(F_{n+1}) + αf Σ(F_n)``
        plus the Kelvin–Voigt stress of η̇_{n+1-αf} (if any); and η̇_{n+1-αf}."""
        s, scheme = self.solver, self.solver.scheme
        af = scheme.alpha_f
        S_alpha = scheme.at(
            s.law.second_piola(self._elastic(F_new)), s.law.second_piola(self._elastic(F_old)), af
        )
        # η̇ at n+1-αf, with η̇_{n+1} the scheme's function of the unknown η_{n+1}.
        v_alpha = scheme.at(scheme.velocity(s.eta, s.eta_n, s.v_n, s.a_n, s.dt), s.v_n, af)
        if s.viscous is not None:
            # The rate pulled back with the mid-step F̄: Ė = (E_{n+1} − E_n)/dt exactly when
            # η̇_{n+1-αf} = (η_{n+1} − η_n)/dt (trapezoidal, quasi-static): see the docstring.
            S_alpha = S_alpha + self._viscous(
                s.viscous.second_piola(scheme.at(F_new, F_old, 0.5), self.coordinates.grad(v_alpha))
            )
        return S_alpha, v_alpha

    def _stress(self, F, S, deta):
        """``∫ F S : ∇δη dx``, the first Piola stress ``F S`` tested (axisymmetric: 3×3, with
        the hoop term ``P_θθ δη_r/r``); prestressed, ``J₀⁻¹ F F₀ S F₀ᵀ`` with S the
        reference's (fsi/physics/prestress.py)."""
        P = F * S if self.prestress is None else self.prestress.first_piola(F, S)
        return ufl.inner(P, self.coordinates.grad(deta)) * self.dx

    def _elastic(self, F):
        """The deformation gradient the law sees: F, or ``F F₀`` when prestressed."""
        return F if self.prestress is None else self.prestress.total(F)

    def _viscous(self, S_v):
        """The viscous stress (of the drawn configuration's rate) as :meth:`_stress` takes it."""
        return S_v if self.prestress is None else self.prestress.pull_back(S_v)

    def _density(self):
        """ρ per unit drawn volume: ρ, or ρ/J₀ when prestressed."""
        rho = self.solver.rho
        return rho if self.prestress is None else rho * self.prestress.volume_ratio

    def _inertia(self, deta):
        """``∫ ρ a_{n+1-αm}·δη dx``."""
        s, scheme = self.solver, self.solver.scheme
        a_new = scheme.acceleration(s.eta, s.eta_n, s.v_n, s.a_n, s.dt)
        return self._density() * ufl.inner(scheme.at(a_new, s.a_n, scheme.alpha_m), deta) * self.dx

    def _body_force(self, deta):
        """``∫ ρ b·δη dx``."""
        return self._density() * ufl.inner(self.gravity, deta) * self.dx

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
        return p * ufl.inner(self.area_normal(F, N), deta) * self.ds_interface

    def area_normal(self, F, N):
        """Nanson's ``J F⁻ᵀ N`` (the deformed area times its normal per reference area) in the
        meridian plane, for the reference normal ``N`` (2-vector).

        Plane: ``det F F⁻ᵀ N`` with the 2×2 F. Axisymmetric: F is block-diagonal,
        ``diag(F₂, F_θθ)``, and N = (N_z, N_r, 0) has no hoop component, so
        ``F⁻ᵀ N = (F₂⁻ᵀ N, 0)`` and ``J = det F₂ F_θθ``: the in-plane vector
        ``F_θθ det F₂ F₂⁻ᵀ N``, where the factor F_θθ = r/R is the ring's change of
        circumference (the 2πR of the measure times F_θθ is the deformed 2πr)."""
        if not self.coordinates.axisymmetric:
            return ufl.det(F) * ufl.inv(F).T * N
        F2 = ufl.as_tensor([[F[0, 0], F[0, 1]], [F[1, 0], F[1, 1]]])
        return F[2, 2] * ufl.det(F2) * ufl.inv(F2).T * N

    def _support(self, eta, v, deta):
        """``∫ (k_s η·N + c_s η̇·N)(δη·N) ds`` over the supported boundary."""
        k_s, c_s, ds_support = self.support
        N = ufl.FacetNormal(self.solver.domain.mesh)
        return (k_s * ufl.dot(eta, N) + c_s * ufl.dot(v, N)) * ufl.dot(deta, N) * ds_support
