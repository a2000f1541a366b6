"""Blood's viscosity: the strain rate D(u), the regularised shear rate s(u), the viscosity laws
μ(s) (one small object per law, as the solid's are in fsi/physics/materials.py; :func:`from_config`
builds the law of a ``fluid.rheology`` section, :mod:`fsi.config.rheology_section`) and the
Cauchy stress σ = −p I + 2 μ(s(u)) D(u) (docs/model.md §2).

``mu(s)`` takes a number or a numpy array (tables, tests, post-processing: a number or array in
Pa s) or a UFL expression (the fluid's forms: a UFL expression).
"""

from __future__ import annotations

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


def strain_rate(u) -> ufl.core.expr.Expr:
    """D(u) = (∇u + ∇uᵀ) / 2 (1/s), ``u`` the velocity (m/s)."""
    return ufl.sym(ufl.grad(u))


def shear_rate(u, epsilon: float = SHEAR_RATE_EPSILON) -> ufl.core.expr.Expr:
    """s(u) = sqrt(2 D(u):D(u) + ε²) (1/s), the regularised shear rate (ε: SHEAR_RATE_EPSILON)."""
    return shear_rate_of(strain_rate(u), epsilon)


def shear_rate_of(D, epsilon: float = SHEAR_RATE_EPSILON) -> ufl.core.expr.Expr:
    """s = sqrt(2 D:D + ε²) (1/s) of a strain rate ``D`` (1/s): with the hoop strain rate
    u_r/r when axisymmetric (fsi.physics.coordinates.Coordinates.strain_rate)."""
    return ufl.sqrt(2 * ufl.inner(D, D) + epsilon**2)


class ViscosityLaw(Protocol):
    """A generalized Newtonian law: ``mu(s)`` is the viscosity (Pa s) at shear rate ``s`` (1/s)."""

    def mu(self, s):
        """μ(s) (Pa s) at the shear rate ``s`` (1/s): a number, an array or a UFL expression."""
        ...


def _is_ufl(s: Any) -> bool:
    return isinstance(s, ufl.core.expr.Expr)


@dataclass(frozen=True)
class NewtonianViscosity:
    """μ(s) = μ (``viscosity``)."""

    viscosity: float

    def mu(self, s):
        """μ (Pa s): a UFL constant for a UFL ``s``, else an array shaped like ``s``."""
        if _is_ufl(s):
            return ufl.as_ufl(self.viscosity)
        return self.viscosity * np.ones_like(np.asarray(s, dtype=float))


@dataclass(frozen=True)
class CarreauViscosity:
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)²)^((n − 1)/2) (``mu_0`` μ0, ``mu_inf`` μ∞,
    ``relaxation_time`` λ, ``power_index`` n)."""

    mu_0: float
    mu_inf: float
    relaxation_time: float
    power_index: float

    def mu(self, s):
        """μ(s) (Pa s) at the shear rate ``s`` (1/s): a number, an array or a UFL expression."""
        n, lam = self.power_index, self.relaxation_time
        return self.mu_inf + (self.mu_0 - self.mu_inf) * (1 + (lam * s) ** 2) ** ((n - 1) / 2)


@dataclass(frozen=True)
class CarreauYasudaViscosity:
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)^a)^((n − 1)/a) (``yasuda_exponent`` a; a = 2 is
    Carreau)."""

    mu_0: float
    mu_inf: float
    relaxation_time: float
    power_index: float
    yasuda_exponent: float

    def mu(self, s):
        """μ(s) (Pa s) at the shear rate ``s`` (1/s): a number, an array or a UFL expression."""
        n, lam, a = self.power_index, self.relaxation_time, self.yasuda_exponent
        return self.mu_inf + (self.mu_0 - self.mu_inf) * (1 + (lam * s) ** a) ** ((n - 1) / a)


@dataclass(frozen=True)
class CrossViscosity:
    """μ(s) = μ∞ + (μ0 − μ∞) / (1 + (λ s)^m) (``exponent`` m)."""

    mu_0: float
    mu_inf: float
    relaxation_time: float
    exponent: float

    def mu(self, s):
        """μ(s) (Pa s) at the shear rate ``s`` (1/s): a number, an array or a UFL expression."""
        lam, m = self.relaxation_time, self.exponent
        return self.mu_inf + (self.mu_0 - self.mu_inf) / (1 + (lam * s) ** m)


@dataclass(frozen=True)
class PowerLawViscosity:
    """μ(s) = K (s² + s0²)^((n − 1)/2) (``consistency`` K, ``power_index`` n,
    ``shear_rate_floor`` s0): the power law K s^(n−1) with the shear rate floored smoothly at s0
    (fsi.config.rheology_section.PowerLaw)."""

    consistency: float
    power_index: float
    shear_rate_floor: float

    def mu(self, s):
        """μ(s) (Pa s) at the shear rate ``s`` (1/s): a number, an array or a UFL expression."""
        K, n, s0 = self.consistency, self.power_index, self.shear_rate_floor
        return K * (s**2 + s0**2) ** ((n - 1) / 2)


@dataclass(frozen=True)
class CassonViscosity:
    """Casson's law with Papanastasiou's regularisation of the yield term:
    μ(s) = (√μc + √(τy / s) (1 − exp(−√(m s))))² (``viscosity`` μc, ``yield_stress`` τy,
    ``regularization`` m; fsi.config.rheology_section.Casson). Evaluated with numbers it is
    exact at s = 0; in the fluid forms s ≥ ε (:func:`shear_rate`)."""

    viscosity: float
    yield_stress: float
    regularization: float

    def mu(self, s):
        """μ(s) (Pa s) at the shear rate ``s`` (1/s): a number, an array or a UFL expression."""
        mu_c, tau_y, m = self.viscosity, self.yield_stress, self.regularization
        if _is_ufl(s):
            yield_term = ufl.sqrt(tau_y / s) * (1 - ufl.exp(-ufl.sqrt(m * s)))
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


LAWS: dict[str, type] = {
    "newtonian": NewtonianViscosity,
    "carreau": CarreauViscosity,
    "carreau_yasuda": CarreauYasudaViscosity,
    "cross": CrossViscosity,
    "power_law": PowerLawViscosity,
    "casson": CassonViscosity,
}
"""The law of each ``fluid.rheology.model``; its fields are the section's parameters."""


def from_config(rheology: config.Rheology) -> ViscosityLaw:
    """The law of a ``fluid.rheology`` section, with the section's parameters."""
    law = LAWS[rheology.model]
    return law(**{name: getattr(rheology, name) for name in law.__dataclass_fields__})


def cauchy_stress(u, p, law: ViscosityLaw) -> ufl.core.expr.Expr:
    """σ(u, p) = −p I + 2 μ(s(u)) D(u) (Pa), ``u`` the velocity (m/s), ``p`` the pressure (Pa)."""
    return -p * ufl.Identity(len(u)) + 2 * law.mu(shear_rate(u)) * strain_rate(u)
