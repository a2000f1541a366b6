"""docs/study.md, docs/study_tables.csv, docs/study_runs/*.json and docs/figures/study_*.png from
the run folders of scripts/reproduce_study.py (the figures: fsi/study/figures.py).

Each run folder is first reduced to a summary (fsi/study/runs.py): its provenance (git
commit, ranks, command), its resolved configuration, the three peaks at the study's report
times and the maxima the findings rest on. The summaries are committed (docs/study_runs/), and
the tables, the CSV and the text are made from them and the configurations their runs ran
(``runs.run_case``) alone, so a reader can check every number without rerunning; only the
figures read the run folders (metrics.csv and the field files; without them the committed
figures stay). A run that is missing or unfinished shows as '–' (and is listed), so the
document can be written at any stage; a summary already in docs/study_runs/ stands in for a run
folder that is not there. The sections that explain the differences from the study are
fsi/study/analyses.py's.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from fsi.study import analyses as study_analyses
from fsi.study import locations, plausible, sensitivity
from fsi.study.figures import field_figures, figure_convergence, figure_sss
from fsi.study.findings import findings
from fsi.study.runs import (
    CONFIGS,
    LABELS,
    PAPER_QUANTITY,
    QUANTITIES,
    TIMES,
    at,
    change,
    comparison_rows,
    difference,
    finished,
    fmt,
    load,
    make_summaries,
    paper_values,
    run_case,
    schedule_text,
    span,
    write_comparison_csv,
)

# --------------------------------------------------------------------------------------------
# The study's tables beside ours


def _by_key(rows: Sequence[dict], quantity: str) -> dict[tuple, dict]:
    """The comparison rows of ``quantity`` by (wall, fluid, t, mesh)."""
    return {
        (r["wall"], r["fluid"], r["t_s"], r["mesh"]): r for r in rows if r["quantity"] == quantity
    }


def paper_table(rows: Sequence[dict], quantity: str, scale: float) -> str:
    """The study's values beside ours, per configuration and report time: paper | fsi |
    difference on the coarse and the fine mesh."""
    key = _by_key(rows, quantity)
    lines = [
        "| configuration | t (s) | paper coarse | fsi coarse | difference | paper fine | fsi fine"
        " | difference |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in CONFIGS:
        wall, fluid = c.split("_")
        for t in TIMES:
            cells = []
            for mesh in ("coarse", "fine"):
                r = key[(wall, fluid, t, mesh)]
                d = difference(r)
                mark = " †" if (r["where"] or {}).get("place") else ""
                cells += [
                    fmt(scale * r["paper"]),
                    fmt(None if r["fsi"] is None else scale * r["fsi"]) + mark,
                    "–" if d is None else f"{100 * d:+.0f} %",
                ]
            lines.append(f"| {LABELS[c]} | {t:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def at_boundaries(rows: Sequence[dict], quantity: str) -> str:
    """The values of ``quantity`` (marked † in its table) whose maximum sits at a boundary's
    corner or an open boundary's edge, each with the place and position its run's summary
    gives, and the runs whose summaries keep no places."""
    flagged, unknown = [], set()
    for r in rows:
        if r["quantity"] != quantity or r["fsi"] is None:
            continue
        found = r["where"]
        run = f"{r['wall']}_{r['fluid']}_{r['mesh']}"
        if found is None:
            unknown.add(run)
        elif found["place"]:
            flagged.append(
                f"{run} at {r['t_s']:g} s: {locations.describe(found['place'])} (x = "
                f"{locations.mm(found['x'])} mm, y = {locations.mm(found['y'])} mm)"
            )
    text = []
    if flagged:
        text.append(
            "† The maximum sits at a boundary's corner or an open boundary's edge (the "
            "summaries' `where`), where a nodal value is the discretisation's as much as the "
            "flow's: " + "; ".join(flagged) + "."
        )
    else:
        text.append(
            "No maximum of this table sits at a boundary's corner or an open boundary's edge "
            "(the summaries' `where`)"
            + (" of the runs that keep their places." if unknown else ".")
        )
    if unknown:
        text.append(
            "Not located (summaries made before the places were kept): "
            + ", ".join(sorted(unknown))
            + "."
        )
    return " ".join(text)


def paper_mesh_changes(rows: Sequence[dict], quantity: str, limit: float = 0.1) -> str:
    """Where the study's own coarse → fine change of a printed value exceeds ``limit``: there
    its two meshes differ as much as a difference from it means, with ours beside."""
    key = _by_key(rows, quantity)
    found = []
    for c in CONFIGS:
        wall, fluid = c.split("_")
        for t in TIMES:
            coarse, fine = key[(wall, fluid, t, "coarse")], key[(wall, fluid, t, "fine")]
            if abs(fine["paper"] / coarse["paper"] - 1) > limit:
                ours = (
                    ""
                    if coarse["fsi"] is None or fine["fsi"] is None
                    else f", fsi {change(coarse['fsi'], fine['fsi'])}"
                )
                found.append(
                    f"{LABELS[c]} at {t:g} s (study {change(coarse['paper'], fine['paper'])}{ours})"
                )
    if not found:
        return ""
    return (
        f"The study's own values change by more than {100 * limit:g} % from its coarse to its "
        "fine mesh at: " + "; ".join(found) + ". There a difference from either of its meshes "
        "is within its own discretisation error."
    )


def agreement(
    rows: Sequence[dict], quantity: str | None = None, limit: float = plausible.LIMIT
) -> str:
    """How many of the printed values ours is within ``limit`` of: "k of n values" (and how
    many have no run)."""
    chosen = [r for r in rows if quantity is None or r["quantity"] == quantity]
    compared = [d for d in map(difference, chosen) if d is not None]
    close = sum(abs(d) <= limit for d in compared)
    return f"{close} of {len(chosen)} values" + (
        "" if len(compared) == len(chosen) else f" ({len(chosen) - len(compared)} without a run)"
    )


# --------------------------------------------------------------------------------------------
# Tables


def printed_table(summaries: dict) -> str:
    lines = [
        "| t (s) | "
        + " | ".join(f"{LABELS[c]}: |u| (m/s), p (Pa), |η| (µm)" for c in CONFIGS)
        + " |",
        "|---" * (1 + len(CONFIGS)) + "|",
    ]
    for t in TIMES:
        cells = []
        for c in CONFIGS:
            s = summaries.get(f"{c}_coarse_printed")
            u, p, d = (at(s, t, k) for k in ("peak_velocity", "peak_pressure", "peak_displacement"))
            cells.append(f"{fmt(u)}, {fmt(p)}, {fmt(None if d is None else 1e6 * d)}")
        lines.append(f"| {t:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def effort_table(summaries: dict, order: Sequence[str]) -> str:
    lines = [
        "| run | git | steps | simulated (s) | ranks | coupling its/step | wall time (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in order:
        s = summaries.get(name)
        if s is None:
            lines.append(f"| {name} | not run | | | | | |")
            continue
        state = "" if s["finished"] else " (unfinished)"
        lines.append(
            f"| {name} | {(s['git'] or '–')[:7]} | {s['steps']}{state} | {fmt(s['end_time_s'])}"
            f" | {s['ranks'] or '–'} | {fmt(s['mean_coupling_iterations'], 3)}"
            f" | {s['wall_time_s']:.0f} |"
        )
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------


def same_answers(summaries: dict, extra: dict) -> str:
    """Evidence that the runs made at different commits and rank counts give the same answers:
    the coarse fixed-wall Newtonian case as a study run and as the degree analysis's 0.5 run."""
    a = summaries.get("fixed_newtonian_coarse")
    b = extra.get("degree", {}).get("degree/degree=0.5")
    if a is None or b is None or a["git"] == b["git"]:
        return ""
    worst = max(
        abs(at(b, t, c) / at(a, t, c) - 1)
        for t in TIMES
        if t <= 0.1
        for c, *_ in QUANTITIES
        if at(a, t, c) and at(b, t, c) is not None
    )
    return (
        f" (the commits differ in the scripts, the documents and fsi options these runs leave "
        f"at their defaults: the coarse fixed-wall Newtonian case run at {a['git'][:7]} on "
        f"{a['ranks']} rank(s) and at {b['git'][:7]} on {b['ranks']} has "
        + (
            "the same peaks at 10–100 ms to the last digit)"
            if worst == 0
            else f"its peaks at 10–100 ms within {worst:.0e} of each other)"
        )
    )


def _shown(folder: Path) -> str:
    """``folder`` relative to the checkout when it is inside it."""
    root = Path(__file__).resolve().parents[2]
    try:  # absolute(), not resolve(): results/study may be a link to runs kept elsewhere
        return str(folder.absolute().relative_to(root))
    except ValueError:
        return str(folder)


def write(folder: Path, study_runs, docs: Path, analyses: dict | None = None) -> Path:
    """docs/study.md (and its CSV, summaries and figures) from the study's runs and the
    ``analyses`` (scripts/reproduce_study.py's ANALYSES) in ``folder``."""
    figures = docs / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    runs = load(folder, study_runs)
    names = [r.name for r in study_runs]
    summaries = make_summaries(runs, docs / "study_runs", names)
    extra = study_analyses.summaries(folder, analyses or {}, docs / "study_runs")
    paper = paper_values()
    missing = [n for n in names if not finished(summaries.get(n))]
    rows = comparison_rows(summaries, paper)
    table_csv = write_comparison_csv(rows, docs / "study_tables.csv")
    parts = _opening(folder, summaries, extra, missing)
    parts += _tables(rows, table_csv, summaries, extra, paper, docs)
    parts.append(plausible.section(summaries, extra, paper) + "\n")
    parts += _convergence_and_changes(summaries, extra, figures)
    parts += _figures(runs, summaries, figures)
    parts += _findings(summaries, paper, extra)
    parts.append(
        "## Wall time on this machine (2 cores)\n\n"
        "Sum of the steps' wall times (metrics.csv), without start-up (mesh, "
        "compilation), as measured: the 2 cores were at times shared with other jobs "
        "(tests, the other runs' start-up), which can slow a run several-fold, so "
        "these are upper bounds; #11's benchmarks time unloaded runs.\n\n"
        + effort_table(summaries, names)
        + "\n"
    )
    path = docs / "study.md"
    path.write_text("\n".join(parts))
    return path


def _opening(folder: Path, summaries: dict, extra: dict, missing: list[str]) -> list[str]:
    """The document's title, where its numbers come from, and what is not finished yet."""
    everything = [*summaries.values(), *(s for runs in extra.values() for s in runs.values())]
    commits = sorted({s["git"][:7] for s in everything if s.get("git")})
    parts = [
        "# The study reproduced\n",
        "Generated by `scripts/reproduce_study.py` from the runs in "
        f"`{_shown(folder)}/`, through their summaries in `docs/study_runs/`: every number "
        "below about a run is read from its summary or computed from the configuration it ran "
        "(the summary's `config`, or its command's case file and overrides: "
        "`fsi.study.runs.run_case`). The four configurations of docs/model.md §4 on the "
        f"coarse and the fine mesh to {_ends(summaries)}, with the shipped configs' resolved "
        f"schedule ({_schedule(summaries, printed=False)}; why: docs/wall-damping.md), and "
        f"with the study's printed schedule ({_schedule(summaries, printed=True)}) on the "
        f"coarse mesh; {_ranks(summaries)}. "
        f"Made with fsi at git {', '.join(commits) or '–'}{same_answers(summaries, extra)}.\n",
    ]
    if missing:
        parts.append("**Not finished yet** (shown as '–'): " + ", ".join(missing) + ".\n")
    return parts


def _schedule(summaries: dict, printed: bool) -> str:
    """The step schedule of the study's runs on the printed (else the resolved) schedule, from
    the configurations they ran; each with its runs where they differ."""
    found: dict[str, list[str]] = {}
    for name, s in summaries.items():
        if name.endswith("_printed") == printed:
            found.setdefault(schedule_text(run_case(s)), []).append(name)
    if len(found) <= 1:
        return next(iter(found), "–")
    return "; ".join(f"{text} ({', '.join(sorted(n))})" for text, n in found.items())


def _ends(summaries: dict) -> str:
    """Where the study's runs end (t = 0.8 s, the whole heartbeat), from their configurations."""
    ends = sorted({run_case(s).time.end for s in summaries.values()})
    return " and ".join(f"t = {t:g} s" for t in ends) + (
        " (the whole heartbeat)" if len(ends) == 1 else ""
    )


def _ranks(summaries: dict) -> str:
    """On how many MPI ranks the study's runs ran, from their summaries."""
    by_ranks: dict = {}
    for name, s in summaries.items():
        by_ranks.setdefault(s.get("ranks"), []).append(name)
    return "; ".join(
        f"on {k or '–'} MPI rank{'s' if (k or 0) > 1 else ''}: " + ", ".join(sorted(names))
        for k, names in sorted(by_ranks.items(), key=lambda kv: kv[0] or 0)
    )


def _tables(
    rows, table_csv: Path, summaries: dict, extra: dict, paper: dict, docs: Path
) -> list[str]:
    """Tables 1–3 beside the study's, each with the sections that explain the differences."""
    parts = []
    parts.append(
        "## Tables 1–3 beside the study's\n\n"
        f"The study's printed values (docs/reference/boujena2014_tables.csv) and ours, also "
        f"in [`{table_csv.name}`]({table_csv.name}) (SI units); difference = (fsi − paper) / "
        f"paper. fsi is within {100 * plausible.LIMIT:g} % of the paper for {agreement(rows)}.\n"
    )
    explain = study_analyses.explanations(extra, summaries, paper, docs / "study_runs")
    for (_, title, unit, scale), quantity in zip(QUANTITIES, PAPER_QUANTITY):
        parts.append(
            f"### {title} ({unit})\n\n{paper_table(rows, quantity, scale)}\n\n"
            f"fsi is within {100 * plausible.LIMIT:g} % of the paper for "
            f"{agreement(rows, quantity)}.\n"
        )
        parts.append(at_boundaries(rows, quantity) + "\n")
        meshes = paper_mesh_changes(rows, quantity)
        parts += [f"{meshes}\n"] if meshes else []
        parts += [f"{section}\n" for section in explain[quantity]]
    return parts


def _convergence_and_changes(summaries: dict, extra: dict, figures: Path) -> list[str]:
    """The mesh and step convergence, what the physiological-flow settings changed and the
    study's printed schedule."""
    parts = []
    parts.append("## Mesh and step convergence\n")
    conv = figure_convergence(summaries, figures / "study_mesh_convergence.png")
    parts.append(
        "Mesh convergence: the coarse → fine change of each peak at the report times, relative "
        "to the coarse value; the moving wall's peak pressure, the ringing wall's sample "
        "(Table 2's section), hollow. "
        + sensitivity.mesh_changes(summaries)
        + f"\n\n![mesh convergence](figures/{conv.name})\n"
    )
    parts.append(sensitivity.pressure_convergence(extra.get("convergence", {}), summaries) + "\n")
    parts.append(
        "Of the stress maxima:\n\n"
        + sensitivity.convergence(extra.get("convergence", {}), summaries)
        + "\n"
    )
    parts.append(
        "## What the physiological-flow settings changed (fine mesh)\n\n"
        + sensitivity.settings_changes(
            summaries, extra.get("earlier", {}), extra.get("inlet", {}), extra.get("p10", {})
        )
    )
    parts.append("## The study's printed schedule (coarse mesh)\n\n" + _printed(summaries) + "\n")
    return parts


def _printed(summaries: dict) -> str:
    """Why the printed schedule's runs stay at rest: its first step against the inlet pulse,
    both read from their configurations; and their peaks."""
    cases = [run_case(s) for n, s in summaries.items() if n.endswith("_printed")]
    first = {c.time.schedule[0].dt for c in cases}
    pulse = {getattr(c.fluid.inlet, "duration", None) for c in cases}
    if len(first) != 1 or len(pulse) != 1 or None in pulse:
        return printed_table(summaries)
    dt, duration = first.pop(), pulse.pop()
    whole = (
        "is the whole inlet pulse, which is back to 0 at t = "
        f"{span(duration)}: the fluid's backward-Euler/BDF step sees P({span(dt)}) = 0"
        if dt >= duration
        else f"is shorter than the inlet pulse ({span(duration)})"
    )
    return (
        f"Its first step, {span(dt)}, {whole}{_at_rest(summaries)} (docs/model.md §4).\n\n"
        + printed_table(summaries)
    )


def _at_rest(summaries: dict) -> str:
    """Whether every peak of the printed-schedule runs is 0 at every report time."""
    values = [
        at(summaries.get(f"{c}_coarse_printed"), t, column)
        for c in CONFIGS
        for t in TIMES
        for column, *_ in QUANTITIES
    ]
    if None in values:
        return ""
    moving = sum(v != 0 for v in values)
    return (
        f": every peak of the {len(CONFIGS)} runs is 0 at every report time (they stay at rest)"
        if moving == 0
        else f": {moving} of the {len(values)} peaks are not 0"
    )


def _figures(runs: dict, summaries: dict, figures: Path) -> list[str]:
    """The study's Figure 6 and Figures 7–9, drawn into ``figures``."""
    parts = []
    fig6 = figure_sss(runs, figures / "study_figure6_sss.png")
    parts.append(
        "## Figure 6: the maximum structural shear stress over time\n\n"
        f"![Figure 6](figures/{fig6.name})\n\n" + figure6_caption(summaries) + "\n"
    )
    fields = field_figures(runs, summaries, figures)
    if fields:
        parts.append("## Figures 7–9: fields\n")
        for caption, path in fields:
            parts.append(f"{caption}\n\n![{path.stem}](figures/{path.name})\n")
    return parts


def figure6_caption(summaries: dict) -> str:
    """Figure 6's caption, its numbers read from the summaries: how far the fixed-wall curves lie
    below the moving-wall ones, how close the rheologies are, and where the whole structure's
    maximum sits."""
    from fsi.study.runs import peak

    def largest(name, what="plaque_sss"):
        found = peak(summaries.get(name), what)
        return None if found is None else found[0]

    below = [
        largest(f"moving_newtonian_{m}") / largest(f"fixed_newtonian_{m}")
        for m in ("coarse", "fine")
        if largest(f"moving_newtonian_{m}") and largest(f"fixed_newtonian_{m}")
    ]
    rheology = [
        abs(largest(f"{w}_carreau_{m}") / largest(f"{w}_newtonian_{m}") - 1)
        for w in ("fixed", "moving")
        for m in ("coarse", "fine")
        if largest(f"{w}_carreau_{m}") and largest(f"{w}_newtonian_{m}")
    ]
    corner = []
    for m in ("coarse", "fine"):
        s = summaries.get(f"moving_newtonian_{m}") or {}
        cell = s.get("largest_sss_at")
        if cell is not None and largest(f"moving_newtonian_{m}", "max_sss"):
            corner.append(
                f"{m}: {largest(f'moving_newtonian_{m}', 'max_sss'):.4g} Pa at x = "
                f"{locations.mm(cell['x'])} mm, y = {locations.mm(cell['y'])} mm, "
                + (locations.describe(cell.get("place")) or "not at a clamped corner")
            )
    return (
        "The largest |σ₁₂| of the plaque (cap and lipid pool; coloured) and, for the moving "
        "wall, of the whole structure (wall and plaque, the study's Figure 6 quantity; black, "
        "Newtonian): left the pulse and the wall's first response on a linear time axis, right "
        "the whole beat on a log one; log stress. The moving wall's plaque maximum is "
        + (f"{min(below):.3g}–{max(below):.3g}×" if below else "–")
        + " the fixed wall's (Newtonian, coarse–fine). Newtonian wide and light, Carreau "
        "narrow and dark on top, coarse solid, fine dashed: the rheologies' plaque maxima differ "
        + (f"by at most {100 * max(rheology):.2g} %" if rheology else "by –")
        + ", so the lower row gives their ratio. The whole structure's maximum ("
        + ("; ".join(corner) or "not located")
        + (
            ") sits where the clamped end meets the loaded lumen: the elastic stress is "
            "singular there and grows with the mesh (the findings), so the plaque's curves are "
            "the ones to compare."
            if corner and all("clamped end's corner" in c for c in corner)
            else "): see the findings."
        )
    )


def _findings(summaries: dict, paper: dict, extra: dict) -> list[str]:
    """The study's findings, checked, and the recirculation zone with the outlet further
    downstream."""
    parts = []
    parts.append(
        "## The study's findings, checked\n\n"
        "All on one mesh, as they compare configurations: the fine one once its four "
        "runs have finished, else the coarse one (the run is named beside its "
        "numbers).\n\n"
        + "\n".join(f"- {f}" for f in findings(summaries, paper, extra.get("convergence")))
        + "\n\nThe recirculation zone with the outlet further downstream (the last finding): "
        f"the fixed wall with {_longer(extra.get('downstream', {}), summaries)}, its inlet "
        "pulse scaled by the blood column's "
        "effective length so that the pulse's impulse moves the longer column as fast (a "
        "pressure pulse into a longer column drives a slower flow; item 4 has the estimate); "
        "the moving wall lengthened as it is becomes another wall (clamped further apart it is "
        "far softer: its largest |η|), so it is not compared (`--only analyses --analysis "
        "downstream`):\n\n" + sensitivity.downstream(extra.get("downstream", {}), summaries) + "\n"
    )
    return parts


def _longer(downstream: dict, summaries: dict) -> str:
    """How the downstream analysis lengthens the segment, from its runs' geometries: "the
    segment 1 and 2 cm longer downstream (`geometry.length`, `geometry.stenosis_centre:
    0.01`)"."""
    base = summaries.get("fixed_newtonian_coarse")
    runs = [s for n, s in downstream.items() if n.startswith("downstream/fixed_")]
    if base is None or not runs:
        return "the segment longer downstream (not run)"
    g0 = base["case"]["geometry"]
    extra = sorted({s["case"]["geometry"]["length"] - g0["length"] for s in runs})
    centres = {s["case"]["geometry"]["stenosis_centre"] for s in runs}
    centre = f"`geometry.stenosis_centre: {centres.pop():g}`" if len(centres) == 1 else "its centre"
    return (
        f"the segment {' and '.join(f'{100 * e:.3g}' for e in extra)} cm longer downstream "
        f"(`geometry.length`, {centre})"
    )
