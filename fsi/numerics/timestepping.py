"""Time schemes, kept apart from the physics (STYLE.md §3).

* :func:`steps` walks the configured step schedule (the study's 5 ms / 10 ms, or a resolved one).
* :func:`bdf_weights` gives the variable-step backward-difference weights used by the fluid:
  ``∂u/∂t (t_{n+1}) ≈ Σ_k w_k u^{n+1-k}``.
* :class:`BdfHistory` keeps a field's accepted levels u^n, u^{n−1} and forms that sum (the
  fluid's velocity, the ALE mesh displacement).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Segment(Protocol):
    until: float
    dt: float


class Schedule(Protocol):
    """What :func:`steps` reads of a case's ``time`` section (:class:`fsi.config.Time`)."""

    end: float
    schedule: Sequence[Segment]


@dataclass(frozen=True)
class Step:
    """Step number ``index`` (1-based) advancing from ``t - dt`` to ``t``."""

    index: int
    t: float
    dt: float


def steps(time: Schedule, t0: float = 0.0, index0: int = 0) -> Iterator[Step]:
    """The steps of the schedule after time ``t0`` (step ``index0``), up to ``time.end``.

    Each segment's last step is shortened so that it ends exactly on the segment's ``until``
    (and the run on ``end``); a leftover shorter than 1e-9 dt is merged into the previous step.
    """
    t, index = t0, index0
    for segment in time.schedule:
        stop = min(segment.until, time.end)
        while stop - t > 1e-9 * segment.dt:
            dt = segment.dt if stop - (t + segment.dt) > 1e-9 * segment.dt else stop - t
            t, index = (stop if dt == stop - t else t + dt), index + 1
            yield Step(index, t, dt)
        if time.end <= segment.until:
            return


def bdf_weights(order: int, dt: float, dt_previous: float | None = None) -> tuple[float, ...]:
    """Weights ``w`` with ``∂u/∂t(t_{n+1}) ≈ w[0] u^{n+1} + w[1] u^n + w[2] u^{n-1}``.

    Order 1 is backward Euler. Order 2 is BDF2 for variable steps, with ``r = dt / dt_previous``:
    ``w = ((1 + 2r) / (1 + r), -(1 + r), r² / (1 + r)) / dt``.
    """
    if order == 1:
        return (1.0 / dt, -1.0 / dt)
    if order == 2:
        if dt_previous is None:
            raise ValueError("BDF2 needs the previous step size")
        r = dt / dt_previous
        return ((1 + 2 * r) / (1 + r) / dt, -(1 + r) / dt, r * r / (1 + r) / dt)
    raise ValueError(f"BDF order {order} is not supported (1 or 2)")


class BdfHistory:
    """The accepted time levels x^n, x^{n−1} of a field x, for the backward difference
    ``Σ_k a_k x^{n+1−k}`` of :func:`bdf_weights`.

    ``x`` is the field's current level x^{n+1} (the one being solved for), ``x_n`` and ``x_nm1``
    the accepted ones: arrays of one shape that the history reads and writes in place, never
    rebinds. So they may be the value arrays of dolfinx Functions (``u_n.x.array``), which stay
    the Functions that forms use. Every operation copies values or forms the sum; no other
    arithmetic.
    """

    def __init__(
        self, x: np.ndarray, x_n: np.ndarray | None = None, x_nm1: np.ndarray | None = None
    ):
        self.x = x
        self.x_n = np.zeros_like(x) if x_n is None else x_n
        self.x_nm1 = np.zeros_like(x) if x_nm1 is None else x_nm1

    def start(self) -> None:
        """x^{n−1} = x^n = x: the history of a field that was x before the first step."""
        self.x_n[:] = self.x
        self.x_nm1[:] = self.x

    def advance(self) -> None:
        """Accept the current level: x^{n−1} ← x^n, x^n ← x."""
        self.x_nm1[:] = self.x_n
        self.x_n[:] = self.x

    def derivative(self, weights: Sequence[float]) -> np.ndarray:
        """``Σ_k a_k x^{n+1−k} = a₀ x + a₁ x^n (+ a₂ x^{n−1})`` for ``weights`` (a₀, a₁[, a₂]),
        summed in that order (a new array)."""
        return sum(a * h for a, h in zip(weights, (self.x, self.x_n, self.x_nm1)))

    def save(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of (x^n, x^{n−1})."""
        return self.x_n.copy(), self.x_nm1.copy()

    def restore(self, x_n: np.ndarray, x_nm1: np.ndarray) -> None:
        """Set the accepted levels to ``x_n``, ``x_nm1`` (e.g. from :meth:`save`)."""
        self.x_n[:] = x_n
        self.x_nm1[:] = x_nm1


# --------------------------------------------------------------------------------------------
# Structural time integration (the Newmark family, used by fsi.physics.solid)


@dataclass(frozen=True)
class NewmarkFamily:
    """Generalized-α / Newmark coefficients for ``M a + f_int(η) = f_ext`` (Chung–Hulbert 1993).

    Balance at intermediate times, with ``x_{n+1-α} = (1 − α) x_{n+1} + α x_n``::

        M a_{n+1-αm} + f_int(η_{n+1-αf}) = f_ext(t_{n+1-αf})

    and Newmark's kinematics::

        η_{n+1} = η_n + dt v_n + dt² ((1/2 − β) a_n + β a_{n+1})
        v_{n+1} = v_n + dt ((1 − γ) a_n + γ a_{n+1})

    ``dynamic = False`` is the quasi-static scheme: no inertia, balance at ``t_{n+1}``, the
    velocity a backward difference and the acceleration zero. The arithmetic below works on
    numbers, numpy arrays and UFL expressions alike, so the solver builds its residual and
    updates its vectors from the same formulas.
    """

    alpha_m: float
    alpha_f: float
    beta: float
    gamma: float
    dynamic: bool = True

    @classmethod
    def newmark(cls) -> NewmarkFamily:
        """The trapezoidal rule (β = 1/4, γ = 1/2), balanced at the midpoint (αm = αf = 1/2).

        Only ``(a_n + a_{n+1})/2`` enters, so this is the implicit midpoint rule
        ``(η_{n+1} − η_n)/dt = (v_n + v_{n+1})/2``, ``M (v_{n+1} − v_n)/dt = −f_int + f_ext``:
        for linear problems identical to the classical trapezoidal Newmark (energy-conserving),
        and with the solver's energy-momentum stress exactly energy-conserving for SVK too.
        It is the generalized-α method with ρ∞ = 1.
        """
        return cls.generalized_alpha(1.0)

    @classmethod
    def generalized_alpha(cls, spectral_radius: float) -> NewmarkFamily:
        """Chung–Hulbert from the high-frequency spectral radius ρ∞ ∈ [0, 1]::

            αm = (2ρ∞ − 1)/(ρ∞ + 1),  αf = ρ∞/(ρ∞ + 1),
            γ = 1/2 − αm + αf,        β = (1 − αm + αf)²/4

        (second-order accurate, unconditionally stable, minimal low-frequency dissipation).
        """
        r = spectral_radius
        if not 0.0 <= r <= 1.0:
            raise ValueError(f"the spectral radius must lie in [0, 1], got {r}")
        alpha_m, alpha_f = (2 * r - 1) / (r + 1), r / (r + 1)
        return cls(alpha_m, alpha_f, (1 - alpha_m + alpha_f) ** 2 / 4, 0.5 - alpha_m + alpha_f)

    @classmethod
    def quasi_static(cls) -> NewmarkFamily:
        return cls(0.0, 0.0, 0.25, 0.5, dynamic=False)

    @staticmethod
    def at(x_new, x_old, alpha: float):
        """``x_{n+1-α} = (1 − α) x_new + α x_old``."""
        return (1 - alpha) * x_new + alpha * x_old

    def acceleration(self, eta, eta_n, v_n, a_n, dt):
        """``a_{n+1} = (η_{n+1} − η_n − dt v_n)/(β dt²) − (1/(2β) − 1) a_n`` (0 if quasi-static)."""
        if not self.dynamic:
            return 0 * eta
        b = self.beta
        return (eta - eta_n - dt * v_n) / (b * dt * dt) - (1 / (2 * b) - 1) * a_n

    def velocity(self, eta, eta_n, v_n, a_n, dt):
        """``v_{n+1} = v_n + dt ((1 − γ) a_n + γ a_{n+1})``; quasi-static ``(η_{n+1} − η_n)/dt``."""
        if not self.dynamic:
            return (eta - eta_n) / dt
        a = self.acceleration(eta, eta_n, v_n, a_n, dt)
        return v_n + dt * ((1 - self.gamma) * a_n + self.gamma * a)

    def amplification_matrix(self, omega_dt: float):
        """The matrix ``A`` of ``x_{n+1} = A x_n``, ``x = (u, dt u̇, dt² ü)``, for ``ü + ω²u = 0``.

        Its spectral radius is the per-step amplitude factor of a mode with ``ω dt = omega_dt``.
        """
        am, af, b, g, w2 = self.alpha_m, self.alpha_f, self.beta, self.gamma, omega_dt**2
        lhs = np.array([[w2 * (1 - af), 0, 1 - am], [1, 0, -b], [0, 1, -g]], dtype=float)
        rhs = np.array([[-w2 * af, 0, -am], [1, 1, 0.5 - b], [0, 1, 1 - g]], dtype=float)
        return np.linalg.solve(lhs, rhs)

    def spectral_radius(self, omega_dt: float) -> float:
        """``ρ(A(ω dt))``: 1 for the trapezoidal rule, → ρ∞ as ``ω dt → ∞``."""
        return float(np.abs(np.linalg.eigvals(self.amplification_matrix(omega_dt))).max())


STRUCTURAL_SCHEMES = {
    "newmark": lambda settings: NewmarkFamily.newmark(),
    "generalized_alpha": lambda settings: NewmarkFamily.generalized_alpha(settings.spectral_radius),
    "quasi_static": lambda settings: NewmarkFamily.quasi_static(),
}
"""The structural schemes by the ``structure.time_integration.scheme`` tag."""


def structural_scheme(settings) -> NewmarkFamily:
    """The scheme of ``structure.time_integration`` (a config object with a ``scheme`` tag)."""
    return STRUCTURAL_SCHEMES[settings.scheme](settings)
