"""The ``geometry`` and ``mesh`` sections of a case: the domain and how finely gmsh meshes it.

``geometry.kind`` picks one of :class:`StenosisGeometry` (the study's artery),
:class:`ChannelGeometry` (verification), :class:`TubeGeometry` (a straight vessel, axisymmetric)
and :class:`TurekHronGeometry` (the benchmark); the
builders that read these sections are in ``geometry/`` and :mod:`fsi.physics.mesh`. The checks
that involve several keys (the plaque inside the segment, the flag inside the channel) are in
:mod:`fsi.config.validation`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from fsi.config.reader import at_least, checked, open_interval, positive


@dataclass(frozen=True)
class StenosisGeometry:
    """The stenosed carotid of docs/model.md §1 (geometry/stenosis.py has the profiles)."""

    kind: Literal["stenosis"] = "stenosis"
    length: float = positive(0.02, "m")
    height: float = positive(0.007, "m")
    wall_thickness: float = positive(0.001, "m")
    stenosis_length: float = positive(0.01, "m")
    stenosis_degree: float = open_interval(0.5, 0.0, 1.0)
    cap_thickness: float = positive(0.0005, "m")
    lipid_length: float = positive(0.006, "m")
    # Where the plaques sit; null: [bottom]. Not with axisymmetric (the plaque is a ring).
    plaque_sides: tuple[Literal["bottom", "top"], ...] | None = None
    # x of the plaque's apex (m); null: length / 2, the study's plaque in the middle.
    stenosis_centre: float | None = checked(
        None, lambda v: v is None or v > 0, "a positive number, or null for length / 2", "m"
    )
    # The meridian half-plane of a circular vessel (docs/axisymmetric.md): y = 0 the axis,
    # height the lumen's radius, the plaque a concentric ring of cap and lipid.
    axisymmetric: bool = False
    # 3: the circular vessel as a solid (docs/3d.md), height the lumen's radius, the plaque the
    # axisymmetric one revolved over plaque_angle.
    dimension: Literal[2, 3] = 2
    # The plaque's angular span in 3D (degrees): 360 the concentric ring, less an eccentric
    # plaque centred on +y.
    plaque_angle: float = checked(360.0, lambda v: 0 < v <= 360, "a number in (0, 360]", "degrees")
    # The part of a 3D vessel that is modelled (degrees): 360 the whole, 90 the quarter
    # y >= 0, z >= 0 between the symmetry planes y = 0 and z = 0 (a concentric plaque's only).
    sector: Literal[90, 360] = 360


@dataclass(frozen=True)
class ChannelGeometry:
    """A straight rigid channel for verification cases (geometry/channel.py)."""

    kind: Literal["channel"] = "channel"
    length: float = positive(0.02, "m")
    height: float = positive(0.007, "m")


@dataclass(frozen=True)
class TubeGeometry:
    """A straight vessel (geometry/tube.py): the lumen ``[0, length] × [0, radius]`` with the axis
    (or, plane, the symmetry line) at y = 0 and a wall of ``wall_thickness`` outside it, clamped
    at both ends. ``axisymmetric`` (the default): the meridian half-plane of a circular tube
    (docs/axisymmetric.md); false: half of a plane channel of height 2 radius, symmetric about
    y = 0; ``dimension: 3`` (with ``axisymmetric: false``): the circular tube as a solid about
    the x axis (geometry/vessel_3d.py)."""

    kind: Literal["tube"] = "tube"
    length: float = positive(0.05, "m")
    radius: float = positive(0.005, "m")
    wall_thickness: float = positive(0.001, "m")
    axisymmetric: bool = True
    # 3: the circular tube as a solid (docs/3d.md; with axisymmetric false).
    dimension: Literal[2, 3] = 2
    # The part of a 3D tube that is modelled (degrees): 360 the whole, 90 the quarter
    # y >= 0, z >= 0 with the symmetry planes y = 0 and z = 0 (docs/3d.md).
    sector: Literal[90, 360] = 360


@dataclass(frozen=True)
class TurekHronGeometry:
    """The Turek–Hron benchmark (Turek & Hron 2006, geometry/turek_hron.py): a
    channel ``[0, length] × [0, height]``, a rigid cylinder and an elastic flag of
    ``flag_length`` (from the cylinder's rightmost point to the tip) × ``flag_thickness`` centred
    on the cylinder's axis. Defaults are the benchmark's (tip and point A at x = 0.6)."""

    kind: Literal["turek_hron"] = "turek_hron"
    length: float = positive(2.5, "m")
    height: float = positive(0.41, "m")
    cylinder_centre: tuple[float, ...] = (0.2, 0.2)
    cylinder_radius: float = positive(0.05, "m")
    flag_length: float = positive(0.35, "m")
    flag_thickness: float = positive(0.02, "m")


GeometrySettings = StenosisGeometry | ChannelGeometry | TubeGeometry | TurekHronGeometry
"""The ``geometry`` section: one of the kinds (``geometry.kind``). Named apart from the gmsh
builders, the package ``fsi.geometry`` (the geometry/ folder)."""


def is_axisymmetric(geometry: GeometrySettings) -> bool:
    """Whether ``geometry`` is the meridian half-plane of a body of revolution."""
    return bool(getattr(geometry, "axisymmetric", False))


def dimension(geometry: GeometrySettings) -> int:
    """The geometry's (and its mesh's) dimension: 3 for a solid vessel, otherwise 2."""
    return int(getattr(geometry, "dimension", 2))


def symmetry_planes(geometry: GeometrySettings) -> tuple[int, ...]:
    """The axes c of the planes x_c = 0 that bound a 3D quarter vessel (``sector: 90``): the
    solution's mirror planes, where the normal components of velocity, displacement and mesh
    motion are 0; none for a whole vessel."""
    return (1, 2) if getattr(geometry, "sector", 360) == 90 else ()


MESH_LEVELS = {"coarse": 0, "medium": 1, "fine": 2, "finest": 3}


@dataclass(frozen=True)
class MeshSettings:
    """gmsh sizes of the coarse mesh: ``size`` away from, ``local_size`` at the plaque (or the
    obstacle); ``level`` adds uniform refinements (medium = coarse × 4, fine = coarse × 16,
    finest = coarse × 64: the third level of the performance study, docs/performance.md).

    ``max_cells``: validation refuses a mesh whose :func:`fsi.config.run_size.estimated_cells`
    exceeds it, before gmsh starts (memory grows with the cells,
    :data:`fsi.config.run_size.BYTES_PER_CELL` each: the default 10⁶ is ~18 GB)."""

    level: Literal["coarse", "medium", "fine", "finest"] = "coarse"
    size: float = positive(6.0e-4, "m")
    local_size: float = positive(2.2e-4, "m")
    # A 3D stenosis' lumen core over the plaque's length (the throat, r <= R - A): its size
    # (m), graded to `size` as the plaque's box is; null: graded from the plaque's box alone.
    lumen_size: float | None = checked(
        None, lambda v: v is None or v > 0, "a positive number, or null", "m"
    )
    max_cells: int = at_least(1_000_000, 1)

    @property
    def refinements(self) -> int:
        """The number of uniform refinements of the coarse mesh that ``level`` asks for."""
        return MESH_LEVELS[self.level]
