"""The section of docs/study.md on the moving wall's displacement (fsi/study/analyses.py composes
it with the others): a ringing wall. Its displacement per Pa at the report times beside the
static compliance (:func:`quasi_static`), with the relaxation time raised, without inertia and
with the study's steps after the pulse (:func:`damping`); its ring (the shipped run's summary's
frequency) beside the measured arterial loss angle; the walls at rest at 0.8 s.

Every threshold a verdict uses is stated beside it; the study's values come from
docs/reference/boujena2014_tables.csv, the runs' settings from their configurations
(:func:`fsi.study.runs.run_case`).
"""

from __future__ import annotations

import math

from fsi.study.runs import TIMES, after_pulse, at, ends, fmt, run_case, span
from fsi.study.wall_analyses import Summaries, in_um, paper_ratio, paper_value, ratio


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
    if shipped is None:
        return "(runs missing)"
    variants = [(f"shipped (τ = {1e3 * shipped['case']['relaxation_time_s']:g} ms)", shipped)]
    taus = sorted(
        (s for name, s in runs.items() if name.startswith("damping/tau=")),
        key=lambda s: s["case"]["relaxation_time_s"],
    )
    variants += [(f"τ = {1e3 * s['case']['relaxation_time_s']:g} ms", s) for s in taus]
    large = runs.get("damping/large_steps")
    variants += [
        ("no inertia (`quasi_static`)", runs.get("damping/quasi_static")),
        (_large_steps_label(large), large),
    ]
    times = [t for t in TIMES if t <= 0.1]
    lines = _damping_table(variants, paper, times)
    c = static["moving_wall"]
    window = [t for t in TIMES if t <= QUASI_STATIC_BY]
    verdicts = [(label, [t for t in window if quasi_static(s, c, t)]) for label, s in variants if s]
    after = "–" if large is None else f"{1e3 * after_pulse(run_case(large))[1]:g} ms"
    text = [
        _damping_opening(c, paper, shipped) + "The coarse moving-wall Newtonian case to "
        f"{ends(runs.values())} with the relaxation time τ of every region raised, without the "
        "wall's inertia (`structure.time_integration.scheme: quasi_static`), and with the "
        f"study's {after} steps after the resolved pulse and the most dissipative "
        "generalized-α (`--only analyses --analysis damping`):",
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
        *_damping_findings(c, verdicts, runs.get("damping/quasi_static"), shipped, taus),
        _large_steps(large, c),
        _late_compliance(main, paper, c, plane),
    ]
    return "\n".join(text)


def _large_steps_label(s: dict | None) -> str:
    """The damping analysis's run with the study's steps after the pulse, in words from its
    configuration: "5 ms steps after the pulse, ρ∞ = 0"."""
    if s is None:
        return "the study's steps after the pulse"
    case = run_case(s)
    rho = getattr(case.structure.time_integration, "spectral_radius", None)
    return f"{1e3 * after_pulse(case)[1]:g} ms steps after the pulse" + (
        "" if rho is None else f", ρ∞ = {rho:g}"
    )


def _ring(shipped: dict) -> str:
    """The shipped moving wall's ring, from its summary: the frequency of its crests of |η|
    after the pulse (fsi.study.runs.ring)."""
    found = shipped.get("ring")
    if not found:
        return "its lowest coupled mode; not measured in this run's summary"
    crests = found["crests_s"]
    return (
        f"its lowest coupled mode, {found['hz']:.0f} Hz: {shipped['name']}'s {len(crests)} "
        f"crests of |η| from {1e3 * crests[0]:.1f} to {1e3 * crests[-1]:.1f} ms, every "
        f"{1e3 * (crests[-1] - crests[0]) / (len(crests) - 1):.2f} ms"
    )


def _damping_opening(c: float, paper: dict, shipped: dict) -> str:
    """The moving wall's static compliance ``c`` beside the study's |η| / p at 10 and 20 ms,
    and whether that is quasi-static; the shipped wall's ring."""
    study = [paper_ratio(paper, t, "moving", "coarse") for t in (0.01, 0.02)]
    quiet = all(c / QUASI_STATIC_FACTOR <= r <= c * QUASI_STATIC_FACTOR for r in study)
    return (
        f"The moving wall's static compliance (uniform pressure, no flow, no inertia) is "
        f"{fmt(1e6 * c, 3)} µm/Pa, and the study's moving wall moves {fmt(1e6 * study[0], 2)} "
        f"and {fmt(1e6 * study[1], 2)} µm per Pa of peak pressure at 10 and 20 ms: "
        + ("" if quiet else "not ")
        + f"quasi-static by the criterion below. fsi's rings after the pulse ({_ring(shipped)}). "
    )


LOSS_ANGLE = 15.0
"""°: the measured loss angle of arterial walls, nearly independent of frequency above a few Hz
(Bergel 1961, Avolio 1980: docs/wall-damping.md §3); a literature value, not a run's."""

HEART_RATE_HZ = 1.0
"""Hz: the nominal heart rate at which a relaxation time is fitted to :data:`LOSS_ANGLE`
(docs/wall-damping.md: tan 15° at 1 Hz gives the damping analysis's τ = 43 ms)."""


def _angle(tau: float, hz: float) -> float:
    """The Kelvin–Voigt loss angle atan(ωτ) (°) at frequency ``hz``."""
    return math.degrees(math.atan(2 * math.pi * hz * tau))


def _damping_findings(
    c: float, verdicts: list, no_inertia: dict | None, shipped: dict, taus: list[dict]
) -> list[str]:
    """What the damping runs show, for the moving wall of static compliance ``c`` (m/Pa): which
    relaxation times (the runs ``taus``) make it quasi-static at 10 and at 20 ms
    (``verdicts``: (label, the report times at which it is)), beside the measured arterial loss
    angle at the shipped wall's ring, and the wall without inertia."""
    labels = [(label, times) for label, times in verdicts if label.startswith("τ")]
    by = {t: [label for label, times in labels if t in times] for t in (0.01, 0.02)}
    held = [] if no_inertia is None else [ratio(no_inertia, t) for t in (0.01, 0.02)]
    amplitude = run_case(shipped).fluid.inlet.amplitude
    lines = [
        "- **Relaxation times that make the wall quasi-static** (of those run: "
        + ", ".join(label for label, _ in labels)
        + f"): at 10 ms {', '.join(by[0.01]) or 'none'}; at 20 ms {', '.join(by[0.02]) or 'none'}. "
        "A small τ leaves the wall ringing, a large one makes it creep back slowly from the "
        f"pulse's {amplitude / 1e3:g} kPa (at {fmt(1e6 * c, 2)} µm/Pa, "
        f"{1e3 * amplitude * c:.2g} mm). " + _loss_angles(shipped, taus, set(by[0.01] + by[0.02])),
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


def _loss_angles(shipped: dict, taus: list[dict], quiet: set[str]) -> str:
    """The measured arterial loss angle against the relaxation times' at the shipped wall's
    ring (its summary's frequency): the shipped τ's, those that make the wall quasi-static
    (labels ``quiet``), and the τ fitted to the loss angle at :data:`HEART_RATE_HZ`."""
    ring = (shipped.get("ring") or {}).get("hz")
    if ring is None:
        return "(The shipped run's ring is not measured: the loss angles are not compared.)"
    tangent = math.tan(math.radians(LOSS_ANGLE))
    tau = shipped["case"]["relaxation_time_s"]
    chosen = [s["case"]["relaxation_time_s"] for s in taus]
    settled = [t for t in chosen if f"τ = {1e3 * t:g} ms" in quiet]
    fitted = min(chosen, key=lambda t: abs(_angle(t, HEART_RATE_HZ) - LOSS_ANGLE), default=None)
    text = (
        f"Measured arterial loss angles are about {LOSS_ANGLE:g}° and nearly independent of "
        "frequency (Bergel 1961, Avolio 1980: docs/wall-damping.md §3): ωτ = "
        f"tan {LOSS_ANGLE:g}° = {tangent:.2g} at the wall's ring ({ring:.0f} Hz), τ ≈ "
        f"{1e3 * tangent / (2 * math.pi * ring):.2g} ms. The shipped {1e3 * tau:g} ms is "
        f"{_angle(tau, ring):.0f}° there"
    )
    if settled:
        text += (
            "; "
            + " and ".join(
                f"{'τ = ' if k == 0 else ''}{1e3 * t:g} ms {'is ' if k == 0 else ''}"
                f"{_angle(t, ring):.0f}°"
                for k, t in enumerate(settled)
            )
            + " at the ring: not physiological there"
        )
    if fitted is not None:
        text += (
            f", however well a τ fitted at the heart rate ({1e3 * fitted:g} ms: "
            f"{_angle(fitted, HEART_RATE_HZ):.0f}° at {HEART_RATE_HZ:g} Hz) may describe the beat"
        )
    return text + "."


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
        f"{1e6 * min(ours):.2g}–{1e6 * max(ours):.2g} µm/Pa in fsi's {len(ours)} moving-wall "
        "runs and "
        f"{1e6 * min(study):.2g}–{1e6 * max(study):.2g} in the study's, beside the static "
        f"compliance {1e6 * compliance:.2g}. The study's moves "
        f"{sum(study) / len(study) / (sum(ours) / len(ours)):.2g}× as much per Pa of peak "
        f"pressure as fsi's (means over the {len(ours)} runs)"
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
    """What the study's steps after the resolved pulse do to the ring; the steps and the pulse
    read from the run's configuration."""
    if s is None:
        return "- **The study's steps after the pulse**: (run missing)"
    case = run_case(s)
    after = after_pulse(case)[1]
    duration = case.fluid.inlet.duration
    steps = round((0.01 - duration) / after)
    d = {t: at(s, t, "peak_displacement") for t in (0.01, 0.02, 0.05)}
    quiet = [t for t in (0.01, 0.02, 0.05) if quasi_static(s, c, t)]
    return (
        f"- **The study's {1e3 * after:g} ms steps** with the most dissipative scheme: |η| "
        f"{in_um(d[0.01])} µm at 10 ms ({steps} step{'s' if steps != 1 else ''} after the "
        f"pulse), {in_um(d[0.02])} µm at 20 ms, {in_um(d[0.05])} µm at 50 ms; quasi-static at "
        + (", ".join(f"{1e3 * t:g} ms" for t in quiet) or "none of them")
        + (
            ": a wall quasi-static at 10 ms needs a solver that damped it within "
            f"{span(0.01 - duration)} of the pulse's end."
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
