"""gmsh builders of the project's geometries and the tags they share with the solvers."""

from fsi.geometry.tags import Boundary, Region

__all__ = ["Boundary", "Region"]
