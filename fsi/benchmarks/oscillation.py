"""Mean, amplitude and frequency of a periodic time series (the Turek–Hron convention), and their
comparison with reference values written "mean ± amplitude [frequency]".

Over the last full period ``[t_c[-2], t_c[-1]]``, t_c the upward crossings of the mean level
(:func:`up_crossings`): ``mean = (max y + min y) / 2``, ``amplitude = (max y − min y) / 2``,
``frequency = 1 / (t_c[-1] − t_c[-2])`` (docs/model.md). Pure numpy: no MPI, no files.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

HYSTERESIS = 0.5
"""An upward crossing counts only if the signal went below ``level − HYSTERESIS × amplitude``
since the previous counted one, so small ripples (higher harmonics, noise) around the level do
not split a period."""


class OscillationError(ValueError):
    """The series holds too few complete periods to be analysed."""


@dataclass(frozen=True)
class Oscillation:
    """The oscillation of one signal over its last ``window`` periods.

    Attributes:
        mean: (max + min) / 2 over the window.
        amplitude: (max − min) / 2 over the window.
        frequency: window / (t_c[-1] − t_c[-1 − window]) (Hz if t is in s).
        periods: complete periods found in the analysed record (upward crossings − 1).
        start, end: the window's first and last crossing times.
        period_change: (T_last − T_previous) / T_last of the last two single periods: near 0
            once the signal is periodic; a transient, or a subharmonic that makes successive
            periods alternate, shows here.
        level: the crossing level (the mean over the window, found by fixed-point iteration).
    """

    mean: float
    amplitude: float
    frequency: float
    periods: int
    start: float
    end: float
    period_change: float
    level: float

    @property
    def period(self) -> float:
        return 1.0 / self.frequency

    def __str__(self) -> str:
        return f"{self.mean:.6g} ± {self.amplitude:.6g} [{self.frequency:.6g}]"


def up_crossings(t: np.ndarray, y: np.ndarray, level: float, band: float = 0.0) -> np.ndarray:
    """Times at which y crosses ``level`` upwards, linear between samples:
    t_c = t_k + (level − y_k) / (y_{k+1} − y_k) (t_{k+1} − t_k) for y_k < level ≤ y_{k+1}.

    A crossing counts only if some sample since the previous counted crossing (or since the
    start, for the first) is below ``level − band``."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    k = np.flatnonzero((y[:-1] < level) & (y[1:] >= level))
    below = np.concatenate([[0], np.cumsum(y < level - band)])  # below[j]: samples < in y[:j]
    times, previous = [], 0
    for i in k:
        if below[i + 1] > below[previous]:
            times.append(t[i] + (level - y[i]) / (y[i + 1] - y[i]) * (t[i + 1] - t[i]))
            previous = i + 1
    return np.asarray(times)


def analyse(
    t: np.ndarray, y: np.ndarray, start: float | None = None, window: int = 1
) -> Oscillation:
    """Mean, amplitude and frequency of y(t) over its last ``window`` full periods.

    Args:
        t: sample times, increasing.
        y: samples.
        start: ignore samples before this time (e.g. the inflow ramp); None: use all.
        window: number of final periods to analyse (1: the benchmark's definition).

    The crossing level starts as the midrange of the last quarter of the record and is iterated
    to the midrange of the window itself. All three results are second-order accurate in the
    sampling step dt (the sampled extremes miss the true ones by at most max|y''| dt²/8). Raises
    :class:`OscillationError` if fewer than ``max(2, window)`` complete periods are present (two,
    so that ``period_change`` can tell whether the signal is periodic).
    """
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise ValueError(f"t and y must be 1D arrays of one length, got {t.shape}, {y.shape}")
    if window < 1:
        raise ValueError(f"window must be at least 1 period, got {window}")
    if start is not None:
        keep = t >= start
        t, y = t[keep], y[keep]
    needed = max(2, window)
    if len(t) < 3:
        raise OscillationError(
            f"{len(t)} samples{_after(start)}: need at least {needed} complete periods"
        )
    tail = t >= t[0] + 0.75 * (t[-1] - t[0])
    level = (y[tail].max() + y[tail].min()) / 2
    half_range = (y[tail].max() - y[tail].min()) / 2
    for _ in range(20):
        crossings = up_crossings(t, y, level, HYSTERESIS * half_range)
        if len(crossings) < needed + 1:
            raise OscillationError(
                f"only {max(len(crossings) - 1, 0)} complete period(s) in t = [{t[0]:.6g}, "
                f"{t[-1]:.6g}]{_after(start)} ({len(crossings)} upward crossings of the level "
                f"{level:.6g}); need at least {needed}: run longer or start the analysis earlier"
            )
        a, b = crossings[-1 - window], crossings[-1]
        inside = (t >= a) & (t <= b)
        high, low = y[inside].max(), y[inside].min()
        new_level, half_range = (high + low) / 2, (high - low) / 2
        if abs(new_level - level) <= 1e-12 * max(abs(high), abs(low), 1e-300):
            break
        level = new_level
    periods = np.diff(crossings)
    return Oscillation(
        mean=(high + low) / 2,
        amplitude=(high - low) / 2,
        frequency=window / (b - a),
        periods=len(periods),
        start=a,
        end=b,
        period_change=(periods[-1] - periods[-2]) / periods[-1],
        level=level,
    )


def _after(start: float | None) -> str:
    return "" if start is None else f" after t = {start:g}"


# --------------------------------------------------------------------------------------------
# Comparison with a reference


@dataclass(frozen=True)
class Reference:
    """A reference oscillation "mean ± amplitude [frequency]"; ``frequency`` None if not given
    (a steady value is ``Reference(value, 0.0, None)``)."""

    mean: float
    amplitude: float = 0.0
    frequency: float | None = None

    @classmethod
    def parse(cls, text: str) -> Reference:
        """From ``"439.45 ± 5.6183 [4.3956]"`` (``+-`` for ±; amplitude and frequency optional)."""
        number = r"([-+−]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"
        match = re.fullmatch(
            rf"\s*{number}\s*(?:(?:±|\+-)\s*{number})?\s*(?:\[\s*{number}\s*"
            r"(?:Hz)?\s*\])?\s*",
            text,
        )
        if match is None:
            raise ValueError(f"not a reference 'mean ± amplitude [frequency]': {text!r}")
        mean, amplitude, frequency = (
            None if g is None else float(g.replace("−", "-")) for g in match.groups()
        )
        return cls(mean, amplitude or 0.0, frequency)

    def __str__(self) -> str:
        text = f"{self.mean:g}"
        if self.amplitude:
            text += f" ± {self.amplitude:g}"
        if self.frequency is not None:
            text += f" [{self.frequency:g}]"
        return text


@dataclass(frozen=True)
class Tolerance:
    """Relative tolerances on mean, amplitude and frequency; None: not checked."""

    mean: float | None = None
    amplitude: float | None = None
    frequency: float | None = None


@dataclass(frozen=True)
class Difference:
    """One compared quantity: relative difference measured / reference − 1 and its verdict
    (``passed`` None when no tolerance applies)."""

    measured: float
    reference: float
    relative: float
    tolerance: float | None

    @property
    def passed(self) -> bool | None:
        return None if self.tolerance is None else bool(abs(self.relative) <= self.tolerance)


def relative_difference(measured: float, reference: float) -> float:
    """measured / reference − 1 (±inf if the reference is 0 and the measurement is not)."""
    if reference == 0:
        return 0.0 if measured == 0 else math.copysign(math.inf, measured)
    return measured / reference - 1


def compare(
    measured: Oscillation, reference: Reference, tolerance: Tolerance = Tolerance()
) -> dict[str, Difference]:
    """Relative differences of mean, amplitude and (if the reference has one) frequency, each
    with its tolerance: ``{"mean": Difference, "amplitude": ..., "frequency": ...}``."""
    pairs = {
        "mean": (measured.mean, reference.mean, tolerance.mean),
        "amplitude": (measured.amplitude, reference.amplitude, tolerance.amplitude),
    }
    if reference.frequency is not None:
        pairs["frequency"] = (measured.frequency, reference.frequency, tolerance.frequency)
    return {
        name: Difference(m, r, relative_difference(m, r), tol)
        for name, (m, r, tol) in pairs.items()
    }
