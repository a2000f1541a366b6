"""``fsi report``'s plots: what each shows (:data:`FIGURES`, each a list of line groups of the
runs' metrics over time) and how it is drawn (:func:`draw`: readable units, a linear or log
axis or panels, the heartbeats marked), and the along-wall and field pictures of the report
(:func:`wall_index_pictures`, :func:`snapshots`). fsi/output/report.py writes them beside the
tables.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fsi import config
from fsi.config import boundary_data
from fsi.numerics.timestepping import SAME_TIME
from fsi.output.report_runs import Run, choose_scale
from fsi.output.units import choose_unit

log = logging.getLogger("fsi")


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
