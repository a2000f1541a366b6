"""The ``fluid.outlet`` section: the outlet's condition (``kind`` picks one of :data:`Outlet`),
one frozen dataclass per condition with its parameters and their checks. The lumped (0D) models
that give the pressure P an outlet imposes from its flow rate Q are fsi/physics/outlets.py's
(the fluid applies σ n = −P n in the ``open_boundary`` form). In 2D every quantity
is per unit depth: Q = ∫_outlet u·n ds (m²/s, positive out of the domain), resistances R in
Pa s/m², a compliance C in m²/Pa (docs/boundary-conditions.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from fsi.config.reader import non_negative, positive

BackflowForm = Literal["tangential", "tangential_velocity", "full"]
"""What an open boundary's backflow term −β/2 ρ min(u·n, 0) (…) acts on where blood enters:
``tangential`` (the outlet's default) the tangential velocity and the variation of the velocity
along the boundary (a tangential regularization: a plug-like reversal keeps the prescribed
traction), ``tangential_velocity`` (the inlet's default) the tangential velocity only (a normal
inflow of any profile keeps it), ``full`` the whole velocity (Esmaily Moghadam et al. 2011:
lowers the pressure of any inflow by β ρ (u·n)²/2). The terms are in
fsi/physics/fluid_boundary_terms.py (``BoundaryTerms._backflow``)."""


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
    fsi.physics.fluid_boundary_terms.LumpedOutlet; the model: fsi.physics.outlets.Resistance)."""

    kind: Literal["resistance"] = field(default="resistance", kw_only=True)
    resistance: float = non_negative(0.0, "Pa s/m^2")
    reference_pressure: float = 0.0
    backflow_stabilization: float = non_negative(1.0)
    backflow_form: BackflowForm = "tangential"


@dataclass(frozen=True)
class WindkesselOutlet:
    """The three-element Windkessel (RCR; Westerhof et al. 2009)::

        C dP_c/dt = Q − (P_c − P_ref)/R_d,    P = P_c + R_p Q,    P_c(0) = P_0,

    ``proximal_resistance`` R_p and ``distal_resistance`` R_d (Pa s/m²), ``compliance`` C (m²/Pa),
    ``initial_pressure`` P_0 and ``reference_pressure`` P_ref (Pa). The ODE's time discretisation
    and its state: fsi.physics.outlets.Windkessel.
    """

    kind: Literal["windkessel"] = field(default="windkessel", kw_only=True)
    proximal_resistance: float = non_negative(0.0, "Pa s/m^2")
    distal_resistance: float = positive(1.0e6, "Pa s/m^2")
    compliance: float = positive(1.0e-7, "m^2/Pa")
    initial_pressure: float = 0.0
    reference_pressure: float = 0.0
    backflow_stabilization: float = non_negative(1.0)
    backflow_form: BackflowForm = "tangential"


Outlet = TractionFreeOutlet | ResistanceOutlet | WindkesselOutlet
