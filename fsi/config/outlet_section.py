"""The ``fluid.outlet`` section: the outlet's condition (``kind`` picks one of :data:`Outlet`),
one frozen dataclass per condition with its parameters and their checks. The lumped (0D) ones
also give the pressure P they impose from the outlet's flow rate Q (fsi.physics.outlets hands
them to the fluid, which applies σ n = −P n in the ``open_boundary`` form). In 2D every quantity
is per unit depth: Q = ∫_outlet u·n ds (m²/s, positive out of the domain), resistances R in
Pa s/m², a compliance C in m²/Pa (docs/boundary-conditions.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from fsi.config.reader import non_negative, positive

BackflowForm = Literal["tangential", "tangential_velocity", "full"]
"""What an open boundary's backflow term −β/2 ρ min(u·n, 0) (…) acts on where blood enters:
``tangential`` (the outlet's default) the tangential velocity and the variation of the velocity
along the boundary (a tangential regularization: a plug-like reversal keeps the prescribed
traction), ``tangential_velocity`` (the inlet's default) the tangential velocity only (a normal
inflow of any profile keeps it), ``full`` the whole velocity (Esmaily Moghadam et al. 2011:
lowers the pressure of any inflow by β ρ (u·n)²/2). The terms are in
fsi/physics/fluid_residual.py (``FluidResidual._backflow``)."""


@dataclass(frozen=True)
class TractionFreeOutlet:
    """σ n = 0 (in the ``open_boundary`` form; the study's outlet, the default). Every outlet's
    ``backflow_stabilization`` β ≥ 0 scales the term that acts where blood re-enters through it,
    in the ``backflow_form`` :data:`BackflowForm` (docs/boundary-conditions.md)."""

    kind: Literal["traction_free"] = field(default="traction_free", kw_only=True)
    backflow_stabilization: float = non_negative(1.0)
    backflow_form: BackflowForm = "tangential"


@dataclass(frozen=True)
class ResistanceOutlet:
    """σ n = −P n with P = P_ref + R Q: ``resistance`` R (Pa s/m², per unit depth),
    ``reference_pressure`` P_ref (Pa). Q is the step's own (implicit:
    fsi.physics.fluid_residual.LumpedOutlet). No state."""

    kind: Literal["resistance"] = field(default="resistance", kw_only=True)
    resistance: float = non_negative(0.0, "Pa s/m^2")
    reference_pressure: float = 0.0
    backflow_stabilization: float = non_negative(1.0)
    backflow_form: BackflowForm = "tangential"

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
class WindkesselOutlet:
    """The three-element Windkessel (RCR; Westerhof et al. 2009)::

        C dP_c/dt = Q − (P_c − P_ref)/R_d,    P = P_c + R_p Q,    P_c(0) = P_0,

    discretised with the fluid's time weights (:func:`fsi.numerics.timestepping.bdf_weights`; all
    zero when steady, then P_c = P_ref + R_d Q) and solved with the step's own (implicit) Q
    (:meth:`capacitor_pressure`), so the step's P is affine in Q (:meth:`pressure_law`).
    ``proximal_resistance`` R_p and ``distal_resistance`` R_d (Pa s/m²), ``compliance`` C (m²/Pa),
    ``initial_pressure`` P_0 and ``reference_pressure`` P_ref (Pa). State: [P_c^n, P_c^{n−1}] (Pa),
    a plain array the fluid solver keeps, saves and checkpoints.
    """

    kind: Literal["windkessel"] = field(default="windkessel", kw_only=True)
    proximal_resistance: float = non_negative(0.0, "Pa s/m^2")
    distal_resistance: float = positive(1.0e6, "Pa s/m^2")
    compliance: float = positive(1.0e-7, "m^2/Pa")
    initial_pressure: float = 0.0
    reference_pressure: float = 0.0
    backflow_stabilization: float = non_negative(1.0)
    backflow_form: BackflowForm = "tangential"

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


Outlet = TractionFreeOutlet | ResistanceOutlet | WindkesselOutlet
