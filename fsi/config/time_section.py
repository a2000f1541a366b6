"""The ``time`` section: the step schedule, its heartbeats and the step size control
(:class:`Time`, :class:`TimeSegment`, :class:`AdaptiveStepping`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

from fsi.config.reader import at_least, checked, non_negative, positive


@dataclass(frozen=True)
class TimeSegment:
    """Steps of ``dt`` until time ``until`` (the last step of a segment ends exactly on it)."""

    until: float = positive(0.4, "s")
    dt: float = positive(5.0e-3, "s")


@dataclass(frozen=True)
class AdaptiveStepping:
    """``time.adaptive``: the step size control of ``time.step_control: adaptive``
    (fsi.numerics.timestepping: :class:`~fsi.numerics.timestepping.LocalError`,
    :class:`~fsi.numerics.timestepping.StepSizeControl`; docs/configuration.md).

    ``tolerance``: the largest local error a step may make in each controlled field (the
    fluid's velocity, the structure's displacement), relative to the largest entry the field
    has had, or to ``velocity_scale`` (m/s) / ``displacement_scale`` (m) while it is smaller: a
    run that starts from rest needs these, the size the fields are expected to reach, else the
    first steps are held to the tolerance relative to fields that are still tiny. A step above
    the tolerance is taken again shorter. ``first_dt``: the size of the first steps (the first
    two have no estimate yet). ``min_dt``: no step is made shorter; a step whose error is still
    above the tolerance there fails the run (with a checkpoint).
    """

    tolerance: float = positive(1.0e-3)
    first_dt: float = positive(1.0e-4, "s")
    min_dt: float = positive(1.0e-7, "s")
    velocity_scale: float = non_negative(0.0, "m/s")
    displacement_scale: float = non_negative(0.0, "m")


MAX_CYCLES = 1000
"""The most heartbeats ``time.cycles`` may ask for (each repeats the schedule's segments)."""


@dataclass(frozen=True)
class Time:
    """The step schedule; the default is the study's: 5 ms to 0.4 s, then 10 ms to 0.8 s.

    ``scheme``: the fluid's time scheme; ``steady`` drops ∂u/∂t and the mesh velocity (each step a
    steady solve with the boundary data at its time). ``step_control``: ``schedule`` steps as
    ``schedule`` says; ``adaptive`` chooses each step from a local error estimate
    (:class:`AdaptiveStepping`), at most its segment's ``dt``, ending on every ``until``, on
    ``output.report_times`` and on ``end``. ``retries``: how often a failed step is retaken from the
    state before it as two halves (up to 2^retries substeps; 0: a failed step ends the run).
    ``max_steps``: the most steps to ``end`` validation accepts
    (:func:`fsi.config.run_size.count_steps`), so a mistyped ``dt`` fails at once. ``cycles``:
    N >= 1 runs N heartbeats of ``fluid.inlet.period`` T, to t = N T, repeating one heartbeat's
    ``schedule`` (:meth:`run_schedule`); ``end`` must then be T or N T. 0: ``end`` and ``schedule``
    as written. docs/configuration.md has the details.
    """

    end: float = positive(0.8, "s")
    scheme: Literal["backward_euler", "bdf2", "steady"] = "bdf2"
    schedule: tuple[TimeSegment, ...] = (TimeSegment(0.4, 5.0e-3), TimeSegment(0.8, 1.0e-2))
    step_control: Literal["schedule", "adaptive"] = "schedule"
    adaptive: AdaptiveStepping = field(default_factory=AdaptiveStepping)
    retries: int = checked(0, lambda v: 0 <= v <= 8, "an integer in [0, 8]")
    max_steps: int = at_least(1_000_000, 1)
    cycles: int = checked(
        0,
        lambda v: 0 <= v <= MAX_CYCLES,
        f"an integer in [0, {MAX_CYCLES}] (0: time.end sets the end)",
    )

    def run_schedule(self, period: float) -> Time:
        """The schedule the run steps through (:func:`fsi.numerics.timestepping.steps` of it): this
        one when ``cycles`` is 0 or there is no ``period``; else ``cycles`` copies of this
        schedule's steps from 0 to ``period`` T, the k-th shifted by (k − 1) T so that every
        heartbeat ends exactly on k T, and ``end`` = ``cycles`` × T."""
        if self.cycles < 1 or not period > 0:
            return self
        beat = []  # one heartbeat's segments: (until within (0, T], dt)
        for segment in self.schedule:
            beat.append((min(segment.until, period), segment.dt))
            if segment.until >= period:
                break
        segments = []
        for k in range(self.cycles):
            for until, dt in beat:
                end_of_beat = until >= period
                segments.append(
                    TimeSegment((k + 1) * period if end_of_beat else k * period + until, dt)
                )
        return dataclasses.replace(
            self, end=self.cycles * period, schedule=tuple(segments), cycles=0
        )
