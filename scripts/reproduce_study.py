#!/usr/bin/env python3
"""Reproduce the study (docs/model.md §4, §6): its four configurations on the coarse and
the fine mesh, the whole heartbeat, with the resolved schedule of the shipped configs, plus the
study's printed schedule (5 ms to 0.4 s, 10 ms to 0.8 s) on the coarse mesh; then write
docs/study.md and its figures from the runs.

    scripts/reproduce_study.py                  # run what is missing, then write docs/study.md
    scripts/reproduce_study.py --only coarse    # the coarse runs only (a few minutes)
    scripts/reproduce_study.py --document-only  # rewrite docs/study.md from the runs there are

Finished runs (summary.json with the run's end time) are skipped, stopped ones (a checkpoint)
resumed with ``--restart``; so the script can be stopped and run again at any point. Each run
is ``mpirun -n RANKS fsi run configs/<case>.yaml --out RUNS/<name>`` (default 2 ranks, the
machine's cores), one at a time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = [
    "stenosis_fixed_newtonian",
    "stenosis_fixed_carreau",
    "stenosis_moving_newtonian",
    "stenosis_moving_carreau",
]
PRINTED_SCHEDULE = "time.schedule=[{until: 0.4, dt: 0.005}, {until: 0.8, dt: 0.01}]"
MPI_ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
}


@dataclass(frozen=True)
class StudyRun:
    """One run of the study: a shipped case on a mesh level, with its schedule."""

    case: str
    level: str  # coarse | fine
    schedule: str  # resolved (the config's) | printed (the study's)

    @property
    def name(self) -> str:
        suffix = "" if self.schedule == "resolved" else "_printed"
        return f"{self.case.removeprefix('stenosis_')}_{self.level}{suffix}"

    @property
    def overrides(self) -> list[str]:
        sets = [f"mesh.level={self.level}"]
        if self.schedule == "printed":
            sets.append(PRINTED_SCHEDULE)
        return sets

    @property
    def config(self) -> Path:
        return ROOT / "configs" / f"{self.case}.yaml"


RUNS = (
    [StudyRun(c, "coarse", "resolved") for c in CASES]
    + [StudyRun(c, "coarse", "printed") for c in CASES]
    + [StudyRun(c, "fine", "resolved") for c in reversed(CASES)]
)  # the moving wall first


def state(out: Path) -> str:
    """``finished``, ``stopped`` (a checkpoint to resume from) or ``new``."""
    summary = out / "summary.json"
    if summary.is_file():
        data = json.loads(summary.read_text())
        if abs(data.get("end_time_s", 0.0) - 0.8) < 1e-9:
            return "finished"
    if (out / "checkpoint" / "checkpoint.json").is_file():
        return "stopped"
    return "new"


def fsi_command(run: StudyRun, out: Path, ranks: int) -> list[str]:
    fsi = [sys.executable, "-m", "fsi", "run", str(run.config), "--out", str(out)]
    for s in run.overrides:
        fsi += ["--set", s]
    status = state(out)
    if status == "stopped":
        fsi += ["--restart", str(out)]
    elif out.exists():
        fsi += ["--overwrite"]
    if ranks > 1:
        return ["mpirun", "-n", str(ranks), "--oversubscribe", *fsi]
    return fsi


def run_all(runs: list[StudyRun], folder: Path, ranks: int) -> None:
    for run in runs:
        out = folder / run.name
        status = state(out)
        if status == "finished":
            print(f"{run.name}: finished, skipped", flush=True)
            continue
        print(f"{run.name}: {'resuming' if status == 'stopped' else 'starting'}", flush=True)
        tic = time.perf_counter()
        log = folder / f"{run.name}.log"
        folder.mkdir(parents=True, exist_ok=True)
        with log.open("a") as f:
            code = subprocess.call(
                fsi_command(run, out, ranks),
                stdout=f,
                stderr=subprocess.STDOUT,
                cwd=ROOT,
                env={**os.environ, **MPI_ENV},
            )
        print(
            f"{run.name}: exit {code} after {time.perf_counter() - tic:.0f} s (log {log})",
            flush=True,
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--runs",
        type=Path,
        default=ROOT / "results" / "study",
        help="folder of the run folders (default results/study)",
    )
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--only", choices=["coarse", "fine"], help="run one mesh level only")
    parser.add_argument(
        "--document-only",
        action="store_true",
        help="write docs/study.md from the runs there are; run nothing",
    )
    parser.add_argument("--docs", type=Path, default=ROOT / "docs")
    args = parser.parse_args(argv)
    runs = [r for r in RUNS if args.only is None or r.level == args.only]
    if not args.document_only:
        run_all(runs, args.runs, args.ranks)
    sys.path.insert(0, str(ROOT))
    from scripts import study_document

    written = study_document.write(args.runs, RUNS, args.docs)
    print(f"wrote {written}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
