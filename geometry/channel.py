"""A straight channel ``[0, length] × [0, height]`` for verification cases (no structure).

Tags: ``fluid``; ``inlet`` (x = 0), ``outlet`` (x = length), ``rigid_wall`` (y = 0 and y = height).
"""

from __future__ import annotations

from typing import Protocol

from fsi.geometry.tags import Boundary, Region, add_physical_groups

# The tags this builder writes (mesh.json reports these).
REGIONS = (Region.FLUID,)
BOUNDARIES = (Boundary.INLET, Boundary.OUTLET, Boundary.RIGID_WALL)


class ChannelParameters(Protocol):
    """The channel's dimensions (m; fsi.config.ChannelGeometry)."""

    length: float
    height: float


def analytic_areas(p: ChannelParameters) -> dict[str, float]:
    """Exact region areas (m²): the fluid's and the total, length × height."""
    return {Region.FLUID.label: p.length * p.height, "total": p.length * p.height}


def build(p: ChannelParameters, size: float) -> None:
    """Add the channel to the current gmsh model (built-in kernel) with physical groups."""
    import gmsh

    geo = gmsh.model.geo
    corners = [geo.addPoint(x, y, 0.0, size) for x, y in
               [(0, 0), (p.length, 0), (p.length, p.height), (0, p.height)]]  # fmt: skip
    bottom, outlet, top, inlet = (geo.addLine(corners[i], corners[(i + 1) % 4]) for i in range(4))
    fluid = geo.addPlaneSurface([geo.addCurveLoop([bottom, outlet, top, inlet])])
    geo.synchronize()
    add_physical_groups(
        {
            Region.FLUID: [fluid],
            Boundary.INLET: [inlet],
            Boundary.OUTLET: [outlet],
            Boundary.RIGID_WALL: [bottom, top],
        }
    )
