"""The physical-group tags written by every geometry builder and read by every solver.

Names follow ../shared/MODEL.md §1: ``interface`` is Γw1, ``rigid_wall`` Γw2, ``clamped`` ΓD and
``exterior`` ΓN. ``cap_lipid`` (fibrous cap | lipid pool) and ``plaque_base`` (plaque | vessel
wall) are internal structure boundaries, tagged for measurements and the fixed-wall mode.
In the Turek–Hron benchmark (geometry/turek_hron.py) ``interface`` is the flag's wetted surface,
``clamped`` the flag–cylinder joint and ``obstacle`` the cylinder's wetted arc.
"""

from enum import IntEnum


class Region(IntEnum):
    """Cell tags (gmsh physical surfaces)."""

    FLUID = 1
    WALL = 2
    CAP = 3
    LIPID = 4
    FLAG = 5  # Turek–Hron: the elastic flag behind the rigid cylinder

    @property
    def label(self) -> str:
        return self.name.lower()


class Boundary(IntEnum):
    """Facet tags (gmsh physical curves)."""

    INLET = 11
    OUTLET = 12
    INTERFACE = 13
    RIGID_WALL = 14
    CLAMPED = 15
    EXTERIOR = 16
    CAP_LIPID = 17
    PLAQUE_BASE = 18
    OBSTACLE = 19  # Turek–Hron: the rigid cylinder's wetted surface

    @property
    def label(self) -> str:
        return self.name.lower()


STRUCTURE_REGIONS = (Region.WALL, Region.CAP, Region.LIPID)
