"""Lumped (0D) outlet models: the pressure P (Pa) an outlet imposes as a function of its flow
rate Q (m²/s per unit depth), applied by the fluid as σ n = −P n (fsi/physics/fluid.py): a
resistance (:class:`Resistance`) and the RCR Windkessel (:class:`Windkessel`), with their time
discretisation; :func:`from_config` builds the model of a ``fluid.outlet`` section
(:mod:`fsi.config.outlet_section`, the parameters).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
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


@dataclass(frozen=True)
class Resistance:
    """P = P_ref + R Q (``resistance`` R in Pa s/m², ``reference_pressure`` P_ref in Pa), Q the
    step's own (implicit). No state."""

    resistance: float
    reference_pressure: float

    def initial_state(self) -> np.ndarray:
        """The state before the first step: empty."""
        return np.zeros(0)

    def pressure_law(self, state: np.ndarray, weights: Sequence[float]) -> tuple[float, float]:
        """(P₀', R') = (P_ref, R): the step's outlet pressure is P = P₀' + R' Q (Pa)."""
        return self.reference_pressure, self.resistance

    def advance(self, state: np.ndarray, flow_rate: float, weights: Sequence[float]) -> np.ndarray:
        """The state after a step: unchanged (empty)."""
        return state

    def state_values(self, state: np.ndarray) -> dict[str, float]:
        """The state as named values for the metrics: none."""
        return {}


@dataclass(frozen=True)
class Windkessel:
    """The three-element Windkessel (RCR; Westerhof et al. 2009)::

        C dP_c/dt = Q − (P_c − P_ref)/R_d,    P = P_c + R_p Q,    P_c(0) = P_0,

    discretised with the fluid's time weights (:func:`fsi.numerics.timestepping.bdf_weights`; all
    zero when steady, then P_c = P_ref + R_d Q) and solved with the step's own (implicit) Q
    (:meth:`capacitor_pressure`), so the step's P is affine in Q (:meth:`pressure_law`).
    ``proximal_resistance`` R_p and ``distal_resistance`` R_d (Pa s/m²), ``compliance`` C (m²/Pa),
    ``initial_pressure`` P_0 and ``reference_pressure`` P_ref (Pa). State: [P_c^n, P_c^{n−1}] (Pa),
    a plain array the fluid solver keeps, saves and checkpoints.
    """

    proximal_resistance: float
    distal_resistance: float
    compliance: float
    initial_pressure: float
    reference_pressure: float

    def initial_state(self) -> np.ndarray:
        """The state before the first step: [P_0, P_0] (Pa)."""
        return np.array([self.initial_pressure, self.initial_pressure])

    def capacitor_pressure(
        self, state: np.ndarray, flow_rate: float, weights: Sequence[float]
    ) -> float:
        """P_c^{n+1} = (Q + P_ref/R_d − C (a₁ P_c^n + a₂ P_c^{n−1})) / (C a₀ + 1/R_d) (Pa), for
        the flow rate Q (m²/s) and the time weights (a₀, a₁, a₂) (1/s) of the step."""
        a0, a1, a2 = weights
        C, Rd = self.compliance, self.distal_resistance
        history = a1 * state[0] + a2 * state[1]
        return float((flow_rate + self.reference_pressure / Rd - C * history) / (C * a0 + 1 / Rd))

    def pressure_law(self, state: np.ndarray, weights: Sequence[float]) -> tuple[float, float]:
        """(P₀', R'): P = P_c^{n+1}(Q) + R_p Q = P₀' + R' Q with P₀' = P_c^{n+1}(0) (Pa) and
        R' = R_p + 1/(C a₀ + 1/R_d) (Pa s/m²), for the time weights (a₀, a₁, a₂) of the step."""
        a0 = weights[0]
        at_zero_flow = self.capacitor_pressure(state, 0.0, weights)
        return at_zero_flow, self.proximal_resistance + 1 / (
            self.compliance * a0 + 1 / self.distal_resistance
        )

    def advance(self, state: np.ndarray, flow_rate: float, weights: Sequence[float]) -> np.ndarray:
        """The state after the step whose flow rate was ``flow_rate`` (m²/s)."""
        return np.array([self.capacitor_pressure(state, flow_rate, weights), state[0]])

    def state_values(self, state: np.ndarray) -> dict[str, float]:
        """``windkessel_pressure``: P_c^n (Pa)."""
        return {"windkessel_pressure": float(state[0])}


def from_config(outlet: config.Outlet) -> OutletModel | None:
    """The model of a ``fluid.outlet`` section, with the section's parameters; None for a
    traction-free outlet."""
    if isinstance(outlet, config.ResistanceOutlet):
        return Resistance(outlet.resistance, outlet.reference_pressure)
    if isinstance(outlet, config.WindkesselOutlet):
        return Windkessel(
            outlet.proximal_resistance,
            outlet.distal_resistance,
            outlet.compliance,
            outlet.initial_pressure,
            outlet.reference_pressure,
        )
    return None
