"""The figures of docs/study.md (docs/figures/study_*.png), read from the run folders: the
study's Figure 6 (SSS over time, :func:`figure_sss`), Figures 7–8 (the fields,
:func:`field_figures`), Figure 9 (the wall shear stress along the walls,
:func:`figure_wall_shear`) and the mesh convergence of the maxima (:func:`figure_convergence`).
fsi/study/document.py writes them beside the text.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fsi.output import field_files, plot, report
from fsi.study.runs import (
    CONFIGS,
    LABELS,
    QUANTITIES,
    TIMES,
    at,
    finished,
    peak,
    plaque_max,
)

# --------------------------------------------------------------------------------------------
# Figures


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


PULSE_END = 0.02
"""s: Figure 6's left column, the pulse and the wall's first response."""


def figure_sss(runs: dict, path: Path) -> Path:
    """Figure 6: the plaque's largest |σ₁₂| (cap and lipid, as the study plots it) over the
    pulse (linear time, left) and the whole beat (log time, right), log stress (the fixed-wall
    values are ~50× below the moving-wall ones); below, the Carreau/Newtonian ratio of each
    wall and mesh, which is what separates curves that lie on each other above. Newtonian
    wide and light, Carreau narrow and dark on top of it; coarse solid, fine dashed. Without
    the run folders (``--document-only`` from the summaries) the committed figure is kept."""
    if path.is_file() and not any(f"{c}_{m}" in runs for c in CONFIGS for m in ("coarse", "fine")):
        return path
    plt = _pyplot()
    fig, axes = plt.subplots(
        2, 2, figsize=(12, 7), sharex="col", height_ratios=(2, 1), layout="constrained"
    )
    colours = {"fixed": "C0", "moving": "C3"}
    styles = {"coarse": "-", "fine": "--"}

    for col, end in enumerate((PULSE_END, None)):
        top, bottom = axes[0, col], axes[1, col]
        _sss_curves(top, runs, end, colours, styles)
        _sss_ratios(bottom, runs, end, colours, styles)
        top.set_yscale("log")
        top.grid(True, which="both", alpha=0.3)
        bottom.axhline(1.0, color="k", lw=0.6)
        bottom.grid(True, alpha=0.3)
        bottom.set_xlabel("t (s)" if end is None else "t (ms)")
        if end is None:
            top.set_xscale("log")
            top.set_title("the whole beat (log time)")
        else:
            top.set_xlim(0, 1e3 * end)
            top.set_title(f"the pulse and the wall's first response (0–{1e3 * end:g} ms)")
    axes[0, 0].set_ylabel("max |σ₁₂| (Pa)")
    axes[1, 0].set_ylabel("Carreau / Newtonian")
    axes[0, 1].legend(fontsize=7, ncol=2)
    axes[1, 1].legend(fontsize=7)
    plot.save_figure(fig, path, dpi=130)
    return path


def _plaque_series(run, end=None):
    """(t, the plaque's max |σ₁₂|), t in ms up to ``end`` (s), else in s."""
    pts = [(r["t"], plaque_max(r)) for r in run.rows if plaque_max(r)]
    return [(t if end is None else 1e3 * t, v) for t, v in pts if end is None or t <= end]


def _whole_series(run, end=None):
    """(t, the whole structure's max |σ₁₂|), as :func:`_plaque_series`."""
    pts = [(r["t"], r["max_sss"]) for r in run.rows if r.get("max_sss")]
    return [(t if end is None else 1e3 * t, v) for t, v in pts if end is None or t <= end]


def _sss_curves(top, runs: dict, end: float | None, colours: dict, styles: dict) -> None:
    """Figure 6's upper panel: each run's plaque max |σ₁₂| up to ``end`` (None: the whole beat)."""
    for c in CONFIGS:
        wall, fluid = c.split("_")
        for level, style in styles.items():
            run = runs.get(f"{c}_{level}")
            if run is None:
                continue
            pts = _plaque_series(run, end)
            if not pts:
                continue
            wide = fluid == "newtonian"
            top.plot(
                *zip(*pts),
                style,
                color=colours[wall],
                lw=3.5 if wide else 1.1,
                alpha=0.35 if wide else 1.0,
                label=f"{LABELS[c]}, {level}",
            )
            whole = _whole_series(run, end)
            if whole and wall == "moving" and fluid == "newtonian":
                top.plot(*zip(*whole), style, color="k", lw=0.8,
                         label=f"whole structure, {LABELS[c]}, {level}")  # fmt: skip


def _sss_ratios(bottom, runs: dict, end: float | None, colours: dict, styles: dict) -> None:
    """Figure 6's lower panel: the Carreau/Newtonian ratio of each wall and mesh."""
    for wall in colours:
        for level, style in styles.items():
            n, c = runs.get(f"{wall}_newtonian_{level}"), runs.get(f"{wall}_carreau_{level}")
            if n is None or c is None:
                continue
            carreau = dict(_plaque_series(c, end))
            pts = [(t, carreau[t] / v) for t, v in _plaque_series(n, end) if t in carreau]
            if pts:
                bottom.plot(
                    *zip(*pts),
                    style,
                    color=colours[wall],
                    lw=1.1,
                    label=f"{wall} wall, {level}",
                )


def figure_convergence(summaries: dict, path: Path) -> Path:
    """The coarse → fine change of the three peaks at the report times, per configuration,
    relative to the coarse value; the moving wall's peak pressure (a sample of its ring) hollow,
    the pressures on a symmetric log axis."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), layout="constrained")
    for ax, (column, title, _, _) in zip(axes, QUANTITIES):
        for k, c in enumerate(CONFIGS):
            pts = []
            for t in TIMES:
                coarse = at(summaries.get(f"{c}_coarse"), t, column)
                fine = at(summaries.get(f"{c}_fine"), t, column)
                if coarse and fine is not None:
                    pts.append((t, 100 * (fine - coarse) / coarse))
            ring = column == "peak_pressure" and c.startswith("moving")
            if pts:
                ax.plot(*zip(*pts), marker="o", color=f"C{k}", label=LABELS[c],
                        mfc="none" if ring else f"C{k}", ls=":" if ring else "-")  # fmt: skip
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xscale("log")
        if column == "peak_pressure":  # the ring's samples move by up to ~100 %
            ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xlabel("t (s)")
        ax.set_title(title.split(": ")[1])
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("(fine − coarse) / coarse (%)")
    axes[-1].legend(fontsize=7)
    plot.save_figure(fig, path, dpi=130)
    return path


RECIRCULATION_TIME = 0.1
"""Figure 9's time: the recirculation zone is developed (its lengths are in the findings)."""


def chosen(summaries: dict, c: str) -> dict | None:
    """The summary of configuration ``c``'s fine run if that run finished, else its coarse
    run's: the run Figures 7–9 show."""
    fine = summaries.get(f"{c}_fine")
    return fine if finished(fine) else summaries.get(f"{c}_coarse")


def _kept(run, path: Path) -> bool:
    """Whether a figure at ``path`` can be shown: drawn from the run folder ``run`` if it is
    here, else the committed picture if there is one (its caption is read from the summary)."""
    return run is not None or path.is_file()


FIGURE_OF_WALL = {"moving": 7, "fixed": 8}
"""The study's Figure 7 shows the moving wall, Figure 8 the fixed wall."""


def warp_for(displacement: float) -> float:
    """The power of ten that draws the largest ``displacement`` (m) as 0.5–5 mm: visible, and
    short of folding the 1 mm wall or the 3.5 mm plaque."""
    return 10.0 ** max(0, math.ceil(math.log10(0.5e-3 / max(displacement, 1e-30))))


def field_figures(runs: dict, summaries: dict, figures: Path) -> list[tuple[str, Path]]:
    """Figures 7–9 from the field files (fsi/output/field_files.py): σ₁₂ on the deformed structure
    of each configuration at the time of the plaque's largest |σ₁₂|, the colours spanning the
    plaque's range (a larger value elsewhere, the moving wall's singular clamped corner, shows
    saturated and is marked); the velocity's streamlines of the Carreau runs (the study's
    Figure 9 is Carreau) at t = RECIRCULATION_TIME, and the wall shear stress along the
    diseased wall. Each figure is drawn when its run folder is here, else the committed one is
    kept (``--document-only`` from the summaries); its caption comes from the summary."""
    out = []
    for c in sorted(CONFIGS, key=lambda c: FIGURE_OF_WALL[c.split("_")[0]]):
        s = chosen(summaries, c)
        if s is None:
            continue
        figure = _stress_figure(c, runs.get(s["name"]), s, figures)
        if figure is not None:
            out.append(figure)
    for c in ("fixed_carreau", "moving_carreau"):
        s = chosen(summaries, c)
        path = figures / f"study_streamlines_{c}.png"
        if s is None or s["end_time_s"] < RECIRCULATION_TIME:
            continue
        run = runs.get(s["name"])
        if not _kept(run, path):
            continue
        if run is not None:
            plot.field_snapshot(run.path, "velocity", RECIRCULATION_TIME, path, streamlines=True)
        out.append(
            (
                f"Figure 9: velocity and streamlines, {LABELS[c]} ({s['name']}), "
                f"t = {RECIRCULATION_TIME:g} s (Carreau, as the study's Figure 9; the Newtonian "
                "runs' recirculation lengths are in the findings)",
                path,
            )
        )
    wss = figure_wall_shear(runs, summaries, figures / "study_figure9_wss.png")
    if wss is not None:
        out.append(
            (
                f"Figure 9: wall shear stress along the diseased (lower) wall at t = "
                f"{RECIRCULATION_TIME:g} s; negative where the flow next to the wall "
                "reverses (the recirculation zone)",
                wss,
            )
        )
    return out


STUDY_WARP = 100.0
"""The study's Figures 7–8 magnify the displacement ×100 (docs/model.md §6)."""


def _stress_figure(c: str, run, s: dict, figures: Path) -> tuple[str, Path] | None:
    """Figure 7 or 8 of configuration ``c``: σ₁₂ on the deformed structure of the run of
    summary ``s`` at the time of the plaque's largest |σ₁₂|, drawn into ``figures`` from its run
    folder ``run`` (None: the committed picture kept); its caption and path, or None without a
    plaque maximum, the structure's |η| then, or a picture."""
    wall = c.split("_")[0]
    plaque, whole, where = peak(s, "plaque_sss"), peak(s, "max_sss"), s.get("largest_sss_at")
    eta = (s.get("plaque_sss_at") or {}).get("peak_displacement")
    if eta is None and run is not None and plaque is not None:
        eta = report.value_at(run.rows, plaque[1], "peak_displacement")
    path = figures / f"study_sss_{c}.png"
    if plaque is None or eta is None or not _kept(run, path):
        return None
    marks, marked = [], ""
    corner = where is not None and where.get("place", "clamped_corner") == "clamped_corner"
    if corner and where["region"] == "wall" and whole[0] > plaque[0]:
        marks.append((where["x"], where["y"], "clamped corner (singular)"))
        marked = (
            f"; the cross marks the clamped corner where the whole structure's largest "
            f"|σ₁₂|, {whole[0]:.4g} Pa at t = {whole[1]:.4g} s, sits (a singularity of the "
            "boundary conditions, see the findings)"
        )
    warp = warp_for(eta)
    if run is not None:
        plot.field_snapshot(
            run.path, "sss", plaque[1], path, warp=warp, limit=plaque[0], marks=marks
        )
    return (
        f"Figure {FIGURE_OF_WALL[wall]}: σ₁₂ on the structure, {LABELS[c]} "
        f"({s['name']}), displacement ×{warp:g} (the study draws ×{STUDY_WARP:g}, which "
        f"would draw this run's largest |η| as {1e3 * STUDY_WARP * eta:.2g} mm; ×{warp:g} "
        f"draws it as {1e3 * warp * eta:.2g} mm), at t = {plaque[1]:.4g} s, "
        f"when the plaque's |σ₁₂| is largest ({plaque[0]:.4g} Pa); the colours span "
        f"±{plaque[0]:.4g} Pa{marked}",
        path,
    )


def boundary_nodes(triangles: np.ndarray) -> np.ndarray:
    """The nodes on the boundary of a triangulation: those of edges that belong to one
    triangle only."""
    edges = np.sort(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1
    )
    unique, count = np.unique(edges, axis=0, return_counts=True)
    return np.unique(unique[count == 1])


def figure_wall_shear(runs: dict, summaries: dict, path: Path) -> Path | None:
    """The signed wall shear stress along the lower wall (the plaque's side) against x, one
    line per configuration, at t = RECIRCULATION_TIME."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 3.6), layout="constrained")
    drawn = False
    shown = [chosen(summaries, c) for c in CONFIGS]
    for k, (c, s) in enumerate(zip(CONFIGS, shown)):
        run = None if s is None else runs.get(s["name"])
        if run is None or run.rows[-1]["t"] < RECIRCULATION_TIME:
            continue
        snap = field_files.read_field(run.path, "wall_shear_stress", RECIRCULATION_TIME)
        x, y = snap.coordinates[:, 0], snap.coordinates[:, 1]
        nodes = boundary_nodes(snap.triangles)
        lower = nodes[
            (y[nodes] < 0.5 * (y.min() + y.max())) & (x[nodes] > x.min()) & (x[nodes] < x.max())
        ]  # not the inlet's and outlet's corners
        order = np.argsort(x[lower])
        ax.plot(
            1e3 * x[lower][order],
            snap.values[lower][order],
            color=f"C{k}",
            lw=1.2,
            label=f"{LABELS[c]} ({run.path.name})",
        )
        drawn = True
    if not drawn:
        plt.close(fig)
        here = any(s is not None and s["name"] in runs for s in shown)
        return path if path.is_file() and not here else None  # the committed one, kept
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("wall shear stress (Pa)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    plot.save_figure(fig, path, dpi=130)
    return path
