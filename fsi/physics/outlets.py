"""Lumped (0D) outlet models: the pressure P (Pa) an outlet imposes as a function of its flow
rate Q (m²/s per unit depth), applied by the fluid as σ n = −P n (fsi/physics/fluid.py). The
models (resistance, RCR Windkessel) and their time discretisation are the ``fluid.outlet``
section's own classes (:mod:`fsi.config.outlet_section`); :func:`from_config` picks them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from fsi import config


class OutletModel(Protocol):
    """P = P₀' + R' Q within a step (:meth:`pressure_law`); :meth:`advance` accepts the step."""

    def initial_state(self) -> np.ndarray:
        """The state before the first step."""
        ...

    def pressure_law(self, state: np.ndarray, weights: Sequence[float]) -> tuple[float, float]:
        """(P₀', R'): the step's outlet pressure is P = P₀' + R' Q (Pa), Q the step's flow
        rate, with the time weights (a₀, a₁, a₂) of the step."""
        ...

    def advance(self, state: np.ndarray, flow_rate: float, weights: Sequence[float]) -> np.ndarray:
        """The state after the step whose flow rate was ``flow_rate``."""
        ...

    def state_values(self, state: np.ndarray) -> dict[str, float]:
        """The state as named values for the metrics (Pa)."""
        ...


def from_config(outlet: config.Outlet) -> OutletModel | None:
    """The model of a ``fluid.outlet`` section: the section itself for a lumped outlet
    (resistance, Windkessel), None for a traction-free one."""
    return None if isinstance(outlet, config.TractionFreeOutlet) else outlet
