"""The kinematics of generalized Newtonian blood: the strain rate D(u), the regularised shear
rate s(u) and the Cauchy stress σ = −p I + 2 μ(s(u)) D(u) (docs/model.md §2), for a viscosity
law μ(s) of the ``fluid.rheology`` section (the laws: :mod:`fsi.config.rheology_section`;
:func:`from_config`).
"""

from __future__ import annotations

from typing import Protocol

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

    @property
    def reference_viscosity(self) -> float:
        """A viscosity scale (Pa s) for penalty parameters: the largest the law takes."""
        ...


def from_config(rheology: config.Rheology) -> ViscosityLaw:
    """The law of a ``fluid.rheology`` section: the section itself, which has ``mu``."""
    return rheology


def cauchy_stress(u, p, law: ViscosityLaw) -> ufl.core.expr.Expr:
    """σ(u, p) = −p I + 2 μ(s(u)) D(u) (Pa), ``u`` the velocity (m/s), ``p`` the pressure (Pa)."""
    return -p * ufl.Identity(len(u)) + 2 * law.mu(shear_rate(u)) * strain_rate(u)
