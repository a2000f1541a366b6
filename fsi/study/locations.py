"""Where the maxima a study run reports sit, read from its field files, and whether such a place
is a boundary's corner or an open boundary's edge (:func:`boundary_place`), where a
discretisation's nodal value is not the flow's or the tissue's: a corner of the stress-free
outlet, the clamped corner's singular stress. fsi/study/runs.py keeps them in each run's
summary; docs/study.md flags every reported maximum that sits at such a place.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

PLACES = {
    "inlet_corner": "the inlet's corner with a wall",
    "outlet_corner": "the outlet's corner with a wall",
    "inlet": "the inlet's edge",
    "outlet": "the outlet's edge",
    "clamped_corner": "a clamped end's corner",
    "clamped_end": "a clamped end",
}
"""What :func:`boundary_place` returns → how the document names it."""

NODE_TOLERANCE = 1e-6
"""A node is on a boundary line within this fraction of the segment's length (the nodes of the
reference mesh lie on it to rounding)."""


def boundary_place(
    x: float, y: float, geometry: dict, domain: str = "fluid", tol: float | None = None
) -> str | None:
    """Whether the point (x, y) (m, reference configuration) of a stenosis run is at a boundary's
    corner or edge: for the ``fluid``, on the inlet (x = 0) or the outlet (x = length) —
    ``inlet``/``outlet``, or ``inlet_corner``/``outlet_corner`` where that edge meets a lumen
    wall (y = 0 or y = height); for the ``structure``, on a clamped end of a wall layer
    (x = 0 or length, within the layer's y range) — ``clamped_end``, or ``clamped_corner`` at
    one of the layer's faces (the lumen side or the exterior). None elsewhere. ``tol``: the
    distance within which a point is on a line (default :data:`NODE_TOLERANCE` × length; a cell
    centroid needs its cell's size)."""
    length, height, t = geometry["length"], geometry["height"], geometry["wall_thickness"]
    tol = NODE_TOLERANCE * length if tol is None else tol
    ends = {"inlet": 0.0, "outlet": length}
    if domain == "fluid":
        faces = (0.0, height)
    else:
        sides = plaque_sides(geometry)
        faces = tuple(
            f for side in sides for f in ((0.0, -t) if side == "bottom" else (height, height + t))
        )
        if not any(
            min(a, b) - tol <= y <= max(a, b) + tol for a, b in zip(faces[::2], faces[1::2])
        ):
            return None  # not in a wall layer: the plaque, which is not clamped
    for name, x_end in ends.items():
        if abs(x - x_end) <= tol:
            corner = any(abs(y - f) <= tol for f in faces)
            if domain == "fluid":
                return f"{name}_corner" if corner else name
            return "clamped_corner" if corner else "clamped_end"
    return None


def plaque_sides(geometry: dict) -> tuple[str, ...]:
    """The sides carrying a plaque (geometry/stenosis.py's rule): the top when axisymmetric
    (the bottom is the axis), else ``plaque_sides`` (default the bottom)."""
    if geometry.get("axisymmetric"):
        return ("top",)
    return tuple(geometry.get("plaque_sides") or ("bottom",))


def mm(value: float) -> str:
    """A position in mm to 0.01 mm (no "-0.00")."""
    return f"{1e3 * value + 0.0:.2f}".replace("-0.00", "0.00")


def describe(place: str | None) -> str:
    return "" if place is None else PLACES[place]


def plaque_range(geometry: dict) -> tuple[float, float]:
    """The x range of the plaque (m)."""
    from types import SimpleNamespace

    from fsi.geometry import stenosis

    centre = stenosis.apex_x(SimpleNamespace(**{"axisymmetric": False, **geometry}))
    return centre - geometry["stenosis_length"] / 2, centre + geometry["stenosis_length"] / 2


def _boundary_nodes(triangles: np.ndarray) -> np.ndarray:
    """The nodes of edges that belong to one triangle only."""
    edges = np.sort(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1
    )
    unique, count = np.unique(edges, axis=0, return_counts=True)
    return np.unique(unique[count == 1])


def _entry(value: float, xy, geometry: dict, domain: str = "fluid", tol=None) -> dict:
    x, y = float(xy[0]), float(xy[1])
    return {
        "value": float(value),
        "x": x,
        "y": y,
        "place": boundary_place(x, y, geometry, domain, tol),
    }


def fluid_maxima(run_dir: Path, t: float, geometry: dict) -> dict:
    """At time ``t``: where the largest pressure and |u| sit (the field file's nodes, reference
    coordinates), the largest pressure off the open boundaries' edges, and the largest pressure
    on the plaque's surface (the lumen's boundary nodes over the plaque's x range, on its
    side), each {value, x, y, place}."""
    from fsi.output import field_files

    p = field_files.read_field(run_dir, "pressure", t, warp=0.0)
    u = field_files.read_field(run_dir, "velocity", t, warp=0.0)
    xy = p.reference
    places = [boundary_place(x, y, geometry) for x, y in xy]
    off = np.array([place not in ("inlet", "outlet", "inlet_corner", "outlet_corner")
                    for place in places])  # fmt: skip
    speed = np.linalg.norm(u.values, axis=1)
    out = {
        "peak_pressure": _entry(p.values.max(), xy[np.argmax(p.values)], geometry),
        "peak_velocity": _entry(speed.max(), u.reference[np.argmax(speed)], geometry),
    }
    k = np.flatnonzero(off)[np.argmax(p.values[off])]
    out["pressure_off_openings"] = _entry(p.values[k], xy[k], geometry)
    lo, hi = plaque_range(geometry)
    nodes = _boundary_nodes(p.triangles)
    sides = set(plaque_sides(geometry))
    below = xy[nodes, 1] < geometry["height"] / 2
    on_side = below if sides == {"bottom"} else ~below if sides == {"top"} else below | ~below
    surface = nodes[(xy[nodes, 0] > lo) & (xy[nodes, 0] < hi) & on_side]
    if len(surface):
        k = surface[np.argmax(p.values[surface])]
        out["plaque_pressure"] = _entry(p.values[k], xy[k], geometry)
    return out


def displacement_maximum(run_dir: Path, t: float, geometry: dict) -> dict | None:
    """Where the structure's largest |η| sits at ``t`` (reference coordinates), or None
    without a structure field file."""
    from fsi.output import field_files

    if not (run_dir / "solid.xdmf").is_file():
        return None
    for name in field_files.DISPLACEMENTS["structure"]:
        try:
            eta = field_files.read_field(run_dir, name, t, warp=0.0)
        except field_files.PlotError:
            continue
        size = np.linalg.norm(eta.values, axis=1)
        return _entry(size.max(), eta.reference[np.argmax(size)], geometry, "structure")
    return None


def cell_maximum(run_dir: Path, field: str, t: float, geometry: dict, regions=None) -> dict:
    """Where the cell field's largest |value| sits at ``t``, over the cells of ``regions``
    (labels; None: all): the cell's centroid (reference coordinates), its size (longest edge,
    m), its region, and whether it touches a clamped end (within the cell's size)."""
    from fsi.geometry.tags import Region
    from fsi.output import field_files

    values = field_files.read_field(run_dir, field, t, warp=0.0)
    region = field_files.read_field(run_dir, "region", t, warp=0.0)
    labels = np.array([Region(int(round(v))).label for v in region.values])
    cells = np.arange(len(labels)) if regions is None else np.flatnonzero(np.isin(labels, regions))
    k = cells[np.argmax(np.abs(values.values[cells]))]
    corners = values.reference[values.triangles[k]]
    size = float(max(np.linalg.norm(corners[i] - corners[i - 1]) for i in range(3)))
    entry = _entry(values.values[k], corners.mean(axis=0), geometry, "structure", tol=size)
    return {**entry, "value": abs(entry["value"]), "h": size, "region": str(labels[k])}
