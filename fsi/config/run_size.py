"""How big a run is before it starts: its number of steps and, without gmsh, of triangles
(tetrahedra in 3D).

Validation (:func:`fsi.config.validate`) refuses a schedule of more than ``time.max_steps``
steps and a mesh of more than ``mesh.max_cells`` triangles with these counts. The functions
take the case's sections (:class:`fsi.config.Time`, :class:`fsi.config.Case`) by attribute.
"""

from __future__ import annotations

import math

from fsi.geometry import stenosis as stenosis_geometry
from fsi.geometry import tube as tube_geometry
from fsi.geometry import turek_hron as turek_hron_geometry
from fsi.geometry import vessel_3d as vessel_3d_geometry
from fsi.numerics.timestepping import SAME_TIME


def format_count(n: float) -> str:
    """A step or cell count for a message: ``1,234,567``, ``8e+12`` if huge, ``over 1e308`` if
    it overflowed."""
    if not math.isfinite(n):
        return "over 1e308"
    return f"{n:.3g}" if n >= 1e12 else f"{int(n):,}"


def count_steps(time) -> float:
    """The number of steps :func:`fsi.numerics.timestepping.steps` takes from t = 0 to ``time.end``,
    counted per segment arithmetically (a schedule of 10¹² steps costs no more than one of 10;
    inf for a dt so small that the count overflows). Each segment's steps end on its ``until``
    (or ``end``), a remainder below 1e-9 dt merged into the last step, as ``steps`` does."""
    t, n = 0.0, 0
    for segment in time.schedule:
        stop = min(segment.until, time.end)
        if stop - t > SAME_TIME * segment.dt:
            segment_steps = (stop - t) / segment.dt
            n += math.ceil(segment_steps - SAME_TIME) if segment_steps < 2.0**52 else segment_steps
            t = stop
        if time.end <= segment.until:
            break
    return n


TRIANGLE_AREA = math.sqrt(3) / 4
"""Area of an equilateral triangle of side 1: a gmsh triangle of size h covers about
``TRIANGLE_AREA · h²``."""


def estimated_cells(case) -> float:
    """About how many triangles :func:`fsi.physics.mesh.build` makes for ``case``, from the geometry
    alone (no gmsh): area / (TRIANGLE_AREA h²), × 4 per uniform refinement of ``mesh.level``.

    The size field h is modelled per geometry: ``size`` everywhere in a channel; in the
    stenosis ``local_size`` over the box under each plaque (stenosis_length × plaque height)
    and ``size`` elsewhere; in Turek–Hron ``local_size + grading · d`` up to ``size`` at the
    distance d from the cylinder and the flag (the builder's Threshold field, integrated over
    bands around the obstacle). Within a factor 1.5 of gmsh's count on the shipped cases (its
    tests check a factor 3); meant for refusing absurd sizes, not for planning.
    """
    g, m = case.geometry, case.mesh
    size, local = m.size, min(m.local_size, m.size)
    if getattr(g, "dimension", 2) == 3:
        lumen = None if m.lumen_size is None else min(m.lumen_size, size)
        return _estimated_tetrahedra(g, size, local, lumen) * 8.0**m.refinements
    if g.kind == "stenosis":
        total = stenosis_geometry.analytic_areas(g)["total"]
        fine_area = (
            len(stenosis_geometry.sides(g)) * stenosis_geometry.plaque_height(g) * g.stenosis_length
        )
        per_size2 = (total - fine_area) / size / size + fine_area / local / local
    elif g.kind == "turek_hron":
        per_size2 = _turek_hron_cells_area(g, size, local)
    elif g.kind == "tube":
        per_size2 = tube_geometry.analytic_areas(g)["total"] / size / size
    else:
        per_size2 = g.length * g.height / size / size
    return per_size2 / TRIANGLE_AREA * 4.0**m.refinements


def _turek_hron_cells_area(g, size: float, local: float) -> float:
    """∫ dA / h² over the Turek–Hron channel with h(d) = min(size, local + k d), k the
    builder's grading and d the distance to the obstacle (perimeter P, convex): the band
    d < D = (size − local)/k, whose level line at d has length P + 2π d, gives
    ``∫₀^D (P + 2π d) / (local + k d)² dd``; the rest of the channel is at ``size``."""
    k = turek_hron_geometry.GRADING
    r, t = g.cylinder_radius, g.flag_thickness
    x_joint = g.cylinder_centre[0] + math.sqrt(r * r - t * t / 4)
    perimeter = 2 * math.pi * r + 2 * (turek_hron_geometry.tip_x(g) - x_joint) + t
    band = (size - local) / k
    near = perimeter / k * (1 / local - 1 / size) + 2 * math.pi / k**2 * (
        math.log(size / local) + local / size - 1
    )
    total = turek_hron_geometry.analytic_areas(g)["total"]
    rest = max(total - perimeter * band - math.pi * band**2, 0.0)
    return near + rest / size / size


TETRAHEDRON_VOLUME = 1 / (6 * math.sqrt(2))
"""Volume of a regular tetrahedron of edge 1: a gmsh tetrahedron of size h fills about
``TETRAHEDRON_VOLUME · h³``."""


def _estimated_tetrahedra(g, size: float, local: float, lumen: float | None = None) -> float:
    """About how many tetrahedra a 3D vessel's coarse mesh has (geometry/vessel_3d.py): its
    volume / (TETRAHEDRON_VOLUME h³), with h = ``local`` in the plaque's box (its angular span
    of the ring ``R − A <= r <= R`` over ``stenosis_length``), ``lumen`` (``mesh.lumen_size``)
    in the throat's cylinder ``r <= R − A`` over that length, and ``size`` elsewhere, × 8 for
    each further level (which halves the sizes). Measured (estimate): the sample's 120° plaque
    (configs/3d/) 39,236 (38,533), its fine level 1,828,068 (2,466,098); the concentric one at
    local size 0.4 mm 52,947 (54,571); the tube at 0.8 mm 14,436 (21,086)."""
    volumes = vessel_3d_geometry.analytic_volumes(g)
    box = core = 0.0
    if g.kind == "stenosis":
        R, A = g.height, stenosis_geometry.plaque_height(g)
        whole = vessel_3d_geometry.sector(g)  # a quarter's box and core are a quarter
        share = min(vessel_3d_geometry.plaque_angle(g), whole) / (2 * math.pi)
        box = share * math.pi * (R**2 - (R - A) ** 2) * g.stenosis_length
        if lumen is not None:
            core = whole / 2 * (R - A) ** 2 * g.stenosis_length
    rest = volumes["total"] - box - core
    core_cells = 0.0 if lumen is None else core / lumen**3
    return (box / local**3 + core_cells + rest / size**3) / TETRAHEDRON_VOLUME


BYTES_PER_CELL = 18e3
"""Memory (bytes) per triangle of a serial coupled run (the fine stenosis, 51k triangles:
~0.9 GB)."""
