"""Viscosity laws of generalized Newtonian blood: μ as a function of the shear rate s.

Each law is a small frozen object with ``mu(s)``; ``s`` may be a UFL expression (the law then
returns a UFL expression for the fluid forms) or a number / numpy array (for tables, tests and
post-processing). The fluid's Cauchy stress is ``σ = −p I + 2 μ(s(u)) D(u)`` with the shear rate
``s(u) = sqrt(2 D(u):D(u))`` (:func:`shear_rate`). Build a law from its configuration with
:func:`from_config`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import ufl

from fsi import config

SHEAR_RATE_EPSILON = 1.0e-8
"""ε (1/s) in ``s = sqrt(2 D:D + ε²)``: keeps ∂s/∂D = 2D/s defined at rest (u = 0, the initial
state), where the exact sqrt has no derivative. Far below any shear rate of interest (blood:
1e-2 to 1e4 1/s)."""


def _is_ufl(x: Any) -> bool:
    return isinstance(x, ufl.core.expr.Expr)


def _sqrt(x):
    return ufl.sqrt(x) if _is_ufl(x) else np.sqrt(x)


def _exp(x):
    return ufl.exp(x) if _is_ufl(x) else np.exp(x)


def strain_rate(u) -> ufl.core.expr.Expr:
    """D(u) = (∇u + ∇uᵀ) / 2."""
    return ufl.sym(ufl.grad(u))


def shear_rate(u, epsilon: float = SHEAR_RATE_EPSILON) -> ufl.core.expr.Expr:
    """s(u) = sqrt(2 D(u):D(u) + ε²), the regularised shear rate (ε: SHEAR_RATE_EPSILON)."""
    D = strain_rate(u)
    return ufl.sqrt(2 * ufl.inner(D, D) + epsilon**2)


class ViscosityLaw(Protocol):
    """A generalized Newtonian law: ``mu(s)`` is the viscosity (Pa s) at shear rate ``s`` (1/s)."""

    def mu(self, s): ...

    @property
    def reference_viscosity(self) -> float:
        """A viscosity scale (Pa s) for penalty parameters: the largest the law takes."""
        ...


@dataclass(frozen=True)
class Newtonian:
    """μ(s) = μ."""

    viscosity: float

    def mu(self, s):
        if _is_ufl(s):
            return ufl.as_ufl(self.viscosity)
        return self.viscosity * np.ones_like(np.asarray(s, dtype=float))

    @property
    def reference_viscosity(self) -> float:
        return self.viscosity


@dataclass(frozen=True)
class PlateauLaw:
    """The laws whose viscosity goes from μ0 (``mu_0``) at rest to μ∞ (``mu_inf``) at high
    shear rates, changing around the shear rate 1/λ (``relaxation_time`` λ): Carreau,
    Carreau–Yasuda and Cross, each with its own ``mu``."""

    mu_0: float
    mu_inf: float
    relaxation_time: float

    @property
    def reference_viscosity(self) -> float:
        return max(self.mu_0, self.mu_inf)


@dataclass(frozen=True)
class Carreau(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)²)^((n − 1)/2) (the study's law, MODEL.md §2)."""

    power_index: float

    def mu(self, s):
        n, lam = self.power_index, self.relaxation_time
        return self.mu_inf + (self.mu_0 - self.mu_inf) * (1 + (lam * s) ** 2) ** ((n - 1) / 2)


@dataclass(frozen=True)
class CarreauYasuda(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)^a)^((n − 1)/a); a = 2 is Carreau."""

    power_index: float
    yasuda_exponent: float

    def mu(self, s):
        n, lam, a = self.power_index, self.relaxation_time, self.yasuda_exponent
        return self.mu_inf + (self.mu_0 - self.mu_inf) * (1 + (lam * s) ** a) ** ((n - 1) / a)


@dataclass(frozen=True)
class Cross(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞) / (1 + (λ s)^m)."""

    exponent: float

    def mu(self, s):
        lam, m = self.relaxation_time, self.exponent
        return self.mu_inf + (self.mu_0 - self.mu_inf) / (1 + (lam * s) ** m)


@dataclass(frozen=True)
class PowerLaw:
    """μ(s) = K (s² + s0²)^((n − 1)/2).

    The power law K s^(n−1) is unbounded at s = 0 for n < 1; the shear rate is floored smoothly
    at s0, so μ(0) = K s0^(n−1) and the law is K s^(n−1) (1 + O(s0²/s²)) for s ≫ s0. Smooth, so
    Newton's Jacobian is continuous (a ``max(s, s0)`` floor would have a kink).
    """

    consistency: float
    power_index: float
    shear_rate_floor: float

    def mu(self, s):
        K, n, s0 = self.consistency, self.power_index, self.shear_rate_floor
        return K * (s**2 + s0**2) ** ((n - 1) / 2)

    @property
    def reference_viscosity(self) -> float:
        return float(self.mu(0.0)) if self.power_index <= 1 else self.consistency


@dataclass(frozen=True)
class Casson:
    """Casson's √τ = √τy + √(μc s) with Papanastasiou's regularisation of the yield term:

        μ(s) = (√μc + √(τy / s) (1 − exp(−√(m s))))²,

    which tends to Casson's (√μc + √(τy/s))² for m s ≫ 1 and to (√μc + √(τy m))² at s = 0
    (Neofytou & Drikakis 2003 use this form for blood). Evaluated with numbers it is exact at
    s = 0; in the fluid forms s ≥ ε (:func:`shear_rate`).
    """

    viscosity: float
    yield_stress: float
    regularization: float

    def mu(self, s):
        mu_c, tau_y, m = self.viscosity, self.yield_stress, self.regularization
        if _is_ufl(s):
            yield_term = _sqrt(tau_y / s) * (1 - _exp(-_sqrt(m * s)))
        else:
            s = np.asarray(s, dtype=float)
            root = np.sqrt(m * s)
            with np.errstate(divide="ignore", invalid="ignore"):
                # (1 − e^(−r)) / r → 1 as r = √(m s) → 0
                ratio = np.where(
                    root > 1e-8, -np.expm1(-root) / np.where(root > 0, root, 1), 1 - root / 2
                )
            yield_term = math.sqrt(tau_y * m) * ratio
        return (math.sqrt(mu_c) + yield_term) ** 2

    @property
    def reference_viscosity(self) -> float:
        return float(self.mu(0.0))


LAWS: dict[str, type] = {
    "newtonian": Newtonian,
    "carreau": Carreau,
    "carreau_yasuda": CarreauYasuda,
    "cross": Cross,
    "power_law": PowerLaw,
    "casson": Casson,
}
"""The laws by the ``fluid.rheology.model`` tag; each takes its section's other keys."""


def from_config(rheology: config.Rheology) -> ViscosityLaw:
    """The law named by a ``fluid.rheology`` section, with the section's parameters."""
    parameters = dataclasses.asdict(rheology)
    return LAWS[parameters.pop("model")](**parameters)


def cauchy_stress(u, p, law: ViscosityLaw) -> ufl.core.expr.Expr:
    """σ(u, p) = −p I + 2 μ(s(u)) D(u)."""
    return -p * ufl.Identity(len(u)) + 2 * law.mu(shear_rate(u)) * strain_rate(u)
