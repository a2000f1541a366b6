"""A straight vessel: the lumen ``[0, length] × [0, radius]`` and its wall
``[0, length] × [radius, radius + wall_thickness]``, clamped at both ends.

y = 0 is the axis of an axisymmetric tube (the meridian half-plane, docs/axisymmetric.md) or,
plane, the symmetry line of a channel of height 2 radius. :func:`point_a`, the inner wall at
mid-length where the elastic-tube benchmarks report the displacement, is a mesh vertex.

Tags: ``fluid``, ``wall``; ``inlet`` (x = 0) and ``outlet`` (x = length) across the lumen,
``axis`` (y = 0), ``interface`` (the lumen surface y = radius), ``clamped`` (the wall's two
ends) and ``exterior`` (y = radius + wall_thickness).
"""

from __future__ import annotations

from typing import Protocol

from fsi.geometry.tags import Boundary, Region, add_physical_groups

# The tags this builder writes (mesh.json reports these).
REGIONS = (Region.FLUID, Region.WALL)
BOUNDARIES = (
    Boundary.INLET,
    Boundary.OUTLET,
    Boundary.AXIS,
    Boundary.INTERFACE,
    Boundary.CLAMPED,
    Boundary.EXTERIOR,
)


class TubeParameters(Protocol):
    """The tube's dimensions (m; fsi.config.TubeGeometry)."""

    length: float
    radius: float
    wall_thickness: float


def point_a(p: TubeParameters) -> tuple[float, float]:
    """Point A, the inner wall at mid-length (z = length/2, r = radius): a mesh vertex."""
    return p.length / 2, p.radius


def analytic_areas(p: TubeParameters) -> dict[str, float]:
    """Exact region areas (m²) of the meridian plane: the lumen's and the wall's rectangles."""
    areas = {
        Region.FLUID.label: p.length * p.radius,
        Region.WALL.label: p.length * p.wall_thickness,
    }
    areas["total"] = sum(areas.values())
    return areas


def build(p: TubeParameters, size: float) -> None:
    """Add the tube to the current gmsh model (built-in kernel) with physical groups; ``size``
    is the element size (m) everywhere. Meshing is left to the caller."""
    import gmsh

    geo = gmsh.model.geo
    L, R, h = p.length, p.radius, p.wall_thickness
    a0, a1 = geo.addPoint(0, 0, 0, size), geo.addPoint(L, 0, 0, size)
    i0, i1 = geo.addPoint(0, R, 0, size), geo.addPoint(L, R, 0, size)
    a = geo.addPoint(*point_a(p), 0, size)
    e0, e1 = geo.addPoint(0, R + h, 0, size), geo.addPoint(L, R + h, 0, size)
    axis, outlet, inlet = geo.addLine(a0, a1), geo.addLine(a1, i1), geo.addLine(a0, i0)
    upstream, downstream = geo.addLine(i0, a), geo.addLine(a, i1)  # the interface, split at A
    clamp_out, exterior, clamp_in = geo.addLine(i1, e1), geo.addLine(e0, e1), geo.addLine(i0, e0)
    lumen = [axis, outlet, -downstream, -upstream, -inlet]
    fluid = geo.addPlaneSurface([geo.addCurveLoop(lumen)])
    wall_loop = [upstream, downstream, clamp_out, -exterior, -clamp_in]
    wall = geo.addPlaneSurface([geo.addCurveLoop(wall_loop)])
    geo.synchronize()
    add_physical_groups(
        {
            Region.FLUID: [fluid],
            Region.WALL: [wall],
            Boundary.INLET: [inlet],
            Boundary.OUTLET: [outlet],
            Boundary.AXIS: [axis],
            Boundary.INTERFACE: [upstream, downstream],
            Boundary.CLAMPED: [clamp_in, clamp_out],
            Boundary.EXTERIOR: [exterior],
        }
    )
