"""``fsi report``: the study's tables and plots from finished run folders (MODEL.md §6).

Tables 1–3 are the peak velocity, pressure and displacement at the report times (the rows of
``metrics.csv`` at those times); a fourth table gives each run's solver effort. The plots show
a column of ``metrics.csv`` over time, one line per run (Figure 6 is ``max_sss``), and the inlet
and outlet flow rates together, one line per run and boundary. A run without a column (an older
run folder, a structure-only run) is left out of that plot and shows '–' in the tables.
Reads only the files ``fsi run`` writes: ``config.yaml``, ``metrics.csv``, ``summary.json``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from fsi import config, io

TABLES = [("peak_velocity", "Peak velocity (m/s)"), ("peak_pressure", "Peak pressure (Pa)"),
          ("peak_displacement", "Peak displacement (m)")]
PLOTS = [("max_sss", "max |σ₁₂| in the structure (Pa)"),
         ("peak_displacement", "peak displacement (m)"),
         ("peak_velocity", "peak velocity (m/s)"),
         ("recirculation_length", "recirculation length (m)"),
         ("coupling_iterations", "coupling iterations")]
FLOW_RATES = [("inlet_flow_rate", "inlet", "-"), ("outlet_flow_rate", "outlet", "--")]
FLOW_RATE_UNIT = ("cm²/s = mL/s per cm of depth", 1.0e4)  # metrics.csv holds m²/s


class ReportError(ValueError):
    """A run folder is missing a file or is not a run folder."""


@dataclass(frozen=True)
class Run:
    path: Path
    case: config.Case
    rows: list[dict[str, float]]
    summary: dict

    @property
    def label(self) -> str:
        c = self.case
        return (f"{self.path.name} ({c.structure.mode}, {c.fluid.rheology.model}, "
                f"{c.mesh.level})")


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
        case = config.load(path / "config.yaml")
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


def value_at(rows: Sequence[dict[str, float]], t: float, column: str) -> float | None:
    """``column`` of the row at time ``t`` (within a thousandth of that step; exactly, for a
    row without ``dt``), or None."""
    for row in rows:
        if abs(row["t"] - t) <= 1e-3 * row.get("dt", 0.0) and column in row:
            return row[column]
    return None


def _number(value: float | None) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{value:.4g}"


def peaks_table(runs: Sequence[Run], column: str, title: str,
                times: Sequence[float] | None = None) -> str:
    """A markdown table: one row per run, one column per report time (default: the first
    run's ``output.report_times``); '–' where a run has no step at that time."""
    times = list(times if times is not None else runs[0].case.output.report_times)
    head = f"| {title} | " + " | ".join(f"t = {t:g} s" for t in times) + " |"
    lines = [head, "|---" * (len(times) + 1) + "|"]
    for run in runs:
        lines.append(f"| {run.label} | "
                     + " | ".join(_number(value_at(run.rows, t, column)) for t in times) + " |")
    return "\n".join(lines)


def effort_table(runs: Sequence[Run]) -> str:
    """Steps, simulated time, coupling iterations per step (mean, max) and wall time."""
    lines = ["| run | steps | end (s) | coupling its/step (mean, max) | s/step | wall time (s) |",
             "|---|---|---|---|---|---|"]
    for run in runs:
        its = [r["coupling_iterations"] for r in run.rows if "coupling_iterations" in r]
        wall = [r["wall_time_s"] for r in run.rows if "wall_time_s" in r]
        end = run.rows[-1]["t"] if run.rows else math.nan
        mean_its = f"{sum(its) / len(its):.2f}, {max(its):g}" if its else "–"
        finished = "" if run.summary else " (stopped)"
        lines.append(f"| {run.label} | {len(run.rows)}{finished} | {_number(end)} | {mean_its} "
                     f"| {_number(sum(wall) / len(wall) if wall else None)} "
                     f"| {_number(sum(wall) if wall else None)} |")
    return "\n".join(lines)


def markdown(runs: Sequence[Run], times: Sequence[float] | None = None) -> str:
    parts = [f"## Table {i + 1}: {title}\n\n{peaks_table(runs, column, title, times)}"
             for i, (column, title) in enumerate(TABLES)]
    parts.append(f"## Solver effort\n\n{effort_table(runs)}")
    return "\n\n".join(parts) + "\n"


def plot(runs: Sequence[Run], column: str, ylabel: str, path: Path) -> bool:
    """``column`` over time, one line per run that has it, as a PNG; False if none has it."""
    series = [(run.label, [r["t"] for r in run.rows if column in r],
               [r[column] for r in run.rows if column in r]) for run in runs]
    return _figure([(label, t, y, "-", None) for label, t, y in series], ylabel, path)


def flow_rate_plot(runs: Sequence[Run], path: Path) -> bool:
    """The inlet (solid) and outlet (dashed, same colour) flow rates per unit depth over time,
    in cm²/s, as a PNG; False if no run has them."""
    unit, scale = FLOW_RATE_UNIT
    series = []
    for k, run in enumerate(runs):
        for column, boundary, style in FLOW_RATES:
            rows = [r for r in run.rows if column in r]
            series.append((f"{run.label} {boundary}", [r["t"] for r in rows],
                           [scale * r[column] for r in rows], style, f"C{k % 10}"))
    return _figure(series, f"flow rate ({unit})", path)


def _figure(series: Sequence[tuple], ylabel: str, path: Path) -> bool:
    """One line per (label, t, y, linestyle, colour) that has points; False if none has."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = [s for s in series if s[1]]
    if not series:
        return False
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    for label, t, y, style, colour in series:
        ax.plot(t, y, style, label=label, lw=1.2, color=colour)
    ax.set_xlabel("t (s)")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True


def write(runs: Sequence[Run], out: Path, times: Sequence[float] | None = None) -> list[Path]:
    """``out/report.md``, one PNG per plotted column and ``flow_rate.png`` (the inlet and outlet
    flow rates); returns the files written."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "report.md"]
    written[0].write_text(markdown(runs, times))
    for column, ylabel in PLOTS:
        path = out / f"{column}.png"
        if plot(runs, column, ylabel, path):
            written.append(path)
    if flow_rate_plot(runs, out / "flow_rate.png"):
        written.append(out / "flow_rate.png")
    return written
