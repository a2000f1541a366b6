"""Performance of the study's moving-wall Carreau case across mesh levels and ranks (issue #11).

For each mesh level (coarse, fine and the third level ``finest``, one refinement above fine) and
each rank count (1 and 2), it runs ``fsi run``'s own loop (:func:`fsi.run.simulation.march`, with
its metrics rows, field files and checkpoints written to a temporary folder) over the first
steps of the case's schedule, coupled and with a rigid wall (``structure.mode=rigid``, the
same mesh and solver settings), each in a fresh process (``mpirun -n R``), and prints:

* per level and rank count: dofs, steps, s/step coupled and rigid and their ratio, coupling
  iterations per step (mean, max), fluid Newton iterations and LU factorisations per step, the
  peak memory of each rank (resident set, MB);
* where a coupled step's time goes, grouped: fluid (assembly, LU, Newton, interface forces),
  structure, mesh motion (extension solve, quality check, mesh move), transfer and coupling
  (interface transfers, accelerations, state save/restore, the loop), output (metrics row,
  field files, checkpoints) and metrics (the row's peaks and stresses, the rest);
* the 2-rank speed-up per level and the growth of the cost per step with the dofs from level
  to level (the exponent p of s/step ∝ dofs^p).

s/step is the mean wall time of steps 2..N, each from the end of the previous step's output to
the end of its own (step 1 holds the symbolic factorisations and is left out); on several ranks
the slowest rank's. The machine's other jobs inflate wall times: the load average is printed,
and the ratios of runs measured side by side are steadier than the times.

Usage::

    .venv/bin/python scripts/benchmark_study.py [--levels coarse fine finest]
        [--steps coarse=all fine=40 finest=3] [--ranks 1 2] [--modes coupled rigid]
        [--config CASE.yaml] [--set key.path=value ...] [--json FILE]

``--steps LEVEL=N`` runs the first N steps of the schedule (``all``: the whole heartbeat, 390
steps of the resolved schedule). Each run is a separate process, so the peak memory is that
run's own. The whole fine heartbeat on 2 ranks (docs/performance.md)::

    .venv/bin/python scripts/benchmark_study.py --levels fine --steps fine=all --ranks 2
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import platform
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fsi.run import child_runs

ROOT = Path(__file__).resolve().parents[2]
CASE = ROOT / "configs" / "stenosis_moving_carreau.yaml"

GROUPS = {
    "fluid": (
        "fluid Jacobian assembly",
        "fluid residual assembly",
        "fluid LU factorisation",
        "fluid LU solves",
        "fluid Newton (rest)",
        "fluid interface forces",
        "fluid side (rest)",
    ),
    "structure": (
        "solid Jacobian assembly",
        "solid residual assembly",
        "solid LU factorisation",
        "solid LU solves",
        "solid Newton (rest)",
        "solid side (rest)",
    ),
    "mesh motion": ("mesh motion solve", "mesh quality check", "mesh move + w (rest)"),
    "transfer+coupling": (
        "interface transfers",
        "acceleration",
        "save/restore state",
        "coupling loop (rest)",
    ),
    "output": ("output: metrics row", "output: fields", "output: checkpoint"),
}
"""The profiler's pieces (fsi/performance/profiling.py) by part of the code; what no piece covers is
``metrics`` (the row's peaks and stresses, the progress line)."""


# --------------------------------------------------------------------------------------------
# One run (a worker process, under mpirun)


def worker(args: argparse.Namespace) -> int:
    from mpi4py import MPI
    from petsc4py import PETSc

    from fsi import config
    from fsi.output import metrics_csv
    from fsi.performance.profiling import Profiler, attach_coupled, attach_rigid, window
    from fsi.run import errors, outputs, simulation, steppers

    comm = MPI.COMM_WORLD
    logging.disable(logging.WARNING)
    PETSc.Log.begin()
    overrides = [f"mesh.level={args.level}", *args.overrides]
    if args.mode == "rigid":
        overrides.append("structure.mode=rigid")
    case = config.load(args.config, overrides)
    if args.steps != "all":
        case = config.load(args.config, [*overrides, f"time.end={window(case, int(args.steps))!r}"])
    coupled = case.structure.mode != "rigid"
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-bench-") if comm.rank == 0 else None))

    profiler = Profiler()
    marks: list[tuple[float, float]] = []  # (wall, cpu) at the end of each step's output
    original_progress = simulation._report_progress

    def progress(*a, **k):
        marks.append((time.perf_counter(), time.process_time()))
        return original_progress(*a, **k)

    simulation._report_progress = progress
    profiler.wrap(outputs.RunOutputs, "write_row", "output: metrics row")
    profiler.wrap(outputs.RunOutputs, "write_fields", "output: fields")
    profiler.wrap(simulation._Checkpoints, "after", "output: checkpoint")
    tic = time.perf_counter()
    stepper = steppers.CoupledStepper(case, comm) if coupled else steppers.RigidStepper(case, comm)
    setup = time.perf_counter() - tic
    (attach_coupled if coupled else attach_rigid)(stepper, profiler)
    failure = ""
    start = time.perf_counter()
    try:
        simulation.march(case, out, comm, stepper, start)
    except errors.RunStopped as e:
        failure = str(e).splitlines()[0][:200]
    rows = metrics_csv.read_metrics(out / "metrics.csv") if comm.rank == 0 else []
    if comm.rank == 0:
        shutil.rmtree(out, ignore_errors=True)
    result = _measured(args, comm, marks, start, setup, failure, profiler, stepper)
    if comm.rank == 0:
        n = max(len(rows), 1)
        result["coupling_iterations"] = [r.get("coupling_iterations", 0) for r in rows]
        result["newton_per_step"] = sum(r.get("newton_iterations", 0) for r in rows) / n
        result["t_end"] = rows[-1]["t"] if rows else 0.0
        Path(args.json).write_text(json.dumps(result))
    return 0


def _measured(
    args, comm, marks, start: float, setup: float, failure: str, profiler, stepper
) -> dict:
    """A worker's result: its steps' wall and CPU times (from the ``marks`` at the end of each
    step's output; the slowest rank's), set-up, memory and the profiled pieces per step."""
    from mpi4py import MPI

    wall = [b[0] - a[0] for a, b in zip(marks, marks[1:])]
    cpu = [b[1] - a[1] for a, b in zip(marks, marks[1:])]
    warm = len(wall)
    result = {
        "level": args.level,
        "mode": args.mode,
        "ranks": comm.size,
        "steps": len(marks),
        "failure": comm.allreduce(failure, op=MPI.MAX),
        "setup_s": comm.allreduce(setup, op=MPI.MAX),
        "s_per_step": comm.allreduce(sum(wall) / warm if warm else math.nan, op=MPI.MAX),
        "cpu_per_step": comm.allreduce(sum(cpu) / warm if warm else math.nan, op=MPI.MAX),
        "memory_mb": comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
        # Each rank's profiled pieces add up to at most its own step time; the slowest rank's
        # sum is the one to set against step_ms (the per-piece maxima below may come from
        # different ranks and add up to more).
        "profiled_ms": 1e3
        * comm.allreduce(sum(profiler.seconds.values()), op=MPI.MAX)
        / max(len(marks), 1),
        "profile_ms": {
            k: 1e3 * comm.allreduce(v, op=MPI.MAX) / max(len(marks), 1)
            for k, v in sorted(profiler.seconds.items())
        },
        "step_ms": 1e3
        * comm.allreduce((marks[-1][0] - start if marks else 0.0), op=MPI.MAX)
        / max(len(marks), 1),
        "fluid_lu_per_step": comm.allreduce(
            profiler.calls.get("fluid factorisations", 0), op=MPI.MAX
        )
        / max(len(marks), 1),
        "summary": stepper.summary(),
    }
    return result


# --------------------------------------------------------------------------------------------
# The driver: one process per run, then the tables


def launch(args: argparse.Namespace, level: str, mode: str, ranks: int, steps: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        target = Path(tmp) / "result.json"
        command = [
            sys.executable,
            "-m",
            "mpi4py",
            "-m",
            "fsi.performance.study_speed",
            "--worker",
            "--level",
            level,
            "--mode",
            mode,
            "--steps",
            steps,
            "--config",
            str(args.config),
            "--json",
            str(target),
        ] + [f"--set={o}" for o in args.overrides]
        if ranks > 1:
            command = ["mpirun", "-n", str(ranks), "--oversubscribe", *command]
        tic = time.perf_counter()
        done = subprocess.run(command, env=child_runs.environment(), capture_output=True, text=True)
        if done.returncode != 0 or not target.exists():
            failure = why_failed(done.stderr or done.stdout)
            return {"level": level, "mode": mode, "ranks": ranks, "failure": failure}
        result = json.loads(target.read_text())
        result["process_s"] = time.perf_counter() - tic
        return result


def why_failed(output: str) -> str:
    """What a failed worker said: its last exception's line (``mpi4py -m`` prints the traceback,
    then Open MPI's MPI_ABORT notice, which says nothing of the cause), else its last 5 lines."""
    lines = output.strip().splitlines()
    raised = [line for line in lines if re.match(r"[A-Za-z_][\w.]*(Error|Exception|Exit)\b", line)]
    return raised[-1] if raised else " | ".join(lines[-5:])


def dofs(r: dict) -> int:
    s = r.get("summary", {})
    return int(s.get("fluid_dofs", 0)) + int(s.get("solid_dofs", 0))


def print_tables(results: list[dict], say) -> None:
    by = {(r["level"], r["mode"], r["ranks"]): r for r in results}
    levels = list(dict.fromkeys(r["level"] for r in results))
    ranks = sorted({r["ranks"] for r in results})
    _print_runs(say, by, levels, ranks)
    _print_profile(say, by, levels, ranks)
    _print_scaling(say, by, levels, ranks)


def _print_runs(say, by: dict, levels: list, ranks: list) -> None:
    """Per level and rank count: dofs, s/step coupled and rigid, iterations, memory."""
    say(
        f"{'level':<8}{'ranks':>6}{'dofs f+s':>16}{'steps':>6}{'coupled':>9}{'rigid':>8}"
        f"{'ratio':>7}{'coup':>6}{'max':>4}{'fNI':>7}{'fLU':>7}{'MB/rank (coupled)':>20}"
    )
    for level in levels:
        for n in ranks:
            c, g = by.get((level, "coupled", n)), by.get((level, "rigid", n))
            if c is None and g is None:
                continue
            r = c or g
            if r.get("failure") and "summary" not in r:
                say(f"{level:<8}{n:>6}  FAILED: {r['failure']}")
                continue
            s = r["summary"]
            coupled = c["s_per_step"] if c else math.nan
            rigid = g["s_per_step"] if g and "s_per_step" in g else math.nan
            iters = c.get("coupling_iterations", []) if c else []
            mean = sum(iters) / len(iters) if iters else math.nan
            memory = "/".join(f"{m:.0f}" for m in (c or g)["memory_mb"])
            say(
                f"{level:<8}{n:>6}{s.get('fluid_dofs', 0):>9}+{s.get('solid_dofs', 0):<6}"
                f"{r['steps']:>6}{coupled:>9.3f}{rigid:>8.3f}{coupled / rigid:>7.2f}"
                f"{mean:>6.2f}{max(iters, default=0):>4.0f}"
                f"{(c or g).get('newton_per_step', math.nan):>7.2f}"
                f"{(c or g).get('fluid_lu_per_step', math.nan):>7.2f}{memory:>20}"
                + (f"  FAILED: {r['failure']}" if r.get("failure") else "")
            )
    say(
        "coupled, rigid: s/step (wall, steps 2..N, output included; slowest rank); ratio: "
        "coupled/rigid; coup, max: coupling iterations per step; fNI, fLU: the coupled run's "
        "fluid Newton iterations and LU factorisations per step; MB/rank: peak resident memory."
    )


def _print_profile(say, by: dict, levels: list, ranks: list) -> None:
    """Where a coupled step's time goes, by group of profiled pieces."""
    say()
    say(
        "Where a coupled step's time goes (ms per step: each part the slowest rank's; metrics: "
        "the step minus the slowest rank's profiled time; % of the step)"
    )
    names = [*GROUPS, "metrics"]
    say(f"{'level':<8}{'ranks':>6}" + "".join(f"{g:>19}" for g in names) + f"{'step':>10}")
    for level in levels:
        for n in ranks:
            c = by.get((level, "coupled", n))
            if not c or "profile_ms" not in c:
                continue
            p = c["profile_ms"]
            parts = {g: sum(p.get(k, 0.0) for k in keys) for g, keys in GROUPS.items()}
            parts["metrics"] = c["step_ms"] - c["profiled_ms"]
            cells = "".join(
                f"{parts[g]:>11.1f} ({100 * parts[g] / c['step_ms']:>3.0f}%)" for g in names
            )
            say(f"{level:<8}{n:>6}{cells}{c['step_ms']:>10.1f}")


def _print_scaling(say, by: dict, levels: list, ranks: list) -> None:
    """The 2-rank speed-up per level and the growth of the cost per step with the dofs."""
    say()
    say("Scaling of the coupled step")
    for level in levels:
        one, two = by.get((level, "coupled", 1)), by.get((level, "coupled", 2))
        if one and two and "s_per_step" in one and "s_per_step" in two:
            say(f"  {level}: 2-rank speed-up {one['s_per_step'] / two['s_per_step']:.2f}")
    for n in ranks:
        known = [
            by[(lv, "coupled", n)]
            for lv in levels
            if "s_per_step" in by.get((lv, "coupled", n), {})
        ]
        for a, b in zip(known, known[1:]):
            if a["steps"] != b["steps"]:  # other windows of the schedule: not comparable
                say(
                    f"  {n} rank(s), {a['level']} -> {b['level']}: {a['steps']} and {b['steps']} "
                    "steps (run both levels over the same steps for the growth of the cost)"
                )
                continue
            p = math.log(b["s_per_step"] / a["s_per_step"]) / math.log(dofs(b) / dofs(a))
            say(
                f"  {n} rank(s), {a['level']} -> {b['level']}: dofs ×{dofs(b) / dofs(a):.2f}, "
                f"s/step ×{b['s_per_step'] / a['s_per_step']:.2f}: cost ∝ dofs^{p:.2f}"
            )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=CASE)
    parser.add_argument("--levels", nargs="+", default=["coarse", "fine", "finest"])
    parser.add_argument(
        "--steps",
        nargs="+",
        default=["coarse=all", "fine=40", "finest=3"],
        metavar="LEVEL=N",
        help="steps per level (N or all); a level not given runs 10",
    )
    parser.add_argument("--ranks", nargs="+", type=int, default=[1, 2])
    parser.add_argument(
        "--modes", nargs="+", default=["coupled", "rigid"], choices=["coupled", "rigid"]
    )
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--json", type=Path, help="also write every run's figures here")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--level", help=argparse.SUPPRESS)
    parser.add_argument("--mode", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        args.steps = args.steps[0]
        return worker(args)
    steps = dict(item.split("=", 1) for item in args.steps)
    for level, n in steps.items():
        if n != "all" and not n.isdigit():
            parser.error(f"--steps {level}={n}: N must be a whole number or 'all'")
    load = os.getloadavg()
    print(
        f"study benchmark: {args.config.name}, levels {' '.join(args.levels)}, ranks "
        f"{' '.join(map(str, args.ranks))}; Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs, load average {load[0]:.2f}"
        + (f"; overrides {' '.join(args.overrides)}" if args.overrides else ""),
        flush=True,
    )
    results = []
    for level in args.levels:
        for n in args.ranks:
            for mode in args.modes:
                r = launch(args, level, mode, n, steps.get(level, "10"))
                results.append(r)
                print(
                    f"[{level}, {mode}, {n} rank(s)] "
                    + (
                        f"{r['steps']} steps to t = {r.get('t_end', 0):g} s, "
                        f"{r['s_per_step']:.3f} s/step, process {r['process_s']:.0f} s"
                        if "s_per_step" in r
                        else f"FAILED: {r['failure']}"
                    ),
                    flush=True,
                )
    print(f"load average at the end {os.getloadavg()[0]:.2f}\n")
    print_tables(results, print)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
