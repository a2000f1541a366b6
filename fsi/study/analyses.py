"""The sections of docs/study.md that explain where fsi differs from the study: each made from
the summaries of the runs of scripts/reproduce_study.py's ``ANALYSES`` that isolate one cause
(docs/study_runs/<analysis>/...), and from :func:`static_compliance`, the structure alone under
a uniform lumen pressure.

Every threshold a verdict uses is stated beside it; the study's values come from
docs/reference/boujena2014_tables.csv.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from fsi.output import report
from fsi.study.runs import (
    DENSITY,
    PAPER_QUANTITY,
    PULSE_AMPLITUDE,
    PULSE_DURATION,
    TIMES,
    apex_x,
    at,
    finished,
    fmt,
    make_summaries,
    peak,
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


def _ratio(s: dict | None, t: float) -> float | None:
    """Peak |η| per Pa of peak pressure at report time ``t`` (m/Pa)."""
    d, p = at(s, t, "peak_displacement"), at(s, t, "peak_pressure")
    return None if d is None or not p else d / p


def _paper(
    paper: dict, quantity: str, t: float, wall: str, mesh: str, fluid: str = "newtonian"
) -> float:
    return paper[(quantity, t, wall, fluid, mesh)]


def _paper_ratio(paper: dict, t: float, wall: str, mesh: str, fluid: str = "newtonian") -> float:
    """The study's peak |η| per Pa of peak pressure (m/Pa)."""
    return _paper(paper, "displacement", t, wall, mesh, fluid) / _paper(
        paper, "pressure", t, wall, mesh, fluid
    )


def _range_from_paper(
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
                found.append(ours / _paper(paper, quantity, t, wall, mesh, fluid) - 1)
    return min(found), max(found)


def _percent_range(found: tuple[float, float] | None) -> str:
    """ "a–b %" of the magnitudes of a same-signed range."""
    if found is None:
        return "–"
    lo, hi = sorted(abs(100 * x) for x in found)
    return f"{lo:.0f}–{hi:.0f} %"


def _um(x: float | None) -> str:
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
    target = _paper_ratio(paper, t, "fixed", "coarse")
    u_paper = _paper(paper, "velocity", t, "fixed", "coarse")
    shipped = _ratio(main.get("fixed_newtonian_coarse"), t)
    by_degree: dict[float, list[dict]] = {}
    for s in shape.values():
        if _ratio(s, t) is not None:
            by_degree.setdefault(s["case"]["geometry"]["stenosis_degree"], []).append(s)
    if not by_degree or shipped is None:
        return "(runs missing)"
    lines = [
        "| stenosis degree | max |u| at 10 ms (m/s) | |η| at 10 ms (µm) | max p (Pa) "
        "| |η| / p (µm/Pa) | × paper | spread over cap × lipid |",
        "|---|---|---|---|---|---|---|",
    ]
    best = None
    for d in sorted(by_degree):
        group = by_degree[d]
        ratios = [_ratio(s, t) for s in group]
        s = group[0]
        spread = max(ratios) / min(ratios) - 1
        lines.append(
            f"| {d:g} | {fmt(at(s, t, 'peak_velocity'), 3)} | "
            f"{_um(at(s, t, 'peak_displacement'))} | {fmt(at(s, t, 'peak_pressure'))} | "
            f"{fmt(1e6 * ratios[0], 3)} | {fmt(ratios[0] / target, 2)} | "
            f"{spread:.1e} ({len(group)} runs) |"
        )
        if best is None or ratios[0] > best[1]:
            best = (d, ratios[0], at(s, t, "peak_velocity"))
    fine = _ratio(main.get("fixed_newtonian_fine"), t)
    mesh_change = "" if fine is None else f"; fine mesh {100 * (fine / shipped - 1):+.1f} %"
    printed = {
        q: [
            _paper(paper, q, t, "fixed", m, f)
            for m in ("coarse", "fine")
            for f in ("newtonian", "carreau")
        ]
        for q in ("displacement", "pressure")
    }
    swept = {
        key: sorted({s["case"]["geometry"][key] for s in shape.values()})
        for key in ("stenosis_degree", "cap_thickness", "lipid_length")
    }
    text = [
        f"The study's fixed wall moves by {_um(min(printed['displacement']))}–"
        f"{_um(max(printed['displacement']))} µm at 10 ms under a peak pressure of "
        f"{min(printed['pressure']):.2g}–{max(printed['pressure']):.2g} Pa: "
        f"{fmt(1e6 * target, 2)} µm per Pa (coarse; "
        f"{fmt(1e6 * _paper_ratio(paper, t, 'fixed', 'fine'), 2)} fine), and "
        f"{fmt(1e6 * _paper_ratio(paper, 0.1, 'fixed', 'coarse'), 2)} µm/Pa at 0.1 s. fsi's "
        f"moves {fmt(1e6 * shipped, 2)} µm/Pa at 10 ms (fixed_newtonian_coarse{mesh_change}), "
        f"{fmt(target / shipped, 2)}× less. Under a "
        "uniform pressure, with no flow and no inertia, the shipped plaque moves only "
        f"{fmt(1e6 * static['fixed_wall'], 2)} µm per Pa (`static_compliance` in "
        f"scripts/study_analyses.py), {fmt(shipped / static['fixed_wall'], 2)}× less than in "
        "the flow: a plaque of ν = 0.45 bonded to a rigid wall hardly compresses, and what "
        "moves it is the flow's pressure differences along it and its shear, not the "
        "pressure level.",
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
        "The cap and the lipid pool change nothing (the last column: the largest relative "
        "spread of |η| / p over the cap × lipid-pool combinations of a degree): the "
        "study prints one modulus for the whole plaque (1.6 MPa, ν = 0.45), so the line "
        "between cap and lipid pool is not a material boundary, and only the plaque's outline "
        f"counts. The most compliant degree, {best[0]:g}, moves {fmt(1e6 * best[1], 2)} µm/Pa, "
        f"still {fmt(target / best[1], 2)}× below the study's, and its jet ({fmt(best[2], 3)} "
        f"m/s at 10 ms) is {fmt(best[2] / u_paper, 2)}× the study's {u_paper:g} m/s: the degree "
        "that would bring the displacement closer takes the velocity away.",
    ]
    held = others.get("compliance/wall_held_outside")
    if _ratio(held, t) is not None:
        r = _ratio(held, t)
        text.append(
            '\nReading "fixed wall" as the vessel wall deforming with its outer surface held '
            "(the moving-wall case with `structure.support.stiffness: 1e12` Pa/m on the "
            f"exterior): {_um(at(held, t, 'peak_displacement'))} µm at 10 ms under "
            f"{fmt(at(held, t, 'peak_pressure'))} Pa, {fmt(1e6 * r, 2)} µm/Pa, "
            f"{fmt(target / r, 2)}× below the study's."
        )
    soft = sorted(
        (s for name, s in others.items() if name.startswith("compliance/lipid_modulus=")),
        key=lambda s: -s["case"]["young_modulus"]["lipid"],
    )
    if soft:
        parts = [
            f"{s['case']['young_modulus']['lipid']:.2g} Pa: {fmt(1e6 * _ratio(s, t), 2)} µm/Pa "
            f"({fmt(_ratio(s, t) / target, 2)}× the study's)"
            for s in soft
            if _ratio(s, t) is not None
        ]
        text.append(
            "\nNot a reading of the study, which prints 1.6 MPa for the plaque, but what "
            "would: a softer lipid pool (`structure.lipid.young_modulus`; real lipid cores "
            "are in the kPa range) under the shipped cap: " + "; ".join(parts) + "."
        )
    flat = (plane or {}).get("plane_stress/fixed_newtonian")
    if _ratio(flat, t) is not None:
        r = _ratio(flat, t)
        text.append(
            "\nReading the 2D model as **plane stress** (a thin slice free to thicken) instead "
            "of plane strain (a slice of a long body; the study states neither): for St. "
            "Venant–Kirchhoff the same in-plane law as plane strain with ν' = ν / (1 + ν), "
            "E' = E (1 + 2ν) / (1 + ν)² (`--only analyses --analysis plane_stress`): "
            f"{_um(at(flat, t, 'peak_displacement'))} µm at 10 ms, {fmt(1e6 * r, 2)} µm/Pa, "
            f"{fmt(r / shipped, 2)}× plane strain's and {fmt(target / r, 2)}× below the study's. "
            "Near incompressibility stiffens plane strain against the plaque's compression "
            "(λ + 2μ = 3.8 E at ν = 0.45) far more than plane stress (1.25 E)."
        )
        if r > best[1]:
            best = ("plane stress", r, at(flat, t, "peak_velocity"))
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
    lines = [
        "| run | " + " | ".join(f"{t:g} s: |η| (µm), |η|/p (µm/Pa)" for t in times) + " |",
        "|---" * (1 + len(times)) + "|",
        "| study, coarse | "
        + " | ".join(
            f"{_um(_paper(paper, 'displacement', t, 'moving', 'coarse'))}, "
            f"{fmt(1e6 * _paper_ratio(paper, t, 'moving', 'coarse'), 3)}"
            for t in times
        )
        + " |",
    ]
    for label, s in variants:
        if s is None:
            lines.append(f"| {label} | " + " | ".join("–" for _ in times) + " |")
            continue
        cells = [
            f"{_um(at(s, t, 'peak_displacement'))}, "
            f"{fmt(None if _ratio(s, t) is None else 1e6 * _ratio(s, t), 3)}"
            for t in times
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    c = static["moving_wall"]
    omega = 2 * math.pi * RING_HZ
    window = [t for t in TIMES if t <= QUASI_STATIC_BY]
    verdicts = [(label, [t for t in window if quasi_static(s, c, t)]) for label, s in variants if s]
    text = [
        f"The moving wall's static compliance (uniform pressure, no flow, no inertia) is "
        f"{fmt(1e6 * c, 3)} µm/Pa, and the study's moving wall moves "
        f"{fmt(1e6 * _paper_ratio(paper, 0.01, 'moving', 'coarse'), 2)} and "
        f"{fmt(1e6 * _paper_ratio(paper, 0.02, 'moving', 'coarse'), 2)} µm per Pa of peak "
        "pressure at 10 and 20 ms: it follows the blood's pressure quasi-statically. fsi's "
        f"rings after the pulse (its lowest coupled mode, ~{RING_HZ:g} Hz, "
        "docs/wall-damping.md). The coarse moving-wall Newtonian case to 0.1 s with the "
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
        "- **No relaxation time makes the wall quasi-static by 10 ms**: a small τ leaves it "
        "ringing, a large one makes it creep back slowly from the pulse's "
        f"{PULSE_AMPLITUDE / 1e3:g} kPa (at {fmt(1e6 * c, 2)} µm/Pa, "
        f"{1e3 * PULSE_AMPLITUDE * c:.2g} mm). τ of a few ms makes it quasi-static by "
        "20 ms. Measured arterial loss angles are about 15° and nearly independent of "
        "frequency (Bergel 1961, Avolio 1980: docs/wall-damping.md §3): ωτ ≈ 0.27 at the "
        f"{RING_HZ:g} Hz ring, τ ≈ {1e3 * 0.27 / omega:.2g} ms. The shipped 0.3 ms (8°) is of "
        f"that order; τ = 1 ms is {math.degrees(math.atan(omega * 1e-3)):.0f}° and 4 ms "
        f"{math.degrees(math.atan(omega * 4e-3)):.0f}° at the ring: not physiological there, "
        "however well a τ fitted at the heart rate (43 ms: 15° at 1 Hz) may describe the "
        "beat.",
        "- **Without the wall's inertia the wall still rings**: the mass that moves is the "
        "blood's (the added mass of the lumen's column), the spring the wall's; the ring is a "
        "property of the coupled system, not of the tissue's density.",
        _large_steps(runs.get("damping/large_steps")),
        _late_compliance(main, paper, c, (plane or {}).get("plane_stress/moving_newtonian")),
    ]
    return "\n".join(text)


def _late_compliance(
    main: Summaries, paper: dict, compliance: float, plane: dict | None = None
) -> str:
    """|η| / p at 0.8 s, when the walls are at rest under the late pressure: ours and the
    study's, beside the static compliance."""
    t = 0.8
    ours, study = [], []
    for fluid in ("newtonian", "carreau"):
        for mesh in ("coarse", "fine"):
            r = _ratio(main.get(f"moving_{fluid}_{mesh}"), t)
            if r is not None:
                ours.append(r)
            study.append(_paper_ratio(paper, t, "moving", mesh, fluid))
    if not ours:
        return ""
    return (
        f"- **At 0.8 s** both walls are at rest under the late pressure: |η| / p is "
        f"{1e6 * min(ours):.2g}–{1e6 * max(ours):.2g} µm/Pa in fsi's four moving-wall runs and "
        f"{1e6 * min(study):.2g}–{1e6 * max(study):.2g} in the study's, beside the static "
        f"compliance {1e6 * compliance:.2g}. Neither wall rings then, so Table 3's "
        "differences at 0.8 s are those of walls at rest: the study's moves "
        f"{sum(study) / len(study) / (sum(ours) / len(ours)):.2g}× as much per Pa of peak "
        "pressure as fsi's (means over the four runs)"
        + _plane_late(plane, main, (min(study), max(study)))
    )


def _plane_late(
    plane: dict | None, main: Summaries, study_range: tuple[float, float], t: float = 0.8
) -> str:
    """The moving wall at rest at 0.8 s read as plane stress, against plane strain."""
    strain = _ratio(main.get("moving_newtonian_coarse"), t)
    stress = _ratio(plane, t)
    if stress is None or not strain:
        return "; we have not isolated why."
    lo, hi = study_range
    where = (
        "within the study's range: the plane-stress reading accounts for the walls at rest"
        if lo <= stress <= hi
        else "outside the study's range"
    )
    return (
        f"; read as plane stress (item 1) fsi's coarse moving Newtonian wall moves "
        f"{1e6 * stress:.2g} µm/Pa at 0.8 s, {stress / strain:.2g}× its plane-strain value, "
        f"{where}."
    )


def _large_steps(s: dict | None) -> str:
    """What the study's 5 ms steps after the resolved pulse do to the ring."""
    if s is None:
        return "- **The study's 5 ms steps**: (run missing)"
    d = {t: at(s, t, "peak_displacement") for t in (0.01, 0.02, 0.05)}
    return (
        "- **The study's 5 ms steps** with the most dissipative scheme damp the ring "
        f"numerically once it is excited (|η| {_um(d[0.02])} µm at 20 ms, {_um(d[0.05])} µm "
        f"at 50 ms), but not at 10 ms ({_um(d[0.01])} µm), one step after the pulse: a wall "
        "quasi-static at 10 ms needs a solver that damped it within 5 ms of the pulse's end."
    )


QUASI_STATIC_FACTOR = 1.5
"""A wall is quasi-static at a report time when its |η| / p is within this factor of the wall's
static compliance."""

QUASI_STATIC_BY = 0.02
"""s: the report times (10 and 20 ms) at which the pressure is still the decelerating flow's,
so that |η| / p measures the wall's compliance."""


def quasi_static(s: dict | None, compliance: float, t: float) -> bool:
    """|η| / p at report time ``t`` within :data:`QUASI_STATIC_FACTOR` of ``compliance``."""
    r = _ratio(s, t)
    return (
        r is not None and compliance / QUASI_STATIC_FACTOR <= r <= compliance * QUASI_STATIC_FACTOR
    )


RING_HZ = 79.0
"""Hz: the coarse moving wall's lowest coupled mode (docs/wall-damping.md, resolved steps)."""


# --------------------------------------------------------------------------------------------
# 3. Pressure


def pressure(
    inlet: Summaries,
    degree: Summaries,
    steps: Summaries,
    main: Summaries,
    paper: dict,
    p10: Summaries,
    element: Summaries,
) -> str:
    """The peak pressure's decay from 10 ms to 0.1 s and its value at 0.8 s: the study's, ours,
    ours with the inlet before the physiological-flow issue, and with other stenosis degrees."""
    lines = [
        "| run | p(10 ms) (Pa) | p(0.1 s) (Pa) | p(10 ms) / p(0.1 s) | p(0.8 s) (Pa) |",
        "|---|---|---|---|---|",
    ]

    def row(label, p10, p100, p800=None):
        decay = None if p10 is None or not p100 else p10 / p100
        lines.append(f"| {label} | {fmt(p10)} | {fmt(p100)} | {fmt(decay, 3)} | {fmt(p800)} |")
        return decay

    study = [
        row(
            f"study, fixed wall, Newtonian, {mesh}",
            *(_paper(paper, "pressure", t, "fixed", mesh) for t in (0.01, 0.1, 0.8)),
        )
        for mesh in ("coarse", "fine")
    ]
    ours = [
        row(f"fsi, {name}", *(at(main.get(name), t, "peak_pressure") for t in (0.01, 0.1, 0.8)))
        for name in ("fixed_newtonian_coarse", "fixed_newtonian_fine")
    ]
    for name, label in (
        ("backward_euler", "backward Euler"),
        ("large_steps_bdf2", "5 ms steps after the pulse, BDF2"),
        ("large_steps_backward_euler", "5 ms steps after the pulse, backward Euler"),
    ):
        found = steps.get(f"steps/{name}")
        if found is not None:
            row(f"fsi, coarse, {label}", *(at(found, t, "peak_pressure") for t in (0.01, 0.1)))
    old = inlet.get("inlet/fixed_newtonian_normal_flow")
    before = row(
        "fsi, coarse, the inlet held normal (before the physiological-flow issue)",
        *(at(old, t, "peak_pressure") for t in (0.01, 0.1, 0.8)),
    )
    for s in sorted(degree.values(), key=lambda s: s["case"]["geometry"]["stenosis_degree"]):
        d = s["case"]["geometry"]["stenosis_degree"]
        if d != 0.5:
            row(
                f"fsi, coarse, stenosis degree {d:g}",
                *(at(s, t, "peak_pressure") for t in (0.01, 0.1)),
            )
    if None in study + ours or before is None:
        return "\n".join(lines)
    late = [
        at(main.get(f"fixed_newtonian_{m}"), 0.8, "peak_pressure")
        / _paper(paper, "pressure", 0.8, "fixed", m)
        - 1
        for m in ("coarse", "fine")
    ]
    moving = main.get("moving_newtonian_fine") or main.get("moving_newtonian_coarse")
    ring = {t: at(moving, t, "peak_pressure") for t in (0.01, 0.02, 0.05)}
    return "\n".join(
        [
            "The study's peak pressure falls "
            f"{fmt(study[0], 2)}–{fmt(study[1], 2)}-fold from 10 ms to 0.1 s (coarse–fine), "
            f"fsi's {fmt(ours[0], 2)}–{fmt(ours[1], 2)}-fold. The inlet, the time scheme and the "
            "stenosis degree varied one at a time (coarse fixed-wall Newtonian runs, `--only "
            "analyses --analysis inlet --analysis steps --analysis degree`):",
            "",
            "\n".join(lines),
            "",
            "- **The inlet.** The study's inlet is a total stress, σ n = −h n, zero after the "
            "pulse; the inlet before the physiological-flow issue held the velocity normal "
            f"(do-nothing form): with it the pressure falls {fmt(before, 2)}-fold. The study's "
            "own condition, shipped now, takes fsi "
            f"{100 * (ours[0] - before) / (study[0] - before):.0f} % of the way from that to "
            "the study's decay (coarse) and puts p(0.8 s) at "
            f"{100 * late[0]:+.0f} % (coarse) and {100 * late[1]:+.0f} % (fine) of the "
            "study's.",
            _degree_bullet(degree, study[0], _paper(paper, "pressure", 0.01, "fixed", "coarse")),
            "",
            stagnation(main, paper),
            "",
            pressure_at_10ms(p10, main, paper),
            "",
            pressure_and_element(element, main, paper),
            "",
            'The moving-wall cases\' "peak pressure" is max p over the fluid. While the '
            "ringing wall draws blood in, it is the small positive pressure left: "
            f"{moving['name'] if moving else '–'} has {fmt(ring[0.01], 3)} Pa at 10 ms, "
            f"{fmt(ring[0.02], 3)} Pa at 20 ms and {fmt(ring[0.05], 3)} Pa at 50 ms. A "
            "difference in such a sample, between the meshes or from the study, is one of the "
            "ring's phase, so the mesh-convergence figure states changes relative to the run's "
            "largest peak pressure.",
        ]
    )


# --------------------------------------------------------------------------------------------
# 4. Velocity: the calibration


PULSE_IMPULSE = PULSE_AMPLITUDE * PULSE_DURATION / 2
"""Pa s: the shipped inlet pulse's impulse, ∫ h dt = (A / 2) T."""


def throat_mean(s: dict, t: float) -> float | None:
    """The mean velocity through the throat at ``t``: flow rate / throat height (m/s)."""
    g = s["case"]["geometry"]
    q = at(s, t, "inlet_flow_rate")
    return None if q is None else q / (g["height"] * (1 - g["stenosis_degree"]))


def effective_length(length: float, stenosis_length: float, degree: float) -> float:
    """∫ H / h(x) dx over the lumen for one cosine plaque closing ``degree`` of H: the straight
    part plus l / sqrt(1 − degree) (the integral of 1 / (1 − d/2 (1 − cos θ)) over a
    period)."""
    return length - stenosis_length + stenosis_length / math.sqrt(1 - degree)


def rigid_column_velocity(
    s: dict, impulse: float = PULSE_IMPULSE, density: float = DENSITY
) -> float:
    """The mean throat velocity of a rigid blood column set moving by the inlet's impulse
    (Pa s): impulse / (ρ L_eff) / (1 − degree)."""
    g = s["case"]["geometry"]
    d = g["stenosis_degree"]
    return impulse / (density * effective_length(g["length"], g["stenosis_length"], d)) / (1 - d)


def velocity(degree: Summaries) -> str:
    """The peak velocity at 10 ms against the stenosis degree: the rigid-column estimate of
    the mean throat velocity, the run's mean throat velocity (flow rate / throat height) and
    its maximum."""
    t = 0.01
    runs = sorted(degree.values(), key=lambda s: s["case"]["geometry"]["stenosis_degree"])
    lines = [
        "| degree | rigid-column mean throat velocity (m/s) | fsi mean throat velocity at 10 ms "
        "(m/s) | fsi max |u| at 10 ms (m/s) | max / mean |",
        "|---|---|---|---|---|",
    ]
    for s in runs:
        mean, u = throat_mean(s, t), at(s, t, "peak_velocity")
        ratio = None if not mean or u is None else u / mean
        lines.append(
            f"| {s['case']['geometry']['stenosis_degree']:g} | "
            f"{fmt(rigid_column_velocity(s), 3)} | {fmt(mean, 3)} | {fmt(u, 4)} | "
            f"{fmt(ratio, 3)} |"
        )
    return "\n".join(lines)


def velocity_text(degree: Summaries, inlet: Summaries, main: Summaries, paper: dict) -> str:
    """Item 4: the calibration of the stenosis degree, redone against the right quantity, and
    why the shipped degree stays."""
    t = 0.01
    shipped = next(
        (s for s in degree.values() if s["case"]["geometry"]["stenosis_degree"] == 0.5), None
    )
    if shipped is None or throat_mean(shipped, t) is None:
        return "(runs missing)"
    estimate = rigid_column_velocity(shipped)
    mean, u = throat_mean(shipped, t), at(shipped, t, "peak_velocity")
    above = _percent_range(_range_from_paper(main, paper, "velocity", t))
    targets = {m: _paper(paper, "velocity", t, "fixed", m) for m in ("coarse", "fine")}
    match = {m: matching_degree(degree, v) for m, v in targets.items()}
    return "\n".join(
        [
            f"fsi's peak velocity is {above} above the study's at 10 ms. The stenosis degree "
            "(50 %) was chosen by the model notes with a rigid-column estimate: just after the "
            "pulse the blood moves almost as a rigid column, whose mean velocity in the throat "
            "is the pulse's impulse (A/2) T over ρ L_eff, with L_eff = ∫ H / h dx = L − l + "
            f"l / √(1 − d), divided by 1 − d: {estimate:.3f} m/s at d = 0.5, the study's coarse "
            f"maximum at 10 ms ({targets['coarse']:g} m/s) to three digits. That compares a "
            "**mean** with a **maximum**. In fsi's run (the degree sweep below, coarse fixed-wall "
            f"Newtonian to 0.1 s, `--only analyses --analysis degree`) at 10 ms the mean throat "
            f"velocity (flow rate / throat height) is {mean:.3f} m/s, "
            f"{100 * (1 - mean / estimate):.0f} % below the rigid column (viscous losses), and "
            f"the maximum {u:.3f} m/s is {u / mean:.2f}× the mean (the jet's profile):",
            "",
            velocity(degree),
            "",
            "Against the right quantity, fsi's maximum equals the study's at a degree of "
            + " (coarse) and ".join(
                "–" if match[m] is None else f"{match[m]:.3f}" for m in ("coarse", "fine")
            )
            + " (fine; interpolated in the sweep). **We keep 0.5**: a degree taken from the "
            "study's Table 1 would fit a model parameter to the numbers the model is compared "
            "with, which this project does not do (docs/model.md §1: the study states no "
            "degree; 50 % is the model's stated default). The calibration is therefore not "
            "redone; its mismatch of quantities is the cause of the difference at 10 ms, and the "
            "sweep gives how much the unstated degree moves every velocity in Table 1.",
            "",
            late_velocity(inlet, main, paper),
        ]
    )


def _degree_bullet(degree: Summaries, study_decay: float, study_p10: float) -> str:
    """What the stenosis degree moves: the decay from 10 ms to 0.1 s and p(10 ms), and whether
    the study's values lie in the swept range."""
    p10 = [at(s, 0.01, "peak_pressure") for s in degree.values()]
    decay = [
        at(s, 0.01, "peak_pressure") / at(s, 0.1, "peak_pressure")
        for s in degree.values()
        if at(s, 0.1, "peak_pressure")
    ]
    if not decay or None in p10:
        return "- **The stenosis degree**: (runs missing)"

    def inside(x, values):
        return "within" if min(values) <= x <= max(values) else "outside"

    degrees = sorted(s["case"]["geometry"]["stenosis_degree"] for s in degree.values())
    return (
        f"- **The stenosis degree**, which the study does not state (degrees {degrees[0]:g}–"
        f"{degrees[-1]:g}, the table's last rows): the decay runs from {min(decay):.2g}- to "
        f"{max(decay):.2g}-fold, {inside(study_decay, decay)} that range the study's "
        f"{study_decay:.2g}-fold; p(10 ms) stays at {min(p10):.3g}–{max(p10):.3g} Pa, "
        f"{inside(study_p10, p10)} it the study's {study_p10:.3g} Pa. "
        + (
            "So the decay is within what the unstated geometry moves, but the "
            f"{100 * (1 - max(p10) / study_p10):.0f}–{100 * (1 - min(p10) / study_p10):.0f} % "
            "lower pressure at 10 ms is not: neither the inlet nor the degree explains it, and "
            "we have not isolated its cause (what is measured about it follows). The time "
            "scheme does not either (the table's backward-Euler rows); the study's 5 ms steps "
            "after the pulse raise p(10 ms) with BDF2 only, whose step grows 20-fold there, "
            "where variable-step BDF2 overshoots (it is stable for ratios below 1 + √2)."
            if inside(study_p10, p10) == "outside"
            else "Both lie within what the unstated geometry moves."
        )
    )


def stagnation(main: Summaries, paper: dict) -> str:
    """Where the fixed wall's peak pressure sits at 10 ms, and the stagnation pressure of the
    inflow there, ½ ρ (Q / H)²."""
    s = main.get("fixed_newtonian_fine") or main.get("fixed_newtonian_coarse")
    where = None if s is None else s.get("peak_pressure_at", {}).get("0.01")
    q = at(s, 0.01, "inlet_flow_rate")
    if where is None or q is None:
        return ""
    g = s["case"]["geometry"]
    u = q / g["height"]
    printed = _paper(paper, "pressure", 0.01, "fixed", "coarse")
    stagnation = 0.5 * DENSITY * u**2
    faster = (printed / stagnation) ** 0.5 - 1
    return (
        f"At 10 ms the peak pressure ({fmt(at(s, 0.01, 'peak_pressure'), 3)} Pa, {s['name']}) "
        f"sits on the plaque's upstream flank (x = {1e3 * where[0]:.1f} mm, y = "
        f"{1e3 * where[1]:.2f} mm; the plaque starts at x = "
        f"{1e3 * (apex_x(s) - g['stenosis_length'] / 2):g} mm), where the oncoming blood "
        f"is turned: the stagnation pressure of the mean inflow, ½ ρ (Q / H)² = "
        f"{stagnation:.3g} Pa (Q / H = {u:.3g} m/s), is of its size. The study's "
        f"{printed:g} Pa would be that of a {100 * faster:.0f} % faster inflow; its "
        "velocities (Table 1) are lower, not higher, so a faster inflow "
        "is not the explanation either."
    )


P10_VARIANTS = {
    "outlet_no_backflow_term": (
        "the outlet without its backflow term",
        ("fluid.outlet.backflow_stabilization=0",),
    ),
    "inlet_no_inflow_term": (
        "the inlet without its term on re-entering blood",
        ("fluid.inflow_stabilization=0",),
    ),
    "no_supg": ("no SUPG (the Galerkin form)", ("fluid.supg=false",)),
    "outlet_stress_form": ("the outlet in the stress form", ("fluid.open_boundary=stress",)),
    "inlet_do_nothing": (
        "the inlet in the do-nothing form",
        ("fluid.inlet_open_boundary=do_nothing",),
    ),
    "degree_0.6": ("stenosis degree 0.6", ("geometry.stenosis_degree=0.6",)),
    "degree_0.7": ("stenosis degree 0.7", ("geometry.stenosis_degree=0.7",)),
    "plaque_both_sides": (
        "a plaque on each side, closing 0.25 of the height each",
        ("geometry.plaque_sides=[bottom, top]",),
    ),
}
"""The coarse fixed-wall Newtonian runs to 20 ms of the ``p10`` analysis (scripts/
reproduce_study.py): name → (what it changes, its ``--set`` overrides)."""


def pressure_at_10ms(p10: Summaries, main: Summaries, paper: dict) -> str:
    """What the fixed wall's p(10 ms) does not depend on (the :data:`P10_VARIANTS`), and how
    the peak pressure falls from 10 to 20 ms beside the square of the peak velocity, fsi's and
    the study's."""
    base = main.get("fixed_newtonian_coarse")
    p_base = at(base, 0.01, "peak_pressure")
    if p_base is None or not p10:
        return ""
    lines = [
        "| coarse fixed-wall Newtonian run | p(10 ms) (Pa) | change | p(20 ms) (Pa) |",
        "|---|---|---|---|",
        f"| shipped | {fmt(p_base)} | – | {fmt(at(base, 0.02, 'peak_pressure'))} |",
    ]
    changes = {}
    for name, (label, _) in P10_VARIANTS.items():
        s = p10.get(f"p10/{name}")
        p = at(s, 0.01, "peak_pressure")
        if p is None:
            continue
        changes[name] = p / p_base - 1
        lines.append(
            f"| {label} | {fmt(p)} | {100 * changes[name]:+.1f} % | "
            f"{fmt(at(s, 0.02, 'peak_pressure'))} |"
        )
    same = [abs(c) for n, c in changes.items() if n != "plaque_both_sides"]
    if not same:
        return ""

    def falls(p10_, p20, u10, u20):  # p(10 ms) / p(20 ms) and (u(10 ms) / u(20 ms))²
        return p10_ / p20, (u10 / u20) ** 2

    ours = falls(
        *(at(base, t, c) for c in ("peak_pressure", "peak_velocity") for t in (0.01, 0.02))
    )
    study = falls(
        *(
            _paper(paper, q, t, "fixed", "coarse")
            for q in ("pressure", "velocity")
            for t in (0.01, 0.02)
        )
    )
    both = changes.get("plaque_both_sides")
    return "\n".join(
        [
            "What p(10 ms) does not depend on (coarse fixed-wall Newtonian runs to 20 ms, `--only "
            "analyses --analysis p10`): the forms of the openings, the stabilizations and steeper "
            "stenoses, one at a time.",
            "",
            "\n".join(lines),
            "",
            f"None of them moves p(10 ms) by more than {100 * max(same):.1f} %"
            + (
                f" (a plaque on each side lowers it by {-100 * both:.0f} %)"
                if both is not None
                else ""
            )
            + ". fsi's peak pressure falls from 10 to 20 ms as the square of its peak velocity "
            f"(p(10 ms) / p(20 ms) = {ours[0]:.3f}, (u(10 ms) / u(20 ms))² = {ours[1]:.3f}), as "
            "a stagnation pressure of the decelerating flow would; the study's falls "
            f"{study[0]:.3f}-fold against {study[1]:.3f} for the square of its own peak "
            "velocity. So the study's p(10 ms) holds a part that is not the stagnation "
            "pressure of its flow, and none of these runs gives fsi such a part.",
        ]
    )


MESHES = ("coarse", "fine")


def pressure_and_element(element: Summaries, main: Summaries, paper: dict) -> str:
    """The fixed wall's peak pressure with fsi's P2–P1 and equal-order P1–P1 fluid on both
    meshes (the ``element`` analysis, the plaque held rigid), beside the study's: the element
    of the study's code (COMSOL's laminar-flow default, P1+P1) on a mesh of its size."""
    times = (0.01, 0.02, 0.05, 0.1)
    runs = {(e, m): element.get(f"element/{e}_{m}") for e in ("p2p1", "p1p1") for m in MESHES}
    if any(at(s, 0.01, "peak_pressure") is None for s in runs.values()):
        return ""
    head = " | ".join(f"p({t * 1000:g} ms) (Pa)" for t in times)
    lines = [f"| run | {head} | u(10 ms) (m/s) |", "|---" * (len(times) + 2) + "|"]
    for mesh in MESHES:
        values = [_paper(paper, "pressure", t, "fixed", mesh) for t in times]
        u = _paper(paper, "velocity", 0.01, "fixed", mesh)
        lines.append(f"| study, {mesh} | {' | '.join(fmt(v) for v in values)} | {fmt(u)} |")
    for (e, mesh), s in runs.items():
        values = [at(s, t, "peak_pressure") for t in times]
        label = {"p2p1": "P2–P1 (shipped)", "p1p1": "P1–P1"}[e]
        lines.append(
            f"| fsi {label}, {mesh} | {' | '.join(fmt(v) for v in values)} | "
            f"{fmt(at(s, 0.01, 'peak_velocity'))} |"
        )

    def p(e, mesh, t=0.01):
        return at(runs[(e, mesh)], t, "peak_pressure")

    def off(value, mesh, t=0.01):  # from the study's, %
        return 100 * (value / _paper(paper, "pressure", t, "fixed", mesh) - 1)

    later = ", ".join(f"{off(p('p1p1', 'coarse', t), 'coarse', t):+.0f} %" for t in times[1:])
    later_p2 = ", ".join(f"{off(p('p2p1', 'coarse', t), 'coarse', t):+.0f} %" for t in times[1:])
    return "\n".join(
        [
            "The element (`--only analyses --analysis element`: the fixed-wall Newtonian case "
            "to 0.1 s with the plaque held rigid, which fsi's P1–P1 needs, being fluid-only; "
            "held rigid, the P2–P1 plaque gives p(10 ms) = "
            f"{fmt(p('p2p1', 'coarse'))} Pa against the deforming one's "
            f"{fmt(at(main.get('fixed_newtonian_coarse'), 0.01, 'peak_pressure'))}). "
            "The study's code, "
            "COMSOL, discretises laminar flow by default with equal-order linear elements "
            "(P1+P1, stabilized); fsi ships P2–P1 and has P1–P1 with SUPG/PSPG/LSIC "
            "(docs/boundary-conditions.md §7):",
            "",
            "\n".join(lines),
            "",
            f"On the coarse mesh P1–P1 raises p(10 ms) from {fmt(p('p2p1', 'coarse'))} to "
            f"{fmt(p('p1p1', 'coarse'))} Pa ({off(p('p1p1', 'coarse'), 'coarse'):+.1f} % from "
            f"the study's coarse value); on the fine mesh it gives {fmt(p('p1p1', 'fine'))} Pa, "
            f"{100 * (p('p1p1', 'fine') / p('p2p1', 'fine') - 1):+.1f} % from P2–P1's. So on a "
            "mesh of the study's coarse size (3,204 triangles here, 3,272 there) the 10 ms "
            "pressure, set in the few cells where the blood is turned on the plaque's flank, "
            "moves with the element by as much as fsi differs from the study there, and it "
            "converges with the mesh to P2–P1's value: the study's coarse p(10 ms) is within "
            "what the discretisation of that mesh moves. The element is not the whole story: "
            f"P1–P1 on the coarse mesh is {later} off the study at 20, 50 and 100 ms (P2–P1: "
            f"{later_p2}), and on fsi's fine mesh P1–P1 is {off(p('p1p1', 'fine'), 'fine'):+.0f} % "
            "from the study's fine value. The study's fine mesh, refined near the stenosis, is "
            "not fsi's and is not printed; why its p(10 ms) rises from coarse to fine where "
            "fsi's converges is not isolated.",
        ]
    )


def late_velocity(inlet: Summaries, main: Summaries, paper: dict) -> str:
    """The peak velocity at 0.8 s: the study's, ours, and ours with the inlet held normal."""
    t = 0.8
    rows = []
    for case, label in (("fixed_newtonian", "fixed"), ("moving_newtonian", "moving")):
        ours = at(main.get(f"{case}_coarse"), t, "peak_velocity")
        normal = at(inlet.get(f"inlet/{case}_normal_flow"), t, "peak_velocity")
        printed = _paper(paper, "velocity", t, label, "coarse")
        if ours is None or normal is None:
            return ""
        rows.append(
            f"{label} wall: study {printed:g}, fsi {ours:.4g} ({100 * (ours / printed - 1):+.0f} "
            f"%), fsi with the inlet held normal {normal:.4g} m/s "
            f"({100 * (normal / printed - 1):+.0f} %)"
        )
    return (
        f"At 0.8 s fsi's peak velocity is "
        f"{_percent_range(_range_from_paper(main, paper, 'velocity', t))} below the study's. "
        "The inlet isolates it "
        "(coarse Newtonian runs, `--analysis inlet`): "
        + "; ".join(rows)
        + ". The study's total-stress inlet, as fsi applies it, lets the velocity at the inlet "
        "turn and the flow slow faster after the pulse than an inlet that holds it normal. "
        "Holding it normal brings the late velocity close to the study's but doubles the late "
        "pressure (Table 2's section), where the stress inlet has it within a few per cent: "
        "neither of the two inlets gives both of the study's late values, so which inlet the "
        "study's code applied cannot be told from its tables. The shipped configs keep the "
        "study's printed condition; the other is one `--set` away "
        "(docs/boundary-conditions.md)."
    )


def matching_degree(degree: Summaries, target: float, t: float = 0.01) -> float | None:
    """The stenosis degree whose max |u| at ``t`` equals ``target``, interpolated linearly
    between the runs that bracket it (None: not bracketed)."""
    pts = sorted(
        (s["case"]["geometry"]["stenosis_degree"], at(s, t, "peak_velocity"))
        for s in degree.values()
        if at(s, t, "peak_velocity") is not None
    )
    for (d0, u0), (d1, u1) in zip(pts, pts[1:]):
        if (u0 - target) * (u1 - target) <= 0 and u0 != u1:
            return d0 + (target - u0) * (d1 - d0) / (u1 - u0)
    return None


# --------------------------------------------------------------------------------------------
# 6. The recirculation zone and the outlet


def downstream(runs: Summaries, main: Summaries) -> str:
    """The longest reversed-flow zone over the heartbeat with the outlet 0, 1 and 2 cm further
    downstream: the fixed wall, its pulse scaled to the longer blood column; the moving wall
    lengthened as it is, to show why it is not compared."""
    lines = [
        "| case | segment (cm) | inlet pulse (Pa) | max |u| at 10 ms (m/s) | largest |η| (µm) "
        "| longest recirculation zone (mm) | at t (s) | change |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for case in ("fixed_newtonian", "moving_newtonian"):
        entries = [main.get(f"{case}_coarse")] + [
            runs.get(f"downstream/{case}_plus_{extra}cm") for extra in (1, 2)
        ]
        base = peak(entries[0], "recirculation_length")
        for s in entries:
            if s is None:
                lines.append(f"| {case} | – | – | – | – | – | – | – |")
                continue
            g = s["case"]["geometry"]
            found = peak(s, "recirculation_length")
            eta = peak(s, "peak_displacement")
            if found is None or not s["finished"]:
                lines.append(f"| {case} | {100 * g['length']:g} | unfinished | | | | | |")
                continue
            rel = "" if s is entries[0] or not base else f"{100 * (found[0] / base[0] - 1):+.0f} %"
            lines.append(
                f"| {case} | {100 * g['length']:g} | {fmt(s['case'].get('inlet_amplitude'))} | "
                f"{fmt(at(s, 0.01, 'peak_velocity'), 3)} | {_um(None if eta is None else eta[0])} "
                f"| {1e3 * found[0]:.2f} | {found[1]:.3g} | {rel} |"
            )
    base = peak(main.get("fixed_newtonian_coarse"), "recirculation_length")
    longest = peak(runs.get("downstream/fixed_newtonian_plus_2cm"), "recirculation_length")
    if base is None or longest is None:
        return "\n".join(lines)
    end = runs["downstream/fixed_newtonian_plus_2cm"]["case"]["end_s"]
    still = " and still growing at the end of the beat" if longest[1] >= end - 1e-9 else ""
    return "\n".join(lines) + (
        f"\n\nWith the outlet 2 cm further away the fixed wall's longest zone is "
        f"{1e3 * longest[0]:.3g} mm instead of {1e3 * base[0]:.3g} "
        f"({100 * (longest[0] / base[0] - 1):+.0f} %){still}: the study's 2 cm segment cuts "
        "the zone at its outlet, so the lengths the finding compares are set by the study's "
        "domain, not by the artery it stands for."
    )


# --------------------------------------------------------------------------------------------
# Mesh and step convergence of the stress maxima


def richardson(coarse: float, medium: float, fine: float) -> tuple[float, float] | None:
    """(observed order p, extrapolated value) from three solutions on meshes refined by 2 each
    time: p = log2((coarse − medium) / (medium − fine)), f* = fine + (fine − medium) / (2^p − 1);
    None unless the differences shrink monotonically."""
    a, b = coarse - medium, medium - fine
    if a == 0 or b == 0 or a / b <= 1:
        return None
    order = math.log2(a / b)
    return order, fine + (fine - medium) / (2**order - 1)


CONVERGED = {
    "plaque_sss": "the plaque's largest |σ₁₂|",
    "max_principal_cap": "the cap's largest principal stress",
}


def convergence(runs: Summaries, main: Summaries) -> str:
    """The stress maxima on four meshes (coarse, medium, fine, finest: each a uniform
    refinement of the one before but coarse → medium), their Richardson extrapolation from the
    last three, and the fine mesh's change when every step is halved."""
    lines = [
        "| case | quantity | coarse | medium | fine | finest | observed order | extrapolated "
        "| finest − extrapolated | fine, dt halved |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for case in ("fixed_newtonian", "moving_newtonian"):
        levels = {
            "coarse": main.get(f"{case}_coarse"),
            "medium": runs.get(f"convergence/{case}_medium"),
            "fine": main.get(f"{case}_fine"),
            "finest": runs.get(f"convergence/{case}_finest"),
        }
        halved = runs.get(f"convergence/{case}_fine_dt_halved")
        for name, label in CONVERGED.items():
            values = {k: peak(s, name) for k, s in levels.items()}
            cells = [fmt(None if v is None else v[0]) for v in values.values()]
            found = None
            if all(values[k] is not None for k in ("medium", "fine", "finest")):
                found = richardson(*(values[k][0] for k in ("medium", "fine", "finest")))
            if found is None:
                last = [values[k][0] for k in ("medium", "fine", "finest") if values[k]]
                spread = f"medium–finest within {100 * (max(last) / min(last) - 1):.2f} %"
                cells += ["not monotone", "–", spread if len(last) == 3 else "–"]
            else:
                order, limit = found
                off = values["finest"][0] / limit - 1
                cells += [f"{order:.2f}", fmt(limit), f"{100 * off:+.2f} %"]
            h, f = peak(halved if finished(halved) else None, name), values["fine"]
            cells.append("–" if h is None or f is None else f"{100 * (h[0] / f[0] - 1):+.2f} %")
            lines.append(f"| {case.replace('_', ', ')} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(
        [
            "The findings rest on the structure's stress maxima, all reached within 12 ms of the "
            "pulse. The fixed- and moving-wall Newtonian cases to 20 ms on the medium (one "
            "refinement of the coarse mesh) and finest (three) meshes, beside the coarse and "
            "fine heartbeats, and the fine mesh with every step halved to 20 ms "
            "(`scripts/reproduce_study.py --only analyses --analysis convergence --ranks 2`); "
            "Richardson's extrapolation from medium, fine and finest (each half the element "
            "size of the one before):",
            "",
            "\n".join(lines),
        ]
    )


# --------------------------------------------------------------------------------------------


def summaries(folder: Path, analyses: dict, docs_runs: Path) -> dict[str, Summaries]:
    """Each analysis's run summaries by run name (``label``, or ``label/<run>`` for a sweep's
    runs): made from the run folders under ``folder`` that exist, else the committed ones in
    ``docs_runs``."""
    out = {}
    for analysis, items in analyses.items():
        names = []
        for item in items:
            if hasattr(item, "vary"):  # a sweep: its run folders, or their committed summaries
                found = {p.parent.name for p in (folder / item.label).glob("*/metrics.csv")}
                found |= {p.stem for p in (docs_runs / item.label).glob("*.json")}
                names += [f"{item.label}/{n}" for n in sorted(found)]
            else:
                names.append(item.label)
        runs = {
            n: report.load_run(folder / n) for n in names if (folder / n / "metrics.csv").is_file()
        }
        out[analysis] = make_summaries(runs, docs_runs, names)
    return out


def explanations(
    extra: dict[str, Summaries], main: Summaries, paper: dict, docs_runs: Path
) -> dict[str, list[str]]:
    """The sections below Tables 1, 2 and 3, by the reference file's quantity names."""
    static = static_compliance(docs_runs)
    shape = {n: s for n, s in extra.get("compliance", {}).items() if "plaque_shape/" in n}
    others = {n: s for n, s in extra.get("compliance", {}).items() if n not in shape}
    return {
        "velocity": [
            "#### Why the velocity differs (item 4: the calibration)\n\n"
            + velocity_text(extra.get("degree", {}), extra.get("inlet", {}), main, paper)
        ],
        "pressure": [
            "#### Why the pressure differs (item 3)\n\n"
            + pressure(
                extra.get("inlet", {}),
                extra.get("degree", {}),
                extra.get("steps", {}),
                main,
                paper,
                extra.get("p10", {}),
                extra.get("element", {}),
            )
        ],
        "displacement": [
            "#### Why the fixed wall's displacement differs (item 1: compliance)\n\n"
            + compliance(shape, others, main, paper, static, extra.get("plane_stress")),
            "#### Why the moving wall's displacement differs (item 2: a ringing wall)\n\n"
            + damping(extra.get("damping", {}), main, paper, static, extra.get("plane_stress")),
        ],
    }
