"""The study's runs reduced to what docs/study.md is made from: a summary per run
(:func:`summarise`: its provenance and case, the three peaks at the study's report times, the
maxima the findings compare, where the largest stresses and pressure sit), written to and read
back from docs/study_runs/, and the study's printed Tables 1–3
(docs/reference/boujena2014_tables.csv) set beside them (:func:`comparison_rows`,
docs/study_tables.csv). fsi/study/document.py and fsi/study/analyses.py build on it.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import math
import re
import shlex
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace

from fsi import config
from fsi.output import report, report_runs

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "docs" / "reference" / "boujena2014_tables.csv"
"""The study's Tables 1–3 as printed (120 values, SI units)."""

TIMES = (0.01, 0.02, 0.05, 0.1, 0.8)
QUANTITIES = [
    ("peak_velocity", "Table 1: peak velocity", "m/s", 1.0),
    ("peak_pressure", "Table 2: peak pressure", "Pa", 1.0),
    ("peak_displacement", "Table 3: peak displacement", "µm", 1.0e6),
]
PAPER_QUANTITY = {
    "velocity": "peak_velocity",
    "pressure": "peak_pressure",
    "displacement": "peak_displacement",
}
"""The reference file's quantity names → our metrics columns."""
LABELS = {
    "fixed_newtonian": "fixed wall, Newtonian",
    "fixed_carreau": "fixed wall, Carreau",
    "moving_newtonian": "moving wall, Newtonian",
    "moving_carreau": "moving wall, Carreau",
}
CONFIGS = list(LABELS)

PULSE_WINDOW = 0.01
"""s: the wall shear stress during the pulse (and the wall's first response) is its maximum up
to this time."""


def plaque_max(row: dict) -> float | None:
    values = [row[c] for c in ("max_sss_cap", "max_sss_lipid") if c in row]
    return max(values) if values else None


def _pulse_wss(row: dict) -> float | None:
    if row["t"] > PULSE_WINDOW or "max_wss" not in row:
        return None
    return max(abs(row["min_wss"]), abs(row["max_wss"]))


AT_COLUMNS = ("peak_velocity", "peak_pressure", "peak_displacement", "inlet_flow_rate")
"""The columns a summary keeps at each of :data:`TIMES`."""

MAXIMA = {
    "peak_velocity": lambda r: r.get("peak_velocity"),
    "peak_pressure": lambda r: r.get("peak_pressure"),
    "max_sss": lambda r: r.get("max_sss"),
    "plaque_sss": plaque_max,
    "max_principal_cap": lambda r: r.get("max_principal_cap"),
    "peak_displacement": lambda r: r.get("peak_displacement"),
    "recirculation_length": lambda r: r.get("recirculation_length"),
    "pulse_wss": _pulse_wss,
}
"""The maxima over the run that the findings compare: name → the row's value (None: not there)."""


def load(folder: Path, runs) -> dict[str, report_runs.Run]:
    """The runs there are (finished or not), by name."""
    loaded = {}
    for run in runs:
        path = folder / run.name
        if (path / "metrics.csv").is_file():
            loaded[run.name] = report_runs.load_run(path)
    return loaded


def summarise(run: report_runs.Run, locations: bool = True) -> dict:
    """The run's provenance and case (the settings the analyses vary), its three peaks and
    flow rate at :data:`TIMES`, the :data:`MAXIMA` (value, time) and, with field files and
    ``locations``, where its maxima are (plane and axisymmetric runs)."""
    rows, info, case = run.rows, run.summary, run.case
    its = [r["coupling_iterations"] for r in rows if "coupling_iterations" in r]
    maxima = {}
    for name, get in MAXIMA.items():
        found = [(get(r), r["t"]) for r in rows if get(r) is not None]
        if found:
            maxima[name] = list(max(found, key=lambda p: p[0]))
    summary = {
        "name": run.path.name,
        "git": info.get("git"),
        "dolfinx": info.get("dolfinx"),
        "ranks": info.get("ranks"),
        "command": re.sub(
            r"\S*/(fsi/__main__\.py|configs/|results/)", r"\1", info.get("command", "")
        ),
        "case": case_record(case),
        "config": config.to_dict(case),
        "steps": len(rows),
        "end_time_s": rows[-1]["t"] if rows else 0.0,
        "finished": bool(rows) and abs(rows[-1]["t"] - case.time.end) < 1e-9,
        "wall_time_s": round(sum(r.get("wall_time_s", 0.0) for r in rows), 1),
        "mean_coupling_iterations": sum(its) / len(its) if its else None,
        "at": {
            f"{t:g}": {column: report.value_at(rows, t, column) for column in AT_COLUMNS}
            for t in TIMES
        },
        "maxima": maxima,
    }
    if case.structure.mode == "moving_wall":
        summary["ring"] = ring(rows, case)
    if summary["finished"] and locations:
        summary.update(_locations(run, maxima, case.time.end))
    return summary


def case_record(case: config.Case) -> dict:
    """The settings the analyses vary, as a summary records them (``case``): the case's name,
    the structure's mode, the geometry, the wall's relaxation time, the regions' moduli, the
    tissue support, the inlet's form and amplitude and the end time."""
    return {
        "name": case.name,
        "structure_mode": case.structure.mode,
        "geometry": dataclasses.asdict(case.geometry),
        "relaxation_time_s": case.structure.wall.viscous_relaxation_time,
        "young_modulus": {
            r: getattr(case.structure, r).young_modulus for r in ("wall", "cap", "lipid")
        },
        "support": dataclasses.asdict(case.structure.support),
        "inlet_open_boundary": case.fluid.inlet_open_boundary,
        "normal_flow": case.fluid.normal_flow,
        "end_s": case.time.end,
        "inlet_amplitude": getattr(case.fluid.inlet, "amplitude", None),
    }


def ring(rows: Sequence[dict], case: config.Case) -> dict | None:
    """The moving wall's ring after the inlet pulse, from its peak |η| over time: the crests
    of |η| (each a row above the one before and not below the one after, its time refined by
    the parabola through the three) after the first crest past the pulse's end (the pulse's own
    peak response) and within the schedule's first segment (the steps that resolve the ring),
    and the frequency they give, (n − 1) / (2 (t_last − t_first)): |η| crests twice per period
    of the wall's lowest coupled mode (docs/wall-damping.md). None without a pulse or three
    such crests."""
    pulse = getattr(case.fluid.inlet, "duration", None)
    window = case.time.schedule[0].until
    series = [(r["t"], r["peak_displacement"]) for r in rows if "peak_displacement" in r]
    crests = [
        t + 0.5 * (t - s) * (a - c) / (a - 2 * b + c)  # the parabola's vertex (equal steps)
        for (s, a), (t, b), (u, c) in zip(series, series[1:], series[2:])
        if pulse is not None and pulse < t and u <= window + 1e-12 and a < b >= c
    ][1:]
    if len(crests) < 3:
        return None
    return {
        "hz": (len(crests) - 1) / (2 * (crests[-1] - crests[0])),
        "crests_s": crests,
    }


def _locations(run: report_runs.Run, maxima: dict, end: float) -> dict:
    """Where the run's reported maxima sit (fsi/study/locations.py), from its field files: at
    each of :data:`TIMES` up to ``end`` the largest pressure, |u| and |η|, the largest pressure
    off the open boundaries and on the plaque's surface (``where``); the whole structure's and
    the plaque's largest |σ₁₂| at their times (``largest_sss_at``, ``plaque_sss_at``, with the
    structure's largest |η| then, which Figures 7–8 magnify)."""
    from fsi.study import locations

    geometry = dataclasses.asdict(run.case.geometry)
    out: dict = {}
    if (run.path / "fields.xdmf").is_file():
        out["where"] = {}
        for t in (t for t in TIMES if t <= end + 1e-12):
            found = locations.fluid_maxima(run.path, t, geometry)
            eta = locations.displacement_maximum(run.path, t, geometry)
            out["where"][f"{t:g}"] = found if eta is None else {**found, "peak_displacement": eta}
    if (run.path / "solid.xdmf").is_file():
        for key, name, regions in (
            ("largest_sss_at", "max_sss", None),
            ("plaque_sss_at", "plaque_sss", ("cap", "lipid")),
        ):
            if name in maxima:
                t = maxima[name][1]
                found = locations.cell_maximum(run.path, "sss", t, geometry, regions)
                eta = report.value_at(run.rows, t, "peak_displacement")
                out[key] = {**found, "t": t, "peak_displacement": eta}
    return out


def where(summary: dict | None, t: float, name: str) -> dict | None:
    """Where ``name`` (``peak_pressure``, ``peak_velocity``, ``peak_displacement``,
    ``pressure_off_openings``, ``plaque_pressure``) sits at report time ``t``: {value, x, y,
    place}, or None (no such run, time or field files). A summary made before the places were
    kept gives the peak pressure's position alone (its ``peak_pressure_at``)."""
    if summary is None:
        return None
    found = summary.get("where", {}).get(f"{t:g}", {}).get(name)
    old = summary.get("peak_pressure_at", {}).get(f"{t:g}")
    if found is None and name == "peak_pressure" and old is not None:
        from fsi.study import locations

        g = summary["case"]["geometry"]
        place = locations.boundary_place(old[0], old[1], g)
        return {"value": at(summary, t, name), "x": old[0], "y": old[1], "place": place}
    return found


def run_case(summary: dict) -> config.Case:
    """The configuration the run used, through fsi.config: the resolved configuration its
    summary keeps (``config``, its run folder's config.yaml); for a summary made before it kept
    one, its command's case file with the command's ``--set`` overrides (and, for a run of
    ``fsi sweep``, its folder's name's settings), which must then give the settings the summary
    recorded (``case``): raises ValueError where today's case file no longer does."""
    if "config" in summary:
        return _config_from_dict(json.dumps(summary["config"], sort_keys=True))
    case = _config_from_command(summary["command"], summary["name"])
    off = _differences(summary["case"], case_record(case))
    if off:
        raise ValueError(
            f"{summary['name']}: the configuration of its command ({summary['command']}) is "
            f"not the one its summary recorded: {'; '.join(off)}"
        )
    return case


@functools.cache
def _config_from_dict(data: str) -> config.Case:
    return config.from_dict(json.loads(data))


@functools.cache
def _config_from_command(command: str, name: str) -> config.Case:
    """The case of ``fsi run CONFIG --set ...`` (or of the run ``name`` of ``fsi sweep CONFIG
    --set ... --vary ...``: its folder is named ``key=value,key=value``)."""
    words = shlex.split(command)
    verb = next(w for w in words if w in ("run", "sweep"))
    case_file = ROOT / words[words.index(verb) + 1]
    overrides = [b for a, b in zip(words, words[1:]) if a == "--set"]
    if verb == "sweep":
        overrides += re.split(r",(?=[\w.]+=)", name)
    return config.load(case_file, overrides)


def _differences(recorded, rebuilt, key: str = "") -> list[str]:
    """Where ``rebuilt`` differs from ``recorded`` (keys only ``rebuilt`` has are new
    settings, not differences)."""
    if isinstance(recorded, dict) and isinstance(rebuilt, dict):
        return [
            d
            for k in recorded
            for d in _differences(recorded[k], rebuilt.get(k), f"{key}.{k}".strip("."))
        ]
    same = recorded == rebuilt or (
        isinstance(recorded, list) and list(recorded) == list(rebuilt or ())
    )
    return [] if same else [f"{key}: {recorded!r} recorded, {rebuilt!r} rebuilt"]


def make_summaries(
    runs: dict[str, report_runs.Run], folder: Path, names: Sequence[str]
) -> dict[str, dict]:
    """Each named run's summary: made from its run folder (and written to ``folder``) if it is
    loaded, else read from ``folder`` (the committed one) if there."""
    out = {}
    for name in names:
        path = folder / f"{name}.json"
        if name in runs:
            out[name] = summarise(runs[name])
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(out[name], indent=1) + "\n")
        elif path.is_file():
            out[name] = json.loads(path.read_text())
    return out


def at(summary: dict | None, t: float, column: str) -> float | None:
    """``column`` at report time ``t`` (None: no such run, time or value)."""
    return None if summary is None else summary["at"].get(f"{t:g}", {}).get(column)


def peak(summary: dict | None, name: str) -> tuple[float, float] | None:
    """(largest value, its time) of :data:`MAXIMA`'s ``name`` over the run, or None."""
    found = None if summary is None else summary["maxima"].get(name)
    return None if found is None else (found[0], found[1])


def apex_x(summary: dict) -> float:
    """x of the run's plaque apex (m), by the geometry's own rule (geometry/stenosis.py)."""
    from fsi.geometry import stenosis

    return stenosis.apex_x(SimpleNamespace(**summary["case"]["geometry"]))


def finished(summary: dict | None) -> bool:
    return summary is not None and summary["finished"]


def fmt(x: float | None, digits: int = 4) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.{digits}g}"


def span(t: float) -> str:
    """A time as the document writes it: below 0.1 s in ms, else in s."""
    return f"{1e3 * t:.4g} ms" if t < 0.1 else f"{t:.4g} s"


def after_pulse(case: config.Case) -> tuple[float, float]:
    """(the step of the schedule up to the inlet pulse's end, the step after it) (s)."""
    duration = case.fluid.inlet.duration
    before = next(s.dt for s in case.time.schedule if s.until >= duration - 1e-12)
    after = next(s.dt for s in case.time.schedule if s.until > duration + 1e-12)
    return before, after


def ends(summaries) -> str:
    """Where the runs of ``summaries`` (an iterable of summaries) end: "20 ms" (or "10 ms and
    0.1 s"), from the end time each configuration set."""
    return " and ".join(span(t) for t in sorted({run_case(s).time.end for s in summaries})) or "–"


def schedule_text(case: config.Case) -> str:
    """The case's step schedule in words: "0.25 ms steps to 50 ms, 1 ms to 0.1 s, …"."""
    return ", ".join(
        f"{1e3 * s.dt:.4g} ms{' steps' if k == 0 else ''} to {span(s.until)}"
        for k, s in enumerate(case.time.schedule)
    )


def change(coarse: float | None, fine: float | None) -> str:
    if coarse is None or fine is None or coarse == 0:
        return "–"
    return f"{100 * (fine - coarse) / abs(coarse):+.1f} %"


# --------------------------------------------------------------------------------------------
# The study's tables beside ours


def paper_values(path: Path = PAPER) -> dict[tuple[str, float, str, str, str], float]:
    """The study's printed values: (quantity, t, wall, fluid, mesh) → value (SI), in the file's
    order."""
    lines = [line for line in path.read_text().splitlines() if line and not line.startswith("#")]
    return {
        (r["quantity"], float(r["t_s"]), r["wall"], r["fluid"], r["mesh"]): float(r["value"])
        for r in csv.DictReader(lines)
    }


def comparison_rows(summaries: dict[str, dict], paper: dict) -> list[dict]:
    """One row per printed value: its key, the paper's value, ours (None: no run) and where
    ours sits (``where``: {value, x, y, place}, None without the run's places)."""
    rows = []
    for (quantity, t, wall, fluid, mesh), printed in paper.items():
        summary = summaries.get(f"{wall}_{fluid}_{mesh}")
        column = PAPER_QUANTITY[quantity]
        rows.append(
            dict(
                quantity=quantity,
                t_s=t,
                wall=wall,
                fluid=fluid,
                mesh=mesh,
                paper=printed,
                fsi=at(summary, t, column),
                where=where(summary, t, column),
            )
        )
    return rows


def write_comparison_csv(rows: Sequence[dict], path: Path) -> Path:
    """docs/study_tables.csv: ``quantity,t_s,wall,fluid,mesh,paper,fsi`` (SI; fsi empty where
    there is no run)."""
    with path.open("w", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(["quantity", "t_s", "wall", "fluid", "mesh", "paper", "fsi"])
        for r in rows:
            ours = "" if r["fsi"] is None else f"{r['fsi']:.6g}"
            writer.writerow(
                [
                    r["quantity"],
                    f"{r['t_s']:g}",
                    r["wall"],
                    r["fluid"],
                    r["mesh"],
                    f"{r['paper']:g}",
                    ours,
                ]
            )
    return path


def difference(row: dict) -> float | None:
    """(fsi − paper) / |paper|, or None."""
    if row["fsi"] is None or row["paper"] == 0:
        return None
    return (row["fsi"] - row["paper"]) / abs(row["paper"])
