"""The study's qualitative findings (docs/model.md §6) checked on our runs, for docs/study.md
(:func:`findings`): each with our numbers, the threshold of its verdict and the caveats that
read it (the moving wall's load, the clamped corner's singular stress, the recirculation's
dependence on the outlet).
"""

from __future__ import annotations

from fsi.study.runs import (
    CONFIGS,
    LABELS,
    PULSE_AMPLITUDE,
    PULSE_WINDOW,
    TIMES,
    apex_x,
    change,
    finished,
    fmt,
    peak,
)

# --------------------------------------------------------------------------------------------
# Findings


def load_reason(newtonian: dict | None, carreau: dict | None) -> str:
    """Why the rheology barely changes the structure's load: the wall shear stresses during
    the pulse against the inlet pressure."""
    wn, wc = peak(newtonian, "pulse_wss"), peak(carreau, "pulse_wss")
    if wn is None or wc is None:
        return ""
    wn, wc = wn[0], wc[0]
    return (
        f" Why we differ: the structure is loaded by the blood's pressure and its "
        f"viscous traction; the pressure, up to {PULSE_AMPLITUDE:g} Pa during the 5 ms pulse, "
        "is set by the inlet and the same for both rheologies, while the largest wall shear "
        f"stress in the first {1e3 * PULSE_WINDOW:g} ms is {wn:.3g} Pa (Newtonian) and "
        f"{wc:.3g} Pa (Carreau): the viscous part differs by {abs(wn - wc):.2g} Pa, "
        f"{100 * abs(wn - wc) / PULSE_AMPLITUDE:.2g} % of the pressure. At the shear rates "
        "of the pulse (hundreds per second) Carreau's viscosity is within about 10 % of the "
        "Newtonian 3.5 mPa·s, so the two runs load the wall alike. A study that finds a "
        "large difference must have loaded the wall differently (e.g. by a flow rate "
        "instead of a pressure, or with a Carreau viscosity near μ0)."
    )


def convergence_of_maxima(summaries: dict) -> str:
    """The coarse → fine change of the structure's stress maxima, for each moving-wall
    configuration that has both runs finished."""
    parts = []
    for c in ("moving_newtonian", "moving_carreau"):
        pair = summaries.get(f"{c}_coarse"), summaries.get(f"{c}_fine")
        if not all(map(finished, pair)):
            continue
        values = []
        for label, name in (
            ("whole structure", "max_sss"),
            ("plaque", "plaque_sss"),
            ("cap's largest principal stress", "max_principal_cap"),
        ):
            coarse, fine = (peak(s, name)[0] for s in pair)
            values.append(f"{label} {coarse:.4g} → {fine:.4g} Pa ({change(coarse, fine)})")
        parts.append(f"{LABELS[c]}, coarse → fine: " + "; ".join(values))
    if not parts:
        return ""
    return (
        " Measured: " + ". ".join(parts) + ". The plaque's maxima converge; the whole "
        "structure's, set at the clamped corner, does not."
    )


def _how_weak_ratio(summaries: dict, ratio: float, convergence: dict | None = None) -> str:
    """How the fixed wall's Newtonian/Carreau SSS ratio compares with the mesh's own effect on
    the same maxima."""
    changes = []
    for c in ("fixed_newtonian", "fixed_carreau"):
        coarse, fine = (
            peak(summaries.get(f"{c}_coarse"), "max_sss"),
            peak(summaries.get(f"{c}_fine"), "max_sss"),
        )
        if coarse and fine:
            changes.append(abs(fine[0] / coarse[0] - 1))
    mesh = (
        f", while the mesh moves each maximum by up to {100 * max(changes):.2f} % (coarse → fine)"
        if changes
        else ""
    )
    halved = peak((convergence or {}).get("convergence/fixed_newtonian_fine_dt_halved"), "max_sss")
    fine = peak(summaries.get("fixed_newtonian_fine"), "max_sss")
    if halved and fine:
        mesh += (
            f" and halving the step the Newtonian one by {100 * (halved[0] / fine[0] - 1):+.2f} %"
        )
    return (
        f" How weak: the rheologies differ by {100 * abs(ratio - 1):.2f} %{mesh}, and the "
        'bounds 1 and 1.1 are ours (the study says only "slightly higher"); the sign of so '
        "small a difference is all the finding rests on."
    )


def _paper_table3(paper: dict | None) -> str:
    """The study's own Table 3: Carreau's moving-wall displacement against Newtonian's at each
    report time, on each of its meshes."""
    if not paper:
        return ""
    parts = []
    for mesh in ("coarse", "fine"):
        ratios = [
            paper[("displacement", t, "moving", "carreau", mesh)]
            / paper[("displacement", t, "moving", "newtonian", mesh)]
            for t in TIMES
        ]
        ahead = sum(r >= 1 for r in ratios)
        parts.append(
            f"{mesh} mesh {', '.join(f'{r:.3f}' for r in ratios)} (Carreau ≥ Newtonian at "
            f"{ahead} of {len(TIMES)} times)"
        )
    return (
        ' The study\'s own Table 3 weighs against "the Newtonian displacements are larger": '
        f"Carreau / Newtonian at t = {', '.join(f'{t:g}' for t in TIMES)} s, "
        + "; ".join(parts)
        + "."
    )


def _recirculation_caveat(summaries: dict) -> str:
    """Where the longest zone starts and whether it reaches the outlet."""
    s = summaries.get("fixed_newtonian_fine") or summaries.get("fixed_newtonian_coarse")
    found = peak(s, "recirculation_length")
    if found is None:
        return ""
    g = s["case"]["geometry"]
    room = g["length"] - apex_x(s) - g["stenosis_length"] / 2
    return (
        f"The zones are long for the segment: {1e3 * found[0]:.3g} mm in a "
        f"{1e3 * g['length']:g} mm segment whose plaque ends {1e3 * room:g} mm before the "
        "outlet, so a zone that starts behind the "
        "plaque runs into the outlet, and the outlet's condition may cut it short (the table "
        "below the findings moves the outlet further downstream)."
    )


def findings(
    summaries: dict, paper: dict | None = None, convergence: dict | None = None
) -> list[str]:
    """The study's qualitative findings (docs/model.md §6), each with our numbers and a verdict.
    They compare configurations, so all on one mesh: the fine one once its four runs have
    finished, else the coarse one."""
    view = _OneMesh(summaries)
    found = [
        _fixed_wall_finding(view, summaries, convergence),
        _moving_wall_finding(view, paper),
        _clamped_corner_note(view, summaries),
        _recirculation_finding(view, summaries),
    ]
    return [f for f in found if f is not None]


class _OneMesh:
    """The study's runs on one mesh: the fine one once its four runs have finished, else the
    coarse one."""

    def __init__(self, summaries: dict):
        self.summaries = summaries
        finished_fine = all(finished(summaries.get(f"{c}_fine")) for c in CONFIGS)
        self.level = "fine" if finished_fine else "coarse"

    def pick(self, c: str) -> dict | None:
        return self.summaries.get(f"{c}_{self.level}")

    def largest(self, c: str, name: str) -> float | None:
        found = peak(self.pick(c), name)
        return None if found is None else found[0]

    def mesh(self, c: str) -> str:
        return f"{c}_{self.level}" if self.pick(c) is not None else "–"


def _fixed_wall_finding(view: _OneMesh, summaries: dict, convergence: dict | None) -> str | None:
    """Fixed wall: Newtonian and Carreau give nearly the same SSS, Newtonian slightly higher."""
    fn, fc = view.largest("fixed_newtonian", "max_sss"), view.largest("fixed_carreau", "max_sss")
    if fn and fc:
        ratio = fn / fc
        verdict = (
            "confirmed"
            if 1.0 <= ratio <= 1.1
            else "partly: nearly the same, but Carreau is higher"
            if 0.9 <= ratio < 1.0
            else "refuted"
        )
        return (
            f"**Fixed wall: Newtonian and Carreau give nearly the same SSS, Newtonian "
            f"slightly higher.** Largest SSS over the heartbeat: Newtonian {fn:.4g} Pa "
            f"({view.mesh('fixed_newtonian')}), Carreau {fc:.4g} Pa "
            f"({view.mesh('fixed_carreau')}); "
            f"ratio {ratio:.4f} — {verdict} (confirmed if 1 ≤ ratio ≤ 1.1)."
            + _how_weak_ratio(summaries, ratio, convergence)
        )
    return None


def _moving_wall_finding(view: _OneMesh, paper: dict | None) -> str | None:
    """Moving wall: the Newtonian SSS maximum greatly exceeds the Carreau one, and the
    Newtonian displacements are larger."""
    mn, mc = view.largest("moving_newtonian", "max_sss"), view.largest("moving_carreau", "max_sss")
    dn = view.largest("moving_newtonian", "peak_displacement")
    dc = view.largest("moving_carreau", "peak_displacement")
    if mn and mc and dn and dc:
        ratio, dratio = mn / mc, dn / dc
        verdict = "confirmed" if ratio > 1.5 and dratio > 1.0 else "refuted"
        return (
            f"**Moving wall: the Newtonian SSS maximum greatly exceeds the Carreau one, "
            f"and the Newtonian displacements are larger.** Largest SSS: Newtonian "
            f"{mn:.4g} Pa, Carreau {mc:.4g} Pa (ratio {ratio:.4f}); largest displacement: "
            f"Newtonian {1e6 * dn:.4g} µm, Carreau {1e6 * dc:.4g} µm (ratio {dratio:.4f}) "
            f"— {verdict} (confirmed if the SSS ratio > 1.5 and the displacement ratio "
            f"> 1). In the plaque alone: {fmt(view.largest('moving_newtonian', 'plaque_sss'))} Pa "
            f"vs {fmt(view.largest('moving_carreau', 'plaque_sss'))} Pa "
            f"({view.mesh('moving_newtonian')}, "
            f"{view.mesh('moving_carreau')})."
            + load_reason(view.pick("moving_newtonian"), view.pick("moving_carreau"))
            + _paper_table3(paper)
        )
    return None


def _clamped_corner_note(view: _OneMesh, summaries: dict) -> str | None:
    """Not a finding of the study: where the moving wall's largest SSS is (the clamped
    corner's singular stress)."""
    s = view.pick("moving_newtonian")
    found = peak(s, "max_sss")
    if found is not None and s.get("largest_sss_at", {}).get("region") == "wall":
        x, y = s["largest_sss_at"]["x"], s["largest_sss_at"]["y"]
        return (
            f"*Not a finding of the study, but needed to read Figure 6:* the moving "
            f"wall's largest SSS ({found[0]:.4g} Pa at t = {found[1]:.4g} s, "
            f"{view.mesh('moving_newtonian')}) is in the vessel wall next to its clamped upstream "
            f"end (x = {1e3 * x:.2f} mm, y = {1e3 * y:.2f} mm), where the held edge "
            "meets the loaded lumen side. The elastic stress is singular at that "
            "corner of the boundary conditions, so this maximum grows as the mesh is "
            "refined and says nothing about the plaque; the plaque's largest SSS, "
            f"{fmt(view.largest('moving_newtonian', 'plaque_sss'))} Pa, is the one to compare "
            "(Figure 6, left)." + convergence_of_maxima(summaries)
        )
    return None


def _recirculation_finding(view: _OneMesh, summaries: dict) -> str | None:
    """The recirculation downstream is the same for fixed and moving walls."""
    rf = [view.largest(c, "recirculation_length") for c in ("fixed_newtonian", "fixed_carreau")]
    rm = [view.largest(c, "recirculation_length") for c in ("moving_newtonian", "moving_carreau")]
    if all(rf + rm):
        spread = (max(rf + rm) - min(rf + rm)) / max(rf + rm)
        verdict = "confirmed" if spread < 0.1 else "refuted"
        return (
            f"**The recirculation downstream is the same for fixed and moving walls.** "
            f"Longest reversed-flow zone over the heartbeat: fixed {1e3 * rf[0]:.3g} / "
            f"{1e3 * rf[1]:.3g} mm (Newtonian / Carreau), moving {1e3 * rm[0]:.3g} / "
            f"{1e3 * rm[1]:.3g} mm; spread {100 * spread:.1f} % — {verdict} (confirmed "
            "if within 10 %; a threshold of our choosing: the study gives none). "
            + _recirculation_caveat(summaries)
        )
    return None
