"""Along-wall plots of the hemodynamic indices in a run's ``wall_indices.csv`` (TAWSS, OSI,
RRT; docs/hemodynamic-indices.md): x along the vessel's axis, one line per wall and side, over
the whole run or over one heartbeat (``fsi plot RUN_DIR --field tawss [--cycle K]``, and
``fsi report`` for every run that has the file).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

from fsi.numerics.timestepping import SAME_TIME
from fsi.output.plot import PlotError, check_out, save_figure

INDICES = {
    "tawss": ("TAWSS", "time-averaged wall shear stress TAWSS", "Pa"),
    "osi": ("OSI", "oscillatory shear index OSI", ""),
    "rrt": ("RRT", "relative residence time RRT", "1/Pa"),
}
"""``--field`` name → (wall_indices.csv column, axis label, unit)."""


@dataclass(frozen=True)
class WallIndex:
    """One index along the walls: per (wall, side) the samples' x (m, reference
    configuration, increasing) and values; ``cycle`` the heartbeat (None: the whole run)."""

    name: str
    run: str
    cycle: int | None
    cycles: int
    lines: dict[str, tuple[list[float], list[float]]]
    reached: tuple[float, float] | None = None  # a partial heartbeat: (its last t, its end)
    surface: tuple[list[float], list[float], list[float]] | None = None
    """A 3D run's samples as (x (m), φ (degrees, from +y towards +z, in (−180, 180]), value):
    the wall unrolled about the x axis (:func:`draw` maps it); None in 2D."""


def read(run_dir: Path, name: str, cycle: int | None = None) -> WallIndex:
    """The index ``name`` (a key of :data:`INDICES`) from ``run_dir/wall_indices.csv``: over
    heartbeat ``cycle`` (default: the last one in the file, which is the part reached so far
    when the run stopped within a beat) for a run with a periodic inlet, else over the run.
    Raises :class:`PlotError` naming the file for a missing or unreadable file, a cycle it
    does not hold, or ``--cycle`` for a run without heartbeats."""
    column = INDICES[name][0]
    path = Path(run_dir) / "wall_indices.csv"
    if not Path(run_dir).is_dir():
        raise PlotError(f"{run_dir}: no such folder")
    try:
        with path.open(newline="") as f:
            reader = csv.DictReader(f)
            rows, line_numbers = [], []
            for row in reader:
                rows.append(row)
                line_numbers.append(reader.line_num)
    except FileNotFoundError:
        raise PlotError(f"{path}: no such file (runs with a fluid write it)") from None
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise PlotError(f"{path}: cannot be read ({e})") from None
    needed = {"wall", "side", "x", column}
    if not rows or not needed <= set(rows[0]):
        raise PlotError(f"{path}: no rows with the columns {', '.join(sorted(needed))}")
    periodic = "cycle" in rows[0]
    beats, points, angles = [], [], []
    three_d = "z" in rows[0]
    for r, line in zip(rows, line_numbers, strict=True):
        where = f"{path}: line {line}"
        beats.append(int(_cell(r, "cycle", where, integer=True)) if periodic else 0)
        points.append((_cell(r, "x", where), _cell(r, column, where, empty=math.nan)))
        if three_d:
            angles.append(math.degrees(math.atan2(_cell(r, "z", where), _cell(r, "y", where))))
    cycles = sorted(set(beats)) if periodic else []
    if periodic:
        cycle = cycles[-1] if cycle is None else cycle
        if cycle not in cycles:
            raise PlotError(f"--cycle {cycle}: {path} holds heartbeats {cycles[0]} to {cycles[-1]}")
    elif cycle is not None:
        raise PlotError(f"--cycle {cycle}: {path} is over the whole run (no periodic inlet)")
    samples: dict[str, list[tuple[float, float]]] = {}
    surface = ([], [], []) if three_d else None
    for k, (r, beat, point) in enumerate(zip(rows, beats, points, strict=True)):
        if not periodic or beat == cycle:
            samples.setdefault(f"{r['wall']}, {r['side']}", []).append(point)
            if surface is not None:
                for column_values, value in zip(surface, (point[0], angles[k], point[1])):
                    column_values.append(value)
    lines = {}
    for label, points in samples.items():
        points.sort()
        lines[label] = ([x for x, _ in points], [v for _, v in points])
    reached = _partial_beat(Path(run_dir), cycle) if periodic and cycle == cycles[-1] else None
    return WallIndex(
        name, Path(run_dir).name, cycle if periodic else None, len(cycles), lines, reached, surface
    )


def _partial_beat(run_dir: Path, cycle: int) -> tuple[float, float] | None:
    """(the last step's t, k T) when heartbeat ``cycle`` = k of the run in ``run_dir`` was not
    finished (its metrics.csv ends before k T: stopped, or still running), else None; None
    too when config.yaml or metrics.csv cannot tell."""
    from fsi import config
    from fsi.output import metrics_csv

    try:
        period = config.heartbeat_period(config.load(run_dir / "config.yaml", run_config=True))
        rows = metrics_csv.read_metrics(run_dir / "metrics.csv")
    except (OSError, config.ConfigError, metrics_csv.MetricsError):
        return None
    end = cycle * period
    if not rows or not period > 0 or rows[-1]["t"] >= end * (1 - SAME_TIME):
        return None
    return rows[-1]["t"], end


def _cell(
    row: dict, column: str, where: str, *, integer: bool = False, empty: float | None = None
) -> float:
    """The number in ``row``'s ``column`` (``empty`` for an empty cell where one is allowed:
    the file writes a value that is not a number, such as OSI where TAWSS is 0, as an empty
    cell), or :class:`PlotError` naming ``where`` (the file and line) and the column: a row
    cut short (its last line, by a run killed while writing it) has no cell there."""
    text = row.get(column)
    if text is None:
        raise PlotError(
            f"{where}: the row ends before its {column} column (cut short? the run may have "
            "been stopped while writing the file)"
        )
    if text.strip() == "" and empty is not None:
        return empty
    try:
        return int(text) if integer else float(text)
    except ValueError:
        kind = "a whole number" if integer else "a number"
        raise PlotError(f"{where}: {column} = {text!r} is not {kind}") from None


def title(index: WallIndex) -> str:
    """The run, the index and what it is averaged over."""
    over = "the whole run" if index.cycle is None else f"heartbeat {index.cycle}"
    if index.reached is not None:
        over += f" (partial: to t = {index.reached[0]:g} s of {index.reached[1]:g} s)"
    elif index.cycle is not None and index.cycle == index.cycles:
        over += " (the last in the file)"
    return f"{index.run}: {INDICES[index.name][1]} along the walls, over {over}"


def draw(index: WallIndex, path: Path) -> Path:
    """Write ``path`` (PNG, PDF or SVG by its suffix): the index against x (mm), one line per
    wall and side, samples where a value is not finite (RRT where TAWSS is 0) left out."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    check_out(path)
    if index.surface is not None:
        return _draw_map(index, path)
    _, label, unit = INDICES[index.name]
    fig, ax = plt.subplots(figsize=(8.0, 3.6), layout="constrained")
    for k, (wall, (x, y)) in enumerate(sorted(index.lines.items())):
        shown = [(1e3 * a, b) for a, b in zip(x, y, strict=True) if math.isfinite(b)]
        ax.plot([a for a, _ in shown], [b for _, b in shown], lw=1.2, color=f"C{k}", label=wall)
    if index.name == "rrt":
        ax.set_yscale("log")
    ax.set_xlabel("x along the axis (mm)")
    ax.set_ylabel(f"{label} ({unit})" if unit else label)
    ax.set_title(title(index), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)
    return path


def _draw_map(index: WallIndex, path: Path) -> Path:
    """The 3D wall unrolled about the x axis: the index over x (mm) and the angle φ (degrees,
    from +y towards +z: an eccentric plaque's middle at 0), the samples' values shaded over
    their Delaunay triangles in that plane (a colour scale in logarithms for RRT), samples
    whose value is not finite left out. The seam at ±180° is the map's edge."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.colors
    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri
    import numpy as np

    x, phi, values = (np.asarray(c, dtype=float) for c in index.surface)
    finite = np.isfinite(values)
    if finite.sum() < 3:
        raise PlotError(f"{index.run}: fewer than 3 wall samples with a finite {index.name}")
    x, phi, values = 1e3 * x[finite], phi[finite], values[finite]
    _, label, unit = INDICES[index.name]
    fig, ax = plt.subplots(figsize=(8.0, 4.2), layout="constrained")
    norm = None
    if index.name == "rrt" and values.min() > 0:
        norm = matplotlib.colors.LogNorm(values.min(), values.max())
    image = ax.tripcolor(mtri.Triangulation(x, phi), values, shading="gouraud", norm=norm)
    ax.set_xlabel("x along the axis (mm)")
    ax.set_ylabel("angle φ about the axis (degrees, from +y)")
    ax.set_ylim(-180, 180)
    ax.set_yticks(range(-180, 181, 60))
    ax.set_title(title(index).replace("along the walls", "on the unrolled wall"), fontsize=9)
    fig.colorbar(image, ax=ax, label=f"{label} ({unit})" if unit else label)
    save_figure(fig, path)
    return path
