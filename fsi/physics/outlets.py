"""Lumped (0D) outlet models: the pressure P an outlet imposes as a function of its flow rate Q.

In 2D every quantity is per unit depth: Q = ∫_outlet u·n ds (m²/s, positive out of the
domain), resistances R in Pa s/m², a compliance C in m²/Pa. The fluid applies P as the
open-boundary traction σ n = −P n (fsi/physics/fluid.py). Two models (docs/boundary-conditions.md):

- resistance: P = P_ref + R Q;
- three-element Windkessel (RCR; Westerhof et al. 2009):

      C dP_c/dt = Q − (P_c − P_ref)/R_d,    P = P_c + R_p Q,    P_c(0) = P_0.

The ODE is discretised with the fluid's own time weights
(:func:`fsi.numerics.timestepping.bdf_weights`: backward Euler, variable-step BDF2; all zero when
steady), dP_c/dt ≈ a₀ P_c^{n+1} + a₁ P_c^n + a₂ P_c^{n−1}, and solved with the step's own (implicit)
Q:

    P_c^{n+1} = (Q + P_ref/R_d − C (a₁ P_c^n + a₂ P_c^{n−1})) / (C a₀ + 1/R_d),

so each step's outlet pressure is affine in the step's flow rate, P = P₀' + R' Q with
R' = R_p + R_d/(1 + R_d C a₀) > 0 (:meth:`Windkessel.pressure_law`); steady (a = 0), P_c is at
its steady value P_ref + R_d Q. A model is a frozen object of its parameters; its state (the
Windkessel's P_c^n, P_c^{n−1}) is a plain array the fluid solver keeps, saves and checkpoints.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from fsi import config


class OutletModel(Protocol):
    """P = P₀' + R' Q within a step (:meth:`pressure_law`); :meth:`advance` accepts the step."""

    def initial_state(self) -> np.ndarray: ...

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
    """P = P_ref + R Q (no state)."""

    resistance: float
    reference_pressure: float = 0.0

    def initial_state(self) -> np.ndarray:
        return np.zeros(0)

    def pressure_law(self, state: np.ndarray, weights: Sequence[float]) -> tuple[float, float]:
        return self.reference_pressure, self.resistance

    def advance(self, state: np.ndarray, flow_rate: float, weights: Sequence[float]) -> np.ndarray:
        return state

    def state_values(self, state: np.ndarray) -> dict[str, float]:
        return {}


@dataclass(frozen=True)
class Windkessel:
    """The RCR model of the module docstring. State: [P_c^n, P_c^{n−1}] (Pa)."""

    proximal_resistance: float
    distal_resistance: float
    compliance: float
    initial_pressure: float = 0.0
    reference_pressure: float = 0.0

    def initial_state(self) -> np.ndarray:
        return np.array([self.initial_pressure, self.initial_pressure])

    def capacitor_pressure(
        self, state: np.ndarray, flow_rate: float, weights: Sequence[float]
    ) -> float:
        """P_c^{n+1} = (Q + P_ref/R_d − C (a₁ P_c^n + a₂ P_c^{n−1})) / (C a₀ + 1/R_d)."""
        a0, a1, a2 = weights
        C, Rd = self.compliance, self.distal_resistance
        history = a1 * state[0] + a2 * state[1]
        return float((flow_rate + self.reference_pressure / Rd - C * history) / (C * a0 + 1 / Rd))

    def pressure_law(self, state: np.ndarray, weights: Sequence[float]) -> tuple[float, float]:
        """P = P_c^{n+1}(Q) + R_p Q: P₀' = P_c^{n+1}(0), R' = R_p + 1/(C a₀ + 1/R_d)."""
        a0 = weights[0]
        at_zero_flow = self.capacitor_pressure(state, 0.0, weights)
        return at_zero_flow, self.proximal_resistance + 1 / (
            self.compliance * a0 + 1 / self.distal_resistance
        )

    def advance(self, state: np.ndarray, flow_rate: float, weights: Sequence[float]) -> np.ndarray:
        return np.array([self.capacitor_pressure(state, flow_rate, weights), state[0]])

    def state_values(self, state: np.ndarray) -> dict[str, float]:
        """``windkessel_pressure``: P_c^n."""
        return {"windkessel_pressure": float(state[0])}


MODELS: dict[str, type] = {"resistance": Resistance, "windkessel": Windkessel}
"""The models by the ``fluid.outlet.kind`` tag; each takes its section's parameters (a
``traction_free`` outlet has none)."""


def from_config(outlet: config.Outlet) -> OutletModel | None:
    """The model of a ``fluid.outlet`` section; None for a traction-free outlet."""
    parameters = dataclasses.asdict(outlet)
    kind = parameters.pop("kind")
    parameters.pop("backflow_stabilization")
    return MODELS[kind](**parameters) if kind in MODELS else None
