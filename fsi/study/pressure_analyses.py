"""The sections of docs/study.md on the fixed wall's peak pressure at 10 ms, each made from
the summaries of the runs that isolate one cause (fsi/study/analyses.py composes them): where
the peak sits and the stagnation pressure of the inflow (:func:`stagnation`), what p(10 ms) does
not depend on (:func:`pressure_at_10ms`), the fluid's element (:func:`pressure_and_element`),
and the moving wall's peak pressure, a sample of its ring (:func:`moving_pressure`).
"""

from __future__ import annotations

from fsi.study import locations
from fsi.study.runs import apex_x, at, ends, fmt, run_case, where
from fsi.study.wall_analyses import Summaries, paper_value


def _place_note(found: dict) -> str:
    return f"; † {locations.describe(found['place'])}" if found["place"] else ""


def stagnation(main: Summaries, paper: dict) -> str:
    """Where the fixed wall's peak pressure sits at 10 ms, and the stagnation pressure of the
    inflow there, ½ ρ (Q / H)²."""
    s = main.get("fixed_newtonian_fine") or main.get("fixed_newtonian_coarse")
    found = where(s, 0.01, "peak_pressure")
    q = at(s, 0.01, "inlet_flow_rate")
    if found is None or q is None:
        return ""
    g = s["case"]["geometry"]
    u = q / g["height"]
    printed = paper_value(paper, "pressure", 0.01, "fixed", "coarse")
    stagnation = 0.5 * run_case(s).fluid.density * u**2
    faster = (printed / stagnation) ** 0.5 - 1
    u_study = paper_value(paper, "velocity", 0.01, "fixed", "coarse")
    u_ours = at(main.get("fixed_newtonian_coarse"), 0.01, "peak_velocity")
    lower = u_ours is not None and u_study < u_ours
    return (
        f"At 10 ms the peak pressure ({fmt(at(s, 0.01, 'peak_pressure'), 3)} Pa, {s['name']}) "
        f"sits on {plaque_side(s, found)} (x = {locations.mm(found['x'])} mm, y = "
        f"{locations.mm(found['y'])} mm{_place_note(found)}; "
        f"the plaque spans x = {1e3 * locations.plaque_range(g)[0]:g}–"
        f"{1e3 * locations.plaque_range(g)[1]:g} mm): the stagnation pressure of the mean "
        f"inflow, ½ ρ (Q / H)² = {stagnation:.3g} Pa (Q / H = {u:.3g} m/s), is of its size. "
        f"The study's {printed:g} Pa would be that of a {100 * faster:.0f} % faster inflow; "
        f"its peak velocity at 10 ms ({u_study:g} m/s, coarse) is "
        + (
            f"lower than fsi's ({fmt(u_ours)}), not higher, so a faster inflow is not the "
            "explanation either."
            if lower
            else f"not lower than fsi's ({fmt(u_ours)})."
        )
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
    "degree_0.6": ("stenosis degree {degree:g}", ("geometry.stenosis_degree=0.6",)),
    "degree_0.7": ("stenosis degree {degree:g}", ("geometry.stenosis_degree=0.7",)),
    "plaque_both_sides": (
        "a plaque on each side, closing {closing:g} of the height each",
        ("geometry.plaque_sides=[bottom, top]",),
    ),
}
"""The coarse fixed-wall Newtonian runs to 20 ms of the ``p10`` analysis (scripts/
reproduce_study.py): name → (what it changes, its ``--set`` overrides); the geometry in the
description (``{degree}``, ``{closing}``: the fraction of the height each plaque closes) is
filled in from the run's configuration (:func:`variant_label`)."""


def variant_label(name: str, s: dict) -> str:
    """The description of the ``p10`` run ``name`` (summary ``s``), its geometry read from
    the configuration it ran."""
    g = run_case(s).geometry
    closing = g.stenosis_degree / len(g.plaque_sides or ("bottom",))
    return P10_VARIANTS[name][0].format(degree=g.stenosis_degree, closing=closing)


def pressure_at_10ms(p10: Summaries, main: Summaries, paper: dict) -> str:
    """What the fixed wall's p(10 ms) does not depend on (the :data:`P10_VARIANTS`), and how
    the peak pressure falls from 10 to 20 ms beside the square of the peak velocity, fsi's and
    the study's."""
    base = main.get("fixed_newtonian_coarse")
    p_base = at(base, 0.01, "peak_pressure")
    if p_base is None or not p10:
        return ""
    lines, changes = _p10_table(p10, base, p_base)
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
            paper_value(paper, q, t, "fixed", "coarse")
            for q in ("pressure", "velocity")
            for t in (0.01, 0.02)
        )
    )
    both = changes.get("plaque_both_sides")
    return "\n".join(
        [
            "What p(10 ms) does not depend on (coarse fixed-wall Newtonian runs to "
            f"{ends(p10.values())}, `--only analyses --analysis p10`): the forms of the "
            "openings, the stabilizations and steeper stenoses, one at a time.",
            "",
            "\n".join(lines),
            "",
            f"None of them moves p(10 ms) by more than {100 * max(same):.1f} %"
            + (
                f" (a plaque on each side lowers it by {-100 * both:.0f} %)"
                if both is not None
                else ""
            )
            + ". "
            + _falls(ours, study),
        ]
    )


SQUARE_WITHIN = 0.02
"""A peak pressure falls "as the square of the peak velocity" when the two ratios agree within
this fraction."""


def _falls(ours: tuple[float, float], study: tuple[float, float]) -> str:
    """How the peak pressure falls from 10 to 20 ms beside the square of the peak velocity:
    fsi's (``ours``) and the study's, each (p(10) / p(20), (u(10) / u(20))²)."""

    def like(r):
        return abs(r[0] / r[1] - 1) <= SQUARE_WITHIN

    text = (
        f"fsi's peak pressure falls {ours[0]:.3f}-fold from 10 to 20 ms against "
        f"{ours[1]:.3f} for the square of its peak velocity; the study's falls "
        f"{study[0]:.3f}-fold against {study[1]:.3f} (alike within {100 * SQUARE_WITHIN:g} %: "
        f"fsi's {'yes' if like(ours) else 'no'}, the study's {'yes' if like(study) else 'no'})."
    )
    if like(ours) and not like(study):
        text += (
            " fsi's falls as a stagnation pressure of the decelerating flow would, the "
            "study's not: its p(10 ms) holds a part that is not the stagnation pressure of its "
            "flow, and none of these runs gives fsi such a part."
        )
    return text


def _p10_table(p10: Summaries, base: dict, p_base: float) -> tuple[list[str], dict[str, float]]:
    """The rows of the p(10 ms) table (the shipped run ``base``, then each of the
    :data:`P10_VARIANTS`) and each variant's relative change of p(10 ms)."""
    lines = [
        "| coarse fixed-wall Newtonian run | p(10 ms) (Pa) | change | p(20 ms) (Pa) |",
        "|---|---|---|---|",
        f"| shipped | {fmt(p_base)} | – | {fmt(at(base, 0.02, 'peak_pressure'))} |",
    ]
    changes = {}
    for name in P10_VARIANTS:
        s = p10.get(f"p10/{name}")
        p = at(s, 0.01, "peak_pressure")
        if p is None:
            continue
        changes[name] = p / p_base - 1
        lines.append(
            f"| {variant_label(name, s)} | {fmt(p)} | {100 * changes[name]:+.1f} % | "
            f"{fmt(at(s, 0.02, 'peak_pressure'))} |"
        )
    return lines, changes


MESHES = ("coarse", "fine")


COMSOL_ELEMENT = (
    "COMSOL's Reference Manual gives P1+P1 (linear velocity and pressure, stabilized) as the "
    "default element order of its Laminar Flow interface ([version 5.5, *Settings for the "
    "Discretization Sections*](https://doc.comsol.com/5.5/doc/com.comsol.help.comsol/"
    "comsol_ref_equationbased.23.019.html)); the study (2014) names neither its COMSOL "
    "version, nor its interface, nor its element, so that it ran P1+P1 is a guess"
)
"""The one source for the study's code's element, and what it does not say."""

ELEMENT_TIMES = (0.01, 0.02, 0.05, 0.1)


def _at_place(found: dict | None) -> str:
    """A maximum's position (mm), with † and the place when at a boundary's corner or edge."""
    if found is None:
        return "–"
    where = f"({locations.mm(found['x'])}, {locations.mm(found['y'])})"
    return f"{where} † {locations.describe(found['place'])}" if found["place"] else where


def plaque_side(s: dict, found: dict | None) -> str:
    """Where on the plaque a position is: its upstream or downstream flank, or off it."""
    if found is None:
        return "–"
    lo, hi = locations.plaque_range(s["case"]["geometry"])
    if not lo <= found["x"] <= hi:
        return "off the plaque"
    return (
        "the plaque's upstream flank"
        if found["x"] < apex_x(s)
        else ("the plaque's downstream flank")
    )


def _element_tables(runs: dict, paper: dict) -> list[str]:
    """The element runs' peak pressure, where it sits, and the plaque's own maximum."""
    head = " | ".join(f"p({t * 1000:g} ms) (Pa)" for t in ELEMENT_TIMES)
    lines = [
        f"| run | {head} | where at 10 ms (x, y mm) | u(10 ms) (m/s) |",
        "|---" * (len(ELEMENT_TIMES) + 3) + "|",
    ]
    for mesh in MESHES:
        values = [paper_value(paper, "pressure", t, "fixed", mesh) for t in ELEMENT_TIMES]
        u = paper_value(paper, "velocity", 0.01, "fixed", mesh)
        lines.append(f"| study, {mesh} | {' | '.join(map(fmt, values))} | not printed | {fmt(u)} |")
    plaque = [
        f"| run | {' | '.join(f'{t * 1000:g} ms' for t in ELEMENT_TIMES)} | where at 10 ms "
        "(x, y mm) |",
        "|---" * (len(ELEMENT_TIMES) + 2) + "|",
    ]
    for (e, mesh), s in runs.items():
        label = f"fsi {ELEMENTS[e]}, {mesh}"
        cells = []
        for t in ELEMENT_TIMES:
            mark = " †" if (where(s, t, "peak_pressure") or {}).get("place") else ""
            cells.append(fmt(at(s, t, "peak_pressure")) + mark)
        lines.append(
            f"| {label} | {' | '.join(cells)} | {_at_place(where(s, 0.01, 'peak_pressure'))} | "
            f"{fmt(at(s, 0.01, 'peak_velocity'))} |"
        )
        own = [where(s, t, "plaque_pressure") for t in ELEMENT_TIMES]
        plaque.append(
            f"| {label} | {' | '.join(fmt(o and o['value']) for o in own)} | "
            f"{_at_place(own[0])}, {plaque_side(s, own[0])} |"
        )
    return ["\n".join(lines), "\n".join(plaque)]


ELEMENTS = {"p2p1": "P2–P1 (shipped)", "p1p1": "P1–P1"}


def pressure_and_element(element: Summaries, main: Summaries, paper: dict) -> str:
    """The fixed wall's peak pressure with fsi's P2–P1 and equal-order P1–P1 fluid on both
    meshes (the ``element`` analysis, the plaque held rigid), where each peak sits, the
    plaque's own maximum (the largest pressure on its surface), and what that shows."""
    runs = {(e, m): element.get(f"element/{e}_{m}") for e in ELEMENTS for m in MESHES}
    if any(at(s, 0.01, "peak_pressure") is None for s in runs.values()):
        return ""
    main_table, plaque_table = _element_tables(runs, paper)
    rigid = at(runs[("p2p1", "coarse")], 0.01, "peak_pressure")
    own = {k: where(s, 0.01, "plaque_pressure") for k, s in runs.items()}
    cornered = [
        f"{ELEMENTS[e]} {m} ({locations.describe(where(s, 0.01, 'peak_pressure')['place'])})"
        for (e, m), s in runs.items()
        if (where(s, 0.01, "peak_pressure") or {}).get("place")
    ]
    text = [
        "The element (`--only analyses --analysis element`: the fixed-wall Newtonian case to "
        f"{ends(element.values())} with the plaque held rigid, which fsi's P1–P1 needs, being "
        f"fluid-only; held rigid, the P2–P1 plaque gives p(10 ms) = {fmt(rigid)} Pa against "
        "the deforming one's "
        f"{fmt(at(main.get('fixed_newtonian_coarse'), 0.01, 'peak_pressure'))}). "
        f"{COMSOL_ELEMENT}. fsi ships P2–P1 and has P1–P1 with SUPG/PSPG/LSIC "
        "(docs/boundary-conditions.md §7). The peak pressure over the fluid, and where it sits "
        "(† at a boundary's corner or an open boundary's edge):",
        "",
        main_table,
        "",
        "The plaque's own maximum, the largest pressure on its surface (the lumen's boundary "
        "nodes over the plaque; Pa):",
        "",
        plaque_table,
        "",
    ]
    if None in own.values():
        return "\n".join(text + ["(the runs' summaries keep no places: rerun them)"])
    return "\n".join(text + [_element_conclusion(own, cornered, paper)])


def _element_conclusion(own: dict, cornered: list[str], paper: dict) -> str:
    """What the element runs show at 10 ms: where the peaks sit, the plaque's own maxima of
    P1–P1 against P2–P1 on each mesh, and how much of fsi's difference from the study the
    element closes on the coarse mesh."""
    p2, p1 = own[("p2p1", "coarse")]["value"], own[("p1p1", "coarse")]["value"]
    f2, f1 = own[("p2p1", "fine")]["value"], own[("p1p1", "fine")]["value"]
    study = paper_value(paper, "pressure", 0.01, "fixed", "coarse")
    spread = max(o["value"] for o in own.values()) / min(o["value"] for o in own.values()) - 1
    closed = (p1 - p2) / (study - p2)
    return (
        "At 10 ms the peak over the fluid sits at a boundary in: "
        + ("; ".join(cornered) or "none of the runs")
        + ". On the plaque itself P1–P1 gives "
        f"{fmt(p1)} Pa on the coarse mesh against P2–P1's {fmt(p2)} ({100 * (p1 / p2 - 1):+.1f} "
        f"%), and the four runs' plaque maxima lie within {100 * spread:.1f} % of each other; "
        f"the study's coarse {fmt(study)} Pa is {100 * (study / p1 - 1):+.0f} % from P1–P1's. "
        f"On the fine mesh P1–P1's plaque maximum is {fmt(f1)} Pa, "
        f"{100 * (f1 / f2 - 1):+.1f} % from P2–P1's {fmt(f2)}. "
        + (
            "So the element does not explain fsi's lower pressure at 10 ms: what P1–P1 "
            "raised on the coarse mesh was "
            + ("a boundary's value, not the plaque's." if cornered else "not the plaque's.")
            if abs(closed) < 0.5
            else f"So on the coarse mesh the element closes {100 * closed:.0f} % of the gap "
            "between fsi's P2–P1 and the study on the plaque, and on the fine mesh the two "
            f"elements differ by {100 * abs(f1 / f2 - 1):.1f} %: on a mesh of the study's "
            "coarse size the element moves the plaque's pressure at 10 ms by "
            + (
                "a part of fsi's difference from the study, not the whole."
                if closed < 0.9
                else "about fsi's difference from the study."
            )  # fmt: skip
            + (" What P1–P1 raised further was a boundary's value." if cornered else "")
        )
    )


def moving_pressure(moving: dict | None, ring: dict) -> str:
    """The moving wall's peak pressure at 10–50 ms: its values and where each sits."""
    if moving is None:
        return ""
    spots = []
    for t in sorted(ring):
        off = where(moving, t, "pressure_off_openings")
        inside = "" if off is None else f"; off the openings at most {fmt(off['value'], 3)} Pa"
        spots.append(f"{fmt(ring[t], 3)} Pa at {1e3 * t:g} ms ({_at_where(moving, t)}{inside})")
    return (
        'The moving-wall cases\' "peak pressure" is max p over the fluid. While the ringing '
        f"wall draws blood in, it is the largest pressure left: {moving['name']} has "
        + ", ".join(spots)
        + ". A difference in such a sample, between the meshes or from the study, is one of "
        "the ring's phase, so the mesh-convergence figure draws it apart. That the study's "
        "moving-wall pressures and displacements at 10–50 ms differ from fsi's by the phase "
        "of the wall's ring is asserted, not shown: no run here reproduces them."
    )


def _at_where(s: dict, t: float) -> str:
    """Where the run's peak pressure sits at ``t``: the plaque's flank or a boundary's place."""
    found = where(s, t, "peak_pressure")
    if found is None:
        return "not located"
    xy = f"x = {locations.mm(found['x'])} mm, y = {locations.mm(found['y'])} mm"
    return f"{xy}, {plaque_side(s, found)}{_place_note(found)}"
