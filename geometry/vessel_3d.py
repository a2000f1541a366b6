"""Three-dimensional vessels (``geometry.dimension: 3``): the straight tube and the stenosed
artery as solids, built with gmsh's OpenCASCADE kernel (docs/3d.md).

The vessel's axis is the x axis, the lumen ``0 <= x <= length``, ``r <= R`` (``R`` = the tube's
``radius``, the stenosis's ``height``, as in the axisymmetric cases) and the wall
``R <= r <= R + wall_thickness``, with ``r`` and the angle ``φ`` about the axis measured from
+y towards +z. The stenosis's plaque is the axisymmetric plaque (geometry/stenosis.py: the same
cosine profiles of the cap's lumen surface and of the lipid pool) revolved about the axis over
``|φ| <= plaque_angle / 2``: 360° is the concentric ring, less an eccentric plaque centred on +y
whose two ends are planes through the axis. Its lipid pool spans :func:`lipid_angle`, less by
the angle that keeps cap material of ``cap_thickness`` over the pool's two ends.

Every part is a meridian section (the plane z = 0, y = r >= 0) revolved in angular pieces of
at most 180° (no periodic seams), split at φ = 0 so that the meridian there is a set of mesh
edges; one boolean fragment makes the pieces conformal. :func:`point_a`, the lumen surface at
mid-length on φ = 0 (the plaque's middle), is a mesh vertex.

A tube's ``sector: 90`` is the quarter ``0 <= φ <= 90°`` (y, z >= 0), one piece revolved by
90°; its cuts on the planes z = 0 and y = 0 (the problem's mirror planes) get no tag.

Tags (geometry/tags.py), the axisymmetric cases' with surfaces for curves and volumes for
surfaces: ``fluid``, ``wall``, ``cap``, ``lipid``; ``inlet`` (x = 0) and ``outlet``
(x = length) across the lumen, ``interface`` (the lumen surface), ``clamped`` (the wall's end
rings, x = 0 and x = length), ``exterior`` (r = R + wall_thickness),
``cap_lipid`` and ``plaque_base`` (the plaque's internal surfaces).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fsi.geometry import stenosis
from fsi.geometry.tags import Boundary, Region, add_physical_groups

TUBE_REGIONS = (Region.FLUID, Region.WALL)
TUBE_BOUNDARIES = (
    Boundary.INLET,
    Boundary.OUTLET,
    Boundary.INTERFACE,
    Boundary.CLAMPED,
    Boundary.EXTERIOR,
)
STENOSIS_REGIONS = (Region.FLUID, Region.WALL, Region.CAP, Region.LIPID)
STENOSIS_BOUNDARIES = (*TUBE_BOUNDARIES, Boundary.CAP_LIPID, Boundary.PLAQUE_BASE)

# Control points of each B-spline of a plaque profile (the cap's lumen surface and the lipid
# pool's, from an end to the apex). A B-spline lies in the convex hull of its control points,
# so the plaque never crosses r = R (an interpolating spline may overshoot at the plaque's
# tangent ends); it passes through the end points (the apex and the plaque's ends) and within
# ~0.2 µm of the cosine elsewhere: the solids' volumes are Pappus's within 1e-5 (cap) and
# 8e-5 (pool) at 101 points, against 3e-4 and 3e-4 at 41.
SPLINE_POINTS = 101
# Growth of the element size away from the plaque (size per metre of distance) in the size
# field of :func:`build_stenosis`: from local_size at the plaque to size.
GRADING = 0.3


def is_stenosis(p) -> bool:
    """Whether ``p`` is a stenosis's parameters (it has a plaque), not a tube's."""
    return hasattr(p, "stenosis_degree")


def lumen_radius(p) -> float:
    """The lumen's radius R (m): the stenosis's ``height``, the tube's ``radius``."""
    return p.height if is_stenosis(p) else p.radius


def plaque_angle(p) -> float:
    """The plaque's angular span (radians): ``plaque_angle`` (degrees; a tube has none)."""
    return math.radians(getattr(p, "plaque_angle", 360.0))


def lipid_angle(p) -> float:
    """The lipid pool's angular span (radians): the plaque's, less ``2 δ`` with
    ``(R − a) sin δ = cap_thickness`` (``a`` the pool's apex height): the cap then covers each
    of the pool's two ends by at least ``cap_thickness``. The whole circle for a concentric
    plaque. Not positive when the plaque is too narrow for its pool (validation refuses it)."""
    alpha = plaque_angle(p)
    if alpha >= 2 * math.pi:
        return 2 * math.pi
    inner = lumen_radius(p) - (stenosis.plaque_height(p) - p.cap_thickness)
    return alpha - 2 * math.asin(min(1.0, p.cap_thickness / inner))


def sector(p) -> float:
    """The modelled part of the vessel's circumference (radians): ``sector`` (degrees; 90: the
    quarter ``0 <= φ <= 90°`` between the symmetry planes z = 0 and y = 0), else 2π."""
    return math.radians(getattr(p, "sector", 360))


def point_a(p) -> tuple[float, float, float]:
    """Point A (m): the lumen surface at mid-length on φ = 0 (+y), ``(length/2, R − s, 0)``
    with ``s`` the plaque's height there (0 for a tube); a mesh vertex."""
    x = p.length / 2
    s = float(stenosis.plaque_profile(p, np.array([x]))[0]) if is_stenosis(p) else 0.0
    return x, lumen_radius(p) - s, 0.0


def _revolved_bump(amplitude: float, length: float, angle: float, radius: float) -> float:
    """Volume (m³) between r = radius − s(x) and r = radius over ``angle`` (radians) for a
    cosine bump s of ``amplitude`` and ``length``: Pappus, ``angle ∫ (radius s − s²/2) dx``
    with ``∫ s dx = A l / 2`` and ``∫ s² dx = 3 A² l / 8``."""
    return angle * (radius * amplitude * length / 2 - 3 * amplitude**2 * length / 16)


def analytic_volumes(p) -> dict[str, float]:
    """Exact region volumes (m³): the lumen πR²L less the plaque, the wall
    π((R + t)² − R²)L, and the plaque's cap and lipid pool by Pappus's theorem (the revolved
    meridian areas of geometry/stenosis.py times their centroid's path); a quarter's are a
    quarter of the whole's."""
    R, t, L = lumen_radius(p), p.wall_thickness, p.length
    share = sector(p) / (2 * math.pi)
    volumes = {
        Region.FLUID.label: share * math.pi * R**2 * L,
        Region.WALL.label: share * math.pi * ((R + t) ** 2 - R**2) * L,
    }
    if is_stenosis(p):
        A = stenosis.plaque_height(p)
        plaque = _revolved_bump(A, p.stenosis_length, min(plaque_angle(p), sector(p)), R)
        lipid_span = min(lipid_angle(p), sector(p))
        lipid = _revolved_bump(A - p.cap_thickness, p.lipid_length, lipid_span, R)
        volumes[Region.FLUID.label] -= plaque
        volumes[Region.CAP.label] = plaque - lipid
        volumes[Region.LIPID.label] = lipid
    volumes["total"] = sum(volumes.values())
    return volumes


def area_reduction(p) -> float:
    """The fraction of the lumen's cross-section the plaque closes at its apex:
    ``(α / 2π) (1 − (1 − d)²)`` for a plaque of angular span α closing the radius fraction
    ``d = stenosis_degree`` (0.75 for the concentric d = 0.5, its quarter's too)."""
    d = stenosis.plaque_height(p) / lumen_radius(p)
    return plaque_angle(p) / (2 * math.pi) * (1 - (1 - d) ** 2)


def interface_area(p, samples: int = 20001) -> float:
    """Exact area (m²) of the lumen surface: the cylinder 2πRL (a quarter's a quarter of it),
    with over the plaque's span the surface of revolution ``∫ (R − s) √(1 + s'²) dx`` per
    radian in place of the cylinder's ``R l``, and for an eccentric plaque its two flat ends
    (each the meridian plaque's area A l / 2). The integral by the trapezoidal rule on
    ``samples`` points (relative error ~1e-9)."""
    R, L, whole = lumen_radius(p), p.length, sector(p)
    if not is_stenosis(p):
        return whole * R * L
    alpha, l = min(plaque_angle(p), whole), p.stenosis_length
    x = np.linspace(stenosis.apex_x(p) - l / 2, stenosis.apex_x(p) + l / 2, samples)
    s = stenosis.plaque_profile(p, x)
    slope = np.gradient(s, x)
    f = (R - s) * np.sqrt(1 + slope**2)
    revolved = float(np.sum((f[1:] + f[:-1]) / 2 * np.diff(x)))
    area = whole * R * (L - l) + alpha * revolved + (whole - alpha) * R * l
    if alpha < whole:
        area += stenosis.plaque_height(p) * l  # the two ends, A l / 2 each
    return area


def build_tube(p, size: float) -> None:
    """Add the 3D tube to the current gmsh model (OpenCASCADE kernel) with physical groups;
    ``size`` is the element size (m) everywhere. Meshing is left to the caller."""
    import gmsh

    builder = _Builder(p, gmsh.model.occ)
    builder.add_sections(plaque=False)
    builder.revolve_pieces()
    builder.tag()
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.0)


def build_stenosis(
    p,
    size: float,
    local_size: float,
    grading: float = GRADING,
    lumen_size: float | None = None,
) -> None:
    """Add the 3D stenosed artery to the current gmsh model (OpenCASCADE kernel) with physical
    groups, and its size field: ``local_size`` in the box around the plaque (its axial extent,
    its angular span and ``R − A <= r <= R``), growing by ``grading`` (size per metre) with
    the distance from it up to ``size``; with ``lumen_size``, also that size in the lumen's core
    over the plaque's axial extent (``r <= R − A``: the throat), graded likewise, the smaller of
    the two sizes wherever both apply. Meshing is left to the caller."""
    import gmsh

    builder = _Builder(p, gmsh.model.occ)
    builder.add_sections(plaque=True)
    builder.revolve_pieces()
    builder.tag()
    _plaque_size_field(p, size, local_size, grading, lumen_size)


def _plaque_size_field(
    p, size: float, local_size: float, grading: float, lumen_size: float | None
) -> None:
    """The background size field: a MathEval field of the distance to the plaque's box (its
    axial, radial and angular excess, each ``(a + |a|) / 2``), thresholded from
    ``local_size`` at 0 to ``size`` at ``(size − local_size) / grading``; with ``lumen_size``
    the minimum of that and the same threshold of the distance to the throat's cylinder over
    the plaque's length (axial excess and ``r − (R − A)``'s) from ``lumen_size``."""
    import gmsh

    field = gmsh.model.mesh.field
    R, A = lumen_radius(p), stenosis.plaque_height(p)
    xc, half = stenosis.apex_x(p), p.stenosis_length / 2
    half_angle = plaque_angle(p) / 2

    def excess(a: str) -> str:
        return f"(({a}) + Fabs({a})) / 2"

    r = "Sqrt(y * y + z * z)"
    terms = [excess(f"Fabs(x - {xc!r}) - {half!r}"), excess(f"{R - A!r} - {r}")]
    terms.append(excess(f"{r} - {R!r}"))
    if half_angle < math.pi:
        # |φ| = acos(y / r): gmsh's MathEval has no two-argument atan2; 1e-15 m keeps the
        # ratio defined on the axis and below 1.
        angle = f"Acos(y / ({r} + 1e-15))"
        terms.append(f"{R!r} * " + excess(f"{angle} - {half_angle!r}"))
    background = plaque = _graded(terms, local_size, size, grading)
    if lumen_size is not None:
        lumen = _graded([terms[0], excess(f"{r} - {R - A!r}")], lumen_size, size, grading)
        background = field.add("Min")
        field.setNumbers(background, "FieldsList", [plaque, lumen])
    field.setAsBackgroundMesh(background)
    # The field alone sets the sizes: none from the points, none extended from the boundary
    # (which would carry a curve's coarse size into the plaque's box).
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)


def _graded(terms: list[str], near: float, size: float, grading: float) -> int:
    """A Threshold field of the distance ``Sqrt(Σ term²)`` (MathEval): ``near`` at 0, growing
    by ``grading`` (size per metre) up to ``size``. Its tag."""
    import gmsh

    field = gmsh.model.mesh.field
    distance = field.add("MathEval")
    field.setString(distance, "F", "Sqrt(" + " + ".join(f"({t})^2" for t in terms) + ")")
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", near)
    field.setNumber(threshold, "SizeMax", size)
    field.setNumber(threshold, "DistMin", 0.0)
    field.setNumber(threshold, "DistMax", (size - near) / grading)
    return threshold


class _Builder:
    """The meridian sections of one vessel, their revolved pieces and the regions they become.

    ``sections``: per angular kind ("plaque", "plain", "lipid"), the meridian faces of each
    region; ``pieces``: the revolved volumes of each region before the fragment."""

    def __init__(self, p, occ: Any) -> None:
        self.p, self.occ = p, occ
        self.R, self.L, self.t = lumen_radius(p), p.length, p.wall_thickness
        self.sections: dict[str, dict[Region, list[int]]] = {}
        self.pieces: dict[Region, list[tuple[int, int]]] = {r: [] for r in STENOSIS_REGIONS}
        self.stenosed = False

    def point(self, x: float, r: float) -> int:
        return self.occ.addPoint(x, r, 0.0)

    def line(self, a: int, b: int) -> int:
        return self.occ.addLine(a, b)

    def face(self, curves: list[int]) -> int:
        return self.occ.addPlaneSurface([self.occ.addCurveLoop(curves)])

    def profile_curve(self, start: int, end: int, x0: float, x1: float, profile) -> int:
        """A B-spline from ``start`` to ``end`` whose control points follow ``r = R − s(x)``
        between ``x0`` and ``x1``."""
        xs = np.linspace(x0, x1, SPLINE_POINTS)[1:-1]
        rs = self.R - profile(self.p, xs)
        inner = [self.point(float(x), float(r)) for x, r in zip(xs, rs)]
        curve = self.occ.addBSpline([start, *inner, end])
        self.occ.remove([(0, q) for q in inner])  # control points only, no model vertices
        return curve

    def add_sections(self, plaque: bool) -> None:
        """The meridian faces: the plain lumen and wall and, for a stenosis, the plaque's lumen,
        plaque (cap and pool) and wall, and the pool alone. Each section has its own curves
        (the plain one is rotated before it is revolved, which must move no other face's
        edges); within a section the faces share theirs."""
        self.sections["plain"] = self._plain_section()
        if plaque:
            self.stenosed = True
            self._add_plaque_sections()

    def _ends(self) -> tuple[tuple[int, int, int, int], dict[str, int]]:
        """A section's corner points on r = R (x = 0, L) and its lines off the lumen surface:
        the axis, inlet, outlet, the wall's two ends and its exterior."""
        R, L, t = self.R, self.L, self.t
        axis0, axis1 = self.point(0, 0), self.point(L, 0)
        in0, in1 = self.point(0, R), self.point(L, R)
        out0, out1 = self.point(0, R + t), self.point(L, R + t)
        lines = {
            "axis": self.line(axis0, axis1),
            "inlet": self.line(axis0, in0),
            "outlet": self.line(axis1, in1),
            "clamp0": self.line(in0, out0),
            "clamp1": self.line(in1, out1),
            "exterior": self.line(out0, out1),
        }
        return (axis0, axis1, in0, in1), lines

    def _plain_section(self) -> dict[Region, list[int]]:
        """The healthy vessel's lumen and wall faces, the lumen line split at mid-length (so
        point A is a vertex)."""
        (_, _, in0, in1), e = self._ends()
        lumen = self._plain_lumen(in0, in1, 0.0, self.L)
        return {
            Region.FLUID: [self._fluid_face(e, lumen)],
            Region.WALL: [self._wall_face(e, lumen)],
        }

    def _fluid_face(self, e: dict[str, int], lumen: list[int]) -> int:
        """The lumen's face: the axis, the outlet, the lumen curves (from x = 0 to L) back and
        the inlet."""
        return self.face([e["axis"], e["outlet"], *[-c for c in reversed(lumen)], -e["inlet"]])

    def _wall_face(self, e: dict[str, int], inner: list[int]) -> int:
        """The wall's face: its inner curves (from x = 0 to L), its ends and its exterior."""
        return self.face([*inner, e["clamp1"], -e["exterior"], -e["clamp0"]])

    def _add_plaque_sections(self) -> None:
        """The plaque's section (lumen, plaque of cap and pool, wall behind) and the pool's."""
        p, R, L = self.p, self.R, self.L
        x_a = L / 2
        (_, _, in0, in1), e = self._ends()
        xc, half, half_lip = stenosis.apex_x(p), p.stenosis_length / 2, p.lipid_length / 2
        A = stenosis.plaque_height(p)
        x0, x1, x2, x3 = xc - half, xc - half_lip, xc + half_lip, xc + half
        q0, q1, q2, q3 = (self.point(x, R) for x in (x0, x1, x2, x3))
        apex, lipid_apex = self.point(xc, R - A), self.point(xc, R - A + p.cap_thickness)
        # The cap's lumen curve, from x0 to x3 through the apex and, if the plaque covers it,
        # mid-length (point A); the plain lumen line on either side, split at A if it is there.
        cap_breaks = [(x0, q0), (xc, apex), (x3, q3)]
        if x0 < x_a < x3 and not math.isclose(x_a, xc, rel_tol=0, abs_tol=1e-12 * L):
            r_a = R - float(stenosis.plaque_profile(p, np.array([x_a]))[0])
            cap_breaks.append((x_a, self.point(x_a, r_a)))
        cap_breaks.sort()
        cap = [
            self.profile_curve(start, end, xs, xe, stenosis.plaque_profile)
            for (xs, start), (xe, end) in zip(cap_breaks, cap_breaks[1:])
        ]
        left = self._plain_lumen(in0, q0, 0.0, x0)
        right = self._plain_lumen(q3, in1, x3, L)
        lipid = [
            self.profile_curve(q1, lipid_apex, x1, xc, stenosis.lipid_profile),
            self.profile_curve(lipid_apex, q2, xc, x2, stenosis.lipid_profile),
        ]
        base = [self.line(q0, q1), self.line(q1, q2), self.line(q2, q3)]
        self.sections["plaque"] = {
            Region.FLUID: [self._fluid_face(e, [*left, *cap, *right])],
            Region.CAP: [self.face([*base, *[-c for c in reversed(cap)]])],
            Region.WALL: [self._wall_face(e, [*left, *base, *right])],
        }
        self.sections["lipid"] = {Region.LIPID: [self.face([base[1], *[-c for c in lipid[::-1]]])]}

    def _plain_lumen(self, start: int, end: int, x0: float, x1: float) -> list[int]:
        """The straight lumen line from ``start`` (x0) to ``end`` (x1), split at mid-length."""
        x_a = self.L / 2
        if x0 < x_a < x1:
            a = self.point(x_a, self.R)
            return [self.line(start, a), self.line(a, end)]
        return [self.line(start, end)]

    def revolve_pieces(self) -> None:
        """Revolve the sections in pieces of at most 180°: the plaque's section over
        ``[−α/2, 0]`` and ``[0, α/2]`` (both from the same faces, so the meridian φ = 0 is made
        of them), its pool's likewise over ``±β/2``, the plain vessel's over the rest, each piece
        continuing from the previous one's end faces; a quarter (a tube's, or a concentric
        plaque's and its pool's) over ``[0, 90°]`` in one piece. Then fragment everything into
        conformal volumes (the pieces' coplanar ends, the pool inside the plaque)."""
        inputs: list[tuple[Region, tuple[int, int]]] = []

        def revolve(faces: dict[Region, list[int]], span: float) -> dict[Region, list[int]]:
            """Revolve ``faces`` together (they keep their shared edges) by ``span``; their
            volumes are added to ``inputs``, their end faces returned."""
            order = [(region, f) for region, fs in faces.items() for f in fs]
            out = self.occ.revolve([(2, f) for _, f in order], 0, 0, 0, 1, 0, 0, span)
            volumes = [i for i, (dim, _) in enumerate(out) if dim == 3]
            tops: dict[Region, list[int]] = {}
            for (region, _), i in zip(order, volumes, strict=True):
                inputs.append((region, out[i]))
                tops.setdefault(region, []).append(out[i - 1][1])  # the top precedes it
            return tops

        plain = self.sections["plain"]
        if sector(self.p) < 2 * math.pi:  # a quarter, φ from 0 to 90°: of a concentric plaque
            kinds = ("plaque", "lipid") if self.stenosed else ("plain",)
            for kind in kinds:
                revolve(self.sections[kind], sector(self.p))
            if self.stenosed:
                self.occ.remove([(2, f) for fs in plain.values() for f in fs], recursive=True)
            self._fragment(inputs)
            return
        if not self.stenosed:  # a tube: from the meridian φ = 0 both ways, as a plaque
            revolve(plain, -math.pi)
            revolve(plain, math.pi)
            self._fragment(inputs)
            return
        alpha, beta = plaque_angle(self.p), lipid_angle(self.p)
        for kind, span in (("plaque", alpha / 2), ("lipid", beta / 2)):
            revolve(self.sections[kind], -span)
            revolve(self.sections[kind], span)
        rest = 2 * math.pi - alpha  # the plain vessel from α/2 to 2π − α/2, pieces <= 180°
        n = math.ceil(rest / math.pi - 1e-12)
        plain_faces = [(2, f) for fs in plain.values() for f in fs]
        if n == 0:  # concentric: the plain section is not part of the vessel
            self.occ.remove(plain_faces, recursive=True)
        else:
            self.occ.rotate(plain_faces, 0, 0, 0, 1, 0, 0, alpha / 2)
        for _ in range(n):
            plain = revolve(plain, rest / n)
        self._fragment(inputs)

    def _fragment(self, inputs: list[tuple[Region, tuple[int, int]]]) -> None:
        """Fragment the revolved ``inputs`` (region, volume) into conformal volumes and file
        each under its region in ``pieces``."""
        self.occ.synchronize()
        dimtags = [d for _, d in inputs]
        _, mapping = self.occ.fragment(dimtags[:1], dimtags[1:])
        self.occ.synchronize()
        owner: dict[int, set[Region]] = {}
        for (region, _), outs in zip(inputs, mapping):
            for dim, tag in outs:
                if dim == 3:
                    owner.setdefault(tag, set()).add(region)
        for tag, regions in owner.items():
            # The pool lies inside the plaque's revolved section: its parts belong to both
            # inputs, and are lipid.
            region = Region.LIPID if Region.LIPID in regions else regions.pop()
            self.pieces[region].append((3, tag))

    def tag(self) -> None:
        """The physical groups: each region's volumes, and each boundary's surfaces found from
        which regions' volumes they bound and where they lie."""
        import gmsh

        bounding: dict[int, list[Region]] = {}
        for region, volumes in self.pieces.items():
            for _, v in volumes:
                for _, s in gmsh.model.getBoundary([(3, v)], oriented=False):
                    bounding.setdefault(abs(s), []).append(region)
        groups: dict[int, list[int]] = {int(t): [] for t in (*Region, *Boundary)}
        for region, volumes in self.pieces.items():
            groups[region] = [v for _, v in volumes]
        tol = 1e-4 * self.L  # OpenCASCADE enlarges its bounding boxes by its tolerance, 1e-7 m
        for surface, regions in sorted(bounding.items()):
            kinds = set(regions)
            x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, surface)
            at_inlet, at_outlet = x1 <= tol, x0 >= self.L - tol
            at_end = at_inlet or at_outlet
            on_symmetry_plane = max(abs(y0), abs(y1)) <= tol or max(abs(z0), abs(z1)) <= tol
            if len(regions) == 1 and on_symmetry_plane and sector(self.p) < 2 * math.pi:
                continue  # a quarter's cut: no tag (fsi/physics: the normal component held)
            if kinds == {Region.FLUID}:
                if at_end:
                    groups[Boundary.INLET if at_inlet else Boundary.OUTLET].append(surface)
            elif Region.FLUID in kinds:
                groups[Boundary.INTERFACE].append(surface)
            elif kinds == {Region.CAP, Region.LIPID}:
                groups[Boundary.CAP_LIPID].append(surface)
            elif Region.WALL in kinds and kinds & {Region.CAP, Region.LIPID}:
                groups[Boundary.PLAQUE_BASE].append(surface)
            elif len(regions) == 1:  # the structure's outer boundary: its ends or the exterior
                groups[Boundary.CLAMPED if at_end else Boundary.EXTERIOR].append(surface)
        add_physical_groups(groups, dimension=3)
