"""Hyperelastic material laws of the structure, as small frozen objects behind a Protocol.

Laws of the 2D plane-strain setting of docs/model.md (Structure), in ``F = I + ∇η`` (2×2; the
out-of-plane stretch is 1): :class:`StVenantKirchhoff` (the study's law) and :class:`NeoHookean`,
which linearise to Hooke's law with the same ``λ, μ`` (:func:`lame`), and the viscous
:class:`KelvinVoigt` stress added to either. The same laws take the 3×3 F of an axisymmetric
structure (the hoop stretch ``F_θθ = 1 + η_r/r``, fsi/physics/solid_residual.py) as they are:
every identity, trace and the neo-Hookean energy's ``d`` follow ``F.ufl_shape``, so they are
then the 3D laws. The parameters may be numbers, :class:`dolfinx.fem.Constant` or DG0 fields
(per-region values): the laws only build UFL.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

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


LAWS: dict[str, type] = {"svk": StVenantKirchhoff, "neo_hookean": NeoHookean}
"""The laws by their configuration name (``structure.<region>.law``)."""


def make_law(name: str, lmbda: Parameter, mu: Parameter) -> HyperelasticLaw:
    """The law called ``name`` with Lamé parameters ``λ, μ``."""
    try:
        return LAWS[name](lmbda, mu)
    except KeyError:
        raise ValueError(f"unknown material law {name!r} (one of {', '.join(LAWS)})") from None
