"""The sections of docs/study.md on the wall's displacement (fsi/study/analyses.py composes
them with the others): the structure alone under a uniform lumen pressure
(:func:`static_compliance`), why the fixed wall's displacement differs from the study's
(:func:`compliance`) and why the moving wall's does (:func:`damping`, a ringing wall), with the
small helpers every analysis formats its numbers with.

Every threshold a verdict uses is stated beside it; the study's values come from
docs/reference/boujena2014_tables.csv.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from fsi.study.runs import (
    PAPER_QUANTITY,
    PULSE_AMPLITUDE,
    TIMES,
    at,
    fmt,
)

Summaries = dict[str, dict]


STATIC_PRESSURE = 1000.0
"""Pa: the uniform lumen pressure of :func:`static_compliance` (the elastic response is linear
to 0.1 % at this load: 0.44 mm on a 1 mm wall)."""


def static_compliance(docs_runs: Path) -> dict[str, float]:
    """The structure's displacement per Pa of a uniform pressure on its lumen side, quasi-static
    (no inertia, no flow): the fixed wall's (plaque only) and the moving wall's peak |η| under
    :data:`STATIC_PRESSURE`, coarse mesh, in m/Pa. Computed once and kept in
    ``docs_runs/static_compliance.json``."""
    path = docs_runs / "static_compliance.json"
    if path.is_file():
        return json.loads(path.read_text())
    config_file = Path(__file__).resolve().parents[2] / "configs" / "stenosis_moving_newtonian.yaml"
    out = {
        mode: uniform_pressure_compliance(config_file, mode)
        for mode in ("fixed_wall", "moving_wall")
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1) + "\n")
    return out


def uniform_pressure_compliance(config_file: Path, mode: str) -> float:
    """The peak |η| per Pa (m/Pa) of the case's structure in ``mode`` under a uniform lumen
    pressure of :data:`STATIC_PRESSURE`, quasi-static, on the config's mesh."""
    from fsi import config
    from fsi.physics import mesh, solid

    case = config.load(
        config_file, [f"structure.mode={mode}", "structure.time_integration={scheme: quasi_static}"]
    )
    structure = solid.build(case, mesh.build(case), pressure=lambda t: STATIC_PRESSURE)
    if not structure.step(1.0, 1.0).converged:
        raise RuntimeError(f"static compliance: the {mode} solve of {config_file} did not converge")
    return structure.max_displacement() / STATIC_PRESSURE


def ratio(s: dict | None, t: float) -> float | None:
    """Peak |η| per Pa of peak pressure at report time ``t`` (m/Pa)."""
    d, p = at(s, t, "peak_displacement"), at(s, t, "peak_pressure")
    return None if d is None or not p else d / p


def paper_value(
    paper: dict, quantity: str, t: float, wall: str, mesh: str, fluid: str = "newtonian"
) -> float:
    return paper[(quantity, t, wall, fluid, mesh)]


def paper_ratio(paper: dict, t: float, wall: str, mesh: str, fluid: str = "newtonian") -> float:
    """The study's peak |η| per Pa of peak pressure (m/Pa)."""
    return paper_value(paper, "displacement", t, wall, mesh, fluid) / paper_value(
        paper, "pressure", t, wall, mesh, fluid
    )


def range_from_paper(
    main: Summaries, paper: dict, quantity: str, t: float
) -> tuple[float, float] | None:
    """The smallest and largest (fsi − paper) / paper of ``quantity`` at ``t`` over the eight
    runs of the study (None: a run missing)."""
    column = PAPER_QUANTITY[quantity]
    found = []
    for wall in ("fixed", "moving"):
        for fluid in ("newtonian", "carreau"):
            for mesh in ("coarse", "fine"):
                ours = at(main.get(f"{wall}_{fluid}_{mesh}"), t, column)
                if ours is None:
                    return None
                found.append(ours / paper_value(paper, quantity, t, wall, mesh, fluid) - 1)
    return min(found), max(found)


def percent_range(found: tuple[float, float] | None) -> str:
    """ "a–b %" of the magnitudes of a same-signed range."""
    if found is None:
        return "–"
    lo, hi = sorted(abs(100 * x) for x in found)
    return f"{lo:.0f}–{hi:.0f} %"


def in_um(x: float | None) -> str:
    return fmt(None if x is None else 1e6 * x, 3)


# --------------------------------------------------------------------------------------------
# 1. The fixed wall's compliance


def compliance(
    shape: Summaries,
    others: Summaries,
    main: Summaries,
    paper: dict,
    static: dict[str, float],
    plane: Summaries | None = None,
) -> str:
    """Which readings of the plaque's shape (and of "fixed wall") give the study's displacement
    per Pa at 10 ms; the velocity each gives, since the shape sets it too."""
    t = 0.01
    target = paper_ratio(paper, t, "fixed", "coarse")
    u_paper = paper_value(paper, "velocity", t, "fixed", "coarse")
    shipped = ratio(main.get("fixed_newtonian_coarse"), t)
    by_degree: dict[float, list[dict]] = {}
    for s in shape.values():
        if ratio(s, t) is not None:
            by_degree.setdefault(s["case"]["geometry"]["stenosis_degree"], []).append(s)
    if not by_degree or shipped is None:
        return "(runs missing)"
    lines, best, spread = _shape_table(by_degree, t, target)
    swept = {
        key: sorted({s["case"]["geometry"][key] for s in shape.values()})
        for key in ("stenosis_degree", "cap_thickness", "lipid_length")
    }
    text = [
        _fixed_wall_paragraph(main, paper, static, target, shipped),
        "",
        "The study states neither the stenosis degree, nor the cap thickness, nor the lipid "
        "pool's size (docs/model.md §1). `fsi sweep` of the three (degree "
        f"{', '.join(f'{d:g}' for d in swept['stenosis_degree'])} × cap "
        f"{', '.join(f'{1e3 * c:g}' for c in swept['cap_thickness'])} mm × lipid pool "
        f"{', '.join(f'{1e3 * c:g}' for c in swept['lipid_length'])} mm) on the coarse "
        "fixed-wall Newtonian case to 10 ms (`scripts/reproduce_study.py --only analyses "
        "--analysis compliance`):",
        "",
        "\n".join(lines),
        "",
        f"The cap and the lipid pool move |η| / p by at most {100 * spread:.2g} % at a "
        "degree (the last column: the largest relative spread over the cap × lipid-pool "
        "combinations of a degree): the study prints one modulus for the whole plaque "
        "(1.6 MPa, ν = 0.45), so the line between cap and lipid pool is not a material "
        "boundary, and only the plaque's outline counts. "
        f"The most compliant degree, {best[0]:g}, moves {fmt(1e6 * best[1], 2)} µm/Pa, "
        f"still {fmt(target / best[1], 2)}× below the study's, and its jet ({fmt(best[2], 3)} "
        f"m/s at 10 ms) is {fmt(best[2] / u_paper, 2)}× the study's {u_paper:g} m/s: the degree "
        "that would bring the displacement closer takes the velocity away.",
    ]
    readings, best = _other_readings(others, plane, t, target, shipped, best)
    text += readings
    verdict = (
        "No plausible reading of what the study leaves open reproduces its fixed-wall compliance"
        if best[1] < target / 2
        else "A reading within a factor 2 of the study's compliance exists"
    )
    text.append(
        f"\n**{verdict}** (within a factor 2; the closest is {fmt(target / best[1], 2)}× "
        "below). We do not change printed parameters to match the study's tables."
    )
    return "\n".join(text)


def _fixed_wall_paragraph(
    main: Summaries, paper: dict, static: dict[str, float], target: float, shipped: float
) -> str:
    """The study's fixed wall's displacement per Pa at 10 ms beside fsi's, in the flow and
    under a uniform pressure."""
    t = 0.01
    fine = ratio(main.get("fixed_newtonian_fine"), t)
    mesh_change = "" if fine is None else f"; fine mesh {100 * (fine / shipped - 1):+.1f} %"
    printed = {
        q: [
            paper_value(paper, q, t, "fixed", m, f)
            for m in ("coarse", "fine")
            for f in ("newtonian", "carreau")
        ]
        for q in ("displacement", "pressure")
    }
    return (
        f"The study's fixed wall moves by {in_um(min(printed['displacement']))}–"
        f"{in_um(max(printed['displacement']))} µm at 10 ms under a peak pressure of "
        f"{min(printed['pressure']):.2g}–{max(printed['pressure']):.2g} Pa: "
        f"{fmt(1e6 * target, 2)} µm per Pa (coarse; "
        f"{fmt(1e6 * paper_ratio(paper, t, 'fixed', 'fine'), 2)} fine), and "
        f"{fmt(1e6 * paper_ratio(paper, 0.1, 'fixed', 'coarse'), 2)} µm/Pa at 0.1 s. fsi's "
        f"moves {fmt(1e6 * shipped, 2)} µm/Pa at 10 ms (fixed_newtonian_coarse{mesh_change}), "
        f"{fmt(target / shipped, 2)}× less. Under a "
        "uniform pressure, with no flow and no inertia, the shipped plaque moves only "
        f"{fmt(1e6 * static['fixed_wall'], 2)} µm per Pa (`static_compliance` in "
        f"fsi/study/wall_analyses.py), {fmt(shipped / static['fixed_wall'], 2)}× less than in "
        "the flow: a plaque of ν = 0.45 bonded to a rigid wall hardly compresses, and what "
        "moves it is the flow's pressure differences along it and its shear, not the "
        "pressure level."
    )


def _shape_table(by_degree: dict[float, list[dict]], t: float, target: float) -> tuple:
    """The table of the plaque's shapes at time ``t`` (one row per stenosis degree), the most
    compliant degree (degree, |η| / p, its peak velocity) and the largest relative spread of
    |η| / p over the cap and lipid pool at a degree."""
    lines = [
        "| stenosis degree | max |u| at 10 ms (m/s) | |η| at 10 ms (µm) | max p (Pa) "
        "| |η| / p (µm/Pa) | × paper | spread over cap × lipid |",
        "|---|---|---|---|---|---|---|",
    ]
    best = None
    for d in sorted(by_degree):
        group = by_degree[d]
        ratios = [ratio(s, t) for s in group]
        s = group[0]
        spread = max(ratios) / min(ratios) - 1
        lines.append(
            f"| {d:g} | {fmt(at(s, t, 'peak_velocity'), 3)} | "
            f"{in_um(at(s, t, 'peak_displacement'))} | {fmt(at(s, t, 'peak_pressure'))} | "
            f"{fmt(1e6 * ratios[0], 3)} | {fmt(ratios[0] / target, 2)} | "
            f"{spread:.1e} ({len(group)} runs) |"
        )
        if best is None or ratios[0] > best[1]:
            best = (d, ratios[0], at(s, t, "peak_velocity"))
    spread = max(
        max(ratio(s, t) for s in group) / min(ratio(s, t) for s in group) - 1
        for group in by_degree.values()
    )
    return lines, best, spread


def _other_readings(
    others: Summaries, plane: Summaries | None, t: float, target: float, shipped: float, best
) -> tuple[list[str], tuple]:
    """The other readings of "fixed wall" and of the plaque (the wall held outside, a softer
    lipid pool, plane stress), as paragraphs, and the most compliant reading so far."""
    text: list[str] = []
    held = others.get("compliance/wall_held_outside")
    if ratio(held, t) is not None:
        r = ratio(held, t)
        text.append(
            '\nReading "fixed wall" as the vessel wall deforming with its outer surface held '
            "(the moving-wall case with `structure.support.stiffness: 1e12` Pa/m on the "
            f"exterior): {in_um(at(held, t, 'peak_displacement'))} µm at 10 ms under "
            f"{fmt(at(held, t, 'peak_pressure'))} Pa, {fmt(1e6 * r, 2)} µm/Pa, "
            f"{fmt(target / r, 2)}× below the study's."
        )
    soft = sorted(
        (s for name, s in others.items() if name.startswith("compliance/lipid_modulus=")),
        key=lambda s: -s["case"]["young_modulus"]["lipid"],
    )
    if soft:
        parts = [
            f"{s['case']['young_modulus']['lipid']:.2g} Pa: {fmt(1e6 * ratio(s, t), 2)} µm/Pa "
            f"({fmt(ratio(s, t) / target, 2)}× the study's)"
            for s in soft
            if ratio(s, t) is not None
        ]
        text.append(
            "\nNot a reading of the study, which prints 1.6 MPa for the plaque, but what "
            "would: a softer lipid pool (`structure.lipid.young_modulus`; real lipid cores "
            "are in the kPa range) under the shipped cap: " + "; ".join(parts) + "."
        )
    flat = (plane or {}).get("plane_stress/fixed_newtonian")
    if ratio(flat, t) is not None:
        r = ratio(flat, t)
        text.append(
            "\nReading the 2D model as **plane stress** (a thin slice free to thicken) instead "
            "of plane strain (a slice of a long body; the study states neither): for St. "
            "Venant–Kirchhoff the same in-plane law as plane strain with ν' = ν / (1 + ν), "
            "E' = E (1 + 2ν) / (1 + ν)² (`--only analyses --analysis plane_stress`): "
            f"{in_um(at(flat, t, 'peak_displacement'))} µm at 10 ms, {fmt(1e6 * r, 2)} µm/Pa, "
            f"{fmt(r / shipped, 2)}× plane strain's and {fmt(target / r, 2)}× below the study's. "
            "Near incompressibility stiffens plane strain against the plaque's compression "
            "(λ + 2μ = 3.8 E at ν = 0.45) far more than plane stress (1.25 E)."
        )
        if r > best[1]:
            best = ("plane stress", r, at(flat, t, "peak_velocity"))
    return text, best


# --------------------------------------------------------------------------------------------
# 2. The moving wall: quasi-static or ringing


def damping(
    runs: Summaries,
    main: Summaries,
    paper: dict,
    static: dict[str, float],
    plane: Summaries | None = None,
) -> str:
    """The moving wall's displacement per Pa at each report time, the study's beside ours with
    the shipped damping and with more, and without inertia."""
    shipped = main.get("moving_newtonian_coarse")
    variants = [("shipped (τ = 0.3 ms)", shipped)]
    taus = sorted(
        (s for name, s in runs.items() if name.startswith("damping/tau=")),
        key=lambda s: s["case"]["relaxation_time_s"],
    )
    variants += [(f"τ = {1e3 * s['case']['relaxation_time_s']:g} ms", s) for s in taus]
    variants += [
        ("no inertia (`quasi_static`)", runs.get("damping/quasi_static")),
        ("5 ms steps after the pulse, ρ∞ = 0", runs.get("damping/large_steps")),
    ]
    times = [t for t in TIMES if t <= 0.1]
    lines = _damping_table(variants, paper, times)
    c = static["moving_wall"]
    window = [t for t in TIMES if t <= QUASI_STATIC_BY]
    verdicts = [(label, [t for t in window if quasi_static(s, c, t)]) for label, s in variants if s]
    text = [
        _damping_opening(c, paper) + "The coarse moving-wall Newtonian case to 0.1 s with the "
        "relaxation time τ of every region raised, without the wall's inertia "
        "(`structure.time_integration.scheme: quasi_static`), and with the study's 5 ms steps "
        "after the resolved pulse and the most dissipative generalized-α (`--only analyses "
        "--analysis damping`):",
        "",
        "\n".join(lines),
        "",
        f"Quasi-static (here: |η| / p within a factor {QUASI_STATIC_FACTOR:g} of the static "
        f"compliance, at the report times up to {1e3 * QUASI_STATIC_BY:g} ms, while the "
        "pressure is still the decelerating flow's): "
        + "; ".join(
            f"{label}: {', '.join(f'{1e3 * t:g} ms' for t in times) if times else 'neither'}"
            for label, times in verdicts
        )
        + ".",
        "",
        *_damping_findings(c, verdicts, runs.get("damping/quasi_static")),
        _large_steps(runs.get("damping/large_steps"), c),
        _late_compliance(main, paper, c, plane),
    ]
    return "\n".join(text)


def _damping_opening(c: float, paper: dict) -> str:
    """The moving wall's static compliance ``c`` beside the study's |η| / p at 10 and 20 ms,
    and whether that is quasi-static."""
    study = [paper_ratio(paper, t, "moving", "coarse") for t in (0.01, 0.02)]
    quiet = all(c / QUASI_STATIC_FACTOR <= r <= c * QUASI_STATIC_FACTOR for r in study)
    return (
        f"The moving wall's static compliance (uniform pressure, no flow, no inertia) is "
        f"{fmt(1e6 * c, 3)} µm/Pa, and the study's moving wall moves {fmt(1e6 * study[0], 2)} "
        f"and {fmt(1e6 * study[1], 2)} µm per Pa of peak pressure at 10 and 20 ms: "
        + ("" if quiet else "not ")
        + "quasi-static by the criterion below. fsi's rings after the pulse (its lowest coupled "
        f"mode, ~{RING_HZ:g} Hz as docs/wall-damping.md measured it). "
    )


def _damping_findings(c: float, verdicts: list, no_inertia: dict | None) -> list[str]:
    """What the damping runs show, for the moving wall of static compliance ``c`` (m/Pa): which
    relaxation times make it quasi-static at 10 and at 20 ms (``verdicts``: (label, the report
    times at which it is)), beside the measured arterial loss angle, and the wall without
    inertia."""
    omega = 2 * math.pi * RING_HZ
    taus = [(label, times) for label, times in verdicts if label.startswith("τ")]
    by = {t: [label for label, times in taus if t in times] for t in (0.01, 0.02)}
    held = [] if no_inertia is None else [ratio(no_inertia, t) for t in (0.01, 0.02)]
    lines = [
        "- **Relaxation times that make the wall quasi-static** (of those run: "
        + ", ".join(label for label, _ in taus)
        + f"): at 10 ms {', '.join(by[0.01]) or 'none'}; at 20 ms {', '.join(by[0.02]) or 'none'}. "
        "A small τ leaves the wall ringing, a large one makes it creep back slowly from the "
        f"pulse's {PULSE_AMPLITUDE / 1e3:g} kPa (at {fmt(1e6 * c, 2)} µm/Pa, "
        f"{1e3 * PULSE_AMPLITUDE * c:.2g} mm). Measured arterial loss angles are about 15° and "
        "nearly independent of frequency (Bergel 1961, Avolio 1980: docs/wall-damping.md §3): "
        f"ωτ ≈ 0.27 at the wall's ring ({RING_HZ:g} Hz, as docs/wall-damping.md measured it; "
        f"not a number of these summaries), τ ≈ {1e3 * 0.27 / omega:.2g} ms. The shipped "
        f"0.3 ms is {math.degrees(math.atan(omega * 3e-4)):.0f}° there; τ = 1 ms is "
        f"{math.degrees(math.atan(omega * 1e-3)):.0f}° and 4 ms "
        f"{math.degrees(math.atan(omega * 4e-3)):.0f}° at the ring: not physiological there, "
        "however well a τ fitted at the heart rate (43 ms: 15° at 1 Hz) may describe the beat.",
    ]
    if held and None not in held:
        quiet = [t for t in (0.01, 0.02) if quasi_static(no_inertia, c, t)]
        lines.append(
            "- **Without the wall's inertia** (`quasi_static`) |η| / p is "
            f"{1e6 * held[0]:.3g} and {1e6 * held[1]:.3g} µm/Pa at 10 and 20 ms against the "
            f"static {1e6 * c:.2g}: quasi-static at "
            + (", ".join(f"{1e3 * t:g} ms" for t in quiet) or "neither")
            + (
                ". The mass that moves is then the blood's (the added mass of the lumen's "
                "column), the spring the wall's: the ring is a property of the coupled system, "
                "not of the tissue's density."
                if not quiet
                else "."
            )
        )
    return lines


def _damping_table(variants: list, paper: dict, times: list[float]) -> list[str]:
    """The rows of the damping table: the study's, then each variant's |η| and |η|/p at
    ``times``."""
    lines = [
        "| run | " + " | ".join(f"{t:g} s: |η| (µm), |η|/p (µm/Pa)" for t in times) + " |",
        "|---" * (1 + len(times)) + "|",
        "| study, coarse | "
        + " | ".join(
            f"{in_um(paper_value(paper, 'displacement', t, 'moving', 'coarse'))}, "
            f"{fmt(1e6 * paper_ratio(paper, t, 'moving', 'coarse'), 3)}"
            for t in times
        )
        + " |",
    ]
    for label, s in variants:
        if s is None:
            lines.append(f"| {label} | " + " | ".join("–" for _ in times) + " |")
            continue
        cells = [
            f"{in_um(at(s, t, 'peak_displacement'))}, "
            f"{fmt(None if ratio(s, t) is None else 1e6 * ratio(s, t), 3)}"
            for t in times
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines


def _late_compliance(
    main: Summaries, paper: dict, compliance: float, plane: dict | None = None
) -> str:
    """|η| / p at 0.8 s, when the walls are at rest under the late pressure: ours and the
    study's, beside the static compliance."""
    t = 0.8
    ours, study = [], []
    rest = sum(
        quasi_static(main.get(f"moving_{f}_{m}"), compliance, t)
        for f in ("newtonian", "carreau")
        for m in ("coarse", "fine")
    )
    for fluid in ("newtonian", "carreau"):
        for mesh in ("coarse", "fine"):
            r = ratio(main.get(f"moving_{fluid}_{mesh}"), t)
            if r is not None:
                ours.append(r)
            study.append(paper_ratio(paper, t, "moving", mesh, fluid))
    if not ours:
        return ""
    return (
        f"- **At 0.8 s** {rest} of fsi's {len(ours)} moving-wall runs are quasi-static by "
        "the criterion above: |η| / p is "
        f"{1e6 * min(ours):.2g}–{1e6 * max(ours):.2g} µm/Pa in fsi's four moving-wall runs and "
        f"{1e6 * min(study):.2g}–{1e6 * max(study):.2g} in the study's, beside the static "
        f"compliance {1e6 * compliance:.2g}. The study's moves "
        f"{sum(study) / len(study) / (sum(ours) / len(ours)):.2g}× as much per Pa of peak "
        "pressure as fsi's (means over the four runs)"
        + _plane_late(plane or {}, main, (min(study), max(study)))
    )


def _plane_late(
    plane: Summaries, main: Summaries, study_range: tuple[float, float], t: float = 0.8
) -> str:
    """The moving walls at rest at 0.8 s read as plane stress (the plane-stress analysis's
    Newtonian run, the most-plausible reading's Newtonian and Carreau runs), against plane
    strain."""
    lo, hi = study_range
    found = []
    for name, fluid in (
        ("plane_stress/moving_newtonian", "newtonian"),
        ("plausible/moving_newtonian_coarse", "newtonian"),
        ("plausible/moving_carreau_coarse", "carreau"),
    ):
        strain, stress = ratio(main.get(f"moving_{fluid}_coarse"), t), ratio(plane.get(name), t)
        if stress is None or not strain:
            continue
        inside = "within" if lo <= stress <= hi else "outside"
        found.append(
            f"{name} {1e6 * stress:.2g} µm/Pa ({stress / strain:.2g}× plane strain's, {inside} "
            "the study's range)"
        )
    if not found:
        return "; plane stress at 0.8 s: not run."
    return "; read as plane stress (item 1), coarse, at 0.8 s: " + "; ".join(found) + "."


def _large_steps(s: dict | None, c: float) -> str:
    """What the study's 5 ms steps after the resolved pulse do to the ring."""
    if s is None:
        return "- **The study's 5 ms steps**: (run missing)"
    d = {t: at(s, t, "peak_displacement") for t in (0.01, 0.02, 0.05)}
    quiet = [t for t in (0.01, 0.02, 0.05) if quasi_static(s, c, t)]
    return (
        "- **The study's 5 ms steps** with the most dissipative scheme: |η| "
        f"{in_um(d[0.01])} µm at 10 ms (one step after the pulse), {in_um(d[0.02])} µm at "
        f"20 ms, {in_um(d[0.05])} µm at 50 ms; quasi-static at "
        + (", ".join(f"{1e3 * t:g} ms" for t in quiet) or "none of them")
        + (
            ": a wall quasi-static at 10 ms needs a solver that damped it within 5 ms of the "
            "pulse's end."
            if 0.01 not in quiet
            else "."
        )
    )


QUASI_STATIC_FACTOR = 1.5
"""A wall is quasi-static at a report time when its |η| / p is within this factor of the wall's
static compliance."""


QUASI_STATIC_BY = 0.02
"""s: the report times (10 and 20 ms) at which the pressure is still the decelerating flow's,
so that |η| / p measures the wall's compliance."""


def quasi_static(s: dict | None, compliance: float, t: float) -> bool:
    """|η| / p at report time ``t`` within :data:`QUASI_STATIC_FACTOR` of ``compliance``."""
    r = ratio(s, t)
    return (
        r is not None and compliance / QUASI_STATIC_FACTOR <= r <= compliance * QUASI_STATIC_FACTOR
    )


RING_HZ = 79.0
"""Hz: the coarse moving wall's lowest coupled mode (docs/wall-damping.md, resolved steps)."""
