"""How far one run's answer is from another's: the largest difference of each headline column of
``metrics.csv`` over the steps, relative to the reference run's peak of that column (the measure
of the speed settings against a tight solve: docs/performance.md, tests/test_solver_settings.py).

Also the command ``scripts/compare_runs.py REFERENCE_DIR RUN_DIR [RUN_DIR ...] [--bound 0.01]``
(:func:`main`), which prints these differences and the runs' effort per step (coupling
iterations, fluid and structure Newton iterations) and exits 1 if a column of a run is further
than ``--bound`` (default 1 %) from the reference.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence
from pathlib import Path

from fsi.output import metrics_csv

HEADLINE = (
    "peak_velocity",
    "peak_pressure",
    "peak_displacement",
    "max_sss",
    "max_principal_cap",
    "min_wss",
    "max_wss",
    "inlet_flow_rate",
    "outlet_flow_rate",
    "mean_inlet_pressure",
    "mean_outlet_pressure",
)
"""The columns a study run is judged by (those of a rigid-wall run are a subset)."""


def largest_differences(
    rows: Sequence[dict], reference: Sequence[dict], columns: Iterable[str] = HEADLINE
) -> dict[str, float]:
    """Per column present in both runs, max over the steps of |rows − reference| divided by
    max |reference|. The runs must have the same steps (same number of rows, same times)."""
    if len(rows) != len(reference):
        raise ValueError(f"{len(rows)} rows against a reference of {len(reference)}")
    for a, b in zip(rows, reference):
        if abs(a["t"] - b["t"]) > 1e-9 * max(abs(b["t"]), 1.0):
            raise ValueError(f"the runs' steps differ: t = {a['t']} against {b['t']}")
    out = {}
    for column in columns:
        if column not in reference[0] or column not in rows[0]:
            continue
        peak = max(abs(r[column]) for r in reference)
        worst = max(abs(a[column] - b[column]) for a, b in zip(rows, reference))
        out[column] = worst / peak if peak > 0 else worst
    return out


EFFORT = ("coupling_iterations", "newton_iterations", "solid_newton_iterations")


def effort(rows: list[dict]) -> str:
    n = max(len(rows), 1)
    return ", ".join(f"{c} {sum(r.get(c, 0) for r in rows) / n:.2f}" for c in EFFORT)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reference", type=Path)
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--bound", type=float, default=1e-2)
    args = parser.parse_args(argv)
    reference = metrics_csv.read_metrics(args.reference / "metrics.csv")
    print(f"reference {args.reference}: {len(reference)} steps; {effort(reference)} per step")
    status = 0
    for run in args.runs:
        rows = metrics_csv.read_metrics(run / "metrics.csv")
        differences = largest_differences(rows, reference)
        column, worst = max(differences.items(), key=lambda item: item[1])
        print(f"\n{run}: {effort(rows)} per step; largest difference {worst:.2e} ({column})")
        for name, value in differences.items():
            flag = "  > bound" if value > args.bound else ""
            print(f"  {name:22s} {value:.2e}{flag}")
        status |= int(worst > args.bound)
    return status
