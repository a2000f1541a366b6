"""Hyperelastic material laws of the structure, as small frozen objects behind a Protocol.

Laws of the 2D plane-strain setting of docs/model.md (Structure), in ``F = I + ∇η`` (2×2; the
out-of-plane stretch is 1): :class:`StVenantKirchhoff` (the study's law) and :class:`NeoHookean`,
which linearise to Hooke's law with the same ``λ, μ`` (:func:`lame`), and the viscous
:class:`KelvinVoigt` stress added to either. The same laws take the 3×3 F of an axisymmetric
structure (the hoop stretch ``F_θθ = 1 + η_r/r``, fsi/physics/solid_residual.py) as they are:
every identity, trace and the neo-Hookean energy's ``d`` follow ``F.ufl_shape``, so they are
then the 3D laws. The parameters may be numbers, :class:`dolfinx.fem.Constant` or DG0 fields
(per-region values): the laws only build UFL. :class:`HolzapfelGasserOgden`, the fibre-reinforced
arterial wall, needs the 3×3 F (axisymmetric or 3D): its fibres lie in the circumferential–axial
plane, which a plane (longitudinal) section does not contain.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import ufl

Parameter = float | Any
"""A number, a :class:`dolfinx.fem.Constant` or a UFL expression (e.g. a DG0 field)."""


def lame(young_modulus: float, poisson_ratio: float) -> tuple[float, float]:
    """Plane-strain Lamé parameters ``(λ, μ)``:
    ``λ = Eν/((1 − 2ν)(1 + ν))``, ``μ = E/(2(1 + ν))``."""
    E, nu = young_modulus, poisson_ratio
    if not (E > 0 and -1.0 < nu < 0.5):
        raise ValueError(f"need E > 0 and -1 < nu < 1/2, got E = {E}, nu = {nu}")
    return E * nu / ((1 - 2 * nu) * (1 + nu)), E / (2 * (1 + nu))


def green_lagrange(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """``E = (FᵀF − I)/2``."""
    return 0.5 * (F.T * F - ufl.Identity(F.ufl_shape[0]))


@runtime_checkable
class HyperelasticLaw(Protocol):
    """A hyperelastic law in terms of the deformation gradient ``F``: 2×2 (plane strain) or
    3×3 (axisymmetric, 3D)."""

    name: str

    def strain_energy(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Stored energy ``W(F)`` per unit reference volume (area × unit depth)."""
        ...

    def second_piola(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Second Piola–Kirchhoff stress ``Σ = ∂W/∂E`` (the shape of F)."""
        ...

    def second_piola_zz(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The out-of-plane component ``Σ₃₃`` that keeps the plane-strain constraint (2×2 F
        only)."""
        ...


def has_volumetric_stress(law: HyperelasticLaw) -> bool:
    """Whether ``law`` is nearly incompressible and names its volumetric Cauchy stress
    ``volumetric_stress(F)`` (``U'(J)``, times I), which the structure's stresses take from a
    projection (fsi/physics/solid_stress.py, ``RecoveredPressure``)."""
    return bool(getattr(law, "nearly_incompressible", False))


def cauchy(law: HyperelasticLaw, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """Cauchy stress on the current configuration, ``σ = J⁻¹ P Fᵀ = J⁻¹ F Σ Fᵀ`` (in-plane
    for a 2×2 F, the whole 3×3 one with the hoop stress for an axisymmetric F)."""
    return F * law.second_piola(F) * F.T / ufl.det(F)


def cauchy_zz(law: HyperelasticLaw, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """Out-of-plane Cauchy stress ``σ₃₃ = J⁻¹ Σ₃₃`` (``F₃₃ = 1``)."""
    return law.second_piola_zz(F) / ufl.det(F)


@dataclass(frozen=True)
class StVenantKirchhoff:
    """St. Venant–Kirchhoff: ``W = λ/2 (tr E)² + μ E:E``, ``Σ = λ tr(E) I + 2μ E``."""

    lmbda: Parameter
    mu: Parameter
    name: str = "svk"

    def strain_energy(self, F):
        E = green_lagrange(F)
        return 0.5 * self.lmbda * ufl.tr(E) ** 2 + self.mu * ufl.inner(E, E)

    def second_piola(self, F):
        E = green_lagrange(F)
        return self.lmbda * ufl.tr(E) * ufl.Identity(F.ufl_shape[0]) + 2 * self.mu * E

    def second_piola_zz(self, F):
        # E₃₃ = 0 in plane strain, so Σ₃₃ = λ tr(E) with the in-plane trace.
        return self.lmbda * ufl.tr(green_lagrange(F))


@dataclass(frozen=True)
class NeoHookean:
    """Compressible neo-Hookean: ``W = μ/2 (tr C − 2 − 2 ln J) + λ/2 (ln J)²``,
    ``Σ = μ (I − C⁻¹) + λ ln J C⁻¹``, ``C = FᵀF``, ``J = det F``, with d = 2 the dimension
    of F: in plane strain (``C₃₃ = 1``) the usual 3D energy ``μ/2 (I₁³ᴰ − 3 − 2 ln J) +
    λ/2 (ln J)²``, which a 3×3 (axisymmetric) F gives with d = 3.
    """

    lmbda: Parameter
    mu: Parameter
    name: str = "neo_hookean"

    def strain_energy(self, F):
        J = ufl.det(F)
        d = F.ufl_shape[0]
        return (
            0.5 * self.mu * (ufl.tr(F.T * F) - d - 2 * ufl.ln(J))
            + 0.5 * self.lmbda * ufl.ln(J) ** 2
        )

    def second_piola(self, F):
        J = ufl.det(F)
        C_inv = ufl.inv(F.T * F)
        return self.mu * (ufl.Identity(F.ufl_shape[0]) - C_inv) + self.lmbda * ufl.ln(J) * C_inv

    def second_piola_zz(self, F):
        # C₃₃ = 1: Σ₃₃ = μ (1 − 1) + λ ln J.
        return self.lmbda * ufl.ln(ufl.det(F))


def green_lagrange_rate(F: ufl.core.expr.Expr, grad_v: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """``Ė = sym(Fᵀ ∇η̇)``, the material time derivative of ``E = (FᵀF − I)/2`` (``Ḟ = ∇η̇``).

    Objective: a rigid spin superposed on any motion, ``∇η̇ = W F`` with ``W`` skew, gives
    ``Fᵀ W F`` skew and ``Ė = 0``."""
    return ufl.sym(F.T * grad_v)


@dataclass(frozen=True)
class KelvinVoigt:
    """Viscous second Piola stress ``S_v = λ_v tr(Ė) I + 2 μ_v Ė``, ``Ė = sym(Fᵀ ∇η̇)``
    (Pa; ``λ_v, μ_v`` in Pa·s). Its first Piola stress ``F S_v`` is added to the elastic one.

    :meth:`stiffness_proportional` makes ``λ_v = τλ, μ_v = τμ``: linearised about the
    reference state the viscous force is τ K η̇ with K the elastic stiffness, so the modes of
    ``M η̈ + τ K η̇ + K η = 0`` are those of the elastic problem and a mode of angular
    frequency ω decays as ``exp(−ζωt)`` with ``ζ = ωτ/2`` (docs/wall-damping.md). The stress
    power ``S_v : Ė = λ_v (tr Ė)² + 2 μ_v Ė:Ė`` is ≥ 0 for ``μ_v ≥ 0, λ_v + μ_v ≥ 0`` (2D).
    """

    lmbda: Parameter
    mu: Parameter
    name: str = "kelvin_voigt"

    @classmethod
    def stiffness_proportional(
        cls, relaxation_time: Parameter, lmbda: Parameter, mu: Parameter
    ) -> KelvinVoigt:
        """``λ_v = τλ, μ_v = τμ`` for the relaxation time τ (s)."""
        return cls(relaxation_time * lmbda, relaxation_time * mu)

    def second_piola(self, F: ufl.core.expr.Expr, grad_v: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """``S_v(F, ∇η̇)``."""
        rate = green_lagrange_rate(F, grad_v)
        return self.lmbda * ufl.tr(rate) * ufl.Identity(F.ufl_shape[0]) + 2 * self.mu * rate


def axisymmetric_fibres(sin_angle: Parameter, cos_angle: Parameter) -> tuple[Any, Any]:
    """The two fibre families at ±β from the circumferential direction in the
    circumferential–axial plane, as unit vectors of the axisymmetric frame (z, r, θ) of
    fsi/physics/coordinates.py: ``a± = (±sin β, 0, cos β)``."""
    return (
        ufl.as_vector([sin_angle, 0, cos_angle]),
        ufl.as_vector([-sin_angle, 0, cos_angle]),
    )


def cylindrical_fibres(x, sin_angle: Parameter, cos_angle: Parameter) -> tuple[Any, Any]:
    """The two fibre families of a 3D vessel whose axis is the x axis (geometry/vessel_3d.py):
    ``a± = cos β e_θ ± sin β e_x`` with the circumferential ``e_θ = (0, −z, y)/√(y² + z²)``
    at the point ``x`` (UFL's spatial coordinate of the reference configuration)."""
    radius = ufl.sqrt(x[1] ** 2 + x[2] ** 2)
    e_theta = ufl.as_vector([0, -x[2] / radius, x[1] / radius])
    e_axial = ufl.as_vector([1, 0, 0])
    return (cos_angle * e_theta + sin_angle * e_axial, cos_angle * e_theta - sin_angle * e_axial)


@dataclass(frozen=True)
class HolzapfelGasserOgden:
    """The Holzapfel–Gasser–Ogden arterial wall with the fibre dispersion of Gasser, Ogden &
    Holzapfel (2006), nearly incompressible (3×3 F: axisymmetric or 3D)::

        W = c/2 (Ī₁ − 3) + Σ_f k₁/(2k₂) (exp(k₂ Ē_f²) − 1) [Ī₄f > 1] + K/4 (J² − 1 − 2 ln J),
        Ē_f = κ (Ī₁ − 3) + (1 − 3κ)(Ī₄f − 1),   Ī₁ = tr C̄,   Ī₄f = a_f·C̄ a_f,   C̄ = J^(−2/3) C,

    with the ground matrix's shear modulus ``c = mu`` and bulk modulus ``K = λ + 2μ/3``
    (:func:`lame` of the region's E and ν: small strains of the matrix obey Hooke's law with
    them), fibre stiffness ``k1`` (Pa) and ``k2`` (> 0), dispersion κ ∈ [0, 1/3] (0: aligned
    fibres, the HGO 2000 model; 1/3: isotropic) and ``fibres`` the reference unit directions
    a_f (:func:`axisymmetric_fibres`). A family carries load only while its mean direction is
    stretched, Ī₄f > 1 (fibres buckle in compression). The fibre terms use the isochoric Ī₄, as
    Abaqus' and FEBio's HGO do; the near-incompressibility (K ≫ c) makes the difference from
    the full I₄ negligible (Sansour 2008 shows the isochoric form's spurious volumetric response
    when K is small).

    Locking: the displacement is P2 (``structure.degree``) and every term is integrated at the
    structure's quadrature degree. The inflated tube (tests/test_hgo_tube.py) shows no locking
    at the shipped degree: its error is the same on 8 and 16 cells across the wall and falls as
    1/K (the compressibility, not the mesh), so K must stand well above the stiffened fibres'
    stress (ν = 0.49999 for a carotid at 25 kPa; docs/arterial-wall.md). Pointwise, the
    volumetric stress :meth:`volumetric_stress` of a P2 displacement is noise: the structure's
    stresses take its P1 projection (fsi/physics/solid_stress.py, ``RecoveredPressure``). A
    one-point integration of the volumetric term (P2–P0) was tried and dropped: dolfinx 0.5's
    form compiler assembles an integrand split over two quadrature degrees wrongly (10 % off
    the sum of the parts, measured), and its Newton then converged only linearly.
    """

    lmbda: Parameter
    mu: Parameter
    k1: Parameter
    k2: Parameter
    dispersion: Parameter
    fibres: tuple[Any, ...]
    name: str = "hgo"
    nearly_incompressible: ClassVar[bool] = True

    @property
    def bulk_modulus(self):
        """``K = λ + 2μ/3``."""
        return self.lmbda + 2 * self.mu / 3

    def isochoric_energy(self, C):
        """``W_iso(C)``: the matrix and the fibres, in terms of C̄ = J^(−2/3) C."""
        C_bar = ufl.det(C) ** (-1.0 / 3.0) * C
        I1 = ufl.tr(C_bar)
        W = 0.5 * self.mu * (I1 - 3)
        kappa = self.dispersion
        for a in self.fibres:
            I4 = ufl.inner(a, C_bar * a)
            E = kappa * (I1 - 3) + (1 - 3 * kappa) * (I4 - 1)
            fibre = self.k1 / (2 * self.k2) * (ufl.exp(self.k2 * E**2) - 1)
            W += ufl.conditional(ufl.gt(I4, 1), fibre, 0)
        return W

    def volumetric_energy(self, J):
        """``U(J) = K/4 (J² − 1 − 2 ln J)``."""
        return 0.25 * self.bulk_modulus * (J**2 - 1 - 2 * ufl.ln(J))

    def strain_energy(self, F):
        return self.isochoric_energy(F.T * F) + self.volumetric_energy(ufl.det(F))

    def volumetric_stress(self, F):
        """The Cauchy stress's volumetric part ``U'(J) = K/2 (J − 1/J)`` (times I)."""
        J = ufl.det(F)
        return 0.5 * self.bulk_modulus * (J - 1 / J)

    def second_piola(self, F):
        """``2 ∂W/∂C``, UFL's derivative of the energy in C."""
        C = ufl.variable(F.T * F)
        W = self.isochoric_energy(C) + self.volumetric_energy(ufl.sqrt(ufl.det(C)))
        return 2 * ufl.diff(W, C)

    def second_piola_zz(self, F):
        raise ValueError(
            "the HGO law has fibres in the circumferential-axial plane: it needs a 3×3 F "
            "(axisymmetric or 3D), not plane strain"
        )


LAWS: dict[str, type] = {
    "svk": StVenantKirchhoff,
    "neo_hookean": NeoHookean,
    "hgo": HolzapfelGasserOgden,
}
"""The laws by their configuration name (``structure.<region>.law``)."""


def make_law(name: str, lmbda: Parameter, mu: Parameter, **parameters: Any) -> HyperelasticLaw:
    """The law called ``name`` with Lamé parameters ``λ, μ`` (and, for ``hgo``, the fibres'
    ``k1, k2, dispersion, fibres``)."""
    try:
        return LAWS[name](lmbda, mu, **parameters)
    except KeyError:
        raise ValueError(f"unknown material law {name!r} (one of {', '.join(LAWS)})") from None
