"""How the study's results depend on what the study leaves open, for docs/study.md: the outlet's
distance (:func:`downstream`, the recirculation zone with the outlet further downstream), the
mesh and the step (:func:`convergence`, the stress maxima on four meshes, their Richardson
extrapolation and the step halved) and the fluid's open-boundary and stabilization settings
(:func:`settings_changes`, the physiological-flow settings against the earlier ones).
"""

from __future__ import annotations

import math

from fsi import config
from fsi.config import MESH_LEVELS
from fsi.study.runs import (
    CONFIGS,
    LABELS,
    QUANTITIES,
    TIMES,
    at,
    change,
    ends,
    finished,
    fmt,
    peak,
    run_case,
    span,
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
    far = runs["downstream/fixed_newtonian_plus_2cm"]["case"]
    shipped = main["fixed_newtonian_coarse"]["case"]["geometry"]["length"]
    still = " and still growing at the end of the beat" if longest[1] >= far["end_s"] - 1e-9 else ""
    return "\n".join(lines) + (
        f"\n\nWith the outlet {100 * (far['geometry']['length'] - shipped):.3g} cm further away "
        f"the fixed wall's longest zone is {1e3 * longest[0]:.3g} mm instead of "
        f"{1e3 * base[0]:.3g} ({100 * (longest[0] / base[0] - 1):+.0f} %){still}"
        + (
            f": the study's {100 * shipped:.3g} cm segment cuts the zone at its outlet, so the "
            "lengths the "
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
            + f". The fixed- and moving-wall Newtonian cases to {ends(runs.values())} on the "
            + _levels(runs)
            + " meshes, beside the coarse and fine heartbeats, and the fine mesh with every step "
            "halved (`scripts/reproduce_study.py --only analyses --analysis convergence "
            f"--ranks {_ranks(runs)}`); Richardson's extrapolation from medium, fine and finest "
            "(each a uniform refinement of the one before: half the element size):",
            "",
            "\n".join(lines),
        ]
    )


def _levels(runs: Summaries) -> str:
    """The convergence runs' mesh levels, each with its refinements of the coarse mesh, read
    from their configurations: "medium (1 refinement of the coarse mesh) and finest (3)"."""
    found = sorted(
        {run_case(s).mesh.level for n, s in runs.items() if "_dt_halved" not in n},
        key=MESH_LEVELS.get,
    )
    named = [
        f"{level} ({MESH_LEVELS[level]} refinement{'s' if MESH_LEVELS[level] != 1 else ''} of "
        "the coarse mesh)"
        if k == 0
        else f"{level} ({MESH_LEVELS[level]})"
        for k, level in enumerate(found)
    ]
    return " and ".join(named) or "–"


def _ranks(runs: Summaries) -> str:
    """The ranks the convergence runs ran on, from their summaries."""
    return "/".join(str(k) for k in sorted({s.get("ranks") or 1 for s in runs.values()})) or "–"


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
        f"(`--analysis convergence`, to {ends(runs.values())}):\n\n"
        + "\n".join(lines)
        + f"\n\np(10 ms) varies by {100 * spread:.2f} % over the meshes and the step."
    )


# --------------------------------------------------------------------------------------------
# What the physiological-flow settings changed: the fine runs against those with the fluid's
# earlier settings (the ``earlier`` analysis)


def settings_changes(
    summaries: Summaries, earlier: Summaries, inlet: Summaries, p10: Summaries
) -> str:
    """The section on what the physiological-flow settings changed: the fluid's settings now
    and before (from the runs' configurations), the fine runs' peaks beside the earlier
    settings' (:func:`changes_table`) and what that shows."""
    parts = [_settings_opening(summaries, earlier) + " Earlier → now (change):\n"]
    for column, title, unit, scale in QUANTITIES:
        parts.append(
            f"{title.split(': ')[1]} ({unit}):\n\n"
            f"{changes_table(summaries, earlier, column, scale)}\n"
        )
    parts.append(_what_changed(summaries, earlier, inlet, p10))
    return "\n".join(parts)


def changes_table(summaries: dict, earlier: dict, column: str, scale: float) -> str:
    """The fine runs' peaks of ``column`` beside those of the same runs with the fluid's
    earlier settings (the ``earlier`` analysis): earlier → now (change)."""
    lines = [
        "| t (s) | " + " | ".join(LABELS[c] for c in CONFIGS) + " |",
        "|---" * (1 + len(CONFIGS)) + "|",
    ]
    for t in TIMES:
        cells = []
        for c in CONFIGS:
            before, now = (
                None if v is None else scale * v
                for v in (
                    at(earlier.get(f"earlier/{c}_fine"), t, column),
                    at(summaries.get(f"{c}_fine"), t, column),
                )
            )
            cells.append(f"{fmt(before)} → {fmt(now)} ({change(before, now)})")
        lines.append(f"| {t:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def fluid_settings(case: config.Case) -> str:
    """The fluid's stabilization and open-boundary settings of a case, in words."""
    f = case.fluid
    inlet = f.open_boundary if f.inlet_open_boundary == "same" else f.inlet_open_boundary
    forms = {"stress": "the study's own total-stress form (σ n = −h n)", "do_nothing": "the "
             "do-nothing form"}  # fmt: skip
    beta = (
        f", β = {f.inflow_stabilization:g} on the tangential velocity of inflow"
        if f.inflow_stabilization
        else ""
    )
    return (
        ("SUPG" if f.supg else "the Galerkin fluid")
        + f", the inlet in {forms[inlet]} with its velocity "
        + ("held normal" if f.normal_flow else "free to turn")
        + beta
        + f", the outlet's backflow term in its `{f.outlet.backflow_form}` form"
    )


def _settings_opening(summaries: dict, earlier: dict) -> str:
    """The fluid's settings of the shipped fine runs and of the earlier-settings runs, read
    from their configurations."""
    now = {fluid_settings(run_case(s)) for n, s in summaries.items() if n.endswith("_fine")}
    before = {fluid_settings(run_case(s)) for s in earlier.values()}
    if len(now) != 1 or len(before) != 1:
        return (
            "The fine runs' fluid settings: "
            + ("; ".join(sorted(now)) or "not run")
            + "; with the earlier settings (`--only analyses --analysis earlier`): "
            + ("; ".join(sorted(before)) or "not run")
            + "."
        )
    return (
        f"The study configs now run {now.pop()} (docs/boundary-conditions.md); the fine runs "
        f"with the fluid's earlier settings (`--only analyses --analysis earlier`: "
        f"{before.pop()}, as the study configs had them at git 3d90d70) beside them."
    )


def _largest_change(summaries: dict, earlier: dict, column: str, configs, times) -> float:
    """The largest |earlier → now| relative change of ``column`` over ``configs`` and
    ``times`` (the earlier-settings runs against the shipped fine runs)."""
    found = []
    for c in configs:
        for t in times:
            before = at(earlier.get(f"earlier/{c}_fine"), t, column)
            now = at(summaries.get(f"{c}_fine"), t, column)
            if before and now is not None:
                found.append(abs(now / before - 1))
    return max(found) if found else math.nan


def _what_changed(summaries: dict, earlier: dict, inlet: dict, p10: dict) -> str:
    """What the earlier → now tables show, in numbers read from them, and the inlet held
    normal (the inlet analysis, coarse) beside the shipped coarse runs."""
    pulse = tuple(t for t in TIMES if t <= PULSE_REPORTS)
    during = max(
        _largest_change(summaries, earlier, "peak_velocity", CONFIGS, pulse),
        _largest_change(summaries, earlier, "peak_displacement", CONFIGS, pulse),
    )
    fixed = ("fixed_newtonian", "fixed_carreau")
    p_fixed = _largest_change(summaries, earlier, "peak_pressure", fixed, pulse)
    late = [t for t in TIMES if t > PULSE_REPORTS]
    late_p = {
        t: _largest_change(summaries, earlier, "peak_pressure", CONFIGS, (t,)) for t in late[-2:]
    }
    late_u = _largest_change(summaries, earlier, "peak_velocity", CONFIGS, late[-1:])
    if math.isnan(during):
        return "(the earlier-settings runs: not run)\n"
    pairs = []
    for c in CONFIGS:
        old, new = inlet.get(f"inlet/{c}_normal_flow"), summaries.get(f"{c}_coarse")
        if old is None or new is None:
            continue
        pairs.append(
            f"{LABELS[c]}: p(0.1 s) {fmt(at(old, 0.1, 'peak_pressure'))} → "
            f"{fmt(at(new, 0.1, 'peak_pressure'))} Pa, u(0.8 s) "
            f"{fmt(at(old, 0.8, 'peak_velocity'))} → {fmt(at(new, 0.8, 'peak_velocity'))} m/s"
        )
    ends = sorted({s["case"]["end_s"] for s in p10.values()})
    compared = "to " + " and ".join(span(t) for t in ends) if ends else "in no run kept here"
    return (
        f"During the pulse and the wall's first response (t ≤ {span(PULSE_REPORTS)}) the peak "
        f"velocity and displacement are within {100 * during:.1f} % of the earlier settings' "
        f"and the fixed wall's peak pressure within {100 * p_fixed:.1f} %; the moving wall's "
        "peak pressure there is the ringing wall's sample (Table 2's section). Afterwards the "
        "stress inlet holds the total normal stress, not the pressure: with h = 0 the inlet's "
        "pressure is 2μ ∂u_n/∂n, and its zero shear stress lets the velocity turn; the peak "
        f"velocity at {late[-1]:g} s moves by up to {100 * late_u:.0f} %, the peak pressure "
        + " and ".join(f"at {t:g} s by up to {100 * v:.0f} %" for t, v in late_p.items())
        + ". The inlet alone, the coarse runs with the inlet held normal (`--analysis inlet`) → "
        "shipped: "
        + ("; ".join(pairs) or "not run")
        + f". SUPG and the outlet's forms alone are compared {compared} (the p10 table); "
        "alone, later, they are not compared by a run kept here.\n"
    )


PULSE_REPORTS = 0.02
"""s: the report times up to this one are the pulse's and the wall's first response."""
