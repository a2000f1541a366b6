"""A run's field files read back for ``fsi plot`` (fsi/output/plot.py draws them): the XDMF
segments of ``fields`` and ``solid`` (one per restart), the times they store
(:func:`stored_times`, :func:`pick_time`) and one field at one time on its mesh, optionally
warped by the displacement and restricted to a region (:func:`read_field`, a :class:`Snapshot`).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fsi.geometry.tags import Region
from fsi.numerics.timestepping import SAME_TIME

FILES = {"fluid": "fields", "structure": "solid"}
"""The field files' stems per domain."""


DISPLACEMENTS = {"fluid": ("mesh_displacement",), "structure": ("displacement", "eta")}
"""The names a domain's displacement field may have (the first present is used)."""


STRUCTURE_REGIONS = {r.label: int(r) for r in (Region.WALL, Region.CAP, Region.LIPID, Region.FLAG)}


REGIONS = ("fluid", *STRUCTURE_REGIONS)


COMPONENTS = ("x", "y", "z", "magnitude")


LABELS_BY_QUANTITY = {
    "velocity": {"velocity": "velocity"},
    "stress": {
        "pressure": "pressure",
        "wall_shear_stress": "wall shear stress",
        "sss": "structural shear stress σ₁₂",
        "von_mises": "von Mises stress",
        "max_principal": "maximum principal stress",
    },
    "viscosity": {"viscosity": "viscosity"},
    "rate": {"shear_rate": "shear rate"},
    "displacement": {
        "mesh_displacement": "mesh displacement",
        "eta": "displacement η",
        "displacement": "displacement",
    },
    "tag": {"region": "region tag"},
}
"""Each field's label, grouped by its quantity, which picks the unit (fsi/output/plot.py)."""


FIELDS = {
    name: (label, quantity)
    for quantity, labels in LABELS_BY_QUANTITY.items()
    for name, label in labels.items()
}
"""Field name -> (label, quantity)."""


class PlotError(ValueError):
    """Bad input: the message names the run folder or file and the option."""


@dataclass(frozen=True)
class _Segment:
    """One XDMF file: its mesh's HDF5 items and, per field, the stored times and HDF5 items
    (``(h5 path, dataset)``) and where the values sit (``"node"`` or ``"cell"``)."""

    xdmf: Path
    topology: tuple[Path, str]
    geometry: tuple[Path, str]
    fields: dict[str, tuple[str, list[tuple[float, tuple[Path, str]]]]]


@dataclass(frozen=True)
class Snapshot:
    """A field at one stored time, on the triangles of its mesh (all, or a region's).

    ``reference`` holds every node of the file's mesh (m) and ``coordinates`` the drawn ones,
    ``reference + warp · displacement``; ``triangles`` the kept cells (node indices) and
    ``cells`` their indices in the file. ``values`` are per node (all nodes) when ``center`` is
    ``"node"`` and per kept cell when it is ``"cell"``; a 2D vector field has 2 columns. A 3D
    field has tetrahedra in ``triangles`` (4 nodes), 3 coordinates and 3 vector columns until
    :func:`fsi.output.section.cut` makes a plane section of it (``section``: its plane).
    ``time`` is the stored time nearest to ``requested_time``; ``step`` the spacing of the
    stored times there (0 if only one is stored)."""

    run_dir: Path
    name: str
    domain: str
    file: Path
    time: float
    requested_time: float
    step: float
    center: str
    reference: np.ndarray
    displacement: np.ndarray | None
    warp: float
    triangles: np.ndarray
    cells: np.ndarray
    values: np.ndarray
    region: str | None
    section: object | None = None  # the plane of a 3D field's section (fsi.output.section)

    @property
    def coordinates(self) -> np.ndarray:
        if self.displacement is None or self.warp == 0.0:
            return self.reference
        return self.reference + self.warp * self.displacement

    @property
    def time_differs(self) -> bool:
        """True if the stored time is further than half a step from the requested one."""
        return abs(self.time - self.requested_time) > 0.5 * self.step + _time_tolerance(self.time)


def _time_tolerance(t: float) -> float:
    """Times are written to the XDMF file as text: equal within this."""
    return SAME_TIME * max(1.0, abs(t))


def _segments(run_dir: Path, stem: str) -> list[Path]:
    """``<stem>.xdmf`` and the restart segments ``<stem>.restart<k>.xdmf`` by k (those that
    exist), in the order they were written."""
    found = [(-1, run_dir / f"{stem}.xdmf")] if (run_dir / f"{stem}.xdmf").is_file() else []
    for path in run_dir.glob(f"{stem}.restart*.xdmf"):
        k = path.name[len(stem) + len(".restart") : -len(".xdmf")]
        if k.isdigit():
            found.append((int(k), path))
    return [path for _, path in sorted(found)]


def _data_item(xdmf: Path, element: ET.Element | None, what: str) -> tuple[Path, str]:
    """The HDF5 file and dataset a ``DataItem`` (``fields.h5:/Function/velocity/0_001``)
    names."""
    item = None if element is None else element.find("DataItem")
    text = (item.text or "").strip() if item is not None else ""
    if item is None or item.get("Format") != "HDF" or ":" not in text:
        raise PlotError(f"{xdmf}: {what} is not an HDF5 data item (not a file written by fsi run)")
    h5, dataset = text.rsplit(":", 1)
    return xdmf.parent / h5, dataset


def _read_segment(xdmf: Path) -> _Segment:
    """The mesh and the time series of one XDMF file as dolfinx 0.5 and 0.9 write them.

    Reads one mesh grid (``Topology`` and ``Geometry`` HDF5 data items) and, per field, a temporal
    collection of grids holding one ``Attribute`` (``Center`` ``Node`` or ``Cell``; 2D vectors are
    stored with 3 components).
    """
    try:
        domain = ET.parse(xdmf).getroot().find("Domain")
    except (ET.ParseError, OSError) as e:
        raise PlotError(f"{xdmf}: unreadable ({e})") from None
    mesh = None if domain is None else domain.find("Grid[@GridType='Uniform']")
    if mesh is None:
        raise PlotError(f"{xdmf}: no mesh grid (not a file written by fsi run)")
    topology = mesh.find("Topology")
    if topology is None or topology.get("TopologyType", "").lower() not in (
        "triangle",
        "tetrahedron",
    ):
        raise PlotError(f"{xdmf}: the mesh is not made of triangles or tetrahedra")
    fields: dict[str, tuple[str, list]] = {}
    for collection in domain.findall("Grid[@GridType='Collection']"):
        name = collection.get("Name", "")
        center, series = "node", []
        for grid in collection.findall("Grid"):
            time, attribute = grid.find("Time"), grid.find("Attribute")
            if time is None or attribute is None:
                continue
            try:
                t = float(time.get("Value", ""))
            except ValueError:
                raise PlotError(
                    f"{xdmf}: field {name!r} has a time that is not a number: {time.get('Value')!r}"
                ) from None
            center = attribute.get("Center", "Node").lower()
            series.append((t, _data_item(xdmf, attribute, f"field {name!r} at t = {t:g}")))
        if series:
            fields[name] = (center, sorted(series, key=lambda s: s[0]))
    return _Segment(
        xdmf,
        _data_item(xdmf, topology, "the topology"),
        _data_item(xdmf, mesh.find("Geometry"), "the geometry"),
        fields,
    )


def _read_array(item: tuple[Path, str], xdmf: Path) -> np.ndarray:
    import h5py

    h5, dataset = item
    try:
        with h5py.File(h5, "r") as f:
            return np.asarray(f[dataset][...])
    except KeyError:
        raise PlotError(f"{h5}: no dataset {dataset} (named by {xdmf})") from None
    except OSError as e:
        raise PlotError(f"{h5}: unreadable ({e}; named by {xdmf})") from None


def _series(run_dir: Path, stem: str) -> tuple[list[_Segment], dict[str, list]]:
    """The segments of one field file and, per field, its stored times in order as
    ``(t, segment, item)``: a later segment wins, i.e. its first time drops the times at and
    after it that earlier segments stored (the steps a restart took again)."""
    segments = [_read_segment(path) for path in _segments(run_dir, stem)]
    merged: dict[str, list] = {}
    for segment in segments:
        for name, (_, series) in segment.fields.items():
            first = series[0][0] - _time_tolerance(series[0][0])
            kept = [entry for entry in merged.get(name, []) if entry[0] < first]
            merged[name] = kept + [(t, segment, item) for t, item in series]
    return segments, merged


def pick_time(times: list[float], t: float, what: str) -> tuple[int, float]:
    """The index of the stored time nearest to ``t`` and the spacing of the stored times
    there (0 if only one is stored). Raises :class:`PlotError` naming ``what`` if ``t`` lies
    outside the stored range by more than one step (by more than rounding if only one time
    is stored)."""
    times_a = np.asarray(times)
    i = int(np.argmin(np.abs(times_a - t)))
    gaps = np.diff(times_a)
    if len(times_a) == 1:
        step = 0.0
    elif t <= times_a[0]:
        step = float(gaps[0])
    elif t >= times_a[-1]:
        step = float(gaps[-1])
    else:
        j = int(np.searchsorted(times_a, t)) - 1  # times[j] < t <= times[j + 1]
        step = float(gaps[j])
    low, high = times_a[0] - step, times_a[-1] + step
    if not low - _time_tolerance(low) <= t <= high + _time_tolerance(high):
        raise PlotError(
            f"--time {t:g}: outside the times stored in {what} "
            f"({times_a[0]:g} to {times_a[-1]:g} s)"
        )
    return i, step


def _find(run_dir: Path, name: str) -> tuple[str, list[_Segment], list]:
    """The domain holding field ``name``, its segments and its merged time series."""
    if not run_dir.is_dir():
        raise PlotError(f"{run_dir}: no such folder")
    available = {}
    for domain, stem in FILES.items():
        segments, merged = _series(run_dir, stem)
        if name in merged:
            return domain, segments, merged[name]
        if segments:
            available[segments[0].xdmf.name] = sorted(merged)
    if not available:
        raise PlotError(
            f"{run_dir}: no fields.xdmf or solid.xdmf (not a folder written by fsi run)"
        )
    listing = "; ".join(
        f"{file} has {', '.join(names) or 'none'}" for file, names in available.items()
    )
    raise PlotError(f"--field {name}: {run_dir} has no such field ({listing})")


def stored_times(run_dir: Path, name: str) -> list[float]:
    """The times (s) at which field ``name`` of the run in ``run_dir`` is stored, in order
    (restart segments merged as :func:`read_field` reads them)."""
    return [entry[0] for entry in _find(Path(run_dir), name)[2]]


def read_field(
    run_dir: Path, name: str, t: float, *, warp: float | None = None, region: str | None = None
) -> Snapshot:
    """Field ``name`` of the run in ``run_dir`` at the stored time nearest to ``t`` (in the
    segment holding it; a later segment wins), on the triangles of ``region`` (``fluid`` for
    a fluid field; ``wall``, ``cap``, ``lipid``, ``flag`` for a structure field, from its
    ``region`` field; None: every triangle), with the nodes moved by ``warp`` × the
    domain's displacement at that time (default: 1 for the fluid of a coupled run, its current
    mesh; 0 for the structure). Raises :class:`PlotError` (naming the folder or file and the
    option) for an unknown folder, field, region or a time outside the stored range."""
    run_dir = Path(run_dir)
    _check_options(t, warp, region)
    domain, segments, series = _find(run_dir, name)
    file = segments[0].xdmf.name
    if region is not None and (region == "fluid") != (domain == "fluid"):
        expected = "fluid" if domain == "fluid" else "wall, cap, lipid or flag"
        raise PlotError(
            f"--region {region}: {name!r} is a {domain} field ({file}): use --region {expected}"
        )
    files = list(dict.fromkeys(entry[1].xdmf.name for entry in series))
    i, step = pick_time(
        [entry[0] for entry in series],
        t,
        f"{run_dir / files[0]}" + "".join(f", {f}" for f in files[1:]),
    )
    time, segment, item = series[i]
    center = segment.fields[name][0]

    triangles = _read_array(segment.topology, segment.xdmf).astype(np.int64)
    gdim = _dimension(triangles)
    reference = _read_array(segment.geometry, segment.xdmf)[:, :gdim]
    values = _read_array(item, segment.xdmf)
    values = values[:, :gdim] if values.ndim == 2 and values.shape[1] > 1 else values.reshape(-1)

    displacement = _at_time(segment, DISPLACEMENTS[domain], time, gdim)
    warp = _warp(segment, domain, warp, displacement)
    cells = np.arange(len(triangles))
    if region is not None and region != "fluid":
        cells = _region_cells(segment, region, time)
        triangles = triangles[cells]
        if center == "cell":
            values = values[cells]
    return Snapshot(
        run_dir,
        name,
        domain,
        segment.xdmf,
        time,
        t,
        step,
        center,
        reference,
        displacement,
        float(warp),
        triangles,
        cells,
        values,
        region,
    )


def _check_options(t: float, warp: float | None, region: str | None) -> None:
    """Raise :class:`PlotError` naming the option if ``t`` or ``warp`` is not finite or
    ``region`` is not one of :data:`REGIONS`."""
    if not math.isfinite(t):
        raise PlotError(f"--time {t}: not a finite number")
    if warp is not None and not math.isfinite(warp):
        raise PlotError(f"--warp {warp}: not a finite number")
    if region is not None and region not in REGIONS:
        raise PlotError(f"--region {region}: not one of {', '.join(REGIONS)}")


def _warp(
    segment: _Segment, domain: str, warp: float | None, displacement: np.ndarray | None
) -> float:
    """The warp factor: ``warp``, or by default 1 for a moving fluid and 0 otherwise; raises
    :class:`PlotError` for a non-zero warp of a domain without a displacement field."""
    if warp is None:
        warp = 1.0 if domain == "fluid" and displacement is not None else 0.0
    if warp != 0.0 and displacement is None:
        raise PlotError(
            f"--warp {warp:g}: {segment.xdmf} has no {DISPLACEMENTS[domain][0]} "
            f"field (the {domain} does not move in this run)"
        )
    return warp


def _region_cells(segment: _Segment, region: str, time: float) -> np.ndarray:
    """The indices of the structure cells of ``region`` (from the ``region`` field at ``time``);
    raises :class:`PlotError` if there is no such field or no such cell."""
    tags = _at_time(segment, ("region",), time)
    if tags is None:
        raise PlotError(
            f"--region {region}: {segment.xdmf} has no 'region' field (a run "
            "written before fsi run stored it)"
        )
    cells = np.flatnonzero(np.rint(tags).astype(np.int64) == STRUCTURE_REGIONS[region])
    if len(cells) == 0:
        raise PlotError(f"--region {region}: no {region} cells in {segment.xdmf}")
    return cells


def _dimension(cells: np.ndarray) -> int:
    """The dimension of a simplex mesh from its cells' node count: 3 for tetrahedra, else 2."""
    return 3 if cells.shape[1] == 4 else 2


def _at_time(
    segment: _Segment, names: tuple[str, ...], time: float, gdim: int = 2
) -> np.ndarray | None:
    """The first of ``names`` stored in ``segment`` at ``time`` (vectors as ``gdim`` columns,
    scalars flat), or None if none is."""
    for name in names:
        for t, item in segment.fields.get(name, ("", []))[1]:
            if abs(t - time) <= _time_tolerance(time):
                values = _read_array(item, segment.xdmf)
                return values[:, :gdim] if values.shape[1] > 1 else values.reshape(-1)
    return None
