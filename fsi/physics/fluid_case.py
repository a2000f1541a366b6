"""The fluid of a case: its boundary conditions (:func:`fluid_conditions`) and its solver
(:func:`fluid_solver`), the one place the runs of a rigid structure (fsi/run/steppers.py), the
coupled problem (fsi/coupled/partitioned.py) and the speed measurements build a
:class:`~fsi.physics.fluid.FluidSolver` from a case file's settings."""

from __future__ import annotations

from collections.abc import Sequence

from fsi import config
from fsi.physics import fluid, mesh
from fsi.physics.fluid_boundaries import BoundaryCondition, boundary_conditions


def fluid_conditions(case: config.Case, moving_interface: bool = False) -> tuple:
    """The case's fluid boundary conditions (:func:`fsi.physics.fluid_boundaries.
    boundary_conditions`): the configured inlet and outlets, no-slip on every wall; the
    interface moves with the structure if ``moving_interface`` (with the Robin condition of
    ``coupling.scheme: robin-neumann``), else it is a rigid wall too."""
    return boundary_conditions(
        case.fluid,
        mesh.boundaries(case),
        moving_interface=moving_interface,
        robin=case.coupling.scheme == "robin-neumann",
        symmetry_planes=config.symmetry_planes(case.geometry),
    )


def fluid_solver(
    case: config.Case,
    part: mesh.TaggedMesh,
    *,
    moving_interface: bool = False,
    conditions: Sequence[BoundaryCondition] | None = None,
) -> fluid.FluidSolver:
    """The case's fluid solver on its fluid mesh ``part``: the case's fluid settings, time scheme
    and coordinates (plane or axisymmetric), with ``conditions`` or, by default, the case's
    (:func:`fluid_conditions`)."""
    return fluid.FluidSolver(
        part.mesh,
        part.facet_tags,
        case.fluid,
        conditions or fluid_conditions(case, moving_interface),
        scheme=case.time.scheme,
        axisymmetric=config.is_axisymmetric(case.geometry),
    )
