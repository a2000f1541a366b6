"""Time schemes, kept apart from the physics (STYLE.md §3).

* :func:`steps` walks the configured step schedule (the study's 5 ms / 10 ms, or a resolved one).
* :func:`bdf_weights` gives the variable-step backward-difference weights used by the fluid:
  ``∂u/∂t (t_{n+1}) ≈ Σ_k w_k u^{n+1-k}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

from fsi.config import Time


@dataclass(frozen=True)
class Step:
    """Step number ``index`` (1-based) advancing from ``t - dt`` to ``t``."""

    index: int
    t: float
    dt: float


def steps(time: Time, t0: float = 0.0, index0: int = 0) -> Iterator[Step]:
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
