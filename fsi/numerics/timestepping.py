"""Time schemes, kept apart from the physics.

The step schedule (:func:`steps`; adaptive: :class:`AdaptiveSteps`, :class:`LocalError`,
:class:`StepSizeControl`), the fluid's variable-step backward differences (:func:`bdf_weights`,
:class:`BdfHistory`), extrapolation from past levels (:func:`extrapolation_weights`) and the
structure's generalized-α / Newmark family (:class:`NewmarkFamily`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol

from mpi4py import MPI

import numpy as np

SAME_TIME = 1e-9
"""Two times closer than this fraction of their scale (the step, the period, the end or the time
itself) are the same time: a schedule's remainder shorter than ``SAME_TIME`` dt is merged into
the step before it, a run whose last row is within ``SAME_TIME`` end has reached the end, and
times read back from files (metrics.csv's 10 significant digits, XDMF's text) match. The one
tolerance on times everywhere in fsi."""


class Segment(Protocol):
    """A stretch of the schedule: steps of ``dt`` (s) until time ``until`` (s)."""

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
        while stop - t > SAME_TIME * segment.dt:
            dt = segment.dt if stop - (t + segment.dt) > SAME_TIME * segment.dt else stop - t
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
# Adaptive time stepping: a local error estimate and the step size it asks for


def extrapolation_weights(times: Sequence[float], t: float) -> list[float]:
    """Weights ``w`` of the polynomial through ``(times[i], x_i)`` evaluated at ``t``:
    ``x(t) ≈ Σ_i w_i x_i`` (Lagrange; degree ``len(times) − 1``, distinct times)."""
    m = len(times)
    return [
        float(np.prod([(t - times[j]) / (times[i] - times[j]) for j in range(m) if j != i]))
        for i in range(m)
    ]


class LocalError:
    """The local time error of a second-order step of one field, by Milne's device.

    The step's result ``x`` at ``t`` and the quadratic extrapolation ``P(t)`` of the last three
    accepted levels differ by ``C h³ x⁽³⁾`` to leading order, as the step's own local error does.
    The estimate is that difference relative to the largest the field has been in the
    accepted levels (not in this step, whose blow-up would otherwise inflate its own scale)::

        e = ‖x − P(t)‖ / max(floor, max_k ‖x_k‖)   (‖x‖ itself only while both are 0)

    with ‖·‖ the largest absolute entry over the first ``owned`` local entries, reduced over
    ``comm``. ``floor`` (the size the field is expected to reach) keeps a field starting from rest
    from being followed to a fixed relative accuracy while it is tiny. e scales with h³
    (:class:`StepSizeControl`, order 2). Until three levels are accepted (a run's first two steps)
    :meth:`estimate` returns None.
    """

    LEVELS = 3

    def __init__(self, comm, owned: int, floor: float = 0.0):
        self.comm, self.owned, self.floor = comm, owned, floor
        self._values: deque[np.ndarray] = deque(maxlen=self.LEVELS)
        self._times: deque[float] = deque(maxlen=self.LEVELS)
        self.scale = 0.0

    def norm(self, x: np.ndarray) -> float:
        """‖x‖: the largest |entry| over the owned entries. Collective."""
        owned = x[: self.owned]
        local = float(np.abs(owned).max()) if owned.size else 0.0
        return float(self.comm.allreduce(local, op=MPI.MAX))

    def estimate(self, x: np.ndarray, t: float) -> float | None:
        """e for the result ``x`` at time ``t`` (None with fewer than three accepted levels).
        Collective."""
        if len(self._values) < self.LEVELS:
            return None
        weights = extrapolation_weights(list(self._times), t)
        predicted = sum(w * v for w, v in zip(weights, self._values))
        # The accepted levels' size, not this step's: a step that blows up cannot inflate the
        # scale it is measured against (only a field at rest throughout has none).
        scale = max(self.floor, self.scale) or self.norm(x)
        return self.norm(x - predicted) / scale if scale > 0 else 0.0

    def accept(self, x: np.ndarray, t: float) -> None:
        """Record ``x`` as the accepted level at ``t``. Collective."""
        self._values.append(np.array(x, dtype=float))
        self._times.append(float(t))
        self.scale = max(self.scale, self.norm(x))

    def state(self) -> dict[str, np.ndarray]:
        """``values`` (local entries × levels, oldest first), their ``times``, ``scale``."""
        values = np.column_stack(list(self._values)) if self._values else np.zeros((0, 0))
        return {
            "values": values,
            "times": np.array(self._times, dtype=float),
            "scale": np.array(self.scale),
        }

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Take back :meth:`state`."""
        self._values.clear()
        self._times.clear()
        for x, t in zip(state["values"].T, state["times"]):
            self._values.append(np.array(x, dtype=float))
            self._times.append(float(t))
        self.scale = float(state["scale"])


@dataclass(frozen=True)
class StepSizeControl:
    """The step size from a local error estimate ``e`` ∝ ``dt^(order+1)``
    (:class:`LocalError`: order 2), keeping e near ``tolerance``::

        dt_next = dt · clip(safety · (tolerance / e)^(1/(order+1)), max_shrink, max_growth)

    except that a step grows only by ``hold`` or more, else it stays as it was: over stretches
    of equal steps the solvers' kept Jacobians (whose time-derivative term holds 1/dt) and the
    coupling's secant columns of past steps stay valid. A step with ``e > tolerance`` is
    rejected (:meth:`accepts`) and taken again with the smaller step; no step is made shorter
    than ``min_dt`` or longer than the ``max_dt`` given.
    """

    tolerance: float
    min_dt: float
    order: int = 2
    safety: float = 0.9
    max_shrink: float = 0.2
    max_growth: float = 2.0
    hold: float = 1.5

    def accepts(self, error: float | None) -> bool:
        """Whether a step with estimate ``error`` (None: none yet) stands."""
        return error is None or error <= self.tolerance

    def next_dt(self, dt: float, error: float | None, max_dt: float) -> float:
        """The step after (or instead of) one of ``dt`` with ``error`` (None: no estimate,
        ``dt`` again), within [min_dt, max_dt]."""
        if error is None:
            factor = 1.0
        elif error <= 0:
            factor = self.max_growth
        else:
            factor = self.safety * (self.tolerance / error) ** (1.0 / (self.order + 1))
            factor = min(self.max_growth, max(self.max_shrink, factor))
            if 1.0 < factor < self.hold:
                factor = 1.0
        return min(max_dt, max(self.min_dt, dt * factor))


def fit_to_stop(t: float, dt: float, stop: float) -> float:
    """The step from ``t`` towards ``stop``: ``dt``; all that is left when that is at most
    ``dt`` (a remainder below 1e-9 dt is not left behind); half of it when it is less than
    2 dt (no sliver of a step just before ``stop``)."""
    left = stop - t
    if left <= dt * (1 + SAME_TIME):
        return left
    if left < 2 * dt:
        return left / 2
    return dt


class AdaptiveSteps:
    """The steps of an adaptive run (``time.step_control: adaptive``), one at a time: each as
    long as ``control`` last asked for (:meth:`accept`, :meth:`retry`), at most the ``dt`` of
    the schedule's segment it lies in, and shortened (:func:`fit_to_stop`) to end exactly on
    every segment's ``until``, on each of ``stops`` (report times) and on ``time.end``.

    ``t0``, ``index0``: the time and number of the last step taken (0, 0 at the start);
    ``dt``: the size to try first."""

    def __init__(
        self,
        time: Schedule,
        control: StepSizeControl,
        stops: Sequence[float],
        t0: float,
        index0: int,
        dt: float,
    ):
        self.time, self.control = time, control
        self.stops = sorted(s for s in stops if 0 < s < time.end)
        self.t, self.index, self.dt = t0, index0, dt

    def _limit(self) -> tuple[float, float]:
        """The largest step allowed from ``t`` and the next time a step must end on."""
        for segment in self.time.schedule:
            if segment.until - self.t > SAME_TIME * segment.dt:
                break
        stop = min(segment.until, self.time.end)
        later = [s for s in self.stops if s - self.t > SAME_TIME * segment.dt]
        return segment.dt, min([stop, *later])

    def _step(self, index: int, dt: float) -> Step:
        max_dt, stop = self._limit()
        dt = fit_to_stop(self.t, min(dt, max_dt), stop)
        return Step(index, stop if dt == stop - self.t else self.t + dt, dt)

    def next_step(self) -> Step | None:
        """The next step, or None at ``time.end``."""
        if self.time.end - self.t <= SAME_TIME * self.dt:
            return None
        return self._step(self.index + 1, self.dt)

    def accept(self, step: Step, error: float | None) -> None:
        """``step`` stands, with the error estimate ``error`` (None: none yet, the next step
        as long as this one was meant to be)."""
        self.t, self.index = step.t, step.index
        if error is not None:
            self.dt = self.control.next_dt(step.dt, error, math.inf)

    def retry(self, step: Step, error: float) -> Step:
        """``step``, rejected for ``error``, taken again shorter (never below ``min_dt``)."""
        self.dt = self.control.next_dt(step.dt, error, step.dt)
        return self._step(step.index, self.dt)


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

    ``dynamic = False`` is quasi-static: no inertia, balance at ``t_{n+1}``, the velocity a
    backward difference, the acceleration zero. The arithmetic works on numbers, numpy arrays and
    UFL expressions alike.
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
