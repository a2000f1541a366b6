"""The measures of a 3D vessel's mesh (geometry/vessel_3d.py) for mesh.json.

:func:`measures` gives the lumen surface's area, the distance from point A to the nearest mesh
vertex and, for a stenosis, the stenosis degree (by radius, as in the axisymmetric case), the
area reduction at the apex and the thinnest fibrous cap, each measured on the mesh (the exact
values are :mod:`fsi.geometry.vessel_3d`'s). Every function here is collective and gives the
same numbers on any number of ranks (it works on the owned facets, gathered on every rank).
"""

from __future__ import annotations

import math

from mpi4py import MPI

import numpy as np
from scipy.spatial import cKDTree

from fsi import compat
from fsi.geometry import stenosis, vessel_3d
from fsi.geometry.tags import Boundary, Region


def regions(g) -> tuple[Region, ...]:
    """The region tags of a 3D vessel's mesh."""
    return vessel_3d.STENOSIS_REGIONS if g.kind == "stenosis" else vessel_3d.TUBE_REGIONS


def boundaries(g) -> tuple[Boundary, ...]:
    """The boundary tags of a 3D vessel's mesh."""
    return vessel_3d.STENOSIS_BOUNDARIES if g.kind == "stenosis" else vessel_3d.TUBE_BOUNDARIES


def facet_triangles(tagged, boundary: Boundary) -> np.ndarray:
    """Vertices (n, 3, 3) of every owned facet on ``boundary``, gathered on all ranks in an
    order independent of the partition (:func:`_canonical`)."""
    mesh = tagged.mesh
    facets = tagged.facets(boundary)
    facets = facets[facets < mesh.topology.index_map(2).size_local]
    nodes = compat.entities_to_geometry(mesh, 2, facets).reshape(-1, 3)
    local = mesh.geometry.x[nodes]
    return _canonical(np.concatenate(tagged.comm.allgather(local)).reshape(-1, 3, 3))


def _canonical(triangles: np.ndarray) -> np.ndarray:
    """``triangles`` (n, 3, 3) with each one's vertices and then the triangles themselves in
    lexicographic order: the same array whatever the partition, so that sums over it are the
    same numbers on any number of ranks."""
    for axis_order in range(3):  # a stable sort by z, then y, then x leaves x-y-z order
        k = 2 - axis_order
        idx = np.argsort(triangles[:, :, k], axis=1, kind="stable")
        triangles = np.take_along_axis(triangles, idx[:, :, None], axis=1)
    keys = triangles.reshape(len(triangles), -1)
    return triangles[np.lexsort(keys.T[::-1])]


def region_volumes(tagged, regions_: tuple[Region, ...]) -> dict[str, float]:
    """The volume (m³) of each region and in all (``total``): the owned tetrahedra's
    |det[b − a, c − a, d − a]| / 6, gathered and summed exactly rounded (math.fsum), so the
    same on any number of ranks."""
    mesh, comm = tagged.mesh, tagged.comm
    n_owned = mesh.topology.index_map(3).size_local
    nodes = compat.geometry_dofmap(mesh)[:n_owned]
    x = mesh.geometry.x[nodes]  # (cells, 4, 3)
    volume = np.abs(np.linalg.det(x[:, 1:] - x[:, :1])) / 6
    tag = np.full(n_owned, -1, dtype=np.int64)
    owned = tagged.cell_tags.indices < n_owned
    tag[tagged.cell_tags.indices[owned]] = tagged.cell_tags.values[owned]
    every = comm.allgather((volume, tag))
    volume = np.concatenate([v for v, _ in every])
    tag = np.concatenate([t for _, t in every])
    result = {r.label: math.fsum(volume[tag == int(r)]) for r in regions_}
    result["total"] = math.fsum(volume)
    return result


def measures(tagged, g) -> dict:
    """``interface_area_m2`` (the lumen surface's triangles), ``point_a_distance_m`` (0 when
    point A is a vertex) and, for a stenosis, ``stenosis_degree`` (the largest radial depth
    of a lumen-surface vertex over R), ``area_reduction`` (:func:`area_reduction`) and
    ``min_cap_thickness_m`` (:func:`min_cap_thickness`)."""
    mesh, comm = tagged.mesh, tagged.comm
    lumen = facet_triangles(tagged, Boundary.INTERFACE)
    x = mesh.geometry.x
    nearest = float(np.sqrt(((x - vessel_3d.point_a(g)) ** 2).sum(axis=1)).min(initial=np.inf))
    result = {
        "interface_area_m2": triangle_area(lumen),
        "point_a_distance_m": float(comm.allreduce(nearest, op=MPI.MIN)),
    }
    if g.kind != "stenosis":
        return result
    R = g.height
    depth = (R - np.hypot(lumen[..., 1], lumen[..., 2])).max(initial=0.0)
    result["stenosis_degree"] = float(depth / R)
    result["area_reduction"] = area_reduction(g, lumen)
    result["min_cap_thickness_m"] = min_cap_thickness(tagged, lumen)
    return result


def triangle_area(triangles: np.ndarray) -> float:
    """The total area of ``triangles`` (n, 3, 3)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    return math.fsum(np.linalg.norm(np.cross(b - a, c - a), axis=1) / 2)


def section_area(triangles: np.ndarray, x: float) -> float:
    """Area of the lumen's cross-section at ``x`` bounded by the lumen-surface ``triangles``
    (n, 3, 3): the plane cuts each triangle it crosses in a segment, and each segment with the
    axis spans a triangle of area |y₁z₂ − y₂z₁| / 2. Their sum is the section's area because
    the lumen is star-shaped about the axis (its radius a function of the angle: the plaque's
    flat ends are radial, and add nothing). ``x`` must be no vertex's x."""
    s = triangles[..., 0] - x
    crossed = (s.min(axis=1) < 0) & (s.max(axis=1) > 0)
    t, s = triangles[crossed], s[crossed]
    points = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        cut = s[:, i] * s[:, j] < 0
        w = (s[:, i] / np.where(cut, s[:, i] - s[:, j], 1.0))[:, None]
        points.append(np.where(cut[:, None], t[:, i] + w * (t[:, j] - t[:, i]), np.nan))
    points = np.stack(points, axis=1)  # (m, 3 edges, 3): two cut edges per triangle
    ends = [row[~np.isnan(row[:, 0])] for row in points]
    ends = np.array([e[:2] for e in ends]).reshape(-1, 2, 3)
    p, q = ends[:, 0], ends[:, 1]
    return math.fsum(np.abs(p[:, 1] * q[:, 2] - p[:, 2] * q[:, 1]) / 2)


def area_reduction(g, lumen: np.ndarray) -> float:
    """``1 − (the lumen's section at the apex) / (its section at the inlet)`` on the mesh
    (:func:`section_area`; both sections are polygons, so their chords' errors largely cancel).
    The sections are taken 10⁻⁶ L past the apex and the inlet, off the vertices there (the
    plaque's profile is flat at its apex: its depth changes by ~10⁻¹¹ of itself there)."""
    offset = 1e-6 * g.length
    throat = section_area(lumen, stenosis.apex_x(g) + offset)
    inlet = section_area(lumen, offset)
    return float(1 - throat / inlet)


def min_cap_thickness(tagged, lumen: np.ndarray) -> float:
    """The smallest distance from a cap–lipid vertex to the lumen surface (the interface
    ``lumen`` triangles, (n, 3, 3)). Exact for the mesh: only triangles whose centroid lies
    within (the nearest lumen vertex's distance + the largest centroid–vertex distance) of a
    point can be nearer than that vertex, so only those are measured."""
    pool = facet_triangles(tagged, Boundary.CAP_LIPID).reshape(-1, 3)
    if len(pool) == 0 or len(lumen) == 0:
        return float("nan")
    pool = np.unique(pool, axis=0)
    vertices = cKDTree(lumen.reshape(-1, 3))
    upper, _ = vertices.query(pool)
    centroids = lumen.mean(axis=1)
    reach = float(np.sqrt(((lumen - centroids[:, None]) ** 2).sum(-1)).max())
    candidates = cKDTree(centroids).query_ball_point(pool, upper + reach)
    best = upper.copy()
    for k, near in enumerate(candidates):
        if near:
            best[k] = min(best[k], point_triangle_distance(pool[k], lumen[near]).min())
    return float(best.min())


def point_triangle_distance(point: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Distance from ``point`` (3,) to each of ``triangles`` (n, 3, 3): to its plane where the
    point projects inside it, otherwise to the nearest of its three edges."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    normal = np.cross(b - a, c - a)
    norm2 = np.maximum((normal**2).sum(-1), np.finfo(float).tiny)
    height = ((point - a) * normal).sum(-1) / norm2
    projected = point - height[:, None] * normal
    inside = np.ones(len(triangles), dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= (np.cross(v - u, projected - u) * normal).sum(-1) >= 0
    edges = [_segment_distance(point, u, v) for u, v in ((a, b), (b, c), (c, a))]
    return np.where(inside, np.abs(height) * np.sqrt(norm2), np.min(edges, axis=0))


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(((point - a) * ab).sum(-1) / np.maximum((ab**2).sum(-1), 1e-300), 0.0, 1.0)
    return np.sqrt(((point - (a + t[:, None] * ab)) ** 2).sum(-1))
