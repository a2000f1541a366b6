"""docs/study.md against the run summaries it was made from (docs/study_runs/): every value of
Tables 1–3 and its † (a maximum at a boundary's corner or an open boundary's edge), the places
and positions the document lists, where the element runs' peaks sit, the times of the
recirculation maxima, where the whole structure's SSS maximum sits, and the counts of values
within 10 % of the study's (the shipped and the most-plausible configuration). Each check is a
function that returns its mismatches, so a document edited by hand (or made from other
summaries) fails; the last test shows that it does."""

import importlib
import json
import math
import re
from pathlib import Path

import pytest

from fsi import config
from fsi.study import locations, plausible
from fsi.study import runs as study_runs

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
LABEL_CONFIG = {label: c for c, label in study_runs.LABELS.items()}


def load_summaries(folder: Path) -> dict[str, dict]:
    """Every summary under ``folder`` by its name relative to it (``element/p1p1_coarse``)."""
    return {
        str(p.relative_to(folder).with_suffix("")): json.loads(p.read_text())
        for p in folder.rglob("*.json")
        if p.name != "static_compliance.json"
    }


def table_mismatches(doc: str, summaries: dict) -> list[str]:
    """Tables 1–3: each fsi value as the summary's, marked † exactly where its maximum sits at
    a boundary's corner or an open boundary's edge."""
    bad = []
    for column, title, _, scale in study_runs.QUANTITIES:
        section = doc.split(f"### {title}")[1].split("\n\n", 2)[1]
        rows = [r for r in section.splitlines() if r.startswith("| ") and " wall, " in r]
        assert len(rows) == 20, title
        for row in rows:
            cells = [c.strip() for c in row.strip("|").split("|")]
            config, t = LABEL_CONFIG[cells[0]], float(cells[1])
            for mesh, cell in (("coarse", cells[3]), ("fine", cells[6])):
                s = summaries.get(f"{config}_{mesh}")
                value = study_runs.at(s, t, column)
                place = (study_runs.where(s, t, column) or {}).get("place")
                expected = study_runs.fmt(None if value is None else scale * value)
                expected += " †" if place else ""
                if cell != expected:
                    bad.append(
                        f"{title}, {config}_{mesh} at {t:g} s: {cell!r}, summary {expected!r}"
                    )
    return bad


PLACED = re.compile(r"(\w+) at ([\d.]+) s: ([^;(]+?) \(x = (-?[\d.]+) mm, y = (-?[\d.]+) mm\)")


def place_mismatches(doc: str, summaries: dict) -> list[str]:
    """The † lists: each run, time, place and position as the run's summary keeps them."""
    bad, found = [], 0
    for block in re.findall(r"† The maximum sits at .*", doc):
        title = doc[: doc.index(block)].rsplit("### ", 1)[1].split("\n")[0].split(" (")[0]
        column = next(c for c, t, *_ in study_runs.QUANTITIES if t == title)
        for run, t, place, x, y in PLACED.findall(block):
            found += 1
            w = study_runs.where(summaries.get(run), float(t), column) or {}
            got = (place, x, y)
            want = (
                locations.describe(w.get("place")),
                locations.mm(w.get("x", 0)),
                locations.mm(w.get("y", 0)),
            )
            if got != want:
                bad.append(f"{title}: {run} at {t} s: {got}, summary {want}")
    return bad


ELEMENT_ROW = re.compile(
    r"^\| fsi (P\d–P1)[^,]*, (coarse|fine) \|.*\| \((-?[\d.]+), (-?[\d.]+)\)( † [^|]+)?"
    r" \| [\d.]+ \|$",
    re.M,
)


def element_mismatches(doc: str, summaries: dict) -> list[str]:
    """The element table: where each run's 10 ms peak pressure sits, and its †."""
    bad, rows = [], ELEMENT_ROW.findall(doc)
    if len(rows) != 4:
        return [f"the element table has {len(rows)} located rows, not 4"]
    for element, mesh, x, y, mark in rows:
        s = summaries.get(f"element/{element.lower().replace('–', '')}_{mesh}")
        w = study_runs.where(s, 0.01, "peak_pressure") or {}
        want = (locations.mm(w.get("x", 0)), locations.mm(w.get("y", 0)))
        place = locations.describe(w.get("place"))
        if (x, y) != want or mark.strip(" †") != place:
            bad.append(f"element {element} {mesh}: ({x}, {y}){mark}, summary {want} {place}")
    return bad


def findings_mismatches(doc: str, summaries: dict) -> list[str]:
    """The recirculation maxima's times, and where the whole structure's SSS maximum sits."""
    bad = []
    fine = [summaries.get(f"{c}_fine") for c in study_runs.CONFIGS]
    level = "fine" if all(map(study_runs.finished, fine)) else "coarse"  # as the findings pick
    m = re.search(r"\(Newtonian / Carreau, at t = ([\d.]+) / ([\d.]+) s\), moving [^(]*"
                  r"\(at t = ([\d.]+) / ([\d.]+) s\)", doc)  # fmt: skip
    if m is None:
        return ["the recirculation finding states no times"]
    want = [
        f"{study_runs.peak(summaries[f'{c}_{level}'], 'recirculation_length')[1]:.3g}"
        for c in study_runs.CONFIGS
    ]
    if list(m.groups()) != want:
        bad.append(f"recirculation times {m.groups()}, summaries {want}")
    cell = summaries[f"moving_newtonian_{level}"].get("largest_sss_at")
    m = re.search(r"moving wall's largest SSS \(([\d.e+]+) Pa at t = ([\d.]+) s, (\w+)\) is[^.]*?"
                  r"x = (-?[\d.]+) mm, y = (-?[\d.]+) mm", doc)  # fmt: skip
    if cell is None or m is None:
        return bad + ["the clamped-corner note or its summary is missing"]
    if m.group(4, 5) != (locations.mm(cell["x"]), locations.mm(cell["y"])):
        bad.append(f"the SSS maximum at {m.group(4, 5)}, summary ({cell['x']}, {cell['y']})")
    return bad


def count_mismatches(doc: str, summaries: dict) -> list[str]:
    """The count of values within 10 % of the study's, over all 120 and per configuration."""
    paper = study_runs.paper_values()
    rows = study_runs.comparison_rows(summaries, paper)
    close = sum(abs(d) <= 0.1 for d in map(study_runs.difference, rows) if d is not None)
    bad = []
    if f"fsi is within 10 % of the paper for {close} of 120 values" not in doc:
        bad.append(f"the 120-value count is not {close}")
    extra = {"plausible": {n: s for n, s in summaries.items() if n.startswith("plausible/")}}
    table = plausible.count_table(
        summaries, {n.split("/")[1]: s for n, s in extra["plausible"].items()}, paper
    )
    if table not in doc:
        bad.append("the shipped / most-plausible count table is not the summaries'")
    return bad


# --------------------------------------------------------------------------------------------
# The settings the document states: each read from the configuration its run ran
# (fsi.study.runs.run_case, through fsi.config), recomputed here from it.


def stated(doc: str, pattern: str) -> re.Match | None:
    """The one place the document states ``pattern`` (a regular expression)."""
    return re.search(pattern, doc)


def seconds(text: str) -> float:
    """ "20 ms" or "0.1 s" in seconds."""
    value, unit = text.split()
    return float(value) * (1e-3 if unit == "ms" else 1.0)


def case_of(summaries: dict, name: str) -> config.Case:
    return study_runs.run_case(summaries[name])


def analysis(summaries: dict, prefix: str) -> list[dict]:
    return [s for n, s in summaries.items() if n.startswith(prefix)]


def _schedule(text: str) -> list[tuple[float, float]]:
    """ "0.25 ms steps to 50 ms, 1 ms to 0.1 s" as [(dt, until)] in s."""
    return [
        (float(dt) * 1e-3, seconds(until))
        for dt, until in re.findall(r"([\d.]+) ms(?: steps)? to ([\d.]+ m?s)", text)
    ]


def schedule_mismatches(doc: str, summaries: dict) -> list[str]:
    """The opening's end time, resolved schedule and printed schedule: every study run's own."""
    m = stated(doc, r"mesh to t = ([\d.]+) s \(the whole heartbeat\), with the shipped configs' "
                    r"resolved schedule \(([^;]+); why: docs/wall-damping\.md\), and with the "
                    r"study's printed schedule \(([^)]+)\)")  # fmt: skip
    if m is None:
        return ["the opening states no schedules"]
    bad = []
    for name in STUDY_RUNS:
        case = case_of(summaries, name)
        steps = [(seg.dt, seg.until) for seg in case.time.schedule]
        stated_steps = _schedule(m.group(3 if name.endswith("_printed") else 2))
        if steps != pytest.approx(stated_steps, rel=1e-9) or len(steps) != len(stated_steps):
            bad.append(f"{name}: schedule {steps}, stated {stated_steps}")
        if case.time.end != float(m.group(1)):
            bad.append(f"{name}: ends at {case.time.end}, stated {m.group(1)}")
    return bad


STUDY_RUNS = [f"{c}_{m}" for c in study_runs.CONFIGS for m in ("coarse", "fine", "coarse_printed")]


def angle(tau: float, hz: float) -> float:
    """The Kelvin–Voigt loss angle atan(2π f τ) in degrees."""
    return math.degrees(math.atan(2 * math.pi * hz * tau))


def ring_mismatches(doc: str, summaries: dict) -> list[str]:
    """The moving wall's ring (its frequency from the crests of |η| its summary keeps) and the
    loss angles at it of the relaxation times the runs ran."""
    m = stated(doc, r"its lowest coupled mode, (\d+) Hz: (\w+)'s (\d+) crests of \|η\| from "
                    r"([\d.]+) to ([\d.]+) ms, every ([\d.]+) ms")  # fmt: skip
    if m is None:
        return ["the ring is not stated"]
    crests = summaries[m.group(2)]["ring"]["crests_s"]
    hz = (len(crests) - 1) / (2 * (crests[-1] - crests[0]))
    want = (f"{hz:.0f}", str(len(crests)), f"{1e3 * crests[0]:.1f}", f"{1e3 * crests[-1]:.1f}",
            f"{1e3 * (crests[-1] - crests[0]) / (len(crests) - 1):.2f}")  # fmt: skip
    got = m.group(1, 3, 4, 5, 6)
    bad = [] if got == want else [f"the ring {got}, its summary's crests give {want}"]
    m = stated(doc, r"ωτ = tan ([\d.]+)° = ([\d.]+) at the wall's ring \((\d+) Hz\), τ ≈ "
                    r"([\d.]+) ms\. The shipped ([\d.]+) ms is (\d+)° there([^(]*)\(([\d.]+) ms: "
                    r"(\d+)° at ([\d.]+) Hz\)")  # fmt: skip
    if m is None:
        return bad + ["the loss angles are not stated"]
    loss = float(m.group(1))
    shipped = case_of(summaries, "moving_newtonian_coarse").structure.wall
    taus = {case_of(summaries, n).structure.wall.viscous_relaxation_time
            for n in summaries if n.startswith("damping/tau=")}  # fmt: skip
    want = [f"{math.tan(math.radians(loss)):.2g}", f"{hz:.0f}",
            f"{1e3 * math.tan(math.radians(loss)) / (2 * math.pi * hz):.2g}",
            f"{1e3 * shipped.viscous_relaxation_time:g}",
            f"{angle(shipped.viscous_relaxation_time, hz):.0f}"]  # fmt: skip
    if list(m.group(2, 3, 4, 5, 6)) != want:
        bad.append(f"the loss angles {m.group(2, 3, 4, 5, 6)}, the runs give {want}")
    for tau, degrees in re.findall(r"([\d.]+) ms (?:is )?(\d+)°", m.group(7)):
        if not any(f"{1e3 * t:g}" == tau and f"{angle(t, hz):.0f}" == degrees for t in taus):
            bad.append(f"τ = {tau} ms at {degrees}° is no damping run's at the ring")
    tau, degrees, rate = m.group(8, 9, 10)
    if not any(f"{1e3 * t:g}" == tau and f"{angle(t, float(rate)):.0f}" == degrees for t in taus):
        bad.append(f"τ = {tau} ms at {degrees}° at {rate} Hz is no damping run's")
    return bad


def p_wave(material) -> float:
    e, nu = material.young_modulus, material.poisson_ratio
    return e * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def material_mismatches(doc: str, summaries: dict) -> list[str]:
    """The plaque's material (the shipped run's configuration), λ + 2μ in plane strain and
    plane stress (the shipped and the plane-stress runs'), the held wall's support."""
    cap = case_of(summaries, "fixed_newtonian_coarse").structure.cap
    lipid = case_of(summaries, "fixed_newtonian_coarse").structure.lipid
    flat = case_of(summaries, "plane_stress/fixed_newtonian").structure.cap
    held = case_of(summaries, "compliance/wall_held_outside").structure.support
    expected = {
        r"cap and lipid pool: ([\d.]+) MPa, ν = ([\d.]+)\)": [
            f"{1e-6 * cap.young_modulus:g}", f"{cap.poisson_ratio:g}"],
        r"a plaque of ν = ([\d.]+) bonded": [f"{lipid.poisson_ratio:g}"],
        r"which prints ([\d.]+) MPa for the plaque": [f"{1e-6 * cap.young_modulus:g}"],
        r"λ \+ 2μ = ([\d.]+) E at ν = ([\d.]+)\) far more than plane stress \(([\d.]+) E\)": [
            f"{p_wave(cap) / cap.young_modulus:.2g}", f"{cap.poisson_ratio:g}",
            f"{p_wave(flat) / cap.young_modulus:.3g}"],
        r"`structure\.support\.stiffness: ([\de.+]+)` Pa/m": [f"{held.stiffness:g}"],
    }  # fmt: skip
    bad = []
    for pattern, want in expected.items():
        m = stated(doc, pattern)
        got = None if m is None else [float(g) for g in m.groups()]
        if got != [float(w) for w in want]:
            bad.append(f"{pattern}: {got}, the configurations give {want}")
    return bad


def carreau_viscosity(law, shear_rate: float) -> float:
    """μ(γ̇) = μ∞ + (μ0 − μ∞)(1 + (λ γ̇)²)^((n − 1)/2)."""
    return law.mu_inf + (law.mu_0 - law.mu_inf) * (1 + (law.relaxation_time * shear_rate) ** 2) ** (
        (law.power_index - 1) / 2
    )


def viscosity_mismatches(doc: str, summaries: dict) -> list[str]:
    """The Carreau run's law against the Newtonian run's viscosity, from their configurations."""
    m = stated(doc, r"The Carreau law of (\w+) \(μ0 = ([\d.]+) mPa·s, μ∞ = ([\d.]+) mPa·s, "
                    r"λ = ([\d.]+) s, n = ([\d.]+)\) is ([+-]\d+) % from (\w+)'s ([\d.]+) mPa·s "
                    r"at ([\d.]+) s⁻¹ and ([+-]\d+) % at ([\d.]+) s⁻¹")  # fmt: skip
    if m is None:
        return ["the viscosities are not stated"]
    law = case_of(summaries, m.group(1)).fluid.rheology
    mu = case_of(summaries, m.group(7)).fluid.rheology.viscosity
    rates = float(m.group(9)), float(m.group(11))
    off = [f"{100 * (carreau_viscosity(law, rate) / mu - 1):+.0f}" for rate in rates]
    want = [f"{1e3 * law.mu_0:g}", f"{1e3 * law.mu_inf:g}", f"{law.relaxation_time:g}",
            f"{law.power_index:g}", off[0], f"{1e3 * mu:g}", off[1]]  # fmt: skip
    got = list(m.group(2, 3, 4, 5, 6, 8, 10))
    return [] if got == want else [f"the viscosities {got}, the configurations give {want}"]


def _steps_around_pulse(case: config.Case) -> tuple[float, float]:
    """(dt up to the inlet pulse's end, dt after it)."""
    end = case.fluid.inlet.duration
    segments = case.time.schedule
    return (next(g.dt for g in segments if g.until >= end - 1e-12),
            next(g.dt for g in segments if g.until > end + 1e-12))  # fmt: skip


SCHEME = {"BDF2": "bdf2", "backward Euler": "backward_euler"}


def steps_mismatches(doc: str, summaries: dict) -> list[str]:
    """The study's steps after the pulse, their ratio to the steps before, the schemes and the
    dissipation the runs' labels state, each from the run's configuration."""
    bad = []
    big = case_of(summaries, "steps/large_steps_bdf2")
    before, after = _steps_around_pulse(big)
    m = stated(doc, r"the study's ([\d.]+) ms steps after the pulse by [^(]*\(the step grows "
                    r"([\d.]+)-fold there, from ([\d.]+) ms")  # fmt: skip
    want = [f"{1e3 * after:g}", f"{after / before:.3g}", f"{1e3 * before:g}"]
    if m is None or list(m.groups()) != want:
        bad.append(f"the step ratio {m and m.groups()}, the configuration gives {want}")
    runs = [
        case_of(summaries, f"steps/{n}") for n in ("large_steps_bdf2", "large_steps_backward_euler")
    ]
    for dt, scheme in re.findall(r"\| fsi, coarse, ([\d.]+) ms steps after the pulse, "
                                 r"(BDF2|backward Euler) \|", doc):  # fmt: skip
        if not any(f"{1e3 * _steps_around_pulse(c)[1]:g}" == dt and c.time.scheme == SCHEME[scheme]
                   for c in runs):  # fmt: skip
            bad.append(f"no steps run has {dt} ms steps after the pulse with {scheme}")
    damped = case_of(summaries, "damping/large_steps")
    m = stated(doc, r"\| ([\d.]+) ms steps after the pulse, ρ∞ = ([\d.]+) \|")
    want = [f"{1e3 * _steps_around_pulse(damped)[1]:g}",
            f"{damped.structure.time_integration.spectral_radius:g}"]  # fmt: skip
    if m is None or list(m.groups()) != want:
        bad.append(f"the damping run's steps {m and m.groups()}, its configuration {want}")
    return bad


def pulse_mismatches(doc: str, summaries: dict) -> list[str]:
    """The inlet pulse, the blood's density and the stenosis degree where the document states
    them: the configurations of the runs each sentence is about."""
    fine = case_of(summaries, "moving_newtonian_fine")
    coarse = case_of(summaries, "fixed_newtonian_coarse")
    printed = case_of(summaries, "fixed_newtonian_coarse_printed")
    degree = f"{coarse.geometry.stenosis_degree:g}"
    s = summaries["fixed_newtonian_fine"]
    flow = study_runs.at(s, 0.01, "inlet_flow_rate") / s["case"]["geometry"]["height"]
    rho = case_of(summaries, "fixed_newtonian_fine").fluid.density
    g = coarse.geometry
    column = g.length - g.stenosis_length + g.stenosis_length / math.sqrt(1 - g.stenosis_degree)
    impulse = coarse.fluid.inlet.amplitude * coarse.fluid.inlet.duration / 2
    expected = {
        r"the pressure, up to ([\d.]+) Pa during the ([\d.]+) ms pulse": [
            fine.fluid.inlet.amplitude, 1e3 * fine.fluid.inlet.duration],
        r"creep back slowly from the pulse's ([\d.]+) kPa": [
            1e-3 * case_of(summaries, "moving_newtonian_coarse").fluid.inlet.amplitude],
        r"the ([\d.]+) Pa total-stress inlet": [coarse.fluid.inlet.amplitude],
        r"Its first step, ([\d.]+) ms, is the whole inlet pulse, which is back to 0 at t = "
        r"([\d.]+) ms": [1e3 * printed.time.schedule[0].dt, 1e3 * printed.fluid.inlet.duration],
        r"½ ρ \(Q / H\)² = ([\d.]+) Pa \(Q / H = ([\d.]+) m/s\)": [
            float(f"{0.5 * rho * flow**2:.3g}"), float(f"{flow:.3g}")],
        r"divided by 1 − d: ([\d.]+) m/s at d = ([\d.]+),": [
            round(impulse / (coarse.fluid.density * column) / (1 - g.stenosis_degree), 3),
            g.stenosis_degree],
        r"The stenosis degree \(([\d.]+) %\)": [100 * g.stenosis_degree],
        r"\*\*We keep ([\d.]+)\*\*": [g.stenosis_degree],
        r"the stenosis degree stays ([\d.]+) ": [g.stenosis_degree],
    }  # fmt: skip
    bad = []
    for pattern, want in expected.items():
        m = stated(doc, pattern)
        got = None if m is None else [float(x) for x in m.groups()]
        if got != pytest.approx(want, rel=1e-12):
            bad.append(f"{pattern}: {got}, the configurations give {want} (degree {degree})")
    return bad


ENDS = {
    r"coarse fixed-wall Newtonian to ([\d.]+ m?s), `--only analyses --analysis degree`": "degree/",
    r"Newtonian runs to ([\d.]+ m?s), `--only analyses --analysis p10`": "p10/",
    r"fixed-wall Newtonian case to ([\d.]+ m?s) with the plaque held rigid": "element/",
    r"Newtonian case to ([\d.]+ m?s) \(`scripts/reproduce_study.py --only analyses "
    r"--analysis compliance`": "compliance/plaque_shape/",
    r"moving-wall Newtonian case to ([\d.]+ m?s) with the relaxation time": "damping/",
    r"`--analysis convergence`, to ([\d.]+ m?s)\)": "convergence/",
    r"Newtonian cases to ([\d.]+ m?s) on the medium": "convergence/",
    r"forms alone are compared to ([\d.]+ m?s) \(the p10 table\)": "p10/",
}
"""Where the document says how far an analysis's runs ran: the pattern → the analysis."""


def ends_mismatches(doc: str, summaries: dict) -> list[str]:
    """How far each analysis's runs ran, and on how many ranks the convergence runs ran."""
    bad = []
    for pattern, prefix in ENDS.items():
        m = stated(doc, pattern)
        ends = {study_runs.run_case(s).time.end for s in analysis(summaries, prefix)}
        if m is None or ends != {seconds(m.group(1))}:
            bad.append(f"{prefix}: stated {m and m.group(1)}, its runs end at {sorted(ends)}")
    m = stated(doc, r"--analysis convergence --ranks (\d+)`")
    ranks = {s["ranks"] for s in analysis(summaries, "convergence/")}
    if m is None or ranks != {int(m.group(1))}:
        bad.append(f"the convergence runs' ranks: stated {m and m.group(1)}, run on {ranks}")
    return bad


def earlier_mismatches(doc: str, summaries: dict) -> list[str]:
    """The earlier → now tables (each cell the earlier-settings run's and the fine run's value)
    and the inflow term's β (the fine runs' configuration)."""
    bad = []
    section = doc.split("## What the physiological-flow settings changed")[1].split("\n## ")[0]
    for (column, title, _, scale), table in zip(
        study_runs.QUANTITIES, re.findall(r"\(\S+\):\n\n((?:\|.*\n)+)", section)
    ):
        for row in table.splitlines()[2:]:
            t, *cells = [c.strip() for c in row.strip("|").split("|")]
            for c, cell in zip(study_runs.CONFIGS, cells):
                values = [study_runs.at(summaries.get(n), float(t), column)
                          for n in (f"earlier/{c}_fine", f"{c}_fine")]  # fmt: skip
                a, b = (None if v is None else scale * v for v in values)
                want = f"{study_runs.fmt(a)} → {study_runs.fmt(b)} ({study_runs.change(a, b)})"
                if cell != want:
                    bad.append(f"{title} {c} at {t} s: {cell!r}, the runs {want!r}")
    m = stated(section, r"β = ([\d.]+) on the tangential velocity of inflow")
    betas = {case_of(summaries, f"{c}_fine").fluid.inflow_stabilization for c in study_runs.CONFIGS}
    if m is None or betas != {float(m.group(1))}:
        bad.append(f"β stated {m and m.group(1)}, the fine runs' {betas}")
    return bad


def downstream_mismatches(doc: str, summaries: dict) -> list[str]:
    """How much longer the downstream analysis's segments are, and where their plaque sits."""
    shipped = summaries["fixed_newtonian_coarse"]["case"]["geometry"]["length"]
    runs = [case_of(summaries, n) for n in summaries if n.startswith("downstream/fixed_")]
    extra = sorted(100 * (c.geometry.length - shipped) for c in runs)
    m = stated(doc, r"the segment ([\d.]+) and ([\d.]+) cm longer downstream \(`geometry\.length`"
                    r", `geometry\.stenosis_centre: ([\d.]+)`\)")  # fmt: skip
    far = stated(
        doc, r"With the outlet ([\d.]+) cm further away .* the study's ([\d.]+) cm segment"
    )
    want = [*extra, {c.geometry.stenosis_centre for c in runs}.pop()]
    got = None if m is None else [float(x) for x in m.groups()]
    bad = [] if got == pytest.approx(want) else [f"the segments {got}, the runs {want}"]
    if far is None or [float(x) for x in far.groups()] != pytest.approx([extra[-1], 100 * shipped]):
        bad.append(f"the outlet further away {far and far.groups()}, the runs {extra[-1]}")
    return bad


NAMED_PATH = re.compile(r"(?<![\w/.])((?:scripts|fsi|docs|tests)/[\w./-]*\w)")
NAMED_MODULE = re.compile(r"`((?:fsi|scripts)\.[\w.]+)`")


def importable(name: str) -> bool:
    """Whether ``a.b.c`` is a module, or a module's attribute."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            found = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attribute in parts[k:]:
            if not hasattr(found, attribute):
                return False
            found = getattr(found, attribute)
        return True
    return False


def names_mismatches(doc: str, summaries: dict | None = None) -> list[str]:
    """The files (scripts/, fsi/, docs/, tests/) and the modules or functions (``fsi.…``) the
    document names exist."""
    missing = [p for p in NAMED_PATH.findall(doc) if not (ROOT / p).exists()]
    return missing + [n for n in NAMED_MODULE.findall(doc) if not importable(n)]


CHECKS = (table_mismatches, place_mismatches, element_mismatches, findings_mismatches,
          count_mismatches, schedule_mismatches, ring_mismatches, material_mismatches,
          viscosity_mismatches, steps_mismatches, pulse_mismatches, ends_mismatches,
          earlier_mismatches, downstream_mismatches, names_mismatches)  # fmt: skip


@pytest.mark.parametrize("check", CHECKS, ids=lambda c: c.__name__)
def test_the_document_states_what_the_summaries_hold(check):
    doc = (DOCS / "study.md").read_text()
    assert check(doc, load_summaries(DOCS / "study_runs")) == []


def test_a_document_edited_by_hand_fails_each_check():
    """One fact changed in a copy of the document is found by the check that covers it."""
    doc = (DOCS / "study.md").read_text()
    summaries = load_summaries(DOCS / "study_runs")
    element = ELEMENT_ROW.search(doc).group(0)
    row = next(r for r in doc.splitlines() if r.startswith("| fixed wall, Newtonian | 0.01 |"))
    cells = row.split(" | ")
    cells[3] += "1"  # fsi's coarse value, one digit more
    edits = {
        table_mismatches: (row, " | ".join(cells)),
        element_mismatches: (element, "(1".join(element.rsplit("(", 1))),
        findings_mismatches: ("(Newtonian / Carreau, at t = ", "(Newtonian / Carreau, at t = 9"),
        count_mismatches: ("of the paper for ", "of the paper for 1"),
    }
    for check, (old, new) in edits.items():
        assert old in doc, check.__name__
        assert check(doc.replace(old, new, 1), summaries) != [], check.__name__
    placed = PLACED.search(doc)
    if placed is not None:
        assert place_mismatches(doc.replace(placed.group(0), placed.group(0).replace(
            "x = ", "x = 1", 1)), summaries) != []  # fmt: skip
    for check, pattern in BUMPS:
        assert check(doc, summaries) == [], check.__name__
        assert check(bumped(doc, pattern), summaries) != [], (check.__name__, pattern)
    stale = doc.replace("fsi/study/wall_analyses.py", "scripts/study_analyses.py")
    assert names_mismatches(stale) == ["scripts/study_analyses.py"]


def bumped(doc: str, pattern: str) -> str:
    """``doc`` with the number ``pattern``'s group matches given one more digit, 9."""
    m = re.search(pattern, doc)
    assert m is not None, pattern
    return doc[: m.end(1)] + "9" + doc[m.end(1) :]


BUMPS = (
    (schedule_mismatches, r"resolved schedule \(([\d.]+)"),
    (schedule_mismatches, r"printed schedule \(([\d.]+)"),
    (ring_mismatches, r"its lowest coupled mode, (\d+) Hz"),
    (ring_mismatches, r"The shipped [\d.]+ ms is (\d+)°"),
    (material_mismatches, r"λ \+ 2μ = ([\d.]+) E"),
    (material_mismatches, r"plane stress \(([\d.]+) E\)"),
    (viscosity_mismatches, r"n = [\d.]+\) is ([+-]\d+) % from"),
    (steps_mismatches, r"the step grows ([\d.]+)-fold"),
    (pulse_mismatches, r"the pressure, up to ([\d.]+) Pa"),
    (pulse_mismatches, r"½ ρ \(Q / H\)² = ([\d.]+) Pa"),
    (ends_mismatches, r"`--analysis convergence`, to ([\d.]+)"),
    (ends_mismatches, r"--ranks (\d+)`"),
    (earlier_mismatches, r"\| 0\.01 \| ([\d.]+) →"),
    (earlier_mismatches, r"β = ([\d.]+)"),
    (downstream_mismatches, r"the segment ([\d.]+) and"),
)
"""A number of each settings check's, given a digit more, which the check must find."""


def test_every_summary_gives_the_configuration_its_run_ran():
    """fsi.study.runs.run_case of every committed summary: its kept configuration, or its
    command's case file and overrides, agreeing with the settings the summary recorded."""
    for name, s in load_summaries(DOCS / "study_runs").items():
        case = study_runs.run_case(s)
        recorded = json.loads(json.dumps(study_runs.case_record(case)))  # as a summary keeps it
        assert {k: recorded[k] for k in s["case"] if k != "geometry"} == {
            k: v for k, v in s["case"].items() if k != "geometry"
        }, name
        assert {k: recorded["geometry"][k] for k in s["case"]["geometry"]} == s["case"][
            "geometry"
        ], name


def test_the_axisymmetric_study_names_what_exists():
    """docs/axisymmetric.md's account of the study's four cases names the study's code as it
    is (it named scripts.study_analyses after that module had moved to fsi/study/)."""
    text = (DOCS / "axisymmetric.md").read_text()
    assert names_mismatches(text) == []
    assert names_mismatches(text.replace("fsi.study.wall_analyses", "scripts.study_analyses"))
