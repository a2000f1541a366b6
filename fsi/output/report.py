"""``fsi report``: the study's tables and plots (docs/model.md, What the study reports) from
finished run folders, read from the files ``fsi run`` writes (``config.yaml``, ``metrics.csv``,
``summary.json``). Tables 1–3 give the peak velocity, pressure and displacement at the report
times, a fourth each run's solver effort, and runs with heartbeats a table of them
(:func:`cycles_table`). The plots (fsi/output/report_figures.py) show the reported metrics over
time in readable units (:func:`fsi.output.units.choose_unit`), on a linear or log axis or in
panels (:func:`fsi.output.report_runs.choose_scale`); a run without a column is left out of that
plot and shows '–' in the tables. ``report.md`` lists every picture with a caption line. The run
folders are read by fsi/output/report_runs.py.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from pathlib import Path

from fsi import config
from fsi.numerics.timestepping import SAME_TIME
from fsi.output.report_figures import FIGURES, SCALE_NOTES, draw, snapshots, wall_index_pictures
from fsi.output.report_runs import MAGNITUDE_RATIO, Run
from fsi.output.units import choose_unit

log = logging.getLogger("fsi")


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
