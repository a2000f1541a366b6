"""Turek–Hron benchmark: run one case through ``fsi run`` and compare it with the reference.

Runs ``configs/turek_hron_<case>.yaml`` through the command line's own code path
(:func:`fsi.cli.main`, so the numbers are those users get) into ``--out``, or, with
``--analyse-only DIR``, only analyses an existing run folder. Then prints, for each of the columns
``drag``, ``lift`` (N/m) and ``ux_A``, ``uy_A`` (point A's displacement; written in m, printed in
mm) that ``metrics.csv`` holds:

- periodic cases (CFD3, CSM3, FSI2, FSI3): "mean ± amplitude [frequency]" over the last period
  (fsi/benchmarks/oscillation.py: mean and amplitude from max and min, the period between upward
  crossings of the mean level), the reference, the relative differences and whether each passes the
  acceptance tolerances of solids4foam (2 % on the mean drag, 3 % on frequencies, 5 % on the
  u_y amplitude, 10 % on the u_x mean and amplitude, 15 % on force amplitudes; quantities
  without a quoted tolerance show "–");
- steady cases (CFD1, CFD2, CSM1, CSM2, FSI1): the last row's value against the reference with
  the same tolerances (drag 2 %, u_x 10 %), and how much the value still moved over the last
  10 % of the run (max − min there, relative to the last value: is it steady?).

Also the run's wall time, steps, mean time per step, mesh level, dt, ranks and the load average
(the machine may be shared: timings are noisy). The report is also written to ``DIR/benchmark.txt``.

Reference values: docs/turek-hron.md (Turek & Hron 2006 and the Featflow pages),
hard-coded below; FSI2's are not in that file and come from the literature (see REFERENCES). FSI2
and FSI3 have two sets (the refined Featflow values, the default, and the 2006 paper;
``--reference paper``). CFD3's drag has one period per shedding cycle, like the lift (its two
maxima per cycle differ, the higher one above the mean and the lower one below it: the
asymmetric channel), so both are compared with the published 4.3956 Hz; FSI3's drag oscillates
at twice the lift's frequency (10.93 vs 5.46 Hz), and the analysis finds that too.

Usage::

    .venv/bin/python scripts/benchmark_turek_hron.py --case cfd3 --out results/cfd3
        [--level medium] [--set time.end=6] [--window 1] [--start 2.0]
    .venv/bin/python scripts/benchmark_turek_hron.py --analyse-only results/cfd3
    mpirun -n 2 .venv/bin/python -m mpi4py scripts/benchmark_turek_hron.py --case cfd3 --out ...
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

import numpy as np
import yaml

from fsi import cli, config
from fsi.benchmarks.oscillation import (
    Difference,
    OscillationError,
    Reference,
    Tolerance,
    analyse,
    compare,
    relative_difference,
)
from fsi.output import metrics_csv
from fsi.run import errors

ROOT = Path(__file__).resolve().parents[2]

# docs/turek-hron.md, "Reference values": forces in N/m, displacements in mm.
REFERENCES: dict[str, dict[str, dict[str, str]]] = {
    "csm1": {"": {"ux_A": "-7.187", "uy_A": "-66.10"}},
    "csm2": {"": {"ux_A": "-0.469", "uy_A": "-16.97"}},
    "csm3": {"": {"ux_A": "-14.305 ± 14.305 [1.0995]", "uy_A": "-63.607 ± 65.160 [1.0995]"}},
    "cfd1": {"": {"drag": "14.29", "lift": "1.119"}},
    "cfd2": {"": {"drag": "136.7", "lift": "10.53"}},
    "cfd3": {"": {"drag": "439.45 ± 5.6183 [4.3956]", "lift": "-11.893 ± 437.81 [4.3956]"}},
    "fsi1": {"": {"ux_A": "0.0227", "uy_A": "0.8209", "drag": "14.295", "lift": "0.7638"}},
    # FSI2 is not in docs/turek-hron.md: the refined Featflow values (Turek et
    # al., "Numerical benchmarking of fluid-structure interaction: a comparison of different
    # discretization and solution approaches", 2010, finest level; NOT yet checked against the
    # source) and the 2006 paper's table (checked against the copy in pyfsi/coconut's Turek
    # example, which cites the paper).
    "fsi2": {
        "featflow": {
            "ux_A": "-14.85 ± 12.70 [3.86]",
            "uy_A": "1.30 ± 81.7 [1.93]",
            "drag": "215.06 ± 77.65 [3.86]",
            "lift": "0.61 ± 237.8 [1.93]",
        },
        "paper": {
            "ux_A": "-14.58 ± 12.44 [3.8]",
            "uy_A": "1.23 ± 80.6 [2.0]",
            "drag": "208.83 ± 73.75 [3.8]",
            "lift": "0.88 ± 234.2 [2.0]",
        },
    },
    "fsi3": {
        "featflow": {
            "ux_A": "-2.88 ± 2.72 [10.93]",
            "uy_A": "1.47 ± 34.99 [5.46]",
            "drag": "460.5 ± 27.74 [10.93]",
            "lift": "2.50 ± 153.91 [5.46]",
        },
        "paper": {
            "ux_A": "-2.69 ± 2.53 [10.9]",
            "uy_A": "1.48 ± 34.38 [5.3]",
            "drag": "457.3 ± 22.66 [10.9]",
            "lift": "2.22 ± 149.78 [5.3]",
        },
    },
}
REFERENCE_NAMES = {
    "": "Turek & Hron 2006 / Featflow",
    "featflow": "Featflow, the refined values (FSI3: Δt 2.5e-4)",
    "paper": "Turek & Hron 2006 paper (FSI3: Δt 5e-4)",
}
PERIODIC = {"csm3", "cfd3", "fsi2", "fsi3"}

# solids4foam's acceptance tolerances (docs/turek-hron.md, last paragraph of
# "Reference values"); None: no tolerance quoted. A steady value uses the ``mean`` entry.
TOLERANCES = {
    "drag": Tolerance(mean=0.02, amplitude=0.15, frequency=0.03),
    "lift": Tolerance(mean=None, amplitude=0.15, frequency=0.03),
    "ux_A": Tolerance(mean=0.10, amplitude=0.10, frequency=0.03),
    "uy_A": Tolerance(mean=None, amplitude=0.05, frequency=0.03),
}
COLUMNS = {"drag": ("N/m", 1.0), "lift": ("N/m", 1.0), "ux_A": ("mm", 1e3), "uy_A": ("mm", 1e3)}
"""Column → (printed unit, factor from metrics.csv's SI value)."""

STEADY_TAIL = 0.1  # a steady value's drift is measured over this last fraction of the run


def reference_set(case: str, name: str | None) -> str:
    sets = REFERENCES[case]
    if name is None:
        return "featflow" if "featflow" in sets else ""
    if name not in sets:
        raise SystemExit(
            f"--reference {name}: case {case} has {sorted(k for k in sets if k)}"
            if len(sets) > 1
            else f"--reference: case {case} has one reference set"
        )
    return name


# --------------------------------------------------------------------------------------------
# Analysis of a run folder


@dataclass
class Row:
    """One line of the table: a column's statistic against the reference."""

    column: str
    stat: str
    unit: str
    difference: Difference


def resolved_config(run: Path) -> dict:
    """``run/config.yaml`` as plain data: read, not validated, so that runs written by an older
    schema stay readable (only name, mesh level, structure mode and the inlet ramp are used)."""
    return yaml.safe_load((run / "config.yaml").read_text()) or {}


def analyse_run(
    run: Path, case_name: str, ref_set: str, window: int, start: float | None
) -> tuple[list[str], list[Row], dict]:
    """Lines describing each column's signal, the comparison rows, and the run's facts."""
    rows_csv = metrics_csv.read_metrics(run / "metrics.csv")
    if not rows_csv:
        raise SystemExit(f"{run / 'metrics.csv'}: no rows")
    case = resolved_config(run)
    t = np.array([r["t"] for r in rows_csv])
    if start is None:  # after the inflow ramp (Turek–Hron: 2 s), if the case has a fluid
        structure = case.get("structure", {})
        has_fluid = (
            structure.get("mode") == "rigid" or structure.get("interface_load", "fluid") == "fluid"
        )
        inlet = case.get("fluid", {}).get("inlet", {})
        start = float(inlet.get("ramp_time", 0.0)) if has_fluid else 0.0
    references = REFERENCES[case_name][ref_set]
    lines, table = [], []
    for column, (unit, factor) in COLUMNS.items():
        if column not in rows_csv[-1]:
            continue
        if column not in references:
            lines.append(f"{column}: no {case_name.upper()} reference value")
            continue
        y = np.array([r.get(column, np.nan) for r in rows_csv]) * factor
        tc, y = t[np.isfinite(y)], y[np.isfinite(y)]  # rows without the column (if any) out
        ref = Reference.parse(references[column])
        tol = TOLERANCES[column]
        if case_name in PERIODIC:
            _periodic_lines(column, unit, tc, y, ref, tol, start, window, lines, table)
        else:
            _steady_lines(column, unit, tc, y, ref, tol, lines, table)
    facts = _facts(run, case, rows_csv, t)
    return lines, table, facts


def _periodic_lines(column, unit, tc, y, ref, tol, start, window, lines, table) -> None:
    """A periodic column's line (mean ± amplitude [frequency] over the last ``window``
    periods after ``start``) and its comparison rows, appended to ``lines`` and ``table``."""
    try:
        osc = analyse(tc, y, start=start, window=window)
    except OscillationError as e:
        lines.append(f"{column}: not analysed: {e}")
        return
    lines.append(
        f"{column:<5} = {osc.mean:.5g} ± {osc.amplitude:.5g} {unit} "
        f"[{osc.frequency:.5g} Hz] over t = [{osc.start:.4f}, {osc.end:.4f}] s "
        f"({window} period{'s' if window > 1 else ''}); {osc.periods} periods "
        f"after t = {start:g} s, last two differ by "
        f"{osc.period_change * 100:+.3f} %"
    )
    for stat, diff in compare(osc, ref, tol).items():
        table.append(Row(column, stat, "Hz" if stat == "frequency" else unit, diff))


def _steady_lines(column, unit, tc, y, ref, tol, lines, table) -> None:
    """A steady column's line (its last value and its drift over the run's last
    STEADY_TAIL) and its comparison row, appended to ``lines`` and ``table``."""
    tail = tc >= tc[-1] * (1 - STEADY_TAIL)
    value = y[-1]
    drift = (y[tail].max() - y[tail].min()) / abs(value) if value else np.inf
    lines.append(
        f"{column:<5} = {value:.6g} {unit} at t = {tc[-1]:g} s; over the last "
        f"{STEADY_TAIL:.0%} of the run (t ≥ {tc[-1] * (1 - STEADY_TAIL):g} s) it "
        f"moved by {drift:.2e} of its value"
    )
    table.append(
        Row(
            column,
            "value",
            unit,
            Difference(value, ref.mean, relative_difference(value, ref.mean), tol.mean),
        )
    )


def _facts(run: Path, case: dict, rows_csv: list[dict], t: np.ndarray) -> dict:
    """The run's facts for the report: mesh level, steps, times, ranks, dofs, effort, load."""
    summary_path = run / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    bench_path = run / "benchmark.json"
    bench = json.loads(bench_path.read_text()) if bench_path.exists() else {}
    dts = sorted({r["dt"] for r in rows_csv})
    step_times = [r["wall_time_s"] for r in rows_csv if "wall_time_s" in r]
    facts = {
        "level": case.get("mesh", {}).get("level", "?"),
        "dt": dts,
        "end": t[-1],
        "steps": summary.get("steps", len(rows_csv)),
        "wall_time_s": summary.get("wall_time_s", bench.get("wall_time_s")),
        "mean_step_time_s": summary.get(
            "mean_step_time_s", float(np.mean(step_times)) if step_times else None
        ),
        "ranks": summary.get("ranks", bench.get("ranks")),
        "cells": (summary.get("cells") or {}).get("total"),
        "fluid_dofs": summary.get("fluid_dofs"),
        "solid_dofs": summary.get("solid_dofs"),
        "mean_coupling_iterations": summary.get("mean_coupling_iterations"),
        "mean_newton_iterations": summary.get("mean_newton_iterations"),
        "load": bench.get("load"),
        "complete": bool(summary),
    }
    return facts


def _averages(values) -> str:
    return " ".join(f"{v:.2f}" for v in values)


def format_report(
    case_name: str, ref_set: str, run: Path, lines: list[str], table: list[Row], facts: dict
) -> str:
    source = (
        "the literature: Turek & Hron 2006, Turek et al. 2010"
        if case_name == "fsi2"
        else "docs/turek-hron.md"
    )
    out = [
        f"Turek–Hron {case_name.upper()} — {run}",
        f"reference: {REFERENCE_NAMES[ref_set]} ({source}); tolerances: solids4foam's acceptance",
    ]
    out += lines
    out += _comparison_table(table)
    out.append("")
    out += _run_facts(facts)
    return "\n".join(out)


def _comparison_table(table: list[Row]) -> list[str]:
    """The report's table: each checked statistic measured, its reference, the relative
    difference, the tolerance and the verdict; then how many pass."""
    out = [""]
    header = (
        f"{'column':<7}{'statistic':<11}{'unit':<5}{'measured':>12}{'reference':>12}"
        f"{'rel. diff':>11}{'tolerance':>11}{'pass':>6}"
    )
    out += [header, "-" * len(header)]
    for r in table:
        d = r.difference
        tol = "–" if d.tolerance is None else f"{d.tolerance:.0%}"
        verdict = {None: "–", True: "yes", False: "NO"}[d.passed]
        out.append(
            f"{r.column:<7}{r.stat:<11}{r.unit:<5}{d.measured:>12.5g}{d.reference:>12.5g}"
            f"{d.relative * 100:>10.2f}%{tol:>11}{verdict:>6}"
        )
    checked = [r.difference.passed for r in table if r.difference.passed is not None]
    out.append(
        f"{sum(checked)}/{len(checked)} checked quantities within tolerance"
        + ("" if table else " (nothing analysed: see above)")
    )
    return out


def _run_facts(facts: dict) -> list[str]:
    """The report's last lines: the mesh, the steps, the time and effort, the load."""
    out = []
    dt = ", ".join(f"{v:g}" for v in facts["dt"])
    wall, per_step = facts["wall_time_s"], facts["mean_step_time_s"]
    sizes = ", ".join(
        f"{k.replace('_', ' ')} {facts[k]}"
        for k in ("cells", "fluid_dofs", "solid_dofs")
        if facts[k]
    )
    out.append(
        f"mesh level {facts['level']}{f' ({sizes})' if sizes else ''}; dt {dt} s; "
        f"t = 0 → {facts['end']:g} s, {facts['steps']} steps"
        + ("" if facts["complete"] else " (INCOMPLETE: no summary.json)")
    )
    timing = (f"wall time {wall:.1f} s" if wall is not None else "wall time unknown") + (
        f", mean {per_step:.3f} s/step" if per_step is not None else ""
    )
    iterations = ", ".join(
        f"{label} {facts[k]:.2f}/step"
        for k, label in (
            ("mean_newton_iterations", "Newton"),
            ("mean_coupling_iterations", "coupling"),
        )
        if facts[k]
    )
    out.append(
        f"{timing}{'; ' + iterations if iterations else ''}; ranks {facts['ranks'] or 'unknown'}"
    )
    load = facts["load"]
    out.append(
        "load average (1, 5, 15 min) "
        + (
            f"at start {_averages(load['start'])}, at end {_averages(load['end'])} "
            f"({os.cpu_count()} CPUs)"
            if load
            else f"now {_averages(os.getloadavg())} (not recorded with the run; "
            f"{os.cpu_count()} CPUs)"
        )
    )
    return out


# --------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    if args.out is not None and args.case is None:
        parser.error("--out needs --case")
    if args.analyse_only is not None:
        args.case = _case_of_run(args, parser, comm)
    ref_set = reference_set(args.case, args.reference)
    status = 0
    if args.out is not None:
        run, status = args.out, _run(args, comm)
        if status == errors.EXIT_USAGE:
            return status
    else:
        run = args.analyse_only
    if not _analysed(run, args, ref_set, comm):
        return 1
    return status


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--case",
        choices=sorted(REFERENCES),
        help="the case (with --analyse-only: default from DIR/config.yaml)",
    )
    parser.add_argument(
        "--level", choices=list(config.MESH_LEVELS), help="mesh level (default: the config's)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="forwarded to fsi run (repeatable)",
    )
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--out", type=Path, metavar="DIR", help="run the case into DIR")
    where.add_argument(
        "--analyse-only",
        type=Path,
        metavar="DIR",
        help="analyse the existing run folder DIR (no run)",
    )
    parser.add_argument(
        "--window",
        type=int,
        default=1,
        metavar="N",
        help="periodic cases: analyse the last N periods (default 1, the benchmark's definition)",
    )
    parser.add_argument(
        "--start",
        type=float,
        metavar="T",
        help="periodic cases: ignore t < T s (default: the end of the inflow ramp, 2 s)",
    )
    parser.add_argument(
        "--reference",
        choices=["featflow", "paper"],
        help="FSI2's and FSI3's reference set (default featflow)",
    )
    return parser


def _case_of_run(args: argparse.Namespace, parser: argparse.ArgumentParser, comm) -> str:
    """``--analyse-only DIR``: the case DIR's config.yaml names, or ``--case`` (with a warning
    where they differ)."""
    try:  # every rank reads it: all of them stop alike
        name = str(resolved_config(args.analyse_only).get("name", ""))
    except (OSError, yaml.YAMLError) as e:
        parser.error(f"--analyse-only: {e}")
    name = name.removeprefix("turek_hron_")
    if args.case is None and name not in REFERENCES:
        parser.error(f"{args.analyse_only}: case '{name}' is not a Turek–Hron case; give --case")
    if args.case not in (None, name) and comm.rank == 0:
        print(
            f"warning: {args.analyse_only} holds case '{name}', analysed as '{args.case}'",
            file=sys.stderr,
        )
    return args.case or name


def _run(args: argparse.Namespace, comm) -> int:
    """Run the case into ``--out`` through ``fsi run``'s own code path (:func:`fsi.cli.main`),
    writing DIR/benchmark.json (the command, wall time, ranks, load); its exit status."""
    run = args.out
    cfg = ROOT / "configs" / f"turek_hron_{args.case}.yaml"
    overrides = ([f"mesh.level={args.level}"] if args.level else []) + args.overrides
    argv_run = ["run", str(cfg), "--out", str(run)]
    for item in overrides:
        argv_run += ["--set", item]
    load_start = os.getloadavg()
    tic = time.perf_counter()
    status = cli.main(argv_run)
    wall = time.perf_counter() - tic
    if status == errors.EXIT_USAGE:
        return status
    if comm.rank == 0:
        run.mkdir(parents=True, exist_ok=True)
        (run / "benchmark.json").write_text(
            json.dumps(
                {
                    "command": ["fsi", *argv_run],
                    "wall_time_s": wall,
                    "ranks": comm.size,
                    "load": {"start": load_start, "end": os.getloadavg()},
                    "status": status,
                },
                indent=2,
            )
            + "\n"
        )
    return status


def _analysed(run: Path, args: argparse.Namespace, ref_set: str, comm) -> bool:
    """Analyse ``run`` on rank 0 (DIR/benchmark.txt), the others waiting for its verdict: True
    unless the analysis failed."""
    failed = None
    if comm.rank == 0:  # the other ranks wait for its verdict (no rank may hang on an error)
        try:
            lines, table, facts = analyse_run(run, args.case, ref_set, args.window, args.start)
            report = format_report(args.case, ref_set, run, lines, table, facts)
            print(report, flush=True)
            (run / "benchmark.txt").write_text(report + "\n")
        except (OSError, ValueError, SystemExit, yaml.YAMLError) as e:
            failed = f"{run}: {e}"
            print(f"benchmark_turek_hron: error: {failed}", file=sys.stderr)
    return comm.bcast(failed, root=0) is None
