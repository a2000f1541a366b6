"""The sections of docs/study.md on the fixed wall's displacement (fsi/study/analyses.py
composes them with the others): the structure alone under a uniform lumen pressure
(:func:`static_compliance`) and why the fixed wall's displacement differs from the study's
(:func:`compliance`), with the small helpers every analysis formats its numbers with (the
moving wall's, a ringing wall: fsi/study/damping_analyses.py).

Every threshold a verdict uses is stated beside it; the study's values come from
docs/reference/boujena2014_tables.csv, the runs' settings from their configurations
(:func:`fsi.study.runs.run_case`).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from fsi.study.runs import (
    PAPER_QUANTITY,
    at,
    ends,
    fmt,
    run_case,
)

Summaries = dict[str, dict]


STATIC_PRESSURE = 1000.0
"""Pa: the uniform lumen pressure of :func:`static_compliance` (the elastic response is linear
to 0.1 % at this load: 0.44 mm on a 1 mm wall)."""


def static_compliance(docs_runs: Path) -> dict:
    """The structure's displacement per Pa of a uniform pressure on its lumen side, quasi-static
    (no inertia, no flow): the fixed wall's (plaque only) and the moving wall's peak |η| under
    :data:`STATIC_PRESSURE`, coarse mesh, in m/Pa. Computed once and kept in
    ``docs_runs/static_compliance.json`` with where it came from (git commit, case file, the
    solves' wall time); remove the file and write the document (``scripts/reproduce_study.py
    --document-only``) to compute it again."""
    from fsi.output import provenance

    path = docs_runs / "static_compliance.json"
    if path.is_file():
        return json.loads(path.read_text())
    config_file = Path(__file__).resolve().parents[2] / "configs" / "stenosis_moving_newtonian.yaml"
    tic = time.perf_counter()
    out: dict = {
        mode: uniform_pressure_compliance(config_file, mode)
        for mode in ("fixed_wall", "moving_wall")
    }
    out.update(
        git=provenance.git_revision(),
        case_file=str(config_file.relative_to(config_file.parents[1])),
        wall_time_s=round(time.perf_counter() - tic, 1),
    )
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
    text = [
        _fixed_wall_paragraph(main, paper, static, target, shipped),
        "",
        _sweep_opening(shape),
        "",
        "\n".join(lines),
        "",
        f"The cap and the lipid pool move |η| / p by at most {100 * spread:.2g} % at a "
        "degree (the last column: the largest relative spread over the cap × lipid-pool "
        "combinations of a degree): the study prints one modulus for the whole plaque "
        f"({plaque_material(main.get('fixed_newtonian_coarse'))}), so the line between cap "
        "and lipid pool is not a material boundary, and only the plaque's outline counts. "
        f"The most compliant degree, {best[0]:g}, moves {fmt(1e6 * best[1], 2)} µm/Pa, "
        f"still {fmt(target / best[1], 2)}× below the study's, and its jet ({fmt(best[2], 3)} "
        f"m/s at 10 ms) is {fmt(best[2] / u_paper, 2)}× the study's {u_paper:g} m/s: the degree "
        "that would bring the displacement closer takes the velocity away.",
    ]
    readings, best = _other_readings(
        others, plane, t, target, shipped, best, main.get("fixed_newtonian_coarse")
    )
    text += readings
    verdict = (
        "No plausible reading of what the study leaves open reproduces its fixed-wall compliance"
        if best[1] < target / WITHIN_FACTOR
        else f"A reading within a factor {WITHIN_FACTOR:g} of the study's compliance exists"
    )
    text.append(
        f"\n**{verdict}** (within a factor {WITHIN_FACTOR:g}; the closest is "
        f"{fmt(target / best[1], 2)}× below). We do not change printed parameters to match the "
        "study's tables."
    )
    return "\n".join(text)


def _sweep_opening(shape: Summaries) -> str:
    """What the sweep of the plaque's shape varies (its runs' geometries) and how far it ran."""
    swept = {
        key: sorted({s["case"]["geometry"][key] for s in shape.values()})
        for key in ("stenosis_degree", "cap_thickness", "lipid_length")
    }
    return (
        "The study states neither the stenosis degree, nor the cap thickness, nor the lipid "
        "pool's size (docs/model.md §1). `fsi sweep` of the three (degree "
        f"{', '.join(f'{d:g}' for d in swept['stenosis_degree'])} × cap "
        f"{', '.join(f'{1e3 * c:g}' for c in swept['cap_thickness'])} mm × lipid pool "
        f"{', '.join(f'{1e3 * c:g}' for c in swept['lipid_length'])} mm) on the coarse "
        f"fixed-wall Newtonian case to {ends(shape.values())} (`scripts/reproduce_study.py "
        "--only analyses --analysis compliance`):"
    )


def _plaque(s: dict):
    """The cap's material (the lipid pool's as well where :func:`plaque_material` says so) of
    the configuration run ``s`` ran."""
    return run_case(s).structure.cap


def plaque_material(s: dict) -> str:
    """The plaque's modulus and Poisson ratio in the configuration run ``s`` ran: one pair
    when the cap and the lipid pool share it (the study prints one), else each."""
    structure = run_case(s).structure
    cap, lipid = structure.cap, structure.lipid
    pairs = {f"{1e-6 * m.young_modulus:g} MPa, ν = {m.poisson_ratio:g}" for m in (cap, lipid)}
    if len(pairs) == 1:
        return f"the shipped configs' cap and lipid pool: {pairs.pop()}"
    return (
        f"the shipped configs' cap: {1e-6 * cap.young_modulus:g} MPa, ν = {cap.poisson_ratio:g}"
        f"; lipid pool: {1e-6 * lipid.young_modulus:g} MPa, ν = {lipid.poisson_ratio:g}"
    )


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
        f"the flow: a plaque of ν = {_plaque(main.get('fixed_newtonian_coarse')).poisson_ratio:g} "
        "bonded to a rigid wall hardly compresses, and what "
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
    others: Summaries,
    plane: Summaries | None,
    t: float,
    target: float,
    shipped: float,
    best,
    base: dict | None = None,
) -> tuple[list[str], tuple]:
    """The other readings of "fixed wall" and of the plaque (the wall held outside, a softer
    lipid pool, plane stress), as paragraphs, and the most compliant reading so far; ``base``
    the shipped run (its plaque's material, from its configuration)."""
    text: list[str] = []
    held = others.get("compliance/wall_held_outside")
    if ratio(held, t) is not None:
        r = ratio(held, t)
        stiffness = f"{held['case']['support']['stiffness']:g}".replace("e+", "e")
        text.append(
            '\nReading "fixed wall" as the vessel wall deforming with its outer surface held '
            f"(the moving-wall case with `structure.support.stiffness: {stiffness}` Pa/m on the "
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
            "\nNot a reading of the study, which prints "
            + ("one modulus" if base is None else f"{1e-6 * _plaque(base).young_modulus:g} MPa")
            + " for the plaque, but what would: a softer lipid pool "
            "(`structure.lipid.young_modulus`; real lipid cores are in the kPa range) under the "
            "shipped cap: " + "; ".join(parts) + "."
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
            + _p_wave(base, flat)
        )
        if r > best[1]:
            best = ("plane stress", r, at(flat, t, "peak_velocity"))
    return text, best


def p_wave(material) -> float:
    """λ + 2μ = E (1 − ν) / ((1 + ν)(1 − 2ν)) of an elastic material (Pa): its stiffness
    against compression in one direction with the others held."""
    e, nu = material.young_modulus, material.poisson_ratio
    return e * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def _p_wave(base: dict | None, flat: dict) -> str:
    """The plaque's λ + 2μ in plane strain (the shipped run's material) and in plane stress
    (the plane-stress run's equivalent plane-strain moduli), in units of the shipped E."""
    if base is None:
        return ""
    strain, stress = _plaque(base), _plaque(flat)
    e = strain.young_modulus
    return (
        "Near incompressibility stiffens plane strain against the plaque's compression "
        f"(λ + 2μ = {p_wave(strain) / e:.2g} E at ν = {strain.poisson_ratio:g}) far more than "
        f"plane stress ({p_wave(stress) / e:.3g} E)."
    )


WITHIN_FACTOR = 2.0
"""A reading reproduces the study's fixed-wall compliance when within this factor of it (our
bound)."""
