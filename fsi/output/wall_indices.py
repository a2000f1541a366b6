"""The hemodynamic indices TAWSS, OSI and RRT of wall samples (docs/hemodynamic-indices.md):
:class:`WallIndices` accumulates their time integrals step by step from the samples' wall shear
stress, a signed scalar in 2D, the vector in 3D (fsi.output.metrics.WallSampler gives both).
"""

from __future__ import annotations

import numpy as np


class WallIndices:
    """The time-averaged wall shear stress (TAWSS), the oscillatory shear index (OSI) and the
    relative residence time (RRT) of wall samples whose signed wall shear stress τ_i(t) is
    given step by step (:meth:`add`), over the window from ``start`` to the last step's end::

        TAWSS = (1/T) ∫ |τ| dt,   OSI = ½ (1 − |∫ τ dt| / ∫ |τ| dt),   RRT = T / |∫ τ dt|

    (docs/hemodynamic-indices.md). With ``interpolate`` (a time-dependent run) the integrals are
    exact for τ linear over each step (also where τ changes sign), second order in any steps; the
    value at the window's end is :meth:`set_value`'s or the last :meth:`add`'s. Without it (a
    steady run) each step counts with its end value. A step across ``start`` counts for its part
    after it. The state (:meth:`state`): the two integrals per sample, the last step's time and T.

    ``components`` 3 (a 3D wall): τ_i is the wall shear stress vector, |τ| its length and
    ∫ τ dt a vector (3 + 1 integrals per sample); |τ| over a step by
    :func:`mean_vector_magnitude`.
    """

    def __init__(
        self,
        size: int,
        start: float = 0.0,
        time: float = 0.0,
        interpolate: bool = True,
        components: int = 1,
    ):
        self.interpolate = interpolate
        self.start = float(start)
        self.time = float(time)  # the end of the last step added
        self.duration = 0.0  # T, the part of the window covered so far
        self.components = components  # 1: a signed τ (2D); 3: the vector τ (3D)
        self.integrals = np.zeros((size, components + 1))  # per sample: ∫ τ dt, ∫ |τ| dt
        self.value: np.ndarray | None = None  # τ at self.time, when known

    def _checked(self, tau: np.ndarray) -> np.ndarray:
        tau = np.asarray(tau, dtype=float)
        shape = (len(self.integrals),) + ((self.components,) if self.components > 1 else ())
        if tau.shape != shape:
            what = f"{shape[0]} wall shear stresses" + (
                f" of {self.components} components" if self.components > 1 else ""
            )
            raise ValueError(f"expected {what}, got {tau.shape}")
        return tau

    def set_value(self, tau: np.ndarray) -> None:
        """τ at the window's current end ``time`` (one per sample): the start of the next
        step's linear interpolant (ignored without ``interpolate``)."""
        self.value = self._checked(tau).copy() if self.interpolate else None

    def value_at(self, t: float, t_end: float, tau: np.ndarray) -> np.ndarray:
        """τ at ``t`` within the step (time, t_end] that ends with ``tau``: linear in time
        from the value at ``time`` where that is known, else ``tau``."""
        tau = np.asarray(tau, dtype=float)
        if self.value is None:
            return tau
        return self.value + (tau - self.value) * ((t - self.time) / (t_end - self.time))

    def add(self, t: float, tau: np.ndarray) -> None:
        """Add the step (time, t] ending with the values ``tau`` (one per sample)."""
        if not t > self.time:
            raise ValueError(f"a step must end after the last one ({self.time!r}), got t = {t!r}")
        tau = self._checked(tau)
        if t > self.start:
            a = max(self.time, self.start)
            begin = self.value_at(a, t, tau)
            weight = t - a
            if self.components == 1:
                self.integrals[:, 0] += weight * 0.5 * (begin + tau)
                self.integrals[:, 1] += weight * mean_magnitude(begin, tau)
            else:
                self.integrals[:, :-1] += weight * 0.5 * (begin + tau)
                self.integrals[:, -1] += weight * mean_vector_magnitude(begin, tau)
            self.duration += weight
        self.time = float(t)
        self.value = tau.copy() if self.interpolate else None

    @property
    def tawss(self) -> np.ndarray:
        """(1/T) ∫ |τ| dt (Pa); NaN before the window has any length."""
        if self.duration <= 0:
            return np.full(len(self.integrals), np.nan)
        return self.integrals[:, -1] / self.duration

    def _mean(self) -> np.ndarray:
        """|∫ τ dt| per sample."""
        if self.components == 1:
            return np.abs(self.integrals[:, 0])
        return np.linalg.norm(self.integrals[:, :-1], axis=1)

    @property
    def osi(self) -> np.ndarray:
        """½ (1 − |∫ τ dt| / ∫ |τ| dt), in [0, ½]; NaN where ∫ |τ| dt = 0 (no shear at all:
        undefined)."""
        mean, magnitude = self._mean(), self.integrals[:, -1]
        osi = np.full(len(mean), np.nan)
        sheared = magnitude > 0
        osi[sheared] = 0.5 * (1.0 - np.minimum(mean[sheared] / magnitude[sheared], 1.0))
        return osi

    @property
    def rrt(self) -> np.ndarray:
        """T / |∫ τ dt| = 1 / ((1 − 2 OSI) TAWSS) (1/Pa); +inf where the mean shear is zero,
        NaN before the window has any length."""
        mean = self._mean()
        if self.duration <= 0:
            return np.full(len(mean), np.nan)
        rrt = np.full(len(mean), np.inf)
        rrt[mean > 0] = self.duration / mean[mean > 0]
        return rrt

    def state(self) -> dict[str, np.ndarray]:
        """``integrals`` (size, 2): ∫ τ dt and ∫ |τ| dt per sample; ``window`` (2,): the time
        of the last step and T. (The value at ``time`` is not kept: :meth:`set_value` it.)"""
        return {"integrals": self.integrals.copy(), "window": np.array([self.time, self.duration])}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Continue from :meth:`state`'s arrays (the integrals of the same samples)."""
        width = self.components + 1
        integrals = np.asarray(state["integrals"], dtype=float).reshape(-1, width)
        if len(integrals) != len(self.integrals):
            raise ValueError(
                f"expected integrals of {len(self.integrals)} samples, got {len(integrals)}"
            )
        self.integrals = integrals.copy()
        self.time, self.duration = (float(v) for v in state["window"])


def mean_magnitude(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The mean of |τ| over a step along which τ goes linearly from ``a`` to ``b``:
    (|a| + |b|)/2 without a change of sign, (a² + b²) / (2 (|a| + |b|)) with one (0 for
    a = b = 0)."""
    same = a * b >= 0
    total = np.abs(a) + np.abs(b)
    crossing = np.divide(a * a + b * b, 2 * total, out=np.zeros_like(total), where=total > 0)
    return np.where(same, 0.5 * total, crossing)


def mean_vector_magnitude(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The mean of |τ| over a step along which the vector τ goes linearly from ``a`` to ``b``
    (rows of (n, k)), by Simpson's rule, (|a| + 4 |(a + b)/2| + |b|) / 6: exact where τ keeps
    its direction over the step, second order in the step where it turns smoothly; where it
    reverses through 0 (the kink of |τ| that :func:`mean_magnitude` integrates exactly for a
    scalar) it is off by up to |a|/6 (a = −b: |a|/3 for |a|/2)."""
    norm = np.linalg.norm
    return (norm(a, axis=1) + 4 * norm(0.5 * (a + b), axis=1) + norm(b, axis=1)) / 6
