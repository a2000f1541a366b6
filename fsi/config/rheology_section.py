"""The ``fluid.rheology`` section: which viscosity law μ(s) of the shear rate s (1/s) blood
follows, one frozen dataclass per law (``model`` picks one of :data:`Rheology`) with its
parameters and their checks. The laws themselves, μ(s), are fsi/physics/rheology.py's
(:func:`fsi.physics.rheology.from_config`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from fsi.config.reader import positive


def _tag(name: str) -> Any:
    """The law's ``model`` tag: the first field (the reader's union tag), keyword-only."""
    return field(default=name, kw_only=True)


@dataclass(frozen=True)
class Newtonian:
    """μ(s) = μ (``viscosity``)."""

    model: Literal["newtonian"] = _tag("newtonian")
    viscosity: float = positive(0.0035, "Pa s")


@dataclass(frozen=True)
class PlateauLaw:
    """The laws whose viscosity goes from μ0 (``mu_0``) at rest to μ∞ (``mu_inf``) at high
    shear rates, changing around the shear rate 1/λ (``relaxation_time`` λ): Carreau,
    Carreau–Yasuda and Cross (their μ(s): fsi/physics/rheology.py). These defaults are the
    study's Carreau law's (docs/model.md §2); the other two laws have their own."""

    model: str = field(kw_only=True)
    mu_0: float = positive(0.0456, "Pa s")
    mu_inf: float = positive(0.0032, "Pa s")
    relaxation_time: float = positive(10.03, "s")


@dataclass(frozen=True)
class Carreau(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)²)^((n − 1)/2) (``power_index`` n). Defaults: the
    study's (docs/model.md §2)."""

    model: Literal["carreau"] = _tag("carreau")
    power_index: float = positive(0.344)


@dataclass(frozen=True)
class CarreauYasuda(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)^a)^((n − 1)/a) (``yasuda_exponent`` a; a = 2 is
    Carreau). Defaults: blood (Cho & Kensey 1991, as used by Johnston et al. 2004)."""

    model: Literal["carreau_yasuda"] = _tag("carreau_yasuda")
    mu_0: float = positive(0.056, "Pa s")
    mu_inf: float = positive(0.00345, "Pa s")
    relaxation_time: float = positive(1.902, "s")
    power_index: float = positive(0.22)
    yasuda_exponent: float = positive(1.25)


@dataclass(frozen=True)
class Cross(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞) / (1 + (λ s)^m) (``exponent`` m). Defaults: blood (Johnston et
    al. 2004)."""

    model: Literal["cross"] = _tag("cross")
    mu_0: float = positive(0.0364, "Pa s")
    mu_inf: float = positive(0.0035, "Pa s")
    relaxation_time: float = positive(0.38, "s")
    exponent: float = positive(1.45)


@dataclass(frozen=True)
class PowerLaw:
    """μ(s) = K (s² + s0²)^((n − 1)/2) (``consistency`` K, ``power_index`` n,
    ``shear_rate_floor`` s0): the power law K s^(n−1), unbounded at s = 0 for n < 1, with the
    shear rate floored smoothly at s0, so μ(0) = K s0^(n−1) and μ = K s^(n−1) (1 + O(s0²/s²))
    for s ≫ s0; smooth, so Newton's Jacobian is continuous. Defaults: blood, K and n of
    Johnston et al. (2004); s0 = 0.0169 1/s puts μ(0) at their cap of 0.056 Pa s."""

    model: Literal["power_law"] = _tag("power_law")
    consistency: float = positive(0.017, "Pa s^n")
    power_index: float = positive(0.708)
    shear_rate_floor: float = positive(0.0169, "1/s")


@dataclass(frozen=True)
class Casson:
    """Casson's √τ = √τy + √(μc s) with Papanastasiou's regularisation of the yield term:

        μ(s) = (√μc + √(τy / s) (1 − exp(−√(m s))))²,

    (``viscosity`` μc, ``yield_stress`` τy, ``regularization`` m), which tends to Casson's
    (√μc + √(τy/s))² for m s ≫ 1 and to (√μc + √(τy m))² at s = 0 (Neofytou & Drikakis 2003
    use this form for blood). Evaluated with numbers it is exact at s = 0; in the fluid forms
    s ≥ ε (fsi.physics.rheology.shear_rate). Defaults: typical blood values (τy 5 mPa, μc
    3.5 mPa s) and m = 100 s."""

    model: Literal["casson"] = _tag("casson")
    viscosity: float = positive(0.0035, "Pa s")
    yield_stress: float = positive(0.005, "Pa")
    regularization: float = positive(100.0, "s")


Rheology = Newtonian | Carreau | CarreauYasuda | Cross | PowerLaw | Casson


def womersley_viscosity(law: Rheology) -> float | None:
    """The constant viscosity (Pa s) of a Womersley inflow profile (docs/boundary-conditions.md):
    the Newtonian μ, or μ∞ (``mu_inf``) of Carreau, Carreau–Yasuda and Cross, the viscosity of
    the sheared, pulsating flow; None for the power law and Casson (no such constant)."""
    if isinstance(law, Newtonian):
        return law.viscosity
    if isinstance(law, PlateauLaw):
        return law.mu_inf
    return None
