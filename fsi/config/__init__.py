"""Typed, validated case configuration loaded from YAML.

A case file is a YAML mapping of sections (``geometry``, ``mesh``, ``fluid``, ``structure``,
``time``, ``coupling``, ``mesh_motion``, ``output``, and the case's ``name``); it mirrors the tree
of frozen dataclasses rooted at :class:`Case` key for key, and every key is optional (defaults
are the study's values, ../shared/MODEL.md). Precedence: defaults < YAML < ``--set
key.path=value`` overrides. Unknown keys, wrong types and out-of-range values raise
:class:`ConfigError` naming the file, the key and what is expected, before anything is computed.
The schema is documented in docs/configuration.md.

What a configuration may not do (each refused with a :class:`ConfigError`): hold a number that
is not finite; break the file limits of :mod:`fsi.config.reader` (size, nesting, repeated keys);
give PETSc any option outside the allow-list of :mod:`fsi.config.petsc_options` (no viewers,
monitors, Python types, options files or file paths); ask for more than ``time.max_steps``
steps or, by :func:`fsi.config.run_size.estimated_cells`, more than ``mesh.max_cells`` triangles;
give an inlet formula the language of :mod:`fsi.config.boundary_data` refuses or one that fails at
t = 0 or at a step time of the schedule; give a ``pressure_file`` inlet whose CSV file cannot be
read or is not a waveform (:func:`fsi.config.boundary_data.read_waveform`).

Where each part lives (this module only re-exports them; use them as ``config.Case``,
``config.load``, ... or ``from fsi.config import Case``):

- the schema, one module per group of sections: :mod:`~fsi.config.domain` (``geometry``,
  ``mesh``), :mod:`~fsi.config.fluid_section` (``fluid``: rheology, inlets, outlets),
  :mod:`~fsi.config.structure_section` (``structure``: materials, time schemes, tissue
  support), :mod:`~fsi.config.stepping` (``time``, ``coupling``, ``mesh_motion``, ``output``),
  :mod:`~fsi.config.solver_settings` (Newton and PETSc settings, quadrature degrees) and
  :mod:`~fsi.config.case` (:class:`Case`, and the heartbeat period and run schedule that
  depend on several sections);
- :mod:`~fsi.config.validation`: :func:`validate`, the checks that involve several keys;
- :mod:`~fsi.config.case_file`: :func:`load` and :func:`from_dict` (read, build, validate;
  a ``pressure_file`` inlet's CSV file is read here), :func:`to_dict`, :func:`to_yaml` and
  :func:`dump` (the resolved configuration written back);
- :mod:`~fsi.config.reader` (strict YAML and the typed builder), :mod:`~fsi.config.boundary_data`
  (inlet formulas and waveform files), :mod:`~fsi.config.petsc_options` (the allow-list) and
  :mod:`~fsi.config.run_size` (step and cell counts before a run).
"""

from fsi.config.case import Case, heartbeat_period, run_time
from fsi.config.case_file import dump, from_dict, load, to_dict, to_yaml
from fsi.config.domain import (
    MESH_LEVELS,
    ChannelGeometry,
    Geometry,
    MeshSettings,
    StenosisGeometry,
    TurekHronGeometry,
)
from fsi.config.fluid_section import (
    Carreau,
    CarreauYasuda,
    Casson,
    Cross,
    Fluid,
    Inlet,
    InletPressure,
    InletPressureFile,
    InletPressureTable,
    InletPulse,
    Newtonian,
    Outlet,
    ParabolicInflow,
    PlateauLaw,
    PowerLaw,
    ResistanceOutlet,
    Rheology,
    TractionFreeOutlet,
    WindkesselOutlet,
)
from fsi.config.reader import ConfigError
from fsi.config.solver_settings import MAX_QUADRATURE_DEGREE, SolverSettings
from fsi.config.stepping import (
    MAX_CYCLES,
    AdaptiveStepping,
    Coupling,
    MeshMotion,
    Output,
    Time,
    TimeSegment,
)
from fsi.config.structure_section import (
    FlagMaterial,
    GeneralizedAlpha,
    Material,
    Newmark,
    QuasiStatic,
    StructuralTimeIntegration,
    Structure,
    TissueSupport,
    WallMaterial,
)
from fsi.config.validation import validate

__all__ = [
    # the case and its files
    "Case",
    "ConfigError",
    "load",
    "from_dict",
    "validate",
    "to_dict",
    "to_yaml",
    "dump",
    "heartbeat_period",
    "run_time",
    # geometry, mesh
    "Geometry",
    "StenosisGeometry",
    "ChannelGeometry",
    "TurekHronGeometry",
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
    "Outlet",
    "TractionFreeOutlet",
    "ResistanceOutlet",
    "WindkesselOutlet",
    # structure
    "Structure",
    "Material",
    "WallMaterial",
    "FlagMaterial",
    "StructuralTimeIntegration",
    "GeneralizedAlpha",
    "Newmark",
    "QuasiStatic",
    "TissueSupport",
    # time, coupling, mesh motion, output; solver settings
    "AdaptiveStepping",
    "Time",
    "TimeSegment",
    "MAX_CYCLES",
    "Coupling",
    "MeshMotion",
    "Output",
    "SolverSettings",
    "MAX_QUADRATURE_DEGREE",
]
