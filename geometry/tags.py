"""The physical-group tags written by every geometry builder and read by every solver.

Names follow docs/model.md §1: ``interface`` is Γw1, ``rigid_wall`` Γw2, ``clamped`` ΓD and
``exterior`` ΓN. ``cap_lipid`` (fibrous cap | lipid pool) and ``plaque_base`` (plaque | vessel
wall) are internal structure boundaries, tagged for measurements and the fixed-wall mode.
In the Turek–Hron benchmark (geometry/turek_hron.py) ``interface`` is the flag's wetted surface,
``clamped`` the flag–cylinder joint and ``obstacle`` the cylinder's wetted arc. ``axis`` is a
tube's axis (geometry/tube.py), where the radial velocity is 0.
:func:`add_physical_groups` writes them into a gmsh model.
"""

from enum import IntEnum


class Region(IntEnum):
    """Cell tags (gmsh physical surfaces; volumes in 3D)."""

    FLUID = 1
    WALL = 2
    CAP = 3
    LIPID = 4
    FLAG = 5  # Turek–Hron: the elastic flag behind the rigid cylinder

    @property
    def label(self) -> str:
        """The physical group's name: the tag's name in lower case."""
        return self.name.lower()


class Boundary(IntEnum):
    """Facet tags (gmsh physical curves; surfaces in 3D)."""

    INLET = 11
    OUTLET = 12
    INTERFACE = 13
    RIGID_WALL = 14
    CLAMPED = 15
    EXTERIOR = 16
    CAP_LIPID = 17
    PLAQUE_BASE = 18
    OBSTACLE = 19  # Turek–Hron: the rigid cylinder's wetted surface
    AXIS = 20  # a tube's axis r = 0 (axisymmetric), or its plane symmetry line

    @property
    def label(self) -> str:
        """The physical group's name: the tag's name in lower case."""
        return self.name.lower()


STRUCTURE_REGIONS = (Region.WALL, Region.CAP, Region.LIPID)


def add_physical_groups(groups: dict[int, list[int]], dimension: int = 2) -> None:
    """Create one named physical group per non-empty tag of ``groups`` (tag → gmsh entities;
    entities of the model's ``dimension`` for a :class:`Region`, one less for a
    :class:`Boundary`: surfaces and curves in 2D, volumes and surfaces in 3D) in the current
    gmsh model."""
    import gmsh

    for tag, entities in groups.items():
        if not entities:
            continue
        dim = dimension if tag in Region._value2member_map_ else dimension - 1
        name = (Region(tag) if dim == dimension else Boundary(tag)).label
        gmsh.model.addPhysicalGroup(dim, entities, tag)
        gmsh.model.setPhysicalName(dim, tag, name)
