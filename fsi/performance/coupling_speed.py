"""Benchmark of the partitioned coupling on the moving-wall Carreau stenosis (issue #5).

For each acceleration (Aitken, IQN-ILS and, optionally, constant relaxation) it runs the first
``--steps`` steps of the case's resolved schedule through the steppers ``fsi run`` uses
(:class:`fsi.run.steppers.CoupledStepper`, the partitioned problem of fsi/coupled/partitioned.py),
then the rigid-wall fluid-only run of the same case (``structure.mode=rigid``,
:class:`fsi.run.steppers.RigidStepper`) on the same mesh and the same steps, and prints:

* per acceleration: mean and max coupling iterations per step, mean fluid and solid Newton
  iterations per step (summed over the step's coupling iterations), fluid/solid Jacobian
  assemblies and LU factorisations per step, the mean wall and CPU time per step and their
  ratios to the rigid-wall step with the same solver settings; when the case reuses the fluid's
  Jacobian (``fluid.solver.jacobian_reuse``, fsi/numerics/newton.py), also to the rigid-wall step
  with plain Newton (``rigid/none``);
* the sub-solvers' residuals at the accepted coupling iterates against the interface force
  (they must stay well below the coupling tolerance);
* where a coupled step's time goes (exclusive wall time per step of the pieces, timed with
  ``perf_counter`` by wrappers this script attaches to the solver objects; the LU
  factorisations and triangular solves come from PETSc's log events ``MatLUFactorNum``,
  ``MatLUFactorSym`` and ``MatSolve`` read around each Newton solve).

The window: the inlet pulse lasts 5 ms and the resolved schedule takes 2.5e-4 s steps until
10 ms, so the default 40 steps are the pulse (steps 1–20) and the 5 ms after it (21–40): where
the coupling works hardest. Only the stepping is timed (no field or CSV output: that is
``fsi run``'s I/O, the same for every acceleration). The first step (symbolic factorisations,
first touch of the matrices) is left out of the mean times ("warm" steps 2..N) and shown apart.

Usage::

    .venv/bin/python scripts/benchmark_coupling.py [--steps 40] [--level coarse]
        [--accelerations aitken iqn-ils constant] [--set key.path=value ...]
    mpirun -n 2 .venv/bin/python -m mpi4py scripts/benchmark_coupling.py ...

Times on several ranks are the slowest rank's. Only rank 0 prints. The machine's other jobs
inflate wall times (the load average is printed); CPU times are steadier in serial runs, while
on several ranks they include MPI's busy waiting.
"""

from __future__ import annotations

import argparse
import gc
import logging
import os
import platform
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import numpy as np

from fsi import config
from fsi.numerics.timestepping import steps
from fsi.performance.profiling import (
    Profiler,
    attach_coupled,
    attach_rigid,
    mean_warm,
    newton_counters,
    window,
)
from fsi.run import errors, steppers

CASE = Path(__file__).resolve().parents[2] / "configs" / "stenosis_moving_carreau.yaml"


def run(case: config.Case, comm: MPI.Comm) -> dict:
    """Step through the case's schedule; per-step rows, times and the profile.

    The garbage collector is off while the run lasts and collects on every rank at its end:
    MUMPS destroys its factors collectively, so a solver of an earlier run freed by an automatic
    collection on one rank only would deadlock the ranks (seen on 2 ranks)."""
    gc.collect()
    comm.barrier()
    gc.disable()
    try:
        return _run(case, comm)
    finally:
        gc.enable()
        gc.collect()
        comm.barrier()


def _run(case: config.Case, comm: MPI.Comm) -> dict:
    tic = time.perf_counter()
    coupled = case.structure.mode != "rigid"
    stepper = steppers.CoupledStepper(case, comm) if coupled else steppers.RigidStepper(case, comm)
    setup = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
    profiler = Profiler()
    (attach_coupled if coupled else attach_rigid)(stepper, profiler)
    rows, times, cpu, accuracy, failure = [], [], [], [], ""
    for step in steps(case.time):
        comm.barrier()
        tic, cpu_tic = time.perf_counter(), time.process_time()
        try:
            rows.append(stepper.step(step))
        except errors.StepFailed as e:
            failure = f"step {step.index}: {str(e).splitlines()[0][:200]}"
            break
        times.append(comm.allreduce(time.perf_counter() - tic, op=MPI.MAX))
        cpu.append(comm.allreduce(time.process_time() - cpu_tic, op=MPI.MAX))
        if coupled:  # the sub-solvers' residuals at the accepted iterate, and the load's size
            p = stepper.problem
            force = float(np.sqrt(comm.allreduce(float((p.solid.forces**2).sum()), op=MPI.SUM)))
            accuracy.append((p.fluid_side.last.residual, p.solid_side.last.residual, force))
    out = {
        "rows": rows,
        "times": np.array(times),
        "cpu": np.array(cpu),
        "failure": failure,
        "setup": setup,
        "accuracy": np.array(accuracy),
        "profile": {k: comm.allreduce(v, op=MPI.MAX) for k, v in sorted(profiler.seconds.items())},
        "calls": dict(profiler.calls),
        "summary": stepper.summary(),
    }
    if coupled:
        p = stepper.problem
        out["interface_nodes"] = p.fluid_side.to_solid.size
        out["jacobians"] = {"fluid": newton_counters(p.fluid), "solid": newton_counters(p.solid)}
    else:
        out["jacobians"] = {"fluid": newton_counters(stepper.solver)}
    return out


def print_table(say, results: dict, comm: MPI.Comm) -> None:
    """Iterations, assemblies, factorisations and times per step of every run."""
    reference = {
        name: (mean_warm(results[name]["times"]), mean_warm(results[name]["cpu"]))
        for name in ("rigid", "rigid/none")
        if name in results
    }
    rigid = reference.get("rigid", (float("nan"), float("nan")))
    plain = reference.get("rigid/none")
    header = (
        f"{'run':<10}{'steps':>6}{'coup mean':>10}{'max':>5}{'fluid NI':>9}{'solid NI':>9}"
        f"{'fJ':>6}{'fLU':>6}{'sJ':>6}{'sLU':>6}{'s/step':>8}{'1st s':>7}{'× rigid':>8}"
        f"{'cpu s':>7}{'× rigid':>8}" + (f"{'× r/none':>9}{'cpu':>6}" if plain else "")
    )
    say(header)
    say("-" * len(header))
    for name, r in results.items():
        rows, t = r["rows"], r["times"]
        n = max(len(rows), 1)
        iters = [row["coupling_iterations"] for row in rows]
        coupled = not name.startswith("rigid")
        per_step = [
            sum(row.get(k, 0) for row in rows) / n
            for k in ("newton_iterations", "solid_newton_iterations")
        ]
        jacobians = [
            r["jacobians"].get(k, (0, 0))[0] / n or float("nan") for k in ("fluid", "solid")
        ]
        lu = [
            comm.allreduce(r["calls"].get(f"{k} factorisations", 0), op=MPI.MAX) / n
            for k in ("fluid", "solid")
        ]
        warm, warm_cpu = mean_warm(t), mean_warm(r["cpu"])
        say(
            f"{name:<10}{len(rows):>6}"
            + (f"{np.mean(iters):>10.2f}{max(iters, default=0):>5}" if coupled else f"{'-':>15}")
            + f"{per_step[0]:>9.2f}{per_step[1]:>9.2f}{jacobians[0]:>6.1f}{lu[0]:>6.1f}"
            f"{jacobians[1]:>6.1f}{lu[1]:>6.1f}{warm:>8.3f}{t[0] if len(t) else 0:>7.2f}"
            f"{warm / rigid[0]:>8.2f}{warm_cpu:>7.3f}{warm_cpu / rigid[1]:>8.2f}"
            + (f"{warm / plain[0]:>9.2f}{warm_cpu / plain[1]:>6.2f}" if plain else "")
            + ("  FAILED " + r["failure"] if r["failure"] else "")
        )
    say(
        "coup: coupling iterations per step (mean, max); fluid/solid NI: Newton iterations per"
        " step (over its coupling iterations); fJ/sJ: Jacobian assemblies per step (nan: none,"
        " or not counted by this version of the solvers); fLU/sLU: numeric LU factorisations"
        " per step (PETSc MatLUFactorNum); s/step: mean wall time of steps 2..N; 1st s: step 1;"
        " × rigid: s/step over the rigid-wall step's (same settings); cpu s: the same in CPU"
        " time (process_time, slowest rank; less sensitive to other jobs on the machine);"
        " rigid/none, × r/none: the rigid-wall run with plain Newton"
        " (fluid.solver.jacobian_reuse=none) and the ratios to it (wall, cpu)."
    )


def print_accuracy(say, results: dict, tolerance: float) -> None:
    """The sub-solvers' residuals at the accepted coupling iterates against the load's size."""
    say(
        f"Sub-solver residuals at each step's accepted coupling iterate (coupling tolerance "
        f"{tolerance:g} on the relative interface residual):"
    )
    for name, r in results.items():
        a = r["accuracy"]
        if len(a):
            say(
                f"  {name:<9} fluid |F| max {a[:, 0].max():.1e} N/m, solid |R| max "
                f"{a[:, 1].max():.1e} N/m; interface force |f_Γ| {a[:, 2].min():.1e}–"
                f"{a[:, 2].max():.1e} N/m; worst |F|/|f_Γ| {(a[:, 0] / a[:, 2]).max():.1e}, "
                f"|R|/|f_Γ| {(a[:, 1] / a[:, 2]).max():.1e}"
            )


def print_profile(say, results: dict) -> None:
    """Exclusive time per step of each timed piece, largest first."""
    labels = sorted(
        {k for r in results.values() for k in r["profile"]},
        key=lambda k: -max(r["profile"].get(k, 0) for r in results.values()),
    )
    say(
        "Where the time of a step goes: exclusive wall time per step (ms, slowest rank's total /"
        " steps, all steps)"
    )
    head = f"{'piece':<28}" + "".join(f"{n:>11}" for n in results)
    say(head)
    say("-" * len(head))
    steps_run = {n: max(len(r["times"]), 1) for n, r in results.items()}

    def line(label: str, value) -> None:
        say(
            f"{label:<28}"
            + "".join(f"{1e3 * value(r) / steps_run[n]:>11.1f}" for n, r in results.items())
        )

    for k in labels:
        line(k, lambda r, k=k: r["profile"].get(k, 0.0))
    line("metrics and the rest", lambda r: r["times"].sum() - sum(r["profile"].values()))
    line("step (wall, all steps)", lambda r: r["times"].sum())
    say(
        "fluid/solid Newton (rest): the Newton loop minus assembly and LU (updates, norms, the "
        "solver's own checks); side (rest): loads, copies; coupling loop (rest): residual "
        "norms, predictor; metrics and the rest: the step minus all pieces (peaks, stresses)."
    )


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    comm = MPI.COMM_WORLD
    logging.disable(logging.WARNING)  # no progress or JIT chatter; failures are reported below
    PETSc.Log.begin()

    def say(*text):
        if comm.rank == 0:
            print(*text, flush=True)

    base = [f"mesh.level={args.level}", *args.overrides]
    end = window(config.load(args.config, base), args.steps)
    base += [f"time.end={end!r}"]
    settings = config.load(args.config, base)
    load_start = os.getloadavg()
    say(
        f"coupling benchmark: {args.config.name}, {args.level}, {args.steps} steps (t <= {end:g}"
        f" s); {comm.size} rank(s), dolfinx {dolfinx.__version__}, PETSc "
        f"{'.'.join(map(str, PETSc.Sys.getVersion()))}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs, load average {load_start[0]:.2f} {load_start[1]:.2f} "
        f"{load_start[2]:.2f}"
    )
    if args.overrides:
        say("overrides: " + " ".join(args.overrides))
    runs = [(a, [f"coupling.acceleration={a}"]) for a in args.accelerations]
    if not args.no_rigid:
        runs.append(("rigid", ["structure.mode=rigid"]))
        if getattr(settings.fluid.solver, "jacobian_reuse", "none") != "none":
            runs.append(
                ("rigid/none", ["structure.mode=rigid", "fluid.solver.jacobian_reuse=none"])
            )
    results = {}
    for name, extra in runs:
        r = results[name] = run(config.load(args.config, base + extra), comm)
        say(
            f"[{name}] {len(r['times'])} steps, set-up {r['setup']:.1f} s, first step "
            f"{r['times'][0]:.3f} s, warm mean {mean_warm(r['times']):.3f} s/step"
            + (f"; FAILED at {r['failure']}" if r["failure"] else "")
        )
    load_end = os.getloadavg()

    say()
    _print_settings(say, args, results, settings, end, (load_start, load_end), comm)
    print_table(say, results, comm)
    coupled = {n: r for n, r in results.items() if not n.startswith("rigid")}
    if coupled:
        say()
        print_accuracy(say, coupled, settings.coupling.tolerance)
        say()
        print_profile(say, results)
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=CASE)
    parser.add_argument("--level", default="coarse", choices=list(config.MESH_LEVELS))
    parser.add_argument("--steps", type=int, default=40, help="steps of the schedule to run")
    parser.add_argument(
        "--accelerations",
        nargs="+",
        default=["aitken", "iqn-ils"],
        choices=["aitken", "iqn-ils", "constant"],
    )
    parser.add_argument("--no-rigid", action="store_true", help="skip the rigid-wall run")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="override a value of every run",
    )
    return parser


def _print_settings(
    say, args, results: dict, settings: config.Case, end: float, load, comm
) -> None:
    """The table's heading: the case, the dofs, the coupling and Newton settings, the load
    average at the start and the end (``load``)."""
    load_start, load_end = load
    say(
        f"Coupling benchmark — {args.config.name} ({args.level}), steps 1..{args.steps} "
        f"(t <= {end:g} s), {comm.size} rank(s), dolfinx {dolfinx.__version__}"
    )
    summary = next(iter(results.values()))["summary"]
    nodes = next((r["interface_nodes"] for r in results.values() if "interface_nodes" in r), "-")
    say(
        f"dofs: fluid {summary.get('fluid_dofs')}, solid {summary.get('solid_dofs', '-')}, "
        f"interface nodes {nodes}; cells {summary.get('cells')}"
    )
    c, f, s = settings.coupling, settings.fluid.solver, settings.structure.solver
    say(
        f"coupling tolerance {c.tolerance:g}, max {c.max_iterations} iterations, predictor "
        f"{c.predictor}, ω0 {c.initial_relaxation:g}, IQN reuse {c.iqn_reuse} filter "
        f"{c.iqn_filter:g}; fluid Newton rtol {f.rtol:g} atol {f.atol:g}; solid Newton rtol "
        f"{s.rtol:g} atol {s.atol:g}"
        + "".join(
            f"; {name} {k} {getattr(v, k)}"
            for name, v in (("fluid", f), ("solid", s))
            for k in ("jacobian_reuse", "jacobian_reuse_rate")
            if hasattr(v, k)
        )
    )
    say(
        f"load average at start {load_start[0]:.2f}, at end {load_end[0]:.2f} "
        f"({os.cpu_count()} CPUs)"
    )
