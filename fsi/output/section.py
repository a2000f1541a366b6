"""Plane sections of a 3D field for ``fsi plot --slice`` (docs/3d.md): the tetrahedra of a
:class:`~fsi.output.field_files.Snapshot` cut by a plane normal to a coordinate axis (``z=0``, the
meridian plane through the plaque's middle; ``x=0.01``, a cross-section), as a 2D snapshot of
triangles in that plane that :func:`fsi.output.plot.draw` draws as it draws a 2D run.

The cut of a tetrahedron by a plane is a triangle (one vertex on one side) or a quadrilateral
(two and two), split into two triangles. A node value is interpolated linearly along each cut
edge (exact for the P1 values the field files hold); a cell value is its cell's. A vertex on the
plane counts as on its positive side (its negative side for a plane on the mesh's low face), so
a plane through mesh nodes cuts no cell twice.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fsi.output.field_files import PlotError, Snapshot

AXES = "xyz"


@dataclasses.dataclass(frozen=True)
class Plane:
    """The plane ``axis`` = ``value`` (m): its in-plane axes, in drawing order, are the other two
    (x, z for y = c; x, y for z = c; y, z for x = c)."""

    axis: int
    value: float

    @classmethod
    def parse(cls, text: str) -> Plane:
        """``x=0.01``, ``y=0``, ``z=-1e-3`` → the plane; :class:`PlotError` naming ``--slice``
        otherwise."""
        name, _, number = text.partition("=")
        name = name.strip().lower()
        try:
            value = float(number)
        except ValueError:
            value = float("nan")
        if name not in AXES or not np.isfinite(value):
            raise PlotError(
                f"--slice {text}: expected AXIS=VALUE, a plane normal to x, y or z at a "
                "coordinate in m (e.g. y=0 through the axis, x=0.01 across it)"
            )
        return cls(AXES.index(name), value)

    @property
    def in_plane(self) -> tuple[int, int]:
        return tuple(i for i in range(3) if i != self.axis)  # type: ignore[return-value]

    @property
    def labels(self) -> tuple[str, str]:
        return tuple(f"{AXES[i]} (mm)" for i in self.in_plane)  # type: ignore[return-value]

    def __str__(self) -> str:
        return f"{AXES[self.axis]} = {self.value:g} m"


def cut(snapshot: Snapshot, plane: Plane) -> Snapshot:
    """The section of ``snapshot`` (tetrahedra, on its drawn coordinates) by ``plane``: a
    snapshot of triangles with 2D coordinates in the plane (:attr:`Plane.in_plane`), values
    per new node (interpolated) or per triangle (its tetrahedron's), vectors keeping their
    three components. Raises :class:`PlotError` if the snapshot is not 3D or the plane misses
    its cells."""
    if snapshot.triangles.shape[1] != 4:
        raise PlotError(f"--slice {plane}: {snapshot.file.name} holds a 2D mesh; draw it whole")
    x = snapshot.coordinates
    tets = snapshot.triangles
    side = x[:, plane.axis] - plane.value
    # Nodes within round-off of the plane are on it (a revolved mesh's meridian nodes carry
    # coordinates like 1e-19 for 0), so that a face in the plane is cut once, not twice.
    side[np.abs(side) <= 1e-12 * np.abs(x).max()] = 0.0
    d = side[tets]  # (n, 4)
    positive = d >= 0
    if np.all(positive):  # the plane on the mesh's low face: its nodes count as below
        positive = d > 0
    count = positive.sum(axis=1)
    points, owners, parents, triangles = [], [], [], []

    def edge_points(rows, a, b):
        """Cut points on the edges (a, b) (vertex slots) of the tetrahedra ``rows``."""
        va, vb = tets[rows, a], tets[rows, b]
        da, db = d[rows, a], d[rows, b]
        t = da / (da - db)
        at = x[va] + t[:, None] * (x[vb] - x[va])
        return at, (va, vb, t)

    for lone_positive in (True, False):
        rows = np.flatnonzero(count == (1 if lone_positive else 3))
        if len(rows) == 0:
            continue
        lone_mask = positive[rows] if lone_positive else ~positive[rows]
        lone = np.argmax(lone_mask, axis=1)
        others = np.array([[j for j in range(4) if j != k] for k in range(4)])[lone]
        corners = [edge_points(rows, lone, others[:, j]) for j in range(3)]
        _add(points, owners, parents, triangles, rows, corners, [(0, 1, 2)])
    rows = np.flatnonzero(count == 2)
    if len(rows):
        order = np.argsort(~positive[rows], axis=1, kind="stable")  # positives first
        p0, p1, n0, n1 = (order[:, j] for j in range(4))
        corners = [
            edge_points(rows, p0, n0),
            edge_points(rows, p0, n1),
            edge_points(rows, p1, n1),
            edge_points(rows, p1, n0),
        ]
        _add(points, owners, parents, triangles, rows, corners, [(0, 1, 2), (0, 2, 3)])
    if not triangles:
        lo, hi = x[:, plane.axis].min(), x[:, plane.axis].max()
        raise PlotError(
            f"--slice {plane}: the plane misses the {snapshot.domain}'s cells "
            f"({AXES[plane.axis]} from {lo:g} to {hi:g} m)"
        )
    return _section(snapshot, plane, points, owners, parents, triangles)


def _add(points, owners, parents, triangles, rows, corners, pattern) -> None:
    """Append the cut polygons' corner points, their edges' interpolation data and the
    triangles ``pattern`` (corner slots) of each tetrahedron in ``rows``."""
    start = sum(len(p) for p in points)
    n = len(rows)
    for at, owner in corners:
        points.append(at)
        owners.append(owner)
    base = start + np.arange(n)
    for a, b, c in pattern:
        triangles.append(np.column_stack([base + a * n, base + b * n, base + c * n]))
        parents.append(rows)


def _section(snapshot, plane, points, owners, parents, triangles) -> Snapshot:
    """The 2D snapshot of the cut: duplicate points (shared edges, vertices on the plane)
    merged, node values interpolated, cell values taken from the parents."""
    xyz = np.concatenate(points)
    va = np.concatenate([o[0] for o in owners])
    vb = np.concatenate([o[1] for o in owners])
    t = np.concatenate([o[2] for o in owners])
    # A cut point is named by its edge (its two nodes, in order), or by its node where the
    # plane passes through one: the same point from every tetrahedron that shares it.
    key = np.column_stack([np.minimum(va, vb), np.maximum(va, vb)])
    on_node = (t <= 0) | (t >= 1)
    node = np.where(t <= 0, va, vb)
    key[on_node] = node[on_node, None]
    _, unique, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    tris = inverse[np.concatenate(triangles)]
    cells = snapshot.cells[np.concatenate(parents)]
    keep = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
    tris, cells = tris[keep], cells[keep]
    if snapshot.center == "node":
        values = snapshot.values
        weights = t[:, None] if values.ndim == 2 else t
        interpolated = values[va] + weights * (values[vb] - values[va])
        values = interpolated[unique]
    else:
        parent_rows = np.concatenate(parents)[keep]
        values = snapshot.values[parent_rows]
    reference = xyz[unique][:, list(plane.in_plane)]
    return dataclasses.replace(
        snapshot,
        reference=reference,
        displacement=None,
        triangles=tris,
        cells=cells,
        values=values,
        section=plane,
    )
