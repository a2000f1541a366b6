"""``fsi sweep``'s table and plots (docs/sweep.md): each run's headline outputs
(:data:`HEADLINES`, :func:`headline_values`), the table of all runs (``sweep.csv``,
``sweep.md``: :func:`write_results`) and the plots of each headline over the varied keys
(:func:`write_plots`). The runs themselves: fsi/run/sweep.py.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from mpi4py import MPI

import yaml

from fsi import config
from fsi.config import reader
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import io, metrics_csv, units
from fsi.run.sweep import SweepRun, Variation

# --------------------------------------------------------------------------------------------
# The table


@dataclass(frozen=True)
class Headline:
    """A column of the table: ``name``, the :mod:`fsi.output.units` quantity it is shown in, what it
    is, and where it comes from: the ``max``/``min`` over the rows of metrics.csv column
    ``source``, or (``how="summary"``) summary.json's key ``source``."""

    name: str
    label: str  # the quantity's short name on a plot's axis
    quantity: str
    meaning: str
    source: str
    how: Literal["max", "min", "summary"]
    structure: bool = False  # a structure's quantity: none for a rigid-structure run


HEADLINES = (
    Headline(
        "max_principal_cap",
        "peak cap stress (max principal)",
        "stress",
        "peak cap stress: the fibrous cap's largest principal Cauchy stress, max over the run",
        "max_principal_cap",
        "max",
        True,
    ),
    Headline(
        "max_sss",
        "max |σ₁₂| in the structure",
        "stress",
        "the structure's largest |σ₁₂| (structural shear stress), max over the run",
        "max_sss",
        "max",
        True,
    ),
    Headline(
        "min_wss",
        "min wall shear stress",
        "stress",
        "the smallest signed wall shear stress over the run (negative: reversed flow)",
        "min_wss",
        "min",
    ),
    Headline(
        "max_wss",
        "max wall shear stress",
        "stress",
        "the largest signed wall shear stress over the run",
        "max_wss",
        "max",
    ),
    Headline(
        "min_tawss",
        "min TAWSS",
        "stress",
        "the smallest time-averaged wall shear stress along the lumen's walls (summary.json)",
        "min_tawss",
        "summary",
    ),
    Headline(
        "max_osi",
        "max OSI",
        "count",
        "the largest oscillatory shear index along the lumen's walls (summary.json)",
        "max_osi",
        "summary",
    ),
    Headline(
        "max_recirculation_length",
        "max recirculation length",
        "length",
        "the longest reversed-flow zone along either wall, max over the run",
        "recirculation_length",
        "max",
    ),
    Headline(
        "peak_displacement",
        "peak displacement",
        "displacement",
        "the structure's largest |η|, max over the run",
        "peak_displacement",
        "max",
        True,
    ),
    Headline(
        "peak_inlet_flow_rate",
        "peak inlet flow rate",
        "flow_rate",
        "the largest inlet flow rate per unit depth over the run (positive downstream)",
        "inlet_flow_rate",
        "max",
    ),
)


class ResultError(Exception):
    """A finished run's summary.json or metrics.csv cannot be read."""


def headline_values(folder: Path, end: float | None = None) -> dict[str, float | None]:
    """The :data:`HEADLINES` of the finished run in ``folder``, over its rows up to ``end``
    (None: all): None for a quantity its case does not have (no such column or key, no value
    in any row; the structure's quantities of a rigid-structure run) and, when ``end`` cuts the
    run short, for those of summary.json (over the whole run). Raises :class:`ResultError`."""
    try:
        summary = json.loads((folder / "summary.json").read_text())
        rows = metrics_csv.read_metrics(folder / "metrics.csv")
    except (OSError, ValueError) as e:  # metrics_csv.MetricsError is a ValueError
        raise ResultError(str(e)) from e
    cut = end is not None and any(r["t"] > end * (1 + SAME_TIME) for r in rows)
    if cut:
        rows = [r for r in rows if r["t"] <= end * (1 + SAME_TIME)]
    rigid = summary.get("structure_mode") == "rigid"
    values: dict[str, float | None] = {}
    for h in HEADLINES:
        if (h.structure and rigid) or (cut and h.how == "summary"):
            value = None
        elif h.how == "summary":
            value = summary.get(h.source)
            value = float(value) if isinstance(value, (int, float)) else None
        else:
            column = [r[h.source] for r in rows if h.source in r]
            value = (max if h.how == "max" else min)(column) if column else None
        values[h.name] = value
    return values


def write_results(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    statuses: Sequence[str],
    out: Path,
    comm: MPI.Comm,
) -> tuple[list[Path], list[str]]:
    """``out/sweep.csv`` (SI units, the :data:`HEADLINES` in their columns, an empty cell where
    there is no value), ``out/sweep.md`` (the same table in readable units, ``–`` where there is
    no value, and what each column is) and :func:`write_plots`. Only runs whose status is
    ``done`` have values (a done run whose files cannot be read becomes ``failed: ...``).
    Returns the files written and the statuses. Collective (rank 0 writes; raises
    :class:`fsi.output.io.OutputError` on every rank if it cannot)."""
    keys = [v.key for v in variations]
    statuses = list(statuses)
    table: list[dict[str, float | None]] = []
    if comm.rank == 0:
        for i, run in enumerate(runs):
            values = {h.name: None for h in HEADLINES}
            if statuses[i] == "done":
                try:
                    values = headline_values(run.folder, config.run_time(run.case).end)
                except ResultError as e:
                    statuses[i] = f"failed: cannot read its results: {e}"
            table.append(values)
    csv_rows = [
        [value for _, value in run.choice]
        + [math.nan if row[h.name] is None else row[h.name] for h in HEADLINES]
        + [status]
        for run, row, status in zip(runs, table, statuses, strict=False)
    ]
    columns = keys + [h.name for h in HEADLINES] + ["status"]
    io.on_rank0(comm, lambda: out.mkdir(parents=True, exist_ok=True), out)
    io.write_table(comm, out / "sweep.csv", columns, csv_rows)
    written = [out / "sweep.csv", out / "sweep.md"]
    io.on_rank0(
        comm,
        lambda: (out / "sweep.md").write_text(markdown(runs, variations, table, statuses)),
        out / "sweep.md",
    )
    plots: list[Path] = []
    io.on_rank0(comm, lambda: plots.extend(write_plots(runs, variations, table, out)), out)
    return written + comm.bcast(plots, root=0), comm.bcast(statuses, root=0)


def markdown(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    table: Sequence[dict[str, float | None]],
    statuses: Sequence[str],
) -> str:
    """The table as markdown: one row per run, each headline in the unit that suits its values
    (:func:`fsi.output.units.choose_unit`), 4 significant digits, ``–`` where there is no value."""
    shown = {}
    for h in HEADLINES:
        values = [row[h.name] for row in table if row[h.name] is not None]
        shown[h.name] = units.choose_unit(h.quantity, values)

    def header(h: Headline) -> str:
        unit = shown[h.name].name
        return f"{h.name} ({unit})" if unit else h.name

    def cell(h: Headline, value: float | None) -> str:
        return "–" if value is None else f"{value * shown[h.name].scale:.4g}"

    def escape(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    columns = [v.key for v in variations] + [header(h) for h in HEADLINES] + ["status"]
    lines = [
        f"# Sweep of {runs[0].case.name}" if runs else "# Sweep",
        "",
        "| " + " | ".join(columns) + " |",
        "|" + "---|" * len(columns),
    ]
    for run, row, status in zip(runs, table, statuses, strict=False):
        cells = (
            [escape(value) for _, value in run.choice]
            + [cell(h, row[h.name]) for h in HEADLINES]
            + [escape(status)]
        )
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "Each run's folder is named by its varied values (e.g. "
        f"`{runs[0].folder.name if runs else ''}`); the columns:",
        "",
    ]
    lines += [f"- `{h.name}`: {h.meaning}." for h in HEADLINES]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# The plots


def _numeric(case: config.Case, key: str) -> float | None:
    """The value of ``key`` in ``case`` if it is a number (not a bool), else None."""
    node = yaml.safe_load(config.to_yaml(case))
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        return None
    return float(node)


def axis_label(case: config.Case, key: str) -> str:
    """A varied key as a quantity with its unit: the key's last part in words, after its
    section's name unless that is ``geometry`` (whose names say what they are), e.g.
    ``geometry.cap_thickness`` → "cap thickness (m)", ``fluid.inlet.amplitude`` → "inlet
    amplitude (Pa)", ``structure.cap.young_modulus`` → "cap young modulus (Pa)"."""
    parts = key.split(".")
    words = parts[-1:] if parts[0] == "geometry" or len(parts) == 1 else parts[-2:]
    text = " ".join(words).replace("_", " ")
    unit = reader.unit_of(case, key)
    return f"{text} ({unit})" if unit else text


def write_plots(
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    table: Sequence[dict[str, float | None]],
    out: Path,
) -> list[Path]:
    """``out/sweep_<headline>.png`` for each headline that some run has: one panel per varied
    key with more than one value (the first key if none has), its values along x (on a number
    axis, ticked at the values, when every value is a number, else in ``--vary`` order), one
    line per combination of the other keys' values (a gap where a run has no value). A
    headline no run has gets no plot (an earlier sweep's is deleted). Rank 0 alone; returns
    the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for h in HEADLINES:
        path = out / f"sweep_{h.name}.png"
        values = [row[h.name] for row in table if row[h.name] is not None]
        if not values:
            path.unlink(missing_ok=True)
            continue
        unit = units.choose_unit(h.quantity, values)
        panels = [i for i, v in enumerate(variations) if len(v.values) > 1] or [0]
        figure, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 3.8), squeeze=False)
        for axis, panel in zip(axes[0], panels, strict=True):
            _panel(axis, panel, runs, variations, table, h.name, unit.scale)
            axis.set_xlabel(axis_label(runs[0].case, variations[panel].key))
            axis.set_ylabel(f"{h.label} ({unit.name})" if unit.name else h.label)
            axis.grid(True, alpha=0.3)
        suptitle(figure, h.meaning)
        figure.tight_layout()
        figure.savefig(path, dpi=110)
        plt.close(figure)
        written.append(path)
    return written


def suptitle(figure, text: str, fontsize: float = 9) -> None:
    """``text`` as ``figure``'s title, broken into lines that fit its width (one 84-character
    headline was cut off at both edges of a one-panel plot)."""
    import textwrap

    # ~0.55 em a character, with a margin: the characters that fit the figure's width
    per_line = int(figure.get_figwidth() * 72 / (0.55 * fontsize) * 0.9)
    figure.suptitle(textwrap.fill(text, per_line), fontsize=fontsize)


def _panel(
    axis,
    panel: int,
    runs: Sequence[SweepRun],
    variations: Sequence[Variation],
    table: Sequence[dict[str, float | None]],
    name: str,
    scale: float,
) -> None:
    """Headline ``name`` against varied key number ``panel``: one line per combination of the
    other keys' values."""
    key = variations[panel].key
    order = list(variations[panel].values)
    numbers = {run.choice[panel][1]: _numeric(run.case, key) for run in runs}
    numeric = all(v is not None for v in numbers.values())
    lines: dict[tuple, list[tuple[float, float]]] = {}
    for run, row in zip(runs, table, strict=True):
        others = tuple(c for i, c in enumerate(run.choice) if i != panel)
        value = run.choice[panel][1]
        x = numbers[value] if numeric else float(order.index(value))
        y = math.nan if row[name] is None else row[name] * scale
        lines.setdefault(others, []).append((x, y))
    for others, points in lines.items():
        points.sort()
        label = ", ".join(f"{k}={v}" for k, v in others) or None
        axis.plot([p[0] for p in points], [p[1] for p in points], "o-", label=label)
    if numeric:  # a tick at each value, labelled as typed (automatic ticks crowd 5e-4 steps)
        ticks = sorted((numbers[value], value) for value in order)
        axis.set_xticks([x for x, _ in ticks], [value for _, value in ticks])
    else:
        axis.set_xticks(range(len(order)), order)
    if len(lines) > 1:
        axis.legend(fontsize=7)
