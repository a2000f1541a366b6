"""``fsi plot``: a picture of one field of a run at one time, without ParaView.

Reads the XDMF/HDF5 field files ``fsi run`` writes (``fields.xdmf``: the fluid on its reference
mesh, with ``mesh_displacement`` in coupled runs; ``solid.xdmf``: the structure, with its
``region`` tags; and their restart segments ``<stem>.restart<k>.xdmf``):
:func:`fsi.output.field_files.read_field` gives a field at one time (a
:class:`~fsi.output.field_files.Snapshot`), :func:`draw` draws it as filled contours,
optionally with the fluid's streamlines, and :func:`field_snapshot` does both.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fsi.geometry.tags import Region
from fsi.output.field_files import COMPONENTS, FIELDS, PlotError, Snapshot, read_field
from fsi.output.units import UNITS, choose_unit


def _unit(quantity: str, largest: float) -> tuple[str, float]:
    """A readable unit for values up to ``largest`` (SI) and the factor to it
    (:func:`fsi.output.units.choose_unit`; a region tag has none)."""
    if quantity not in UNITS:
        return "", 1.0
    unit = choose_unit(quantity, [largest])
    return unit.name, unit.scale


def _component(snapshot: Snapshot, component: str | None) -> tuple[np.ndarray, str]:
    """The scalar to draw and its label's prefix."""
    values = snapshot.values
    if values.ndim == 1:
        if component is not None:
            raise PlotError(f"--component {component}: {snapshot.name!r} is a scalar field")
        return values, ""
    if component in (None, "magnitude"):
        return np.linalg.norm(values, axis=1), "magnitude of the "
    if component not in COMPONENTS[: values.shape[1]]:
        choices = ", ".join((*COMPONENTS[: values.shape[1]], "magnitude"))
        raise PlotError(f"--component {component}: not one of {choices}")
    return values[:, COMPONENTS.index(component)], f"{component} component of the "


def streamline_field(snapshot: Snapshot) -> Snapshot:
    """The fluid velocity at the snapshot's time on the same nodes (the same warp), for
    :func:`draw`'s streamlines. Raises :class:`PlotError` if the snapshot is not a fluid
    field."""
    if snapshot.domain != "fluid":
        raise PlotError(
            f"--streamlines: draws the fluid velocity over a fluid field, but "
            f"{snapshot.name!r} is a {snapshot.domain} field ({snapshot.file.name})"
        )
    flow = read_field(snapshot.run_dir, "velocity", snapshot.time, warp=snapshot.warp)
    if snapshot.section is None:
        return flow
    from fsi.output import section

    cut = section.cut(flow, snapshot.section)
    return dataclasses.replace(cut, values=cut.values[:, list(snapshot.section.in_plane)])


FIBRES = ("fibre_1", "fibre_2")
"""The HGO wall's fibre families in solid.xdmf: each cell's current unit direction, as the
three cell fields ``fibre_k_x``, ``_y``, ``_z`` (axisymmetric: z, r, θ)."""


def fibre_fields(snapshot: Snapshot) -> list[Snapshot]:
    """The fibre families' directions at the snapshot's time on its cells (the same warp,
    region and section), projected onto the picture's plane (an axisymmetric run's (z, r),
    dropping the hoop component; a section's in-plane axes), for :func:`draw`'s ``fibres``.
    Raises :class:`PlotError` unless the snapshot is a structure field of a run with an HGO
    wall."""
    if snapshot.domain != "structure":
        raise PlotError(
            f"--fibres: draws the wall's fibres over a structure field, but "
            f"{snapshot.name!r} is a {snapshot.domain} field ({snapshot.file.name})"
        )
    families = []
    for family in FIBRES:
        try:
            parts = [
                read_field(
                    snapshot.run_dir,
                    f"{family}_{axis}",
                    snapshot.time,
                    warp=snapshot.warp,
                    region=snapshot.region,
                )
                for axis in "xyz"
            ]
        except PlotError as e:
            raise PlotError(
                f"--fibres: no fibres in {snapshot.file} (a structure.<region> with law: hgo "
                f"writes them): {e}"
            ) from None
        fibre = dataclasses.replace(
            parts[0], name=family, values=np.stack([p.values for p in parts], axis=1)
        )
        plane = (0, 1)
        if snapshot.section is not None:
            from fsi.output import section

            fibre = section.cut(fibre, snapshot.section)
            plane = snapshot.section.in_plane
        families.append(dataclasses.replace(fibre, values=fibre.values[:, list(plane)]))
    return families


def axis_labels(run_dir: Path) -> tuple[str, str]:
    """The picture's axis labels: ``z (mm)``, ``r (mm)`` for an axisymmetric run (its
    ``config.yaml`` says so: docs/axisymmetric.md), ``x (mm)``, ``y (mm)`` otherwise (also when
    the run folder has no readable configuration)."""
    from fsi import config

    try:
        axisymmetric = config.is_axisymmetric(config.load(Path(run_dir) / "config.yaml").geometry)
    except (config.ConfigError, OSError):
        axisymmetric = False
    return ("z (mm)", "r (mm)") if axisymmetric else ("x (mm)", "y (mm)")


def title(snapshot: Snapshot) -> str:
    """The run, the field and the stored time (and the requested one if it differs by more
    than half a step)."""
    label = FIELDS.get(snapshot.name, (snapshot.name, ""))[0]
    where = f" ({snapshot.region})" if snapshot.region else ""
    if snapshot.section is not None:
        where += f" on the plane {snapshot.section}"
    text = f"{snapshot.run_dir.resolve().name}: {label}{where} at t = {snapshot.time:.6g} s"
    if snapshot.time_differs:
        text += f" (nearest stored to {snapshot.requested_time:.6g} s)"
    if snapshot.warp != 0.0:
        text += (
            ", current mesh"
            if snapshot.domain == "fluid" and snapshot.warp == 1.0
            else f", displacement ×{snapshot.warp:g}"
        )
    return text


FORMATS = ("png", "pdf", "svg")
"""The picture formats, named by the file's suffix: PNG (150 dpi) for the screen, PDF and SVG
(vector; the shaded field stays a raster inside them) for papers."""


def check_out(path: Path) -> None:
    """Raises :class:`PlotError` unless ``path`` can name the picture to write (.png, .pdf or
    .svg)."""
    path = Path(path)
    if path.suffix.lower().lstrip(".") not in FORMATS:
        raise PlotError(
            f"--out {path}: the picture's file name must end in "
            + ", ".join(f".{f}" for f in FORMATS)
        )
    if path.is_dir():
        raise PlotError(f"--out {path}: is a folder, not a file name")
    if path.parent.exists() and not path.parent.is_dir():
        raise PlotError(f"--out {path}: {path.parent} is not a folder")


def draw(
    snapshot: Snapshot,
    path: Path,
    *,
    component: str | None = None,
    flow: Snapshot | None = None,
    fibres: Sequence[Snapshot] = (),
    limit: float | None = None,
    marks: Sequence[tuple[float, float, str]] = (),
) -> Path:
    """Write ``path`` (PNG, PDF or SVG, by its suffix): the field as filled contours (node
    values shaded between the nodes, cell values flat) on the snapshot's coordinates in mm,
    equal aspect, with a colour bar labelled with the field and its unit and the :func:`title`;
    with ``flow`` (the fluid velocity on the same nodes, :func:`streamline_field`) its
    streamlines over it, the velocity interpolated linearly on a regular grid and masked outside
    the fluid mesh; with ``fibres`` (:func:`fibre_fields`) their lines (:func:`_fibre_lines`).
    ``limit`` (the field's SI unit) caps the colour range at ±limit (signed) or limit: larger
    values show in the end colour (the bar says so), so a singular peak need not wash out the
    rest. ``marks``: points (x, y in m, as drawn) to mark with a cross and a label. The file
    appears complete or not at all (written under another name, then renamed). Raises
    :class:`PlotError` for a bad ``component`` or ``path`` first, OSError if unwritable."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri

    path = Path(path)
    check_out(path)
    if snapshot.triangles.shape[1] != 3:
        raise PlotError(
            f"{snapshot.file}: a 3D field: draw a plane section of it (--slice z=0 through the "
            "axis, --slice x=VALUE across it)"
        )
    values, prefix = _component(snapshot, component)
    label, quantity = FIELDS.get(snapshot.name, (snapshot.name, ""))
    used = np.unique(snapshot.triangles)
    values, shown, unit, scale = _in_unit(snapshot, values, used, quantity)
    cmap, norm = _colours(shown, quantity, None if limit is None else limit * scale)

    xy = snapshot.coordinates * 1e3  # mm
    triangulation = mtri.Triangulation(xy[:, 0], xy[:, 1], snapshot.triangles)
    lo, hi = xy[used].min(axis=0), xy[used].max(axis=0)
    aspect = (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-30)
    fig, ax = plt.subplots(
        figsize=(9.0, min(max(9.0 * aspect + 1.6, 3.0), 9.0)), layout="constrained"
    )
    if snapshot.center == "node":
        image = ax.tripcolor(triangulation, values, shading="gouraud", cmap=cmap, norm=norm)
    else:
        image = ax.tripcolor(triangulation, facecolors=values, cmap=cmap, norm=norm)
    if flow is not None:
        _streamlines(ax, flow, lo, hi)
    for fibre, colour in zip(fibres, ("k", "0.45"), strict=False):
        _fibre_lines(ax, fibre, colour)
    _frame(ax, snapshot, lo, hi, marks)
    bar_label = f"{prefix}{label}" + (f" ({unit})" if unit else "")
    _colour_bar(fig, ax, image, bar_label, quantity, shown, wide=aspect < 0.6, norm=norm)
    save_figure(fig, path)
    return path


def _frame(ax, snapshot: Snapshot, lo: np.ndarray, hi: np.ndarray, marks) -> None:
    """The picture's marks (a cross and a label each), its extent ``lo``..``hi`` (mm) at equal
    aspect, its axis labels and its title."""
    for x, y, text in marks:
        ax.plot(1e3 * x, 1e3 * y, "kx", ms=9, mew=2)
        ax.annotate(text, (1e3 * x, 1e3 * y), xytext=(6, 6), textcoords="offset points", fontsize=8)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    if snapshot.section is not None:
        xlabel, ylabel = snapshot.section.labels
    else:
        xlabel, ylabel = axis_labels(snapshot.run_dir)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title(snapshot), fontsize=9)


def _in_unit(
    snapshot: Snapshot, values: np.ndarray, used: np.ndarray, quantity: str
) -> tuple[np.ndarray, np.ndarray, str, float]:
    """``values`` and those shown (at the ``used`` nodes, or every cell) in a readable unit
    (:func:`_unit` of the largest shown magnitude), that unit's name and its factor."""
    shown = values[used] if snapshot.center == "node" else values
    unit, scale = _unit(quantity, float(np.max(np.abs(shown))) if len(shown) else 0.0)
    return values * scale, shown * scale, unit, scale


def _colours(shown: np.ndarray, quantity: str, limit: float | None = None):
    """The colour map and its normalization: for region tags one distinct colour per tag shown
    (a discrete bar); signed values symmetric about zero in ``RdBu_r``; else the values' range
    in ``viridis``; never an empty range. ``limit`` (the shown values' unit) caps the range:
    ±limit for signed values, the top otherwise."""
    from matplotlib import colors

    if quantity == "tag":
        tags = np.unique(np.rint(shown))
        bounds = np.concatenate([[tags[0] - 0.5], (tags[1:] + tags[:-1]) / 2, [tags[-1] + 0.5]])
        palette = colors.ListedColormap([f"C{k % 10}" for k in range(len(tags))])
        return palette, colors.BoundaryNorm(bounds, len(tags))
    low, high = float(np.min(shown)), float(np.max(shown))
    cmap = "viridis"
    if low < 0.0 < high:  # signed: zero in the middle, white
        low, high, cmap = -max(-low, high), max(-low, high), "RdBu_r"
        if limit is not None:
            low, high = max(low, -limit), min(high, limit)
    elif limit is not None:
        high = min(high, limit)
    if low == high:
        low, high = low - 1.0, high + 1.0
    return cmap, colors.Normalize(low, high)


def _colour_bar(
    fig, ax, image, label: str, quantity: str, shown: np.ndarray, wide: bool, norm=None
) -> None:
    """The colour bar of ``image``, labelled ``label``: below a ``wide`` picture, else on the
    right, with an arrow at an end whose range ``norm`` cut values off; for region tags, a tick
    named after each region shown."""
    below = norm is not None and quantity != "tag" and float(np.min(shown)) < norm.vmin
    above = norm is not None and quantity != "tag" and float(np.max(shown)) > norm.vmax
    bar = fig.colorbar(
        image,
        ax=ax,
        label=label,
        location="bottom" if wide else "right",
        shrink=0.6 if wide else 0.9,
        aspect=40 if wide else 20,
        extend={(True, True): "both", (True, False): "min", (False, True): "max"}.get(
            (below, above), "neither"
        ),
    )
    if quantity == "tag":  # name the regions present
        tags = [int(tag) for tag in np.unique(np.rint(shown))]
        bar.set_ticks(tags)
        bar.set_ticklabels([Region(tag).label if tag in set(Region) else str(tag) for tag in tags])


def save_figure(fig, path: Path, dpi: int = 150) -> None:
    """Write ``fig`` to ``path`` in the format of its suffix (:data:`FORMATS`; PNG at ``dpi``)
    under another name, then rename it: the file appears complete or not at all. Closes ``fig``
    once the writing was tried."""
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    try:
        fig.savefig(partial, dpi=dpi, format=path.suffix.lower().lstrip("."))
        os.replace(partial, path)
    finally:
        plt.close(fig)
        partial.unlink(missing_ok=True)


def _fibre_lines(ax, fibre: Snapshot, colour: str) -> None:
    """A line through each cell's centroid along the in-plane part of its fibre direction, 0.8
    of the cells' mean size long for a fibre in the plane, shorter as it leaves the plane (none
    where it is 0: no fibres)."""
    from matplotlib.collections import LineCollection

    xy = fibre.coordinates * 1e3  # mm
    corners = xy[fibre.triangles]  # (cells, 3, 2)
    centroids = corners.mean(axis=1)
    edges = corners[:, 1:] - corners[:, :1]
    area = 0.5 * np.abs(edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0])
    half = 0.4 * np.sqrt(2.0 * area.mean()) if len(area) else 0.0
    direction = np.asarray(fibre.values, dtype=float)[:, :2]
    keep = np.linalg.norm(direction, axis=1) > 0
    ends = np.stack([centroids - half * direction, centroids + half * direction], axis=1)
    ax.add_collection(LineCollection(ends[keep], colors=colour, linewidths=0.6))


def _streamlines(ax, flow: Snapshot, lo: np.ndarray, hi: np.ndarray) -> None:
    """The velocity's streamlines over ``ax`` between the corners ``lo`` and ``hi`` (mm)."""
    import matplotlib.tri as mtri

    xy = flow.coordinates * 1e3
    triangulation = mtri.Triangulation(xy[:, 0], xy[:, 1], flow.triangles)
    nx = 400
    ny = max(int(nx * (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-30)), 20)
    x, y = np.linspace(lo[0], hi[0], nx), np.linspace(lo[1], hi[1], ny)
    grid_x, grid_y = np.meshgrid(x, y)
    u = [
        mtri.LinearTriInterpolator(triangulation, flow.values[:, k])(grid_x, grid_y)
        for k in range(2)
    ]
    ax.streamplot(
        x,
        y,
        u[0],
        u[1],
        density=(2.0, max(2.0 * ny / nx, 0.6)),
        color="k",
        linewidth=0.5,
        arrowsize=0.6,
    )


def field_snapshot(
    run_dir: Path,
    field: str,
    t: float,
    path: Path,
    *,
    warp: float | None = None,
    region: str | None = None,
    streamlines: bool = False,
    component: str | None = None,
    limit: float | None = None,
    marks: Sequence[tuple[float, float, str]] = (),
) -> Path:
    """:func:`read_field` then :func:`draw` (with the velocity's streamlines if asked, the
    colour range capped at ``limit``, the ``marks``): writes ``path`` and returns it."""
    check_out(Path(path))
    snapshot = read_field(run_dir, field, t, warp=warp, region=region)
    flow = streamline_field(snapshot) if streamlines else None
    return draw(snapshot, path, component=component, flow=flow, limit=limit, marks=marks)
