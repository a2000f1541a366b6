"""``fsi report``: the study's tables and plots (docs/model.md, What the study reports) from
finished run folders, read from the files ``fsi run`` writes (``config.yaml``, ``metrics.csv``,
``summary.json``). Tables 1–3 give the peak velocity, pressure and displacement at the report
times, a fourth each run's solver effort, and runs with heartbeats a table of them
(:func:`cycles_table`). The plots (:data:`FIGURES`) show the reported metrics over time in
readable units (:func:`fsi.output.units.choose_unit`), on a linear or log axis or in panels
(:func:`choose_scale`); a run without a column is left out of that plot and shows '–' in the
tables. ``report.md`` lists every picture with a caption line.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fsi import config
from fsi.config import boundary_data
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import io
from fsi.output.units import choose_unit

log = logging.getLogger("fsi")


class ReportError(ValueError):
    """A run folder is missing a file or is not a run folder."""


def check_times(times: Sequence[float] | None) -> None:
    """Raise :class:`ReportError` naming ``--times`` unless every report time (s) is a finite
    number ≥ 0 given once (None: the runs' own report times)."""
    for i, t in enumerate(times or ()):
        if not math.isfinite(t) or t < 0:
            raise ReportError(f"--times {t}: expected a finite time >= 0 (s)")
        if t in times[:i]:
            raise ReportError(f"--times {t}: given twice")


@dataclass(frozen=True)
class Run:
    """A finished run folder: its resolved case, metrics rows (SI) and summary."""

    path: Path
    case: config.Case
    rows: list[dict[str, float]]
    summary: dict
    name: str = ""  # unique among the runs of a report (load_runs); default the folder's name

    @property
    def label(self) -> str:
        """The run's name in tables and legends: its name, mode, rheology and mesh level."""
        c = self.case
        return f"{self.title} ({c.structure.mode}, {c.fluid.rheology.model}, {c.mesh.level})"

    @property
    def title(self) -> str:
        """The run's name: :attr:`name`, or its folder's."""
        return self.name or self.path.name

    @property
    def stem(self) -> str:
        """The run's name as the start of a file name (``/`` → ``_``)."""
        return self.title.replace("/", "_")


def unique_names(paths: Sequence[Path]) -> list[str]:
    """A name for each run folder, unique among them unless two are the same folder: its
    folder name, with as many parent folders as it takes (``A/run`` and ``B/run``)."""
    resolved = [Path(p).resolve() for p in paths]
    distinct = set(resolved)
    names = []
    for path in resolved:
        for k in range(1, len(path.parts) + 1):
            tail = path.parts[-k:]
            if all(other.parts[-k:] != tail for other in distinct if other != path):
                break
        names.append("/".join(tail))
    return names


def load_runs(paths: Sequence[Path]) -> list[Run]:
    """:func:`load_run` of each path, named by :func:`unique_names`. Raises
    :class:`ReportError` for a run folder given twice (also as another spelling of the same
    folder, ``R`` and ``./R/``, or a link to it): its rows would be tabled twice."""
    seen: dict[Path, Path] = {}
    for path in paths:
        key = Path(path).resolve()
        if key in seen:
            same = "" if str(seen[key]) == str(path) else f" (as {seen[key]})"
            raise ReportError(f"RUN_DIR {path}: given twice{same}: each run is tabled once")
        seen[key] = Path(path)
    return [
        dataclasses.replace(load_run(path), name=name)
        for path, name in zip(paths, unique_names(paths), strict=True)
    ]


def check_out(out: Path | None) -> None:
    """Raises :class:`ReportError` unless ``out`` (None: no files) is a folder or a path where
    one can be made: not a file, nor below one."""
    if out is None:
        return
    existing = next(p for p in (out, *out.absolute().parents) if p.exists())
    if not existing.is_dir():
        what = "is a file" if existing == out else f"{existing} is a file"
        raise ReportError(f"--out {out}: {what}, not a folder")


def load_run(path: Path) -> Run:
    """A finished (or stopped, or running) run folder; summary.json is absent when the run
    stopped. The complete rows of metrics.csv (a last row cut short by a run stopped while
    writing it is left out, with a warning). Raises :class:`ReportError` naming the file (and
    the line of metrics.csv) if a file is missing, unreadable or damaged."""
    path = Path(path)
    for name in ("config.yaml", "metrics.csv"):
        if not (path / name).is_file():
            raise ReportError(f"{path}: no {name} (not a folder written by fsi run)")
    try:
        case = config.load(path / "config.yaml", run_config=True)
    except config.ConfigError as e:
        raise ReportError(f"{path}: {e}") from None
    try:
        rows = io.read_metrics(path / "metrics.csv")
    except io.MetricsError as e:
        raise ReportError(str(e)) from None
    except OSError as e:
        raise ReportError(f"{path / 'metrics.csv'}: unreadable ({e.strerror or e})") from None
    return Run(path, case, rows, _summary(path / "summary.json"))


def _summary(path: Path) -> dict:
    """summary.json's content; {} if there is none (a run that stopped)."""
    if not path.is_file():
        return {}
    try:
        summary = json.loads(path.read_bytes())
    except (OSError, ValueError) as e:
        raise ReportError(f"{path}: unreadable ({e})") from None
    if not isinstance(summary, dict):
        raise ReportError(f"{path}: not a summary written by fsi run")
    return summary


# --------------------------------------------------------------------------------------------
# Units and scales


MAGNITUDE_RATIO = 10.0
"""Groups of lines whose magnitudes (largest |value|) differ by more than this factor are not
drawn on one linear axis (:func:`choose_scale`)."""


def choose_scale(series: Sequence[Sequence[float]]) -> str:
    """How to draw groups of values on one plot (one sequence per group; empty ones are
    ignored): ``"linear"`` when their magnitudes (largest |value|) are within a factor
    :data:`MAGNITUDE_RATIO` of each other or there is at most one group; else ``"log"`` when
    every value is positive, ``"panels"`` (one panel per group) when one is not."""
    series = [list(values) for values in series if len(values)]
    peaks = [max(abs(v) for v in values) for values in series]
    if len(peaks) < 2 or max(peaks) <= MAGNITUDE_RATIO * min(peaks):
        return "linear"
    if all(v > 0 for values in series for v in values):
        return "log"
    return "panels"


# --------------------------------------------------------------------------------------------
# Tables


TABLES = [
    ("peak_velocity", "Peak velocity", "velocity"),
    ("peak_pressure", "Peak pressure", "pressure"),
    ("peak_displacement", "Peak displacement", "displacement"),
]


def value_at(rows: Sequence[dict[str, float]], t: float, column: str) -> float | None:
    """``column`` of the row at time ``t`` (within a thousandth of that step; exactly, for a
    row without ``dt``), or None."""
    for row in rows:
        if abs(row["t"] - t) <= 1e-3 * row.get("dt", 0.0) and column in row:
            return row[column]
    return None


def _four_digits(value: float | None, scale: float = 1.0) -> str:
    """``scale`` × ``value`` to 4 significant digits; '–' for no (or a non-finite) value."""
    return "–" if value is None or not math.isfinite(value) else f"{scale * value:.4g}"


def peaks_table(
    runs: Sequence[Run],
    column: str,
    title: str,
    quantity: str,
    times: Sequence[float] | None = None,
) -> str:
    """A markdown table: one row per run, one column per report time (default: the first
    run's ``output.report_times``); '–' where a run has no step at that time. The values are
    in the unit :func:`choose_unit` picks for ``quantity`` from all of them, named in the
    header: ``| <title> (<unit>) | t = ... |``."""
    times = list(times if times is not None else runs[0].case.output.report_times)
    values = [[value_at(run.rows, t, column) for t in times] for run in runs]
    unit = choose_unit(quantity, [v for row in values for v in row if v is not None])
    head = f"| {title} ({unit.name}) | " + " | ".join(f"t = {t:g} s" for t in times) + " |"
    lines = [head, "|---" * (len(times) + 1) + "|"]
    for run, row in zip(runs, values):
        cells = " | ".join(_four_digits(v, unit.scale) for v in row)
        lines.append(f"| {run.label} | {cells} |")
    return "\n".join(lines)


def unreached_report_times(runs: Sequence[Run]) -> str | None:
    """A note when the default report times (the first run's ``output.report_times``) lie
    beyond the last step of every run, whose cells are then '–' (a short try of a case whose
    report times are the study's: tables of dashes without a word); None otherwise."""
    ends = [run.rows[-1]["t"] for run in runs if run.rows]
    end = max(ends, default=0.0)
    late = [t for t in runs[0].case.output.report_times if t > end * (1 + SAME_TIME)]
    if not late:
        return None
    shown = ", ".join(f"{t:g}" for t in late)
    return (
        f"**Note**: no run reaches the report time{'s' if len(late) > 1 else ''} {shown} s "
        f"(output.report_times of {runs[0].name or runs[0].path.name}): the runs end by "
        f"t = {end:g} s, and those "
        f"columns hold '–'. Give times within the runs: `fsi report ... --times T ...`."
    )


def effort_table(runs: Sequence[Run]) -> str:
    """Steps, simulated time, coupling iterations per step (mean, max) and wall time."""
    lines = [
        "| run | steps | end (s) | coupling its/step (mean, max) | s/step | wall time (s) |",
        "|---|---|---|---|---|---|",
    ]
    for run in runs:
        its = [r["coupling_iterations"] for r in run.rows if "coupling_iterations" in r]
        wall = [r["wall_time_s"] for r in run.rows if "wall_time_s" in r]
        end = run.rows[-1]["t"] if run.rows else math.nan
        mean_its = f"{sum(its) / len(its):.2f}, {max(its):g}" if its else "–"
        finished = "" if run.summary else " (stopped)"
        lines.append(
            f"| {run.label} | {len(run.rows)}{finished} | {_four_digits(end)} | {mean_its} "
            f"| {_four_digits(sum(wall) / len(wall) if wall else None)} "
            f"| {_four_digits(sum(wall) if wall else None)} |"
        )
    return "\n".join(lines)


CYCLE_COLUMNS = [
    ("peak_velocity", "peak velocity", "velocity"),
    ("peak_pressure", "peak pressure", "pressure"),
    ("peak_displacement", "peak displacement", "displacement"),
    ("max_sss", "max SSS", "stress"),
    ("max_principal_cap", "cap max principal", "stress"),
    ("inlet_flow_rate", "inlet flow rate", "flow_rate"),
    ("min_tawss", "min TAWSS", "stress"),
    ("max_osi", "max OSI", "count"),
]
"""The per-heartbeat values of summary.json's ``cycles`` that :func:`cycles_table` shows."""


def cycles_table(run: Run) -> str | None:
    """A markdown table of the run's heartbeats (summary.json ``cycles``, written when the
    inlet has a period), or None without them: per heartbeat its time span, steps (marked
    ``(partial)`` if it did not reach its end), each :data:`CYCLE_COLUMNS` value the run has
    (a column that is 0 throughout, e.g. a rigid run's displacement, is left out) with its
    relative change from the previous heartbeat, and the largest |change| of all its values:
    where that becomes small, the solution is periodic."""
    cycles = run.summary.get("cycles") or []
    if not cycles:
        return None
    shown = []
    for column, title, quantity in CYCLE_COLUMNS:
        values = [beat["values"].get(column) for beat in cycles]
        if any(v for v in values):
            unit = choose_unit(quantity, [v for v in values if v is not None])
            shown.append((column, f"{title} ({unit.name})" if unit.name else title, unit))
    lines = [
        "| heartbeat | t (s) | steps | "
        + " | ".join(head for _, head, _ in shown)
        + " | largest change |",
        "|---" * (len(shown) + 4) + "|",
    ]
    for beat in cycles:
        cells = []
        for column, _, unit in shown:
            cell = _four_digits(beat["values"].get(column), unit.scale)
            change = beat["change"].get(column)
            cells.append(cell if change is None else f"{cell} ({100 * change:+.2g} %)")
        largest = beat.get("max_change")
        steps = f"{beat['steps']}{'' if beat['complete'] else ' (partial)'}"
        lines.append(
            f"| {beat['cycle']} | {beat['start_s']:g}–{beat['end_s']:g} | {steps} | "
            + " | ".join(cells)
            + f" | {'–' if largest is None else f'{100 * largest:.2g} %'} |"
        )
    return "\n".join(lines)


def markdown(
    runs: Sequence[Run],
    times: Sequence[float] | None = None,
    figures: Sequence[tuple[str, str]] = (),
) -> str:
    """Tables 1–3 and the solver effort; for runs with heartbeats (a periodic inlet), a table
    of each run's heartbeats (:func:`cycles_table`); with ``figures`` ((picture file name,
    caption) pairs), a section that shows each picture followed by its caption line."""
    parts = [
        f"## Table {i + 1}: {title}\n\n{peaks_table(runs, column, title, quantity, times)}"
        for i, (column, title, quantity) in enumerate(TABLES)
    ]
    late = None if times is not None else unreached_report_times(runs)
    if late:
        parts.insert(0, late)
    parts.append(f"## Solver effort\n\n{effort_table(runs)}")
    beats = [(run, cycles_table(run)) for run in runs]
    if any(table for _, table in beats):
        parts.append(
            "## Heartbeats\n\nPer heartbeat: the largest value over its steps "
            "(TAWSS: the smallest of that heartbeat's own wall indices), in brackets "
            "its change from the previous heartbeat.\n\n"
            + "\n\n".join(f"{run.label}:\n\n{table}" for run, table in beats if table)
        )
    if figures:
        parts.append(
            "## Figures\n\n"
            + "\n\n".join(f"![{name}]({name})\n*{name}*: {caption}" for name, caption in figures)
        )
    return "\n\n".join(parts) + "\n"


# --------------------------------------------------------------------------------------------
# What the plots show


@dataclass(frozen=True)
class Line:
    """One curve: ``y`` (SI units) over ``t``; no ``label`` keeps it out of the legend."""

    label: str
    t: list[float]
    y: list[float]
    style: str = "-"


@dataclass(frozen=True)
class Group:
    """The lines of one run (or one inlet waveform), drawn in colour ``colour`` (an index of
    matplotlib's cycle) and in a panel of their own when the plot has panels. ``band``: the two
    lines are a lower and an upper bound at the same times, the range between them is shaded
    and labelled ``label``."""

    label: str
    colour: int
    lines: list[Line]
    band: bool = False


def column_groups(runs: Sequence[Run], column: str) -> list[Group]:
    """``column`` over time, one group of one line per run (empty for a run without it)."""
    groups = []
    for k, run in enumerate(runs):
        rows = [r for r in run.rows if column in r]
        groups.append(
            Group(
                run.label, k, [Line(run.label, [r["t"] for r in rows], [r[column] for r in rows])]
            )
        )
    return groups


def maximum_groups(runs: Sequence[Run], columns: Sequence[str]) -> list[Group]:
    """The maximum of ``columns`` (those a row has) over time, one line per run, from the rows
    that have at least one of them."""
    groups = []
    for k, run in enumerate(runs):
        rows = [r for r in run.rows if any(c in r for c in columns)]
        y = [max(r[c] for c in columns if c in r) for r in rows]
        groups.append(Group(run.label, k, [Line(run.label, [r["t"] for r in rows], y)]))
    return groups


def range_groups(runs: Sequence[Run], low: str, high: str) -> list[Group]:
    """The range from ``low`` to ``high`` over time, shaded, one group per run (from the rows
    that have both)."""
    groups = []
    for k, run in enumerate(runs):
        rows = [r for r in run.rows if low in r and high in r]
        t = [r["t"] for r in rows]
        groups.append(
            Group(
                run.label,
                k,
                [
                    Line("", t, [r[low] for r in rows], "--"),
                    Line("", t, [r[high] for r in rows], "-"),
                ],
                band=True,
            )
        )
    return groups


FLOW_RATES = [("inlet_flow_rate", "inlet", "-"), ("outlet_flow_rate", "outlet", "--")]


def flow_rate_groups(runs: Sequence[Run]) -> list[Group]:
    """The inlet (solid) and outlet (dashed) flow rates over time, one group per run."""
    groups = []
    for k, run in enumerate(runs):
        lines = []
        for column, boundary, style in FLOW_RATES:
            rows = [r for r in run.rows if column in r]
            lines.append(
                Line(
                    f"{run.label} {boundary}",
                    [r["t"] for r in rows],
                    [r[column] for r in rows],
                    style,
                )
            )
        groups.append(Group(run.label, k, lines))
    return groups


BOUNDARY_PRESSURES = [
    ("mean_inlet_pressure", "inlet", "-"),
    ("mean_outlet_pressure", "outlet", "--"),
]


def boundary_pressure_groups(runs: Sequence[Run]) -> list[Group]:
    """The mean inlet (solid) and outlet (dashed) pressures over time, one group per run: with
    a resistance or Windkessel outlet the outlet's is the pressure the lumped model sets."""
    groups = []
    for k, run in enumerate(runs):
        lines = []
        for column, boundary, style in BOUNDARY_PRESSURES:
            rows = [r for r in run.rows if column in r]
            t, y = [r["t"] for r in rows], [r[column] for r in rows]
            lines.append(Line(f"{run.label} {boundary}", t, y, style))
        groups.append(Group(run.label, k, lines))
    return groups


INLET_SAMPLES = 2001
"""Evenly spaced times at which P(t) is evaluated over a time span (besides the runs' step
times and a table's rows)."""


def inlet_pressure_groups(runs: Sequence[Run]) -> list[Group]:
    """P(t) of the traction inlets of the runs' configurations (``fluid.inlet``; velocity
    inlets are left out), one group per distinct inlet, over [0, the last step of the runs that
    share it] (for runs without steps their end: ``time.end``, or ``time.cycles`` heartbeats).
    Points where a formula cannot be evaluated are left out."""
    from fsi.physics.fluid_boundaries import inlet_pressure

    shared: dict[object, list[Run]] = {}
    for run in runs:
        shared.setdefault(run.case.fluid.inlet, []).append(run)
    groups = []
    for inlet, sharing in shared.items():
        try:
            pressure = inlet_pressure(inlet)
        except TypeError:  # a velocity inlet
            continue
        end = max(
            run.rows[-1]["t"] if run.rows else config.run_time(run.case).end for run in sharing
        )  # time.cycles: N T
        times = {end * i / (INLET_SAMPLES - 1) for i in range(INLET_SAMPLES)}
        times.update(r["t"] for run in sharing for r in run.rows)
        if isinstance(inlet, config.InletPressureTable):
            times.update(row[0] for row in inlet.table if 0 <= row[0] <= end)
        t, y = [], []
        for time in sorted(times):
            try:
                y.append(pressure(time))
            except boundary_data.FormulaError:
                continue
            t.append(time)
        label = f"{', '.join(run.title for run in sharing)}: {_describe(inlet)}"
        groups.append(Group(label, len(groups), [Line(label, t, y)]))
    return groups


def _describe(inlet: config.Inlet) -> str:
    """A short legend entry for a traction inlet."""
    if isinstance(inlet, config.InletPulse):
        return (
            f"pulse (A/2)(1 − cos 2πt/T), A = {inlet.amplitude:g} Pa, "
            f"T = {inlet.duration * 1e3:g} ms"
        )
    if isinstance(inlet, config.InletPressure):
        formula = inlet.formula if len(inlet.formula) <= 60 else inlet.formula[:57] + "..."
        return f"P = {formula}"
    if isinstance(inlet, (config.InletPressureTable, config.InletPressureFile)):
        period = f", period {inlet.period:g} s" if inlet.period > 0 else ""
        return f"table of {len(inlet.table)} rows{period}"
    return inlet.kind


@dataclass(frozen=True)
class Figure:
    """One picture, ``<name>.<format>``: ``groups(runs)`` drawn with :func:`draw`, the y-axis
    labelled ``ylabel`` and the unit :func:`choose_unit` picks for ``quantity``; ``caption``
    says what it shows (report.md), ``group`` what one group of lines is (for the caption of
    panels)."""

    name: str
    caption: str
    ylabel: str
    quantity: str
    groups: Callable[[Sequence[Run]], list[Group]]
    group: str = "run"


def _column(column: str) -> Callable[[Sequence[Run]], list[Group]]:
    return lambda runs: column_groups(runs, column)


FIGURES = [
    Figure(
        "max_sss",
        "Figure 6: the maximum structural shear stress max |σ₁₂| in the whole "
        "structure (wall, cap and lipid) over time, one line per run.",
        "max |σ₁₂| in the structure",
        "stress",
        _column("max_sss"),
    ),
    Figure(
        "max_sss_plaque",
        "Figure 6 in the plaque, as the study plots it: max |σ₁₂| over "
        "the fibrous cap and the lipid pool (the larger of max_sss_cap and max_sss_lipid) "
        "over time, one line per run.",
        "max |σ₁₂| in the plaque",
        "stress",
        lambda runs: maximum_groups(runs, ("max_sss_cap", "max_sss_lipid")),
    ),
    Figure(
        "max_principal_cap",
        "The largest principal stress in the fibrous cap "
        "(max_principal_cap, the usual rupture indicator) over time, one line per run.",
        "max principal stress in the cap",
        "stress",
        _column("max_principal_cap"),
    ),
    Figure(
        "peak_velocity",
        "Table 1's peak velocity max |u| over time, one line per run.",
        "peak velocity",
        "velocity",
        _column("peak_velocity"),
    ),
    Figure(
        "peak_pressure",
        "Table 2's peak pressure max p over time, one line per run.",
        "peak pressure",
        "pressure",
        _column("peak_pressure"),
    ),
    Figure(
        "peak_displacement",
        "Table 3's peak displacement max |η| over time, one line per run.",
        "peak displacement",
        "displacement",
        _column("peak_displacement"),
    ),
    Figure(
        "wall_shear_stress",
        "The range of the signed wall shear stress along the walls "
        "over time, min_wss (dashed) to max_wss (solid), shaded, one band per run; negative "
        "where the flow next to the wall reverses.",
        "wall shear stress",
        "stress",
        lambda runs: range_groups(runs, "min_wss", "max_wss"),
    ),
    Figure(
        "recirculation_length",
        "The recirculation length (the longest reversed-flow zone "
        "along either wall) over time, one line per run.",
        "recirculation length",
        "length",
        _column("recirculation_length"),
    ),
    Figure(
        "coupling_iterations",
        "Dirichlet–Neumann coupling iterations per step, one line per run.",
        "coupling iterations",
        "count",
        _column("coupling_iterations"),
    ),
    Figure(
        "flow_rate",
        "The inlet (solid) and outlet (dashed) flow rates per unit depth over "
        "time, in cm²/s (= mL/s per cm of depth), one colour per run.",
        "flow rate",
        "flow_rate",
        flow_rate_groups,
    ),
    Figure(
        "boundary_pressure",
        "The pressure averaged over the inlet (solid) and over the outlet (dashed) over "
        "time, one colour per run; with a resistance or Windkessel outlet the outlet's is "
        "the pressure the lumped model sets from the flow rate.",
        "mean pressure",
        "pressure",
        boundary_pressure_groups,
    ),
    Figure(
        "inlet_pressure",
        "The inlet pressure P(t) of the runs' configurations (traction "
        "inlets; velocity inlets have none) over their time span, one line per distinct "
        "waveform, named by the runs that share it.",
        "inlet pressure P",
        "pressure",
        inlet_pressure_groups,
        group="waveform",
    ),
]


# --------------------------------------------------------------------------------------------
# Drawing


def heartbeat_ends(periods: Sequence[float], end: float) -> list[float]:
    """The times k T (k = 1, 2, ...) up to ``end`` at which a heartbeat of one of ``periods``
    ends (each once, sorted)."""
    counts = {T: math.floor(end / T * (1 + SAME_TIME)) for T in periods if T > 0}
    return sorted({k * T for T, n in counts.items() for k in range(1, n + 1)})


def draw(
    groups: Sequence[Group],
    ylabel: str,
    quantity: str,
    path: Path,
    periods: Sequence[float] = (),
) -> str | None:
    """The groups' lines that have points as a picture at ``path`` (PNG, PDF or SVG by its
    suffix), in the unit :func:`choose_unit` picks for ``quantity`` from all their values, on
    the scale :func:`choose_scale` picks from each group's values, with a dotted vertical line
    where a heartbeat of one of ``periods`` ends (:func:`heartbeat_ends`); returns that scale,
    or None (and writes nothing) when no line has a point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fsi.output import plot

    groups = [
        Group(g.label, g.colour, [line for line in g.lines if line.t], g.band) for g in groups
    ]
    groups = [g for g in groups if g.lines and (not g.band or len(g.lines) == 2)]
    if not groups:
        return None
    values = [[v for line in g.lines for v in line.y] for g in groups]
    unit = choose_unit(quantity, [v for vs in values for v in vs])
    scale = choose_scale(values)
    label = f"{ylabel} ({unit.name})" if unit.name else ylabel
    panels = len(groups) if scale == "panels" else 1
    fig, axes = plt.subplots(
        panels,
        1,
        sharex=True,
        squeeze=False,
        layout="constrained",
        figsize=(7, 4 if panels == 1 else 1.2 + 1.7 * panels),
    )
    axes = list(axes[:, 0])
    for k, group in enumerate(groups):
        _plot_group(axes[k if scale == "panels" else 0], group, unit.scale)
    end = max(t for g in groups for line in g.lines for t in line.t)
    for ax in axes:
        if scale == "log":
            ax.set_yscale("log")
        for t in heartbeat_ends(periods, end):
            ax.axvline(t, color="0.5", ls=":", lw=0.8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[-1].set_xlabel("t (s)")
    if scale == "panels":
        fig.supylabel(label)
    else:
        axes[0].set_ylabel(label)
    plot.save_figure(fig, path, dpi=120)
    return scale


def _plot_group(ax, group: Group, factor: float) -> None:
    """The group's lines on ``ax`` (values × ``factor``, in the group's colour), and for a band
    the area between its two lines shaded."""
    colour = f"C{group.colour % 10}"
    for line in group.lines:
        ax.plot(
            line.t,
            [factor * v for v in line.y],
            line.style,
            lw=1.2,
            color=colour,
            label=line.label or "_nolegend_",
        )
    if group.band:
        low, high = group.lines
        ax.fill_between(
            low.t,
            [factor * v for v in low.y],
            [factor * v for v in high.y],
            color=colour,
            alpha=0.2,
            label=group.label,
        )


SCALE_NOTES = {
    "linear": "",
    "log": " Log y-axis: the {group}s' magnitudes differ by more than {ratio:g}×.",
    "panels": " One panel per {group} (each its own y-range): their magnitudes differ by more "
    "than {ratio:g}× and not every value is positive.",
}


def write(
    runs: Sequence[Run], out: Path, times: Sequence[float] | None = None, picture: str = "png"
) -> list[Path]:
    """The pictures of :data:`FIGURES` that have a line (``out/<name>.<picture>``, ``picture``
    one of fsi.output.plot.FORMATS) and ``out/report.md`` (the tables, then each picture with
    its caption and scale); returns the files written, report.md first. With periodic inlets
    the time plots mark the heartbeats' ends."""
    out.mkdir(parents=True, exist_ok=True)
    periods = sorted({config.heartbeat_period(run.case) for run in runs} - {0.0})
    beats = (
        " Dotted vertical lines: the ends of the heartbeats (period "
        + ", ".join(f"{T:g} s" for T in periods)
        + ")."
        if periods
        else ""
    )
    pictures, captions = [], []
    for figure in FIGURES:
        path = out / f"{figure.name}.{picture}"
        scale = draw(figure.groups(runs), figure.ylabel, figure.quantity, path, periods)
        if scale is not None:
            pictures.append(path)
            note = SCALE_NOTES[scale].format(group=figure.group, ratio=MAGNITUDE_RATIO)
            captions.append((path.name, figure.caption + note + beats))
    for path, caption in [
        *wall_index_pictures(runs, out, picture),
        *snapshots(runs, out, times, picture),
    ]:
        pictures.append(path)
        captions.append((path.name, caption))
    (out / "report.md").write_text(markdown(runs, times, captions))
    return [out / "report.md", *pictures]


def wall_index_pictures(
    runs: Sequence[Run], out: Path, picture: str = "png"
) -> list[tuple[Path, str]]:
    """TAWSS and OSI along the walls (fsi/output/wall_plot.py) of every run with a
    ``wall_indices.csv``: ``<run>_tawss.<picture>``, ``<run>_osi.<picture>``, over the last
    heartbeat in the file (periodic inlets) or the whole run. Returns (file, caption) pairs."""
    from fsi.output import plot, wall_plot

    written = []
    for run in runs:
        if not (run.path / "wall_indices.csv").is_file():
            continue
        for name in ("tawss", "osi"):
            path = out / f"{run.stem}_{name}.{picture}"
            try:
                index = dataclasses.replace(wall_plot.read(run.path, name), run=run.title)
                wall_plot.draw(index, path)
            except plot.PlotError as e:
                log.warning("fsi report: no %s: %s", path.name, e)
                continue
            written.append((path, wall_plot.title(index) + ", one line per wall and side."))
    return written


def snapshots(
    runs: Sequence[Run], out: Path, times: Sequence[float] | None = None, picture: str = "png"
) -> list[tuple[Path, str]]:
    """Field pictures (fsi/output/plot.py) at the report times of every run that has field files:
    the structural shear stress σ₁₂ on the structure (``<run>_sss_t<T>.<picture>``) and the
    velocity with its streamlines on the current fluid mesh (``<run>_velocity_t<T>.<picture>``).
    A time the run has not reached is skipped. Returns (file, caption) pairs."""
    from fsi.output import plot

    written = []
    for run in runs:
        report_times = list(times if times is not None else run.case.output.report_times)
        last = run.rows[-1]["t"] if run.rows else -math.inf
        pictures = [
            ("sss", "solid.xdmf", {}, "structural shear stress σ₁₂ on the structure"),
            (
                "velocity",
                "fields.xdmf",
                {"streamlines": True},
                "velocity and streamlines on the current fluid mesh",
            ),
        ]
        for field, file, options, what in pictures:
            if not (run.path / file).is_file():
                continue
            for t in report_times:
                if t > last * (1 + SAME_TIME):
                    continue
                path = out / f"{run.stem}_{field}_t{t:g}.{picture}"
                try:
                    plot.field_snapshot(run.path, field, t, path, **options)
                except plot.PlotError as e:  # a run written before the field existed
                    log.warning("fsi report: no %s: %s", path.name, e)
                    continue
                written.append((path, f"{run.label}: {what} at t = {t:g} s"))
    return written
