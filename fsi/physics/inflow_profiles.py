"""Velocity profiles across a straight inlet of width H (numpy and scipy.special): the
Poiseuille parabola (:func:`parabola`), the plane Womersley profile of one harmonic
(:func:`womersley`), their pipe counterparts across an axisymmetric inlet of radius R
(:func:`pipe_parabola`, :func:`pipe_womersley`), and the inflow speed of a flow-rate inlet
(:class:`FlowRateProfile`; docs/boundary-conditions.md, docs/axisymmetric.md).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.special

from fsi.config.boundary_data import HARMONIC_SAMPLES, sample_times

HARMONICS = 32
"""Harmonics k = 1 … 32 of Q that get their Womersley profile (a physiological waveform's
content is in its first ~10); the rest of Q is carried by the parabola."""

SMALL_ALPHA = 1e-4
"""|α| H/2 below which the Womersley profile is the parabola: their relative difference is
O((α H/2)²) ≤ 1e-8, and the closed form loses ~1e-16/(α H/2)² to cancellation (2e-10 of the
flux at α H/2 = 0.01, 1e-12 at 0.1)."""


def parabola(s, width: float, mean_velocity: float):
    """1.5 Ū 4 s (H − s)/H² (m/s): Poiseuille's profile of mean velocity Ū (``mean_velocity``,
    m/s; flow rate Ū H) at the distance ``s`` (m) from one side of a channel of width H."""
    return 1.5 * mean_velocity * 4 * s * (width - s) / width**2


def womersley(s, width: float, omega: float, rho: float, mu: float) -> np.ndarray:
    """φ(s), the complex plane Womersley profile of unit flux (∫_0^H φ ds = 1, 1/m) at the
    distance ``s`` (m) across a channel of width H, for the angular frequency ω (1/s), density
    ρ (kg/m³) and viscosity μ (Pa s): with y = s − H/2 and α² = i ω ρ/μ,

        φ(y) = (1 − cosh(α y)/cosh(α H/2)) / (H − (2/α) tanh(α H/2)),

    the solution of i ω ρ φ − μ φ'' = G (a constant) with φ(±H/2) = 0. The cosh ratio is
    evaluated as e^{α(|y| − H/2)} (1 + e^{−2α|y|}) / (1 + e^{−αH}) (Re α > 0: no overflow at
    any α H); ω = 0 (|α| H/2 < :data:`SMALL_ALPHA`): the parabola 6 s (H − s)/H³."""
    s = np.asarray(s, dtype=float)
    alpha = np.sqrt(1j * omega * rho / mu)
    if abs(alpha) * width / 2 < SMALL_ALPHA:
        return parabola(s, width, 1 / width).astype(complex)
    y = np.abs(s - width / 2)
    decay = np.exp(-alpha * width)
    ratio = np.exp(alpha * (y - width / 2)) * (1 + np.exp(-2 * alpha * y)) / (1 + decay)
    tanh = (1 - decay) / (1 + decay)
    return (1 - ratio) / (width - 2 / alpha * tanh)


def pipe_parabola(r, radius: float, mean_velocity: float):
    """2 Ū (1 − r²/R²) (m/s): Poiseuille's pipe profile of mean velocity Ū (``mean_velocity``,
    m/s; flow rate Ū π R²) at the radius ``r`` (m) of a pipe of radius R."""
    r = np.asarray(r, dtype=float)
    return 2 * mean_velocity * (1 - (r / radius) ** 2)


def pipe_womersley(r, radius: float, omega: float, rho: float, mu: float) -> np.ndarray:
    """φ(r), the complex Womersley pipe profile of unit flux (∫_0^R φ 2π r dr = 1, 1/m²) at the
    radius ``r`` (m) of a pipe of radius R, for the angular frequency ω (1/s), density ρ and
    viscosity μ: with β² = i ω ρ/μ and I₀, I₁ the modified Bessel functions,

        φ(r) = (1 − I₀(β r)/I₀(β R)) / (π R² (1 − 2 I₁(β R)/(β R I₀(β R)))),

    the solution of i ω ρ φ − μ (φ'' + φ'/r) = G (a constant) with φ(R) = 0, φ'(0) = 0. The
    ratios use the scaled Bessel functions (ive: I_ν(z) e^{−|Re z|}), so no overflow at any
    β R; ω = 0 (|β| R < :data:`SMALL_ALPHA`): the parabola 2 (1 − r²/R²)/(π R²)."""
    r = np.asarray(r, dtype=float)
    area = np.pi * radius**2
    beta = np.sqrt(1j * omega * rho / mu)
    if abs(beta) * radius < SMALL_ALPHA:
        return pipe_parabola(r, radius, 1 / area).astype(complex)
    i0 = scipy.special.ive(0, beta * radius)
    ratio = scipy.special.ive(0, beta * r) / i0 * np.exp(beta.real * (r - radius))
    flux = 1 - 2 * scipy.special.ive(1, beta * radius) / (beta * radius * i0)
    return (1 - ratio) / (area * flux)


def harmonics(flow_rate: Callable[[float], float], period: float) -> np.ndarray:
    """Q̂_k, k = 0 … :data:`HARMONICS`: Q(t) ≈ Q̂_0 + Σ_k 2 Re(Q̂_k e^{i k ω t}), ω = 2π/T,
    from the FFT of Q at :func:`sample_times`."""
    samples = np.array([flow_rate(t) for t in sample_times(period)])
    return np.fft.rfft(samples)[: HARMONICS + 1] / HARMONIC_SAMPLES


class FlowRateProfile:
    """The inflow speed u(s, t) (m/s, along the inward normal) of a flow-rate inlet at the
    distances ``s`` (m) across it (width H), before the ramp. Parabolic (``mu`` None):

        u = Q(t) φ_0(s),   φ_0 = 6 s (H − s)/H³;

    Womersley (period T, density ρ, viscosity μ; ω = 2π/T):

        u = Q(t) φ_0(s) + Σ_{k=1}^{K} 2 Re(Q̂_k (φ_k(s) − φ_0(s)) e^{i k ω t}),

    φ_k = :func:`womersley` at k ω, Q̂_k = :func:`harmonics`, K = :data:`HARMONICS`: the
    Womersley solution Re Σ Q̂_k φ_k e^{ikωt} of the band-limited Q, whose flux is Q(t) exactly
    (∫ φ_k − φ_0 = 0; Q's harmonics beyond K ride on the parabola).

    ``axisymmetric``: the inlet is a pipe's cross-section, ``s`` the radii and ``width`` the
    radius R, Q in m³/s: φ_0 = 2 (1 − r²/R²)/(π R²) and φ_k = :func:`pipe_womersley`."""

    def __init__(
        self,
        flow_rate: Callable[[float], float],
        s: np.ndarray,
        width: float,
        period: float = 0.0,
        rho: float = 0.0,
        mu: float | None = None,
        axisymmetric: bool = False,
    ):
        self.flow_rate = flow_rate
        s = np.asarray(s, dtype=float)
        if axisymmetric:
            self.parabola = pipe_parabola(s, width, 1 / (np.pi * width**2))
            unit_flux = pipe_womersley
        else:
            self.parabola = parabola(s, width, 1 / width)
            unit_flux = womersley
        self.omega = 0.0
        self.modes = np.zeros((0, len(self.parabola)), dtype=complex)
        if mu is not None:
            self.omega = 2 * np.pi / period
            q = harmonics(flow_rate, period)
            self.modes = np.array(
                [
                    2 * q[k] * (unit_flux(s, width, k * self.omega, rho, mu) - self.parabola)
                    for k in range(1, len(q))
                ]
            )

    def __call__(self, t: float) -> np.ndarray:
        """u at the time ``t`` (s), one value per distance s."""
        k = np.arange(1, len(self.modes) + 1)
        waves = np.exp(1j * k * self.omega * t) @ self.modes
        return self.flow_rate(t) * self.parabola + waves.real
