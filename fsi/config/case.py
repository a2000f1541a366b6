"""The whole case (:class:`Case`, one field per section of the case file) and the run's time
line that depends on several sections (:func:`heartbeat_period`, :func:`run_time`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fsi.config.coupling_section import Coupling, MeshMotionSettings
from fsi.config.domain import GeometrySettings, MeshSettings, StenosisGeometry
from fsi.config.fluid_section import Fluid
from fsi.config.output_section import Output
from fsi.config.structure_section import Structure
from fsi.config.time_section import Time


@dataclass(frozen=True)
class Case:
    """A case: its ``name`` and one field per section of the case file, each a frozen
    dataclass whose fields are that section's keys (docs/configuration.md)."""

    name: str = "case"
    geometry: GeometrySettings = field(default_factory=StenosisGeometry)
    mesh: MeshSettings = field(default_factory=MeshSettings)
    fluid: Fluid = field(default_factory=Fluid)
    structure: Structure = field(default_factory=Structure)
    time: Time = field(default_factory=Time)
    coupling: Coupling = field(default_factory=Coupling)
    mesh_motion: MeshMotionSettings = field(default_factory=MeshMotionSettings)
    output: Output = field(default_factory=Output)


def heartbeat_period(case: Case) -> float:
    """The inlet's period T (s) when it repeats (a ``pressure_table``, ``pressure_file`` or
    flow-rate inlet with ``period`` > 0), else 0."""
    return float(getattr(case.fluid.inlet, "period", 0.0))


def run_time(case: Case) -> Time:
    """The schedule the run steps through: ``time`` itself, or with ``time.cycles`` and a
    periodic inlet the heartbeats one after another (:meth:`Time.run_schedule`), whose ``end``
    is cycles × period."""
    return case.time.run_schedule(heartbeat_period(case))
