"""How far run folders' answers are from a reference run's (issue #31's measure of a speed
setting): per headline column of ``metrics.csv`` (fsi/output/comparison.py), the largest
difference over the steps relative to the reference's peak, and the runs' effort per step
(coupling iterations, fluid and structure Newton iterations).

Usage::

    .venv/bin/python scripts/compare_runs.py REFERENCE_DIR RUN_DIR [RUN_DIR ...] [--bound 0.01]

Exits 1 if a column of a run is further than ``--bound`` (default 1 %) from the reference.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fsi.output import io  # noqa: E402
from fsi.output.comparison import largest_differences  # noqa: E402

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
    reference = io.read_metrics(args.reference / "metrics.csv")
    print(f"reference {args.reference}: {len(reference)} steps; {effort(reference)} per step")
    status = 0
    for run in args.runs:
        rows = io.read_metrics(run / "metrics.csv")
        differences = largest_differences(rows, reference)
        column, worst = max(differences.items(), key=lambda item: item[1])
        print(f"\n{run}: {effort(rows)} per step; largest difference {worst:.2e} ({column})")
        for name, value in differences.items():
            flag = "  > bound" if value > args.bound else ""
            print(f"  {name:22s} {value:.2e}{flag}")
        status |= int(worst > args.bound)
    return status


if __name__ == "__main__":
    sys.exit(main())
