"""Display units: each quantity is shown in the largest of its units in which the largest value
is at least 1 (300 Pa, 17 kPa; 230 µm; 27 cm/s), for the report's tables and plots
(fsi/output/report.py) and the field pictures (fsi/output/plot.py)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Unit:
    """A display unit: a value in it is ``scale`` × the SI value."""

    name: str
    scale: float


STRESS_UNITS = (Unit("Pa", 1.0), Unit("kPa", 1.0e-3), Unit("MPa", 1.0e-6))
UNITS: dict[str, tuple[Unit, ...]] = {  # per quantity, from the smallest unit to the largest
    "stress": STRESS_UNITS,
    "pressure": STRESS_UNITS,
    "displacement": (Unit("µm", 1.0e6), Unit("mm", 1.0e3)),
    "length": (Unit("mm", 1.0e3),),
    "velocity": (Unit("cm/s", 1.0e2), Unit("m/s", 1.0)),
    "flow_rate": (Unit("cm²/s", 1.0e4),),  # per unit depth: mL/s per cm of depth
    "viscosity": (Unit("mPa·s", 1.0e3),),
    "rate": (Unit("1/s", 1.0),),
    "count": (Unit("", 1.0),),
}


def choose_unit(quantity: str, values: Sequence[float]) -> Unit:
    """The unit of ``UNITS[quantity]`` to show ``values`` (SI) in: the largest one in which the
    largest finite |value| is at least 1; the smallest one if there is none (or no values)."""
    units = UNITS[quantity]
    peak = max((abs(v) for v in values if math.isfinite(v)), default=0.0)
    fitting = [unit for unit in units if peak * unit.scale >= 1.0]
    return fitting[-1] if fitting else units[0]
