"""The Holzapfel–Gasser–Ogden (HGO) law in closed form, and the inflation and extension of a
thick incompressible HGO tube by the radial equilibrium integral.

Independent of the UFL law it checks (fsi/physics/materials.py, ``HolzapfelGasserOgden``): the
stresses are written out from the invariants, not differentiated by a program.

**The law** (Holzapfel, Gasser & Ogden 2000, J. Elasticity 61; the dispersion κ of Gasser,
Ogden & Holzapfel 2006, J. R. Soc. Interface 3): with C̄ = J^(−2/3) C, Ī₁ = tr C̄, Ī₄f = a_f·C̄a_f,

    W = c/2 (Ī₁ − 3) + Σ_f k₁/(2k₂) (exp(k₂ Ē_f²) − 1) [Ī₄f > 1] + K/4 (J² − 1 − 2 ln J),
    Ē_f = κ (Ī₁ − 3) + (1 − 3κ)(Ī₄f − 1),

two families a± = cos β e_θ ± sin β e_z. Its Cauchy stress (Holzapfel, *Nonlinear Solid
Mechanics*, 2000, §6.7: τ = dev τ̄ + J U'(J) I for a decoupled energy)::

    σ = J⁻¹ dev(τ̄) + U'(J) I,   τ̄ = c b̄ + Σ_f 2ψ_f' (κ b̄ + (1 − 3κ) ā_f ⊗ ā_f),
    ψ_f' = k₁ Ē_f exp(k₂ Ē_f²) (0 when Ī₄f ≤ 1),   b̄ = F̄F̄ᵀ,   ā_f = F̄ a_f,   F̄ = J^(−1/3) F.

**Incompressible, principal stretches** (λ_r, λ_θ, λ_z), λ_r = 1/(λ_θ λ_z): the pressure is a
Lagrange multiplier and only the differences are constitutive (the reduced energy
Ŵ(λ_θ, λ_z), σ_θθ − σ_rr = λ_θ ∂Ŵ/∂λ_θ, σ_zz − σ_rr = λ_z ∂Ŵ/∂λ_z)::

    σ_θθ − σ_rr = c(λ_θ² − λ_r²) + 4ψ' (κ(λ_θ² − λ_r²) + (1 − 3κ) λ_θ² cos²β),
    σ_zz − σ_rr = c(λ_z² − λ_r²) + 4ψ' (κ(λ_z² − λ_r²) + (1 − 3κ) λ_z² sin²β),

with Ī₄ = λ_θ² cos²β + λ_z² sin²β the same for both families.

**The tube** (Holzapfel et al. 2000 §5; Ogden, *Non-linear Elastic Deformations*, §5.3): the
unloaded tube R_i ≤ R ≤ R_o stretched axially by λ_z and inflated by the pressure P keeps its
cross-sections plane, r² = r_i² + (R² − R_i²)/λ_z, λ_θ = r/R; radial equilibrium
dσ_rr/dr = (σ_θθ − σ_rr)/r with σ_rr(r_i) = −P, σ_rr(r_o) = 0 gives

    P = ∫_{r_i}^{r_o} (σ_θθ − σ_rr) dr/r,
    σ_rr(r) = −P + ∫_{r_i}^{r} (σ_θθ − σ_rr) dr'/r',

and the axial force on an open end (the pressure does not act on the end faces) is
N = ∫ σ_zz 2πr dr = π r_i² P + π ∫ (2(σ_zz − σ_rr) − (σ_θθ − σ_rr)) r dr. Each integral is a
1D quadrature and r_i a root of P(r_i): :func:`inflation`. :func:`unloaded_radii` inverts it:
the unloaded tube whose loaded radii are given (the prestressed tube's exact state).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import integrate, optimize


@dataclass(frozen=True)
class HGOParameters:
    """The law's parameters: ground matrix shear modulus ``c`` (Pa), fibre stiffness ``k1``
    (Pa) and exponent ``k2``, fibre ``angle`` β from the circumferential direction (degrees),
    ``dispersion`` κ, ``bulk_modulus`` K (Pa; only :func:`cauchy_stress` uses it)."""

    c: float
    k1: float
    k2: float
    angle: float
    dispersion: float = 0.0
    bulk_modulus: float = math.inf

    def fibres(self) -> tuple[np.ndarray, np.ndarray]:
        """a± in the frame (z, r, θ) of the axisymmetric model: (±sin β, 0, cos β)."""
        b = math.radians(self.angle)
        return np.array([math.sin(b), 0.0, math.cos(b)]), np.array([-math.sin(b), 0.0, math.cos(b)])


def _fibre_slope(parameters: HGOParameters, I1: float, I4: float) -> tuple[float, float]:
    """(ψ', Ē): the fibre energy's derivative in Ē and Ē (ψ' = 0 when Ī₄ ≤ 1)."""
    kappa = parameters.dispersion
    E = kappa * (I1 - 3) + (1 - 3 * kappa) * (I4 - 1)
    if I4 <= 1:
        return 0.0, E
    return parameters.k1 * E * math.exp(parameters.k2 * E**2), E


def cauchy_stress(F: np.ndarray, parameters: HGOParameters) -> np.ndarray:
    """The Cauchy stress (3×3, frame (z, r, θ)) of the nearly incompressible law at the
    deformation gradient ``F`` (the module docstring)."""
    p = parameters
    F = np.asarray(F, dtype=float)
    J = float(np.linalg.det(F))
    F_bar = J ** (-1.0 / 3.0) * F
    b_bar = F_bar @ F_bar.T
    I1 = float(np.trace(b_bar))
    tau_bar = p.c * b_bar
    for a in p.fibres():
        a_bar = F_bar @ a
        slope, _ = _fibre_slope(p, I1, float(a_bar @ a_bar))
        tau_bar = tau_bar + 2 * slope * (
            p.dispersion * b_bar + (1 - 3 * p.dispersion) * np.outer(a_bar, a_bar)
        )
    deviator = tau_bar - np.trace(tau_bar) / 3 * np.eye(3)
    return deviator / J + 0.5 * p.bulk_modulus * (J - 1 / J) * np.eye(3)


def stress_differences(
    hoop_stretch: float, axial_stretch: float, parameters: HGOParameters
) -> tuple[float, float]:
    """(σ_θθ − σ_rr, σ_zz − σ_rr) of the incompressible law at the principal stretches
    λ_θ, λ_z (λ_r = 1/(λ_θ λ_z)), Pa."""
    p = parameters
    lt, lz = hoop_stretch, axial_stretch
    lr = 1 / (lt * lz)
    b = math.radians(p.angle)
    I1 = lr**2 + lt**2 + lz**2
    I4 = lt**2 * math.cos(b) ** 2 + lz**2 * math.sin(b) ** 2
    slope, _ = _fibre_slope(p, I1, I4)
    k = p.dispersion
    hoop = p.c * (lt**2 - lr**2) + 4 * slope * (
        k * (lt**2 - lr**2) + (1 - 3 * k) * lt**2 * math.cos(b) ** 2
    )
    axial = p.c * (lz**2 - lr**2) + 4 * slope * (
        k * (lz**2 - lr**2) + (1 - 3 * k) * lz**2 * math.sin(b) ** 2
    )
    return hoop, axial


@dataclass(frozen=True)
class TubeState:
    """The inflated, extended tube: loaded radii ``r_i``, ``r_o`` (m), ``pressure`` P (Pa),
    ``axial_force`` N on an open end (N), and the stresses at the inner surface (Pa)."""

    r_i: float
    r_o: float
    pressure: float
    axial_force: float
    hoop_stress_inner: float
    axial_stress_inner: float


class Tube:
    """The unloaded incompressible tube ``R_i ≤ R ≤ R_o`` of ``parameters``, stretched by
    ``axial_stretch`` λ_z (the module docstring)."""

    def __init__(self, R_i: float, R_o: float, axial_stretch: float, parameters: HGOParameters):
        self.R_i, self.R_o, self.lz, self.parameters = R_i, R_o, axial_stretch, parameters

    def radius(self, r_i: float, R: float) -> float:
        """The loaded radius of the material at R when the inner radius is r_i."""
        return math.sqrt(r_i**2 + (R**2 - self.R_i**2) / self.lz)

    def _integral(self, r_i: float, integrand, upper: float | None = None) -> float:
        """∫_{R_i}^{upper} integrand(r, σ_θθ − σ_rr, σ_zz − σ_rr) dr, written in R
        (dr = R dR/(λ_z r))."""

        def in_R(R: float) -> float:
            r = self.radius(r_i, R)
            hoop, axial = stress_differences(r / R, self.lz, self.parameters)
            return integrand(r, hoop, axial) * R / (self.lz * r)

        value, _ = integrate.quad(
            in_R, self.R_i, self.R_o if upper is None else upper, epsabs=0, epsrel=1e-11, limit=200
        )
        return value

    def pressure(self, r_i: float) -> float:
        """P(r_i) = ∫ (σ_θθ − σ_rr) dr/r."""
        return self._integral(r_i, lambda r, hoop, axial: hoop / r)

    def state(self, r_i: float) -> TubeState:
        """Everything at inner radius ``r_i``."""
        P = self.pressure(r_i)
        N = math.pi * r_i**2 * P + math.pi * self._integral(
            r_i, lambda r, hoop, axial: (2 * axial - hoop) * r
        )
        hoop, axial = stress_differences(r_i / self.R_i, self.lz, self.parameters)
        return TubeState(r_i, self.radius(r_i, self.R_o), P, N, hoop - P, axial - P)

    def inflated(self, pressure: float) -> TubeState:
        """The state at the inner pressure ``pressure`` (Pa): r_i the root of P(r_i)."""
        low, high = 0.3 * self.R_i, 1.0 * self.R_i
        while self.pressure(low) > pressure:
            low *= 0.5
        while self.pressure(high) < pressure:
            high *= 1.5
        r_i = optimize.brentq(
            lambda r: self.pressure(r) - pressure, low, high, xtol=1e-16, rtol=1e-14
        )
        return self.state(r_i)

    def stresses(self, r_i: float, r: np.ndarray) -> dict[str, np.ndarray]:
        """σ_rr, σ_θθ, σ_zz (Pa) at the loaded radii ``r`` when the inner radius is r_i."""
        P = self.pressure(r_i)
        out = {"rr": [], "tt": [], "zz": []}
        for radius in np.atleast_1d(r):
            # the material radius R of the loaded radius r
            R = math.sqrt(self.R_i**2 + self.lz * (radius**2 - r_i**2))
            rr = -P + self._integral(r_i, lambda r_, hoop, axial: hoop / r_, upper=R)
            hoop, axial = stress_differences(radius / R, self.lz, self.parameters)
            out["rr"].append(rr)
            out["tt"].append(rr + hoop)
            out["zz"].append(rr + axial)
        return {k: np.array(v) for k, v in out.items()}


def unloaded_tube(
    r_i: float, r_o: float, axial_stretch: float, pressure: float, parameters: HGOParameters
) -> Tube:
    """The unloaded tube that the pressure and the axial stretch take to the loaded radii
    ``r_i``, ``r_o``: R_o² − R_i² = λ_z (r_o² − r_i²), R_i the root of P = ``pressure``."""
    area = axial_stretch * (r_o**2 - r_i**2)

    def mismatch(R_i: float) -> float:
        return (
            Tube(R_i, math.sqrt(R_i**2 + area), axial_stretch, parameters).pressure(r_i) - pressure
        )

    R_i = optimize.brentq(
        mismatch, 0.2 * r_i, r_i * math.sqrt(axial_stretch) * 1.5, xtol=1e-16, rtol=1e-14
    )
    return Tube(R_i, math.sqrt(R_i**2 + area), axial_stretch, parameters)
