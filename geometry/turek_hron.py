"""The Turek–Hron FSI benchmark geometry (Turek & Hron 2006).

A channel ``[0, length] × [0, height]`` holds a rigid cylinder (centre ``(cx, cy)``, radius
``r``) with an elastic flag attached behind it: the part of the strip ``|y − cy| <= t/2``
(``t = flag_thickness``) outside the cylinder and left of the tip (:func:`tip_x`), clamped on
the cylinder arc between the joints ``(cx + sqrt(r² − t²/4), cy ± t/2)``. Point A
(:func:`point_a`) is a gmsh point, so a mesh vertex on every level.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

from fsi.geometry.tags import Boundary, Region, add_physical_groups

# The tags this builder writes (mesh.json reports these).
REGIONS = (Region.FLUID, Region.FLAG)
BOUNDARIES = (
    Boundary.INLET,
    Boundary.OUTLET,
    Boundary.RIGID_WALL,
    Boundary.OBSTACLE,
    Boundary.INTERFACE,
    Boundary.CLAMPED,
)


class TurekHronParameters(Protocol):
    """The benchmark's dimensions (m; fsi.config.TurekHronGeometry)."""

    length: float
    height: float
    cylinder_centre: Sequence[float]
    cylinder_radius: float
    flag_length: float
    flag_thickness: float


def tip_x(p: TurekHronParameters) -> float:
    """x of the flag tip (and of point A): the cylinder's rightmost point plus the flag length."""
    return p.cylinder_centre[0] + p.cylinder_radius + p.flag_length


def point_a(p: TurekHronParameters) -> tuple[float, float]:
    """Point A, the middle of the flag tip, whose displacement the benchmark reports."""
    return tip_x(p), p.cylinder_centre[1]


def joint_half_angle(p: TurekHronParameters) -> float:
    """Half the angle θ the clamped arc subtends at the cylinder centre: sin θ = (t/2) / r."""
    return math.asin(p.flag_thickness / 2 / p.cylinder_radius)


def analytic_areas(p: TurekHronParameters) -> dict[str, float]:
    """Exact region areas (m²).

    flag  = t (tip − x_j) − r² (θ − sin θ cos θ): the strip from the chord ``x = x_j`` to the tip
    minus the circular segment of the cylinder beyond that chord (x_j = cx + r cos θ);
    fluid = length × height − π r² − flag.
    """
    r, t = p.cylinder_radius, p.flag_thickness
    theta = joint_half_angle(p)
    x_j = p.cylinder_centre[0] + r * math.cos(theta)
    segment = r**2 * (theta - math.sin(theta) * math.cos(theta))
    flag = t * (tip_x(p) - x_j) - segment
    fluid = p.length * p.height - math.pi * r**2 - flag
    return {Region.FLUID.label: fluid, Region.FLAG.label: flag, "total": fluid + flag}


GRADING = 0.15
"""Growth of the element size with the distance from the cylinder and the flag (dh/dd), the
default of :func:`build` (fsi.config's cell-count estimate uses it too)."""


def build(p: TurekHronParameters, size: float, local_size: float, grading: float = GRADING) -> None:
    """Add the benchmark to the current gmsh model (built-in kernel) with physical groups.

    Regions ``fluid`` and ``flag``; boundaries ``inlet`` (x = 0), ``outlet`` (x = length),
    ``rigid_wall`` (y = 0 and y = height), ``obstacle`` (the cylinder arc wetted by the fluid),
    ``interface`` (the flag's wetted top, tip and bottom, shared by both regions, so their meshes
    are conforming) and ``clamped`` (the flag–cylinder joint arc). The element size (m) is
    ``local_size`` on the cylinder and the flag and grows linearly with the distance ``d`` from
    them, ``h(d) = min(size, local_size + grading·d)``, up to ``size`` (a gmsh Distance + Threshold
    background field). Meshing is left to the caller.
    """
    import gmsh

    geo = gmsh.model.geo
    bottom, outlet, top, inlet = _add_channel(geo, p, size)
    joints, obstacle, clamped = _add_cylinder(geo, p, local_size)
    interface = _add_flag_outline(geo, p, local_size, joints)

    flag = geo.addPlaneSurface([geo.addCurveLoop([*interface, -clamped])])
    outer = geo.addCurveLoop([bottom, outlet, top, inlet])
    hole = geo.addCurveLoop([*interface, *obstacle])  # joint_bottom -> tip -> joint_top -> around
    fluid = geo.addPlaneSurface([outer, hole])
    geo.synchronize()
    _add_size_field(gmsh.model.mesh.field, [*obstacle, clamped, *interface], size, local_size,
                    grading)  # fmt: skip

    add_physical_groups(
        {
            Region.FLUID: [fluid],
            Region.FLAG: [flag],
            Boundary.INLET: [inlet],
            Boundary.OUTLET: [outlet],
            Boundary.RIGID_WALL: [bottom, top],
            Boundary.OBSTACLE: obstacle,
            Boundary.INTERFACE: interface,
            Boundary.CLAMPED: [clamped],
        }
    )


def _add_channel(geo, p: TurekHronParameters, size: float) -> tuple[int, ...]:
    """The channel's corner points and its bottom, outlet, top and inlet lines."""
    L, H = p.length, p.height
    corners = [geo.addPoint(x, y, 0.0, size) for x, y in [(0, 0), (L, 0), (L, H), (0, H)]]
    return tuple(geo.addLine(corners[i], corners[(i + 1) % 4]) for i in range(4))


def _add_cylinder(
    geo, p: TurekHronParameters, fine: float
) -> tuple[tuple[int, int], list[int], int]:
    """The cylinder: its (bottom, top) joint points with the flag, its wetted arcs and the
    clamped arc between the joints."""
    cx, cy = p.cylinder_centre
    r, half = p.cylinder_radius, p.flag_thickness / 2
    x_j = cx + math.sqrt(r**2 - half**2)
    centre = geo.addPoint(cx, cy, 0.0, fine)
    joint_bottom, joint_top = (geo.addPoint(x_j, y, 0.0, fine) for y in (cy - half, cy + half))
    # Built-in circle arcs must be shorter than π: split the wetted arc at the top, left and bottom.
    north, west, south = (geo.addPoint(x, y, 0.0, fine) for x, y in
                          [(cx, cy + r), (cx - r, cy), (cx, cy - r)])  # fmt: skip
    arcs = [(joint_top, north), (north, west), (west, south), (south, joint_bottom)]
    obstacle = [geo.addCircleArc(start, centre, end) for start, end in arcs]
    clamped = geo.addCircleArc(joint_bottom, centre, joint_top)
    return (joint_bottom, joint_top), obstacle, clamped


def _add_flag_outline(
    geo, p: TurekHronParameters, fine: float, joints: tuple[int, int]
) -> list[int]:
    """The flag's wetted outline from the bottom joint round the tip (through point A) to the
    top joint: bottom, lower tip, upper tip and top lines."""
    joint_bottom, joint_top = joints
    cy, half, x_tip = p.cylinder_centre[1], p.flag_thickness / 2, tip_x(p)
    tip_bottom, a, tip_top = (geo.addPoint(x_tip, y, 0.0, fine) for y in (cy - half, cy, cy + half))
    return [
        geo.addLine(joint_bottom, tip_bottom), geo.addLine(tip_bottom, a),
        geo.addLine(a, tip_top), geo.addLine(tip_top, joint_top),
    ]  # fmt: skip


def _add_size_field(field, curves: list[int], size: float, fine: float, grading: float) -> None:
    """The background size field h(d) = min(size, fine + grading·d), d the distance to
    ``curves``."""
    distance = field.add("Distance")
    field.setNumbers(distance, "CurvesList", curves)
    field.setNumber(distance, "NumPointsPerCurve", 200)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", fine)
    field.setNumber(threshold, "SizeMax", size)
    field.setNumber(threshold, "DistMin", 0.0)
    field.setNumber(threshold, "DistMax", (size - fine) / grading)
    field.setAsBackgroundMesh(threshold)
