"""How the study's results depend on what the study leaves open, for docs/study.md: the outlet's
distance (:func:`downstream`, the recirculation zone with the outlet further downstream) and
the mesh and the step (:func:`convergence`, the stress maxima on four meshes, their Richardson
extrapolation and the step halved).
"""

from __future__ import annotations

import math

from fsi.study.runs import (
    CONFIGS,
    LABELS,
    QUANTITIES,
    TIMES,
    at,
    finished,
    fmt,
    peak,
)
from fsi.study.wall_analyses import (
    Summaries,
    in_um,
)

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
                f"{fmt(at(s, 0.01, 'peak_velocity'), 3)} | "
                f"{in_um(None if eta is None else eta[0])} "
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
        f"({100 * (longest[0] / base[0] - 1):+.0f} %){still}"
        + (
            ": the study's 2 cm segment cuts the zone at its outlet, so the lengths the "
            "finding compares are set by the study's domain, not by the artery it stands for."
            if longest[0] / base[0] - 1 > 0.1
            else ": the study's segment does not cut the zone short."
        )
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


def _reached(main: Summaries) -> str:
    """When the study's runs reach their stress maxima: the latest time over the runs."""
    times = [
        found[1]
        for s in main.values()
        for name in CONVERGED
        if (found := peak(s, name)) is not None
    ]
    if not times:
        return "(no run)"
    return f"which the study's runs reach by t = {1e3 * max(times):.3g} ms"


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
            "The findings rest on the structure's stress maxima, "
            + _reached(main)
            + ". The fixed- and moving-wall Newtonian cases to 20 ms on the medium (one "
            "refinement of the coarse mesh) and finest (three) meshes, beside the coarse and "
            "fine heartbeats, and the fine mesh with every step halved to 20 ms "
            "(`scripts/reproduce_study.py --only analyses --analysis convergence --ranks 2`); "
            "Richardson's extrapolation from medium, fine and finest (each half the element "
            "size of the one before):",
            "",
            "\n".join(lines),
        ]
    )


def mesh_changes(main: Summaries) -> str:
    """The largest coarse → fine change of each peak over the report times, relative to the
    coarse value (the peak pressure of the fixed wall only: the moving wall's is a sample of
    its ring)."""
    parts = []
    for column, title, _, _ in QUANTITIES:
        walls = ("fixed",) if column == "peak_pressure" else ("fixed", "moving")
        found = []
        for c in (c for c in CONFIGS if c.split("_")[0] in walls):
            for t in TIMES:
                a, b = at(main.get(f"{c}_coarse"), t, column), at(main.get(f"{c}_fine"), t, column)
                if a and b is not None:
                    found.append((abs(b / a - 1), b / a - 1, c, t))
        if found:
            _, change, c, t = max(found)
            which = "the fixed wall's " if walls == ("fixed",) else ""
            parts.append(
                f"{which}{title.split(': ')[1]} {100 * change:+.1f} % ({LABELS[c]}, {t:g} s)"
            )
    return "The largest changes: " + "; ".join(parts) + "." if parts else ""


def pressure_convergence(runs: Summaries, main: Summaries) -> str:
    """fsi's own fixed-wall Newtonian p(10 ms) and p(20 ms) on the four meshes and with every
    step halved (the convergence analysis's runs beside the study's), beside the study's."""
    levels = {
        "coarse": main.get("fixed_newtonian_coarse"),
        "medium": runs.get("convergence/fixed_newtonian_medium"),
        "fine": main.get("fixed_newtonian_fine"),
        "finest": runs.get("convergence/fixed_newtonian_finest"),
        "fine, dt halved": runs.get("convergence/fixed_newtonian_fine_dt_halved"),
    }
    rows = {t: [at(s, t, "peak_pressure") for s in levels.values()] for t in (0.01, 0.02)}
    if any(v is None for v in rows[0.01]):
        return ""
    lines = [
        "| fixed wall, Newtonian | " + " | ".join(levels) + " |",
        "|---" * (1 + len(levels)) + "|",
    ]
    lines += [
        f"| p({1e3 * t:g} ms) (Pa) | " + " | ".join(map(fmt, v)) + " |" for t, v in rows.items()
    ]
    p10 = rows[0.01]
    spread = max(p10) / min(p10) - 1
    return (
        "fsi's own peak pressure after the pulse on the four meshes and with every step halved "
        "(`--analysis convergence`, to 20 ms):\n\n"
        + "\n".join(lines)
        + f"\n\np(10 ms) varies by {100 * spread:.2f} % over the meshes and the step."
    )
