"""The stenosed artery of docs/model.md §1: lumen, vessel wall, lipid pool, fibrous cap.

The lumen is ``0 <= x <= length``, ``0 <= y <= height``. A plaque side ("bottom" or "top",
:func:`sides`) carries a vessel-wall layer of ``wall_thickness`` outside the lumen and a
cosine-shaped plaque centred at :func:`apex_x` (``length / 2`` unless ``stenosis_centre`` is
set; :func:`plaque_profile`): a lipid pool (:func:`lipid_profile`) under a fibrous cap. A side
without plaque is the healthy, rigid wall Γw2 and carries no structure. Axisymmetric
(``axisymmetric``): the meridian half-plane of a circular vessel, whose bottom side y = 0 is
the axis (tag ``axis``) and whose top side carries the plaque, a concentric ring; ``height`` is
the lumen's radius.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from fsi.geometry.tags import Boundary, Region, add_physical_groups

# The tags this builder writes (mesh.json reports these; :func:`boundaries` of a geometry).
REGIONS = (Region.FLUID, Region.WALL, Region.CAP, Region.LIPID)
BOUNDARIES = (
    Boundary.INLET,
    Boundary.OUTLET,
    Boundary.INTERFACE,
    Boundary.RIGID_WALL,
    Boundary.CLAMPED,
    Boundary.EXTERIOR,
    Boundary.CAP_LIPID,
    Boundary.PLAQUE_BASE,
)

SIDES = ("bottom", "top")
AXIS_SIDE = "bottom"  # the axis y = 0 of an axisymmetric stenosis


class StenosisParameters(Protocol):
    """The stenosis's dimensions (m; fsi.config.StenosisGeometry): ``stenosis_degree`` the
    fraction of ``height`` the plaques close, ``plaque_sides`` of :data:`SIDES` (None: bottom),
    ``axisymmetric`` the meridian half-plane of a circular vessel."""

    length: float
    height: float
    wall_thickness: float
    stenosis_length: float
    stenosis_degree: float
    cap_thickness: float
    lipid_length: float
    plaque_sides: Sequence[str] | None  # None: ("bottom",)
    stenosis_centre: float | None  # None: length / 2
    axisymmetric: bool


def sides(p: StenosisParameters) -> tuple[str, ...]:
    """The sides that carry a plaque: ``plaque_sides`` (``("bottom",)`` when None) in the plane;
    the top, the vessel's wall, when axisymmetric (the bottom is the axis)."""
    if p.axisymmetric:
        return ("top",)
    return tuple(p.plaque_sides) if p.plaque_sides is not None else ("bottom",)


def boundaries(p: StenosisParameters) -> tuple[Boundary, ...]:
    """The boundary tags of the mesh: :data:`BOUNDARIES`, with ``axis`` for the rigid wall when
    axisymmetric (the bottom side is the axis, the top carries the plaque), and without the
    rigid wall when both sides carry a plaque (the lumen is bounded by the interface alone)."""
    if p.axisymmetric:
        return tuple(Boundary.AXIS if b == Boundary.RIGID_WALL else b for b in BOUNDARIES)
    if set(sides(p)) == set(SIDES):
        return tuple(b for b in BOUNDARIES if b != Boundary.RIGID_WALL)
    return BOUNDARIES


def apex_x(p: StenosisParameters) -> float:
    """x of the plaque's apex (m): ``stenosis_centre``, or the middle of the segment."""
    return p.length / 2 if p.stenosis_centre is None else p.stenosis_centre


def plaque_height(p: StenosisParameters) -> float:
    """Apex height ``A`` of each plaque above its wall."""
    return p.stenosis_degree * p.height / len(sides(p))


def _cosine_bump(x: np.ndarray, amplitude: float, centre: float, length: float) -> np.ndarray:
    s = amplitude / 2 * (1 - np.cos(2 * np.pi * (x - centre + length / 2) / length))
    return np.where(np.abs(x - centre) <= length / 2, s, 0.0)


def plaque_profile(p: StenosisParameters, x: np.ndarray) -> np.ndarray:
    """Height of the fibrous-cap surface (the lumen boundary) above the wall at ``x``.

    ``s = A/2 (1 - cos(2π (x - x0) / l))`` on ``[x0, x0 + l]`` (0 elsewhere), centred at
    :func:`apex_x`, with ``l = stenosis_length`` and ``A`` = :func:`plaque_height`
    ``= stenosis_degree * height / number of plaque sides``.
    """
    return _cosine_bump(np.asarray(x, dtype=float), plaque_height(p), apex_x(p), p.stenosis_length)


def lipid_profile(p: StenosisParameters, x: np.ndarray) -> np.ndarray:
    """Height of the lipid-pool surface above the wall at ``x``: the plaque's cosine bump
    (:func:`plaque_profile`) with length ``lipid_length`` and amplitude ``A - cap_thickness``.
    """
    a = plaque_height(p) - p.cap_thickness
    return _cosine_bump(np.asarray(x, dtype=float), a, apex_x(p), p.lipid_length)


def analytic_areas(p: StenosisParameters) -> dict[str, float]:
    """Exact region areas (m²): a cosine bump of amplitude ``A``, length ``l`` has area A l / 2."""
    n = len(sides(p))
    plaque = plaque_height(p) * p.stenosis_length / 2
    lipid = (plaque_height(p) - p.cap_thickness) * p.lipid_length / 2
    areas = {
        Region.FLUID.label: p.length * p.height - n * plaque,
        Region.WALL.label: n * p.length * p.wall_thickness,
        Region.CAP.label: n * (plaque - lipid),
        Region.LIPID.label: n * lipid,
    }
    areas["total"] = sum(areas.values())
    return areas


def distance_to_polyline(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance from each point (n, 2) to the polyline through ``vertices`` (m, 2)."""
    a, b = vertices[:-1], vertices[1:]
    return distance_to_segments(points, a, b)


def distance_to_segments(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from each point (n, 2) to the nearest of the segments ``a[k]``–``b[k]``."""
    ab = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), np.finfo(float).tiny)
    out = np.empty(len(points))
    for i0 in range(0, len(points), 256):  # chunks keep the (points × segments) arrays small
        q = points[i0 : i0 + 256, None, :]
        t = np.clip(np.einsum("pij,ij->pi", q - a, ab) / length2, 0.0, 1.0)
        nearest = a + t[..., None] * ab
        out[i0 : i0 + 256] = np.sqrt(((q - nearest) ** 2).sum(-1)).min(axis=1)
    return out


def min_cap_thickness(p: StenosisParameters, samples: int = 801) -> float:
    """Smallest distance from the lipid-pool surface to the lumen (the thinnest fibrous cap).

    It is ``cap_thickness``, at the apex, as long as the lipid pool is short enough. Sampled
    densely (an odd count, so the apex is a sample); accurate to about 1e-8 m.
    """
    xc = apex_x(p)
    x_lipid = np.linspace(xc - p.lipid_length / 2, xc + p.lipid_length / 2, samples)
    x_cap = np.linspace(xc - p.stenosis_length / 2, xc + p.stenosis_length / 2, 2 * samples)
    lipid = np.column_stack([x_lipid, lipid_profile(p, x_lipid)])
    cap = np.column_stack([x_cap, plaque_profile(p, x_cap)])
    # Every 10th sample first, then the samples around a coarse one that may hold the minimum:
    # a point's distance to the cap changes by at most the length it moves, so a sample whose
    # nearest coarse sample is farther than the coarse minimum plus the path between them
    # cannot be closer. The same minimum as over all the samples, in a fraction of the time.
    stride = 10
    coarse = np.arange(0, samples, stride)
    coarse = np.unique(np.append(coarse, samples - 1))
    distance = distance_to_polyline(lipid[coarse], cap)
    path = np.cumsum(np.r_[0.0, np.hypot(*np.diff(lipid, axis=0).T)])
    # every sample lies within `reach` of path from its nearest coarse sample
    reach = float(np.diff(path[coarse]).max()) / 2
    near = coarse[distance <= distance.min() + reach]
    half = stride // 2 + 1
    fine = np.unique(np.concatenate([np.arange(i - half, i + half + 1) for i in near]))
    fine = fine[(fine >= 0) & (fine < samples)]
    return float(min(distance.min(), distance_to_polyline(lipid[fine], cap).min()))


def build(p: StenosisParameters, size: float, local_size: float, spline_points: int = 101) -> None:
    """Add the stenosed artery to the current gmsh model (built-in kernel) with physical groups.

    ``size`` is the element size (m) away from the plaque, ``local_size`` the size at the
    plaque's corner and apex points; gmsh interpolates in between. A plaque's surfaces are
    splines through ``spline_points`` points. Meshing is left to the caller.
    """
    import gmsh

    b = _Builder(p, size, local_size, spline_points, gmsh.model.geo)
    lumen_chain: dict[str, list[int]] = {}  # left-to-right curves of each lumen side
    corners: dict[str, tuple[int, int]] = {}  # (x = 0, x = L) end points of each lumen side
    for side in SIDES:
        left, right = b.point(side, 0.0, 0.0, size), b.point(side, p.length, 0.0, size)
        corners[side] = (left, right)
        if side not in sides(p):
            lumen_chain[side] = [b.geo.addLine(left, right)]
            plain = Boundary.AXIS if p.axisymmetric and side == AXIS_SIDE else Boundary.RIGID_WALL
            b.groups[plain].extend(lumen_chain[side])
        else:
            lumen_chain[side] = _add_plaque_side(b, side, left, right)
    _add_lumen(b, lumen_chain, corners)
    b.geo.synchronize()
    add_physical_groups(b.groups)


@dataclass
class _Builder:
    """The state of one :func:`build`: its arguments, gmsh's ``geo`` kernel and the entities of
    each physical group added so far."""

    p: StenosisParameters
    size: float
    local_size: float
    spline_points: int
    geo: Any
    groups: dict[int, list[int]] = field(
        default_factory=lambda: {int(t): [] for t in (*Region, *Boundary)}
    )

    def point(self, side: str, x: float, s: float, lc: float) -> int:
        """A gmsh point at ``x``, ``s`` from the ``side`` wall into the lumen, of size ``lc``."""
        xy = (x, s) if side == "bottom" else (x, self.p.height - s)
        return self.geo.addPoint(*xy, 0.0, lc)

    def spline(self, side: str, start: int, end: int, x0: float, x1: float, profile) -> int:
        """A spline from ``start`` to ``end`` through the ``profile`` heights between x0, x1."""
        xs = np.linspace(x0, x1, self.spline_points)[1:-1]
        inner = [self.point(side, x, float(profile(np.array([x]))[0]), self.local_size) for x in xs]
        return self.geo.addSpline([start, *inner, end])


def _add_plaque_side(b: _Builder, side: str, left: int, right: int) -> list[int]:
    """The plaque, lipid pool and vessel wall of ``side``, whose lumen corners are ``left`` and
    ``right``; returns the side's lumen curves from left to right."""
    p, geo, hs = b.p, b.geo, b.local_size
    xc, l, l_lip = apex_x(p), p.stenosis_length, p.lipid_length
    A = plaque_height(p)
    a = A - p.cap_thickness
    p_x0, p_top, p_x3 = (
        b.point(side, xc - l / 2, 0, hs),
        b.point(side, xc, A, hs),
        b.point(side, xc + l / 2, 0, hs),
    )
    p_x1, p_lip, p_x2 = (
        b.point(side, xc - l_lip / 2, 0, hs),
        b.point(side, xc, a, hs),
        b.point(side, xc + l_lip / 2, 0, hs),
    )

    def cap_profile(x):
        return plaque_profile(p, x)

    def lipid_prof(x):
        return lipid_profile(p, x)

    healthy_left, healthy_right = geo.addLine(left, p_x0), geo.addLine(p_x3, right)
    cap_left = b.spline(side, p_x0, p_top, xc - l / 2, xc, cap_profile)
    cap_right = b.spline(side, p_top, p_x3, xc, xc + l / 2, cap_profile)
    lip_left = b.spline(side, p_x1, p_lip, xc - l_lip / 2, xc, lipid_prof)
    lip_right = b.spline(side, p_lip, p_x2, xc, xc + l_lip / 2, lipid_prof)
    base = (geo.addLine(p_x0, p_x1), geo.addLine(p_x1, p_x2), geo.addLine(p_x2, p_x3))
    chain = [healthy_left, cap_left, cap_right, healthy_right]
    _add_plaque_regions(b, side, (left, right), chain, (lip_left, lip_right), base)
    return chain


def _add_plaque_regions(
    b: _Builder,
    side: str,
    corners: tuple[int, int],
    chain: list[int],
    lipid: tuple[int, int],
    base: tuple[int, int, int],
) -> None:
    """The cap, lipid-pool and wall surfaces of ``side`` from its lumen ``corners`` and curves
    (``chain``), the lipid surface's two splines and the plaque base's three lines, with the
    wall's clamped ends and exterior; each in its physical group."""
    geo, groups, size = b.geo, b.groups, b.size
    left, right = corners
    healthy_left, cap_left, cap_right, healthy_right = chain
    lip_left, lip_right = lipid
    base_left, base_mid, base_right = base
    cap_loop = [base_left, lip_left, lip_right, base_right, -cap_right, -cap_left]
    lipid_loop = [base_mid, -lip_right, -lip_left]
    tw = b.p.wall_thickness
    q_left, q_right = b.point(side, 0.0, -tw, size), b.point(side, b.p.length, -tw, size)
    clamp_left, clamp_right = geo.addLine(q_left, left), geo.addLine(right, q_right)
    exterior = geo.addLine(q_right, q_left)
    wall_loop = [healthy_left, base_left, base_mid, base_right, healthy_right,
                 clamp_right, exterior, clamp_left]  # fmt: skip

    groups[Region.CAP].append(geo.addPlaneSurface([geo.addCurveLoop(cap_loop)]))
    groups[Region.LIPID].append(geo.addPlaneSurface([geo.addCurveLoop(lipid_loop)]))
    groups[Region.WALL].append(geo.addPlaneSurface([geo.addCurveLoop(wall_loop)]))
    groups[Boundary.INTERFACE].extend(chain)
    groups[Boundary.CLAMPED].extend([clamp_left, clamp_right])
    groups[Boundary.EXTERIOR].append(exterior)
    groups[Boundary.CAP_LIPID].extend([lip_left, lip_right])
    groups[Boundary.PLAQUE_BASE].extend([base_left, base_mid, base_right])


def _add_lumen(
    b: _Builder, lumen_chain: dict[str, list[int]], corners: dict[str, tuple[int, int]]
) -> None:
    """The inlet and outlet lines between the two sides' lumen ``corners`` and the fluid
    surface bounded by them and each side's lumen curves (``lumen_chain``)."""
    geo, groups = b.geo, b.groups
    inlet = geo.addLine(corners["bottom"][0], corners["top"][0])
    outlet = geo.addLine(corners["bottom"][1], corners["top"][1])
    bottom, top = lumen_chain["bottom"], lumen_chain["top"]
    fluid_loop = [*bottom, outlet, *[-c for c in reversed(top)], -inlet]
    groups[Region.FLUID].append(geo.addPlaneSurface([geo.addCurveLoop(fluid_loop)]))
    groups[Boundary.INLET].append(inlet)
    groups[Boundary.OUTLET].append(outlet)
