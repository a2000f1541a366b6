"""The study's cases in the plane, axisymmetric and 3D models, side by side
(docs/axisymmetric.md, "The study, axisymmetric"; docs/3d.md, "Plane, axisymmetric and 3D on
the same plaque").

Runs (unless ``--reuse`` finds them finished) ``fsi run`` of each case's config in each model —
configs/stenosis_CASE.yaml, configs/axisymmetric/stenosis_CASE.yaml and
configs/3d/stenosis_eccentric_CASE.yaml (the 3D plaque eccentric over 120°; the moving-wall
cases only) — on the coarse mesh and ``--ranks`` ranks, into ``--out``, then prints, per case and
model: the wall's displacement per Pa of peak pressure at rest (0.8 s), the cap's largest
principal stress (when and where), the largest wall shear stress of the pulse (t ≤ 10 ms), the
longest recirculation zone and the cost (cells, the steps' wall time, steps, coupling iterations
per step); and the structure's displacement per Pa under a uniform static lumen pressure in each
model beside the thin tube's R²/(E h) and Lamé's thick cylinder.
The last line of its standard output is one JSON object of all of it.

Usage::

    .venv/bin/python scripts/compare_models.py --out results/axisymmetric_study
    .venv/bin/python scripts/compare_models.py --out results/models --ranks 2 \
        --models plane axisymmetric 3d --cases moving_carreau
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from fsi import config
from fsi.output import report_runs
from fsi.run import child_runs
from fsi.study.runs import CONFIGS, LABELS, summarise
from fsi.study.wall_analyses import uniform_pressure_compliance
from fsi.study.wall_compliance import estimates

ROOT = Path(__file__).resolve().parents[2]

MODELS = {
    "plane": "configs/stenosis_{}.yaml",
    "axisymmetric": "configs/axisymmetric/stenosis_{}.yaml",
    "3d": "configs/3d/stenosis_eccentric_{}.yaml",
}
"""Model → its study configs under the checkout, ``{}`` the case's name (3D: the moving-wall
cases only)."""

AT_REST = 0.8
"""s: the report time at which both walls are at rest under the late pressure."""


def config_file(model: str, name: str) -> Path:
    return ROOT / MODELS[model].format(name)


def run(model: str, name: str, out: Path, settings: list[str], ranks: int, reuse: bool) -> Path:
    """The run folder of one case in one model (:func:`fsi.run.child_runs.run`)."""
    return child_runs.run(config_file(model, name), out / f"{model}_{name}", settings, ranks, reuse)


def row(folder: Path) -> dict:
    """What the comparison takes from one run."""
    loaded = report_runs.load_run(folder)
    summary = summarise(loaded, locations=False)  # the cap's σ₁ is placed from metrics.csv
    maxima, rest = summary["maxima"], summary["at"][f"{AT_REST:g}"]
    cap, when = maxima["max_principal_cap"]
    at_cap = next(r for r in loaded.rows if r["t"] == when)
    return {
        "peak_velocity": maxima["peak_velocity"][0],
        "peak_displacement": maxima["peak_displacement"][0],
        "displacement_per_pa_at_rest": rest["peak_displacement"] / rest["peak_pressure"],
        "cap_principal": cap,
        "cap_principal_t": when,
        "cap_principal_at": [
            at_cap[f"max_principal_cap_{axis}"]
            for axis in "xyz"
            if f"max_principal_cap_{axis}" in at_cap
        ],
        "pulse_wss": maxima["pulse_wss"][0],
        "recirculation_length": maxima["recirculation_length"][0],
        "cells": loaded.summary["cells"],
        "wall_time_s": summary["wall_time_s"],
        "steps": summary["steps"],
        "coupling_iterations": summary["mean_coupling_iterations"],
        "finished": summary["finished"],
    }


def _where(r: dict) -> str:
    return "(" + ", ".join(f"{1e3 * c:.2f}" for c in r["cap_principal_at"]) + ")"


def _structure(cells: dict) -> int:
    return cells["total"] - cells["fluid"]


TABLES = {
    "The blood": [
        ("largest velocity (m/s)", lambda r: f"{r['peak_velocity']:.4g}"),
        ("largest \\|WSS\\|, t ≤ 10 ms (Pa)", lambda r: f"{r['pulse_wss']:.4g}"),
        ("longest recirculation (mm)", lambda r: f"{1e3 * r['recirculation_length']:.3g}"),
    ],
    "The structure": [
        ("largest \\|η\\| (µm)", lambda r: f"{1e6 * r['peak_displacement']:.4g}"),
        ("\\|η\\|/p at 0.8 s (µm/kPa)", lambda r: f"{1e9 * r['displacement_per_pa_at_rest']:.4g}"),
        ("cap's largest σ₁ (kPa)", lambda r: f"{1e-3 * r['cap_principal']:.4g}"),
        ("at t (ms)", lambda r: f"{1e3 * r['cap_principal_t']:.4g}"),
        ("at (z, r), (x, y) or (x, y, z) (mm)", _where),
    ],
    "The cost": [
        ("cells: fluid, structure", lambda r: f"{r['cells']['fluid']}, {_structure(r['cells'])}"),
        ("wall time (s)", lambda r: f"{r['wall_time_s']:.4g}"),
        ("steps", lambda r: f"{r['steps']}"),
        ("coupling iterations per step", lambda r: f"{r['coupling_iterations']:.3g}"),
    ],
}
"""Title → its columns (markdown tables): header and the cell made from a :func:`row`."""


def static(models: list[str]) -> dict[str, float]:
    """The moving wall's peak |η| per Pa under a uniform static lumen pressure in each of
    ``models`` and, for the tube they stand for (the axisymmetric config's radius), the thin
    tube's R²/(E h) and Lamé's thick cylinder (m/Pa)."""
    tube = config.load(config_file("axisymmetric", "moving_newtonian"))
    return {
        **{
            model: uniform_pressure_compliance(
                config_file(model, "moving_newtonian"), "moving_wall"
            )
            for model in models
        },
        **estimates(tube, tube.geometry.height),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="folder of the runs")
    parser.add_argument(
        "--models", nargs="+", choices=list(MODELS), default=["plane", "axisymmetric"]
    )
    parser.add_argument("--cases", nargs="+", choices=CONFIGS, default=CONFIGS)
    parser.add_argument("--ranks", type=int, default=1)
    parser.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--reuse", action="store_true", help="keep finished runs in --out")
    args = parser.parse_args(argv)
    missing = [
        str(config_file(m, n))
        for m in args.models
        for n in args.cases
        if not config_file(m, n).is_file()
    ]
    if missing:
        parser.error(f"--models/--cases: no config {', '.join(missing)}")
    rows = {
        model: {
            name: row(run(model, name, args.out, args.settings, args.ranks, args.reuse))
            for name in args.cases
        }
        for model in args.models
    }
    statics = static(args.models)

    for title, columns in TABLES.items():
        print(f"\n{title}\n")
        print("| case | model | " + " | ".join(header for header, _ in columns) + " |")
        print("|---|---|" + "---|" * len(columns))
        for name in args.cases:
            for model in args.models:
                cells = [cell(rows[model][name]) for _, cell in columns]
                print(f"| {LABELS[name]} | {model} | " + " | ".join(cells) + " |")
    print("\nUniform static pressure, the moving wall's peak |η| per kPa:")
    for model in args.models:
        ratio = statics[model] / statics["thin_tube"]
        print(f"  {model}: {1e9 * statics[model]:.4g} µm/kPa (×{ratio:.3g} of the thin tube)")
    tube = f"thin {1e9 * statics['thin_tube']:.4g}, Lamé {1e9 * statics['lame']:.4g} µm/kPa"
    print(f"  the tube they stand for: {tube}")
    print(json.dumps({"runs": rows, "static": statics}))
    return 0
