"""The columns of a run's ``metrics.csv``: the lists each kind of run writes, the structure's
stress columns and their values (:func:`stress_row`), and the heartbeat a row belongs to
(:func:`heartbeat`, the ``cycle`` column with a periodic inlet).
"""

from __future__ import annotations

import math

from fsi.geometry.tags import Region
from fsi.numerics.timestepping import SAME_TIME
from fsi.physics import solid

COLUMNS = [
    "step",
    "t",
    "dt",
    "peak_velocity",
    "peak_pressure",
    "peak_displacement",
    "max_sss",
    "coupling_iterations",
    "coupling_residual",
    "newton_iterations",
    "newton_residual",
    "wall_time_s",
]
"""Every run's columns (the others are added after them)."""
COUPLED_COLUMNS = COLUMNS + [
    "peak_wall_displacement",
    "relaxation",
    "solid_newton_iterations",
    "mesh_jacobian_ratio",
]
"""``peak_wall_displacement``: max |η| over the vessel wall (0 in the fixed-wall mode);
``relaxation``: Aitken's (or the constant) ω of the step's last iteration, empty for IQN-ILS;
``newton_iterations``/``solid_newton_iterations``: fluid/solid Newton iterations summed over the
step's coupling iterations; ``mesh_jacobian_ratio``: the fluid mesh's smallest J/J_ref."""
WALL_COLUMNS = ["min_wss", "max_wss", "recirculation_length"]
"""Channel-like lumens (stenosis, channel): the signed wall shear stress's extremes (Pa) and the
longest reversed-flow zone along either wall (m) (fsi.output.metrics.wall_shear_summary)."""


def stress_columns(solver: solid.SolidSolver) -> list[str]:
    """The structure's stress maxima (Pa) beside ``max_sss``: ``max_von_mises``,
    ``max_principal`` over the whole structure, and ``max_sss_<region>``,
    ``max_von_mises_<region>``, ``max_principal_<region>`` per region (cap, lipid, wall; the
    Turek–Hron flag), where ``max_sss`` is the largest |σ₁₂|
    (fsi.physics.solid_stress.StressFields); with a fibrous cap, :data:`CAP_LOCATION_COLUMNS`."""
    return (
        ["max_von_mises", "max_principal"]
        + [
            f"{name}_{region.label}"
            for region in solver.regions
            for name in ("max_sss", "max_von_mises", "max_principal")
        ]
        + (cap_location_columns(solver) if Region.CAP in solver.regions else [])
    )


CAP_LOCATION_COLUMNS = ["max_principal_cap_x", "max_principal_cap_y"]
"""Where ``max_principal_cap`` is attained: the reference coordinates (m) of the stress
field's node that holds it (fsi.physics.solid_stress.StressFields.location_of_max); a 3D
structure adds ``max_principal_cap_z``."""


def cap_location_columns(solver: solid.SolidSolver) -> list[str]:
    """:data:`CAP_LOCATION_COLUMNS` in the structure's dimension."""
    three_d = solver.domain.mesh.geometry.dim == 3
    return CAP_LOCATION_COLUMNS + (["max_principal_cap_z"] if three_d else [])


def stress_row(solver: solid.SolidSolver) -> dict[str, float]:
    """``max_sss`` and the :func:`stress_columns` of the current stresses (call
    ``solver.stress.update()`` first). Collective."""
    row = {}
    for label, m in solver.stress.region_maxima().items():
        suffix = "" if label == "all" else f"_{label}"
        row.update(
            {
                f"max_sss{suffix}": m.max_abs_shear,
                f"max_von_mises{suffix}": m.max_von_mises,
                f"max_principal{suffix}": m.max_principal,
            }
        )
    if Region.CAP in solver.regions:
        _, *point = solver.stress.location_of_max("max_principal", Region.CAP)
        row.update(zip(cap_location_columns(solver), point, strict=True))
    return row


FLOW_COLUMNS = ["inlet_flow_rate", "outlet_flow_rate"]
"""Every fluid mesh with an inlet and an outlet: the volume flow rate per unit depth (m²/s)
through each, positive downstream, on the current mesh (fsi.output.metrics.flow_rate)."""
PRESSURE_COLUMNS = ["mean_inlet_pressure", "mean_outlet_pressure"]
"""Every fluid mesh with an inlet and an outlet: the pressure p averaged over the inlet and
over the outlet (Pa; in 2D the length average ∫ p ds / ∫ ds, on the current mesh;
fsi.output.metrics.BoundaryMean)."""


def heartbeat(t: float, period: float) -> int:
    """The heartbeat that holds time ``t``.

    Args:
        t: a time (s).
        period: the heartbeat's period T (s), > 0.

    Returns:
        The 1-based number k of the heartbeat (k − 1) T < t <= k T (a step ending on k T
        belongs to heartbeat k; times within 1e-9 T of k T count as on it); 1 for t <= T.
    """
    return max(1, math.ceil(t / period - SAME_TIME))
