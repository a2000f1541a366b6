"""Benchmark of the fluid solver on the study's rigid-structure stenosis case.

For each mesh level and rheology it prints: global dofs; Jacobian and residual assembly time per
dof (µs, wall time of ``NonlinearProblem.J``/``.F`` — assembly, Dirichlet rows, PETSc
finalisation — on compiled forms, best and mean of ``--repeats``); Newton iterations per step;
the linear-solve time per Newton iteration (PETSc's ``PCSetUp`` + ``PCApply`` events: MUMPS
factorisation and triangular solves; in PETSc 3.18 the ``KSPSolve`` event leaves part of the
set-up out); the Jacobian and residual time inside Newton (its callbacks, timed); and the wall
time per step. A second table shows the Carreau Jacobian's
assembly cost against the quadrature degree, including the degree UFL would estimate if none
were set (why ``fluid.quadrature_degree`` is fixed).

The case: configs/stenosis_fixed_newtonian.yaml with ``structure.mode=rigid``, the rheology
replaced by the chosen model's defaults, and ``--steps`` steps of ``--dt`` from rest (inside the
inlet pulse, so Carreau runs at non-zero shear rates).

Usage::

    .venv/bin/python scripts/benchmark_fluid.py [--levels coarse fine]
        [--models newtonian carreau] [--steps 10] [--dt 1e-4] [--repeats 5] [--set KEY=VALUE ...]
    mpirun -n 2 .venv/bin/python -m mpi4py scripts/benchmark_fluid.py ...

Times on several ranks are the slowest rank's wall time; "µs/dof" divides by the global dofs,
"core-µs/dof" multiplies that by the number of ranks (the cost per dof per core).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import basix
import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import ufl

from fsi import compat, config
from fsi.geometry.tags import Region
from fsi.numerics.timestepping import steps
from fsi.performance.profiling import wall
from fsi.physics import fluid, fluid_case, mesh
from fsi.run import steppers

CASE = Path(__file__).resolve().parents[2] / "configs" / "stenosis_fixed_newtonian.yaml"
RHEOLOGY = {"newtonian": "{model: newtonian}", "carreau": "{model: carreau}"}
PETSC_EVENTS = ("PCSetUp", "PCApply")


def load_case(
    level: str, model: str, n_steps: int, dt: float, settings: tuple[str, ...] = ()
) -> config.Case:
    end = n_steps * dt
    return config.load(
        CASE,
        [
            "structure.mode=rigid",
            f"mesh.level={level}",
            f"fluid.rheology={RHEOLOGY[model]}",
            f"time.end={end!r}",
            f"time.schedule=[{{until: {end!r}, dt: {dt!r}}}]",
            *settings,
        ],
    )


def fluid_solver(part: mesh.TaggedMesh, case: config.Case) -> fluid.FluidSolver:
    """The case's fluid solver on the fluid mesh ``part`` (its boundaries and time scheme)."""
    return fluid_case.fluid_solver(case, part)


def event_totals(comm: MPI.Comm) -> dict[str, tuple[int, float]]:
    """(count, slowest rank's time) of PETSc's log events so far."""
    totals = {}
    for name in PETSC_EVENTS:
        info = PETSc.Log.Event(name).getPerfInfo()
        totals[name] = (int(info["count"]), comm.allreduce(float(info["time"]), op=MPI.MAX))
    return totals


def assembly_times(
    solver: fluid.FluidSolver, repeats: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wall times of the Jacobian (into Newton's matrix) and residual evaluations at U, U put
    exactly on its Dirichlet values (as at every Newton iterate after a solve's first): the
    residual as the solver evaluates it (the lifting skipped, being zero) and as dolfinx's
    ``NonlinearProblem.F`` does (the lifting assembled)."""
    problem, x = solver.problem, compat.petsc_vector(solver.U)
    dolfinx.fem.petsc.set_bc(x, problem.bcs)
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    A, b = solver.newton.solver.A, solver.newton.solver.b
    problem.J(x, A)  # warm-up: first touch of the matrix and of the kernels' caches
    problem.F(x, b)
    return (
        wall(solver.comm, lambda: problem.J(x, A), repeats),
        wall(solver.comm, lambda: problem.F(x, b), repeats),
        wall(solver.comm, lambda: dolfinx.fem.petsc.NonlinearProblem.F(problem, x, b), repeats),
    )


class Timed:
    """Wraps a Newton callback ``f(x, out)`` and adds up its wall time (this rank)."""

    def __init__(self, f):
        self.f, self.seconds, self.calls = f, 0.0, 0

    def __call__(self, x, out):
        tic = time.perf_counter()
        self.f(x, out)
        self.seconds += time.perf_counter() - tic
        self.calls += 1


def run_steps(solver: fluid.FluidSolver, case: config.Case) -> dict:
    """Step through the schedule; Newton iterations, linear-solve and assembly times."""
    comm, newton, problem = solver.comm, solver.newton.solver, solver.problem
    J, F = Timed(problem.J), Timed(problem.F)
    newton.setJ(J, newton.A)  # the same callbacks NewtonSolver set, timed
    newton.setF(F, newton.b)
    before = event_totals(comm)
    iterations, step_times, failed = [], [], 0
    for step in steps(case.time):
        comm.barrier()
        tic = time.perf_counter()
        result = solver.step(step.t, step.dt)
        step_times.append(comm.allreduce(time.perf_counter() - tic, op=MPI.MAX))
        iterations.append(result.iterations)
        if not result.converged:
            failed += 1
            if comm.rank == 0:
                print(f"  step to t = {step.t:g} failed: {result.reason}", flush=True)
            break
        solver.advance()
    after = event_totals(comm)
    newton.setJ(problem.J, newton.A)
    newton.setF(problem.F, newton.b)
    n_solves = after["PCApply"][0] - before["PCApply"][0]

    def per_solve(name):
        return (after[name][1] - before[name][1]) / max(n_solves, 1)

    n = len(step_times)
    return {
        "iterations": float(np.mean(iterations)),
        "steps": n,
        "failed": failed,
        "solves": n_solves,
        "factor_s": per_solve("PCSetUp"),
        "lu_solve_s": per_solve("PCApply"),
        "linear_s": per_solve("PCSetUp") + per_solve("PCApply"),
        "J_step_s": comm.allreduce(J.seconds, op=MPI.MAX) / n,
        "F_step_s": comm.allreduce(F.seconds, op=MPI.MAX) / n,
        "step_s": float(np.mean(step_times)),
        "first_step_s": step_times[0],
    }


# --------------------------------------------------------------------------------------------
# The quadrature degree of the Carreau Jacobian


def with_degree(form: ufl.Form, degree: int | None) -> ufl.Form:
    """``form`` with every integral's quadrature degree set to ``degree`` (None: unset, so that
    FFCx uses UFL's estimate)."""
    integrals = []
    for itg in form.integrals():
        metadata = {k: v for k, v in itg.metadata().items() if k != "quadrature_degree"}
        if degree is not None:
            metadata["quadrature_degree"] = degree
        integrals.append(itg.reconstruct(metadata=metadata))
    return ufl.Form(integrals)


def estimated_degrees(form: ufl.Form) -> dict[str, int]:
    """UFL's estimated polynomial degree per integral type (what FFCx uses with no degree set)."""
    data = ufl.algorithms.compute_form_data(
        form,
        do_apply_function_pullbacks=True,
        do_apply_integral_scaling=True,
        do_apply_geometry_lowering=True,
        preserve_geometry_types=(ufl.classes.Jacobian,),
        do_apply_restrictions=True,
        do_append_everywhere_integrals=False,
    )
    degrees: dict[str, int] = {}
    for integral_data in data.integral_data:
        for itg in integral_data.integrals:
            d = int(np.max(itg.metadata()["estimated_polynomial_degree"]))
            key = integral_data.integral_type
            degrees[key] = max(degrees.get(key, 0), d)
    return degrees


def quadrature_points(degree: int, cell: basix.CellType) -> int:
    return len(basix.make_quadrature(cell, degree)[1])


def degree_study(
    part: mesh.TaggedMesh, case_with_degree, degrees: list[int], repeats: int
) -> list[dict]:
    """Carreau Jacobian assembly time for each quadrature degree (a solver built with
    ``fluid.quadrature_degree`` at that degree: SUPG's held τ lives at the degree's points, so
    the degree is the solver's, not a form's afterthought), and UFL's estimate, not assembled
    (``case_with_degree(d)``: the case at degree d)."""
    comm = part.comm
    rows = []
    for degree in degrees:
        case = case_with_degree(degree)
        comm.barrier()
        tic = time.perf_counter()
        # The state (rest, zero BDF weights) does not change the cost: the kernel is the same.
        solver = fluid_solver(part, case)
        for coefficient in solver.step_coefficients:
            coefficient.evaluate()
        problem, x, A = solver.problem, compat.petsc_vector(solver.U), solver.newton.solver.A
        problem.J(x, A)
        jit = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
        times = wall(comm, lambda problem=problem, x=x, A=A: problem.J(x, A), repeats)
        if not rows or degree == 4:  # held τ's own degree enters the estimate: degree 4's
            J = ufl.derivative(solver.residual_form, solver.U, ufl.TrialFunction(solver.W))
            auto = estimated_degrees(with_degree(J, None))
        rows.append(
            {
                "degree": f"{degree}",
                "points": quadrature_points(degree, basix.CellType.triangle),
                "jit_s": jit,
                "best": times.min(),
                "mean": times.mean(),
            }
        )
        del solver
    rows.append(
        {
            "degree": f"auto ({', '.join(f'{k} {v}' for k, v in auto.items())})",
            "points": quadrature_points(auto["cell"], basix.CellType.triangle),
            "jit_s": float("nan"),
            "best": float("nan"),
            "mean": float("nan"),
        }
    )
    return rows


# --------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    comm = MPI.COMM_WORLD
    PETSc.Log.begin()

    def say(*text):
        if comm.rank == 0:
            print(*text, flush=True)

    load_start = os.getloadavg()
    say(
        f"fluid benchmark: {comm.size} rank(s), dolfinx {dolfinx.__version__}, PETSc "
        f"{'.'.join(map(str, PETSc.Sys.getVersion()))}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs, load average {load_start[0]:.2f} {load_start[1]:.2f} "
        f"{load_start[2]:.2f}"
    )
    rows, studies = [], {}
    for level in args.levels:
        base = load_case(level, args.models[0], args.steps, args.dt, args.settings)
        tic = time.perf_counter()
        part = mesh.restrict(mesh.build(base, comm), Region.FLUID)
        cells = part.mesh.topology.index_map(2).size_global
        say(f"[{level}] fluid mesh: {cells} cells ({time.perf_counter() - tic:.1f} s)")
        for model in args.models:
            rows.append(_measure(level, model, part, cells, args, comm, say))
        if "carreau" in args.models and args.degrees:
            studies[level] = (
                steppers.global_dofs(
                    compat.mixed_space(part.mesh, [("Lagrange", 2, (2,)), ("Lagrange", 1, ())])
                ),
                degree_study(
                    part,
                    lambda d, level=level: load_case(
                        level,
                        "carreau",
                        args.steps,
                        args.dt,
                        (*args.settings, f"fluid.quadrature_degree={d}"),
                    ),
                    args.degrees,
                    args.repeats,
                ),
            )

    load_end = os.getloadavg()
    say()
    _print_table(rows, args, comm, say, load_start, load_end)
    _print_degree_studies(studies, comm, say)
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--levels", nargs="+", default=["coarse", "fine"], choices=list(config.MESH_LEVELS)
    )
    parser.add_argument(
        "--models", nargs="+", default=["newtonian", "carreau"], choices=list(RHEOLOGY)
    )
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--dt", type=float, default=1e-4, help="step (s)")
    parser.add_argument("--repeats", type=int, default=10, help="assemblies timed per form")
    parser.add_argument(
        "--degrees",
        type=int,
        nargs="*",
        default=[2, 4, 6],
        help="quadrature degrees of the Carreau Jacobian study (UFL's estimate"
        " is added); `--degrees` with none: skip the study",
    )
    parser.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a config override for every case (e.g. fluid.supg=false)",
    )
    return parser


def _measure(level: str, model: str, part, cells: int, args, comm, say) -> dict:
    """One level and rheology: the solver set up, its steps run and its forms' assembly timed;
    the table's row."""
    case = load_case(level, model, args.steps, args.dt, args.settings)
    tic = time.perf_counter()
    solver = fluid_solver(part, case)
    setup = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
    dofs = steppers.global_dofs(solver.W)
    say(
        f"[{level}/{model}] {dofs} dofs, solver set-up {setup:.1f} s (JIT if not cached);"
        f" {args.steps} steps of {args.dt:g} s"
    )
    run = run_steps(solver, case)
    J, F, F_lifted = assembly_times(solver, args.repeats)
    row = {
        "level": level,
        "model": model,
        "dofs": dofs,
        "cells": cells,
        "degree": case.fluid.quadrature_degree,
        "J_best": J.min() / dofs * 1e6,
        "J_mean": J.mean() / dofs * 1e6,
        "F_best": F.min() / dofs * 1e6,
        "F_lifted_best": F_lifted.min() / dofs * 1e6,
        **run,
    }
    say(
        f"[{level}/{model}] done: {run['steps']} steps, Newton {run['iterations']:.2f}"
        f"/step, step {run['step_s']:.3f} s"
    )
    del solver
    return row


def _print_table(rows: list[dict], args, comm, say, load_start, load_end) -> None:
    """The benchmark's table: one row per level and rheology, with its legend."""
    linear = "/".join(str(v) for v in config.load(CASE).fluid.solver.petsc_options.values())
    degree = rows[0]["degree"] if rows else "-"
    say(
        f"Fluid solver benchmark — {comm.size} rank(s), dolfinx {dolfinx.__version__}, "
        f"quadrature degree {degree} (fluid.quadrature_degree), Taylor–Hood P2/P1, "
        f"Newton + {linear}"
    )
    say(
        f"case: {CASE.name} + structure.mode=rigid, {args.steps} steps of {args.dt:g} s "
        f"from rest ({config.load(CASE).time.scheme}), assembly best of {args.repeats}"
    )
    say(
        f"load average at start {load_start[0]:.2f}, at end {load_end[0]:.2f} "
        f"({os.cpu_count()} CPUs)"
    )
    header = (
        f"{'level':<7}{'model':<10}{'dofs':>8}{'J µs/dof':>9}{'(mean)':>7}{'core':>6}"
        f"{'F µs/dof':>9}{'+lift':>7}{'Newton':>7}{'lin s/it':>9}{'(LU)':>7}{'step s':>8}"
        f"{'(1st)':>7}{'J+F s':>7}"
    )
    say(header)
    say("-" * len(header))
    for r in rows:
        newton = f"{r['iterations']:.2f}" + ("!" if r["failed"] else "")
        say(
            f"{r['level']:<7}{r['model']:<10}{r['dofs']:>8}{r['J_best']:>9.3f}"
            f"{r['J_mean']:>7.3f}{r['J_best'] * comm.size:>6.2f}{r['F_best']:>9.3f}"
            f"{r['F_lifted_best']:>7.3f}"
            f"{newton:>7}{r['linear_s']:>9.4f}{r['factor_s']:>7.4f}{r['step_s']:>8.3f}"
            f"{r['first_step_s']:>7.3f}{r['J_step_s'] + r['F_step_s']:>7.3f}"
        )
    say(
        "J, F µs/dof: one Jacobian / residual evaluation (NonlinearProblem.J/F: assembly, "
        "Dirichlet rows, PETSc finalisation) per global dof, best (and mean) of the repeats; "
        "F at an iterate on its Dirichlet values, the lifting skipped as the solver does, "
        "+lift: with it assembled (dolfinx's NonlinearProblem.F); "
        "core: J µs/dof × ranks. Newton: iterations (linear solves) per step. lin s/it: MUMPS "
        "per Newton iteration, PETSc events PCSetUp + PCApply; (LU): of which the "
        "factorisation. step s: wall time per step, mean (1st: the first step, with the "
        "symbolic factorisation); J+F s: per step, the Jacobian and residual evaluations inside "
        "Newton." + ("  !: a step failed." if any(r["failed"] for r in rows) else "")
    )


def _print_degree_studies(studies: dict, comm, say) -> None:
    """The Carreau Jacobian's assembly time against the quadrature degree, per level."""
    for level, (dofs, study) in studies.items():
        say()
        say(f"Carreau Jacobian vs quadrature degree — {level}, {dofs} dofs, {comm.size} rank(s)")
        head = f"{'degree':<30}{'points':>7}{'J µs/dof':>10}{'(mean)':>8}{'× deg 4':>9}{'JIT s':>8}"
        say(head)
        say("-" * len(head))
        ref = next((s["best"] for s in study if s["degree"] == "4"), None)
        for s in study:
            if np.isnan(s["best"]):  # UFL's estimate, not assembled
                say(f"{s['degree']:<30}{s['points']:>7}{'-':>10}{'-':>8}{'-':>9}{'-':>8}")
                continue
            ratio = f"{s['best'] / ref:.2f}" if ref else "-"
            say(
                f"{s['degree']:<30}{s['points']:>7}{s['best'] / dofs * 1e6:>10.3f}"
                f"{s['mean'] / dofs * 1e6:>8.3f}{ratio:>9}{s['jit_s']:>8.1f}"
            )
        say(
            "auto: UFL's estimated polynomial degree (per integral type), what FFCx would use"
            " with no quadrature_degree set, for the form with τ held at degree 4's points (the"
            " first degree's without 4); not assembled (SUPG's held τ needs a set degree)."
            " JIT s: the solver's set-up, form compilation included (cached after the first"
            " run)."
        )
