"""The linear solves inside the study's Newton iterations, one at a time (issue #11).

It builds the coupled moving-wall Carreau case on a mesh level, takes the first ``--steps`` steps
of its schedule (so the fluid and the structure are in motion), assembles each system's
Jacobian at that state and solves with it under each linear solver asked for: the case's own
(MUMPS's LU) and every ``--try SYSTEM 'OPTIONS'``. Per system and solver it prints:

* set-up (s): the first ``KSPSetUp`` (for LU: ordering, symbolic and numeric factorisation);
* refactorisation (ms): ``KSPSetUp`` after the matrix changed (numeric factorisation only, as
  in a Newton iteration that renews its Jacobian; median of ``--repeats``);
* solve (ms): one ``KSPSolve`` (for LU the two triangular solves, as in every chord iteration;
  median of ``--repeats``) and its Krylov iterations;
* |Ax − b|/|b|: the accuracy of that solve (b random, the same on every run);
* the factor's entries (MUMPS's INFOG(29), summed over ranks) for a MUMPS factorisation.

Times are the slowest rank's. Comparing 1 and 2 ranks (``mpirun -n 2 ... -m mpi4py``) shows how
each piece scales; comparing solvers shows what an iterative one would cost per Newton
iteration against the chord iterations' triangular solves (docs/performance.md).

Usage::

    .venv/bin/python scripts/benchmark_linear.py [--level fine] [--steps 3] [--repeats 10]
        [--systems fluid structure] [--try structure 'ksp_type=cg pc_type=gamg' ...]
        [--set 'structure.solver.petsc_options={ksp_type: cg, pc_type: gamg}' ...]
    mpirun -n 2 .venv/bin/python -m mpi4py scripts/benchmark_linear.py ...
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from fsi import compat, config
from fsi.coupled import partitioned
from fsi.numerics.newton import petsc_options, set_fields
from fsi.numerics.timestepping import steps
from fsi.performance.profiling import wall, window

CASE = Path(__file__).resolve().parents[2] / "configs" / "stenosis_moving_carreau.yaml"
SYSTEMS = ("fluid", "structure")


def parse_options(text: str) -> dict[str, str]:
    """'ksp_type=cg pc_type=gamg' → {'ksp_type': 'cg', 'pc_type': 'gamg'}."""
    pairs = [item.split("=", 1) for item in text.split()]
    if any(len(pair) != 2 for pair in pairs):
        raise SystemExit(f"benchmark_linear: options must be KEY=VALUE pairs, got {text!r}")
    return dict(pairs)


def measure(
    comm: MPI.Comm,
    A: PETSc.Mat,
    prefix: str,
    options: dict,
    repeats: int,
    fields: dict[str, PETSc.IS] | None = None,
) -> dict[str, float]:
    """Set up, refactorise and solve with ``A`` under ``options`` (PETSc names without the
    prefix; a ``pc_type: fieldsplit`` gets the system's ``fields``, as its Newton solver gives
    them); see the module docstring for what each figure means."""
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix(prefix)
    with petsc_options(prefix, options):
        ksp.setFromOptions()
        set_fields(ksp, fields)
        ksp.setOperators(A)
        setup = wall(comm, ksp.setUp, 1)[0]

        def refactorise():
            A.stateIncrease()  # "changed": the next set-up redoes the numeric phase
            ksp.setOperators(A)
            ksp.setUp()

        refactor = wall(comm, refactorise, max(1, repeats // 3))
        b = A.createVecLeft()
        x = A.createVecRight()
        rows = b.getOwnershipRange()
        b.setValues(
            np.arange(*rows, dtype=PETSc.IntType),
            np.random.default_rng(rows[0]).standard_normal(rows[1] - rows[0]),
        )
        b.assemble()
        solves = wall(comm, lambda: ksp.solve(b, x), repeats)
    r = b.duplicate()
    A.mult(x, r)
    r.axpy(-1.0, b)
    pc = ksp.getPC()
    entries = float("nan")
    if pc.getType() in ("lu", "cholesky") and pc.getFactorSolverType() == "mumps":
        entries = float(pc.getFactorMatrix().getMumpsInfog(29))
    row = {
        "setup_s": setup,
        "refactor_ms": 1e3 * float(np.median(refactor)),
        "solve_ms": 1e3 * float(np.median(solves)),
        "iterations": ksp.getIterationNumber(),
        "converged": ksp.getConvergedReason() > 0,
        "relative_residual": r.norm() / b.norm(),
        "factor_entries": entries,
    }
    for vec in (b, x, r):
        vec.destroy()
    ksp.destroy()
    return row


def jacobians(case: config.Case, comm: MPI.Comm, n_steps: int) -> tuple[object, dict]:
    """The coupled problem after its first ``n_steps`` steps, and each system's Jacobian
    assembled anew at that state: {system: (matrix, options prefix, the case's options, dofs,
    the fields of a fieldsplit preconditioner)}.
    The matrices belong to the problem's Newton solvers: keep the problem while using them
    (dolfinx 0.9's solver destroys its matrix with itself)."""
    problem = partitioned.build_coupled(case, comm)
    for step in steps(case.time):
        if step.index > n_steps:
            break
        problem.step(step.index, step.t, step.dt)
    systems = {}
    for name, solver, unknown, settings in (
        ("fluid", problem.fluid, problem.fluid.U, case.fluid.solver),
        ("structure", problem.solid, problem.solid.eta, case.structure.solver),
    ):
        newton = solver.newton
        newton.problem.J(compat.petsc_vector(unknown), newton.solver.A)
        systems[name] = (
            newton.solver.A,
            newton.prefix,
            dict(settings.petsc_options),
            newton.solver.A.getSize()[0],
            newton.fields,
        )
    return problem, systems


def main(argv: list[str] | None = None) -> list[dict]:
    parser = _parser()
    args = parser.parse_args(argv)
    for system, _ in args.tries:
        if system not in SYSTEMS:
            parser.error(f"--try: SYSTEM must be one of {', '.join(SYSTEMS)}, got {system!r}")
    tries = [(system, text, parse_options(text)) for system, text in args.tries]  # before work
    comm = MPI.COMM_WORLD

    def say(text: str) -> None:
        if comm.rank == 0:
            print(text, flush=True)

    overrides = [f"mesh.level={args.level}", *args.overrides]
    case = config.load(args.config, overrides)
    case = config.load(args.config, [*overrides, f"time.end={window(case, args.steps)!r}"])
    say(
        f"linear solves: {args.config.name}, {args.level}, after {args.steps} steps; "
        f"{comm.size} rank(s), PETSc {'.'.join(map(str, PETSc.Sys.getVersion()))}, "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}"
    )
    problem, systems = jacobians(case, comm, args.steps)
    rows = []
    for system in args.systems:
        A, prefix, own, dofs, fields = systems[system]
        solvers = [("case", own)] + [(text, opts) for name, text, opts in tries if name == system]
        for label, options in solvers:
            row = measure(comm, A, prefix, options, args.repeats, fields)
            rows.append({"system": system, "dofs": dofs, "solver": label, **row})
    del problem, systems  # the matrices, with their solvers
    _print_rows(say, rows, args.repeats)
    return rows


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=CASE)
    parser.add_argument("--level", default="fine")
    parser.add_argument("--steps", type=int, default=3, help="steps taken before measuring")
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--systems", nargs="+", choices=SYSTEMS, default=list(SYSTEMS))
    parser.add_argument(
        "--try",
        dest="tries",
        nargs=2,
        action="append",
        default=[],
        metavar=("SYSTEM", "OPTIONS"),
        help="another linear solver for SYSTEM: PETSc options 'key=value ...' without prefix",
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a config override, as fsi run's (e.g. the case's own solvers, where LU does not fit)",
    )
    return parser


def _print_rows(say, rows: list[dict], repeats: int) -> None:
    """The table: per system and solver, set-up, refactorisation and solve times, iterations,
    the residual and the factor's size."""
    say(
        f"{'system':10} {'dofs':>8} {'set-up s':>9} {'refactor ms':>12} {'solve ms':>9} "
        f"{'its':>5} {'|Ax-b|/|b|':>11} {'factor entries':>15}  solver"
    )
    for r in rows:
        its = str(r["iterations"]) + ("" if r["converged"] else "!")
        say(
            f"{r['system']:10} {r['dofs']:8d} {r['setup_s']:9.3f} {r['refactor_ms']:12.1f} "
            f"{r['solve_ms']:9.1f} {its:>5} {r['relative_residual']:11.2e} "
            f"{r['factor_entries']:15.3g}  {r['solver']}"
        )
    say(
        f"times: the slowest rank's, median of {repeats} solves and "
        f"{max(1, repeats // 3)} refactorisations; its: Krylov iterations of the last "
        "solve (!: not converged); case: the config's own options (MUMPS LU)."
    )
