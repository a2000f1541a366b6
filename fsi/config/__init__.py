"""Typed, validated case configuration loaded from YAML: the tree of frozen dataclasses rooted
at :class:`Case` (one module per group of sections: ``*_section``, :mod:`~fsi.config.domain`,
:mod:`~fsi.config.solver_settings`), reading and writing case files (:mod:`~fsi.config.case_file`,
strict YAML: :mod:`~fsi.config.reader`) and the checks that involve several keys
(:mod:`~fsi.config.validation`). This module re-exports them (``config.Case``, ``config.load``).
The schema is documented in docs/configuration.md; its defaults are the study's (docs/model.md).
"""

from fsi.config.case import Case, heartbeat_period, run_time
from fsi.config.case_file import (
    RUN_CONFIG_BYTES,
    differences,
    dump,
    from_dict,
    load,
    loader,
    to_dict,
    to_yaml,
)
from fsi.config.coupling_section import Coupling, MeshMotionSettings
from fsi.config.domain import (
    MESH_LEVELS,
    ChannelGeometry,
    GeometrySettings,
    MeshSettings,
    StenosisGeometry,
    TubeGeometry,
    TurekHronGeometry,
    dimension,
    is_axisymmetric,
    symmetry_planes,
)
from fsi.config.fluid_section import (
    FLOW_RATE_INLETS,
    Fluid,
    Inlet,
    InletFlowRate,
    InletFlowRateFile,
    InletFlowRateTable,
    InletPressure,
    InletPressureFile,
    InletPressureTable,
    InletPulse,
    ParabolicInflow,
)
from fsi.config.outlet_section import Outlet, ResistanceOutlet, TractionFreeOutlet, WindkesselOutlet
from fsi.config.output_section import Output
from fsi.config.reader import ConfigError
from fsi.config.rheology_section import (
    Carreau,
    CarreauYasuda,
    Casson,
    Cross,
    Newtonian,
    PlateauLaw,
    PowerLaw,
    Rheology,
)
from fsi.config.solver_settings import (
    MAX_QUADRATURE_DEGREE,
    FluidSolverSettings,
    SolverSettings,
)
from fsi.config.structure_section import (
    Fibres,
    FlagMaterial,
    GeneralizedAlpha,
    Material,
    Newmark,
    PrestressLoad,
    QuasiStatic,
    StructuralTimeIntegration,
    Structure,
    TissueSupport,
    WallMaterial,
)
from fsi.config.time_section import MAX_CYCLES, AdaptiveStepping, Time, TimeSegment
from fsi.config.validation import cannot_run, cautions, validate

__all__ = [
    # the case and its files
    "Case",
    "ConfigError",
    "load",
    "loader",
    "from_dict",
    "validate",
    "cautions",
    "cannot_run",
    "to_dict",
    "to_yaml",
    "dump",
    "differences",
    "RUN_CONFIG_BYTES",
    "heartbeat_period",
    "run_time",
    # geometry, mesh
    "GeometrySettings",
    "StenosisGeometry",
    "ChannelGeometry",
    "TubeGeometry",
    "TurekHronGeometry",
    "dimension",
    "symmetry_planes",
    "is_axisymmetric",
    "MESH_LEVELS",
    "MeshSettings",
    # fluid
    "Fluid",
    "Rheology",
    "Newtonian",
    "PlateauLaw",
    "Carreau",
    "CarreauYasuda",
    "Cross",
    "PowerLaw",
    "Casson",
    "Inlet",
    "InletPulse",
    "InletPressure",
    "InletPressureTable",
    "InletPressureFile",
    "ParabolicInflow",
    "InletFlowRate",
    "InletFlowRateTable",
    "InletFlowRateFile",
    "FLOW_RATE_INLETS",
    "Outlet",
    "TractionFreeOutlet",
    "ResistanceOutlet",
    "WindkesselOutlet",
    # structure
    "Structure",
    "Material",
    "Fibres",
    "WallMaterial",
    "FlagMaterial",
    "StructuralTimeIntegration",
    "GeneralizedAlpha",
    "Newmark",
    "QuasiStatic",
    "TissueSupport",
    "PrestressLoad",
    # time, coupling, mesh motion, output; solver settings
    "AdaptiveStepping",
    "Time",
    "TimeSegment",
    "MAX_CYCLES",
    "Coupling",
    "MeshMotionSettings",
    "Output",
    "FluidSolverSettings",
    "SolverSettings",
    "MAX_QUADRATURE_DEGREE",
]
