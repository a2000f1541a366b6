"""Jacobian reuse (modified Newton, fsi/numerics/newton.py) in the fluid and the solid solvers.

Reuse changes the path of Newton's iterations, not the answer: on the study's moving-wall Carreau
stenosis (coarse, steps of 0.25 ms inside the inlet pulse) the fluid alone, the structure alone
and the coupled problem give, with ``jacobian_reuse`` ``step`` or ``run``, the solution of plain
Newton to the solvers' tolerance, with fewer Jacobian assemblies and one LU factorisation per
assembly. ``step`` makes a step depend only on the state at its start (restarts stay exact); a
solve that fails with a reused Jacobian is repeated with fresh ones.

Tolerance of "the same solution". The solvers stop on dolfinx's test (|F| or the increment below
atol, or below rtol × the first increment), so each answer is off the exact discrete solution U*
by about its Newton correction c = |J(U)⁻¹ F(U)| (the step one more fresh Newton iteration would
take; to second order, |U − U*| = c). Hence |U_reuse − U_newton| <= c_reuse + c_newton, checked
with 10 % for the second-order terms plus round-off (1e-12 |U|), from the same state at the start
of each step. Measured (1 rank): fluid |ΔU| 8e-6–3e-3 (|U| 5e2–8e3: pressures in Pa), 0.45–0.96 of
c_reuse + c_newton; structure |Δη| 5e-17–2e-12 m (|η| 1e-5–8e-4 m), 0.98–1.00 of it (plain Newton
is exact to ~1e-18 m there, so the bound is the reused solve's own correction). The coupled runs
stop on the interface residual (coupling.tolerance 1e-6): their answers agree to that (measured
≤ 1e-8 relative).
"""

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import pytest
import ufl

from fsi import compat, config
from fsi.config.solver_settings import SolverSettings
from fsi.geometry.tags import Region
from fsi.numerics.newton import Forcing, Newton
from fsi.numerics.timestepping import steps
from fsi.physics import fluid, mesh, solid
from fsi.physics.fluid_boundaries import inlet_pressure
from fsi.physics.fluid_case import fluid_conditions
from fsi.run.steppers import CoupledStepper

CASE = "configs/stenosis_moving_carreau.yaml"
SHORT = ["time.end=0.001", "time.schedule=[{until: 0.001, dt: 0.00025}]"]  # 4 steps


def case_with(*overrides: str) -> config.Case:
    return config.load(CASE, [*SHORT, *overrides])


@pytest.fixture(scope="module")
def whole():
    return mesh.build(case_with(), MPI.COMM_WORLD)


def global_norm(comm: MPI.Comm, a: np.ndarray) -> float:
    return float(np.sqrt(comm.allreduce(float(a @ a), op=MPI.SUM)))


def newton_correction(problem, u) -> float:
    """|J(u)⁻¹ F(u)|: the size of one more (fresh) Newton step from u."""
    comm = u.function_space.mesh.comm
    x = compat.petsc_vector(u)
    b = dolfinx.fem.petsc.create_vector(problem.L)
    A = dolfinx.fem.petsc.create_matrix(problem.a)
    problem.F(x, b)
    problem.J(x, A)
    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    dx = A.createVecRight()
    ksp.solve(b, dx)
    size = dx.norm()
    for obj in (ksp, A, b, dx):
        obj.destroy()
    return size


def lu_factorisations() -> int:
    """Numeric LU factorisations on this rank so far (PETSc's MatLUFactorNum event)."""
    return int(PETSc.Log.Event("MatLUFactorNum").getPerfInfo()["count"])


def owned(solver_function) -> np.ndarray:
    """Owned entries (no ghosts) of a Function's array."""
    V = solver_function.function_space
    return solver_function.x.array[: V.dofmap.index_map.size_local * V.dofmap.index_map_bs]


def gathered_by_position(comm: MPI.Comm, points: np.ndarray, values: np.ndarray) -> np.ndarray:
    """All ranks' interface values, sorted by their points (the same on every rank)."""
    points = np.concatenate(comm.allgather(np.asarray(points)[:, :2]))
    values = np.concatenate(comm.allgather(np.asarray(values)))
    return values[np.lexsort((points[:, 1].round(12), points[:, 0].round(12)))]


def assert_equal_arrays(a: np.ndarray, b: np.ndarray, comm: MPI.Comm) -> None:
    """Equal to the bit on one rank; on several, to round-off: there two plain Newton solves of
    the same step by two solver objects differ by ~1e-16 relative (measured 2 ranks: 1.2e-16 of
    max |U|, MUMPS's parallel order of operations), hence 1e-13."""
    if comm.size == 1:
        assert np.array_equal(a, b)
    else:
        assert np.allclose(a, b, rtol=0, atol=1e-13 * np.abs(b).max())


def assert_same_solution(a, b, problems, comm, what):
    """|a − b| <= 1.1 (c_a + c_b) + 1e-12 |b| (see the module docstring)."""
    corrections = [newton_correction(p, f) for p, f in problems]
    difference = global_norm(comm, owned(a) - owned(b))
    bound = 1.1 * sum(corrections) + 1e-12 * global_norm(comm, owned(b))
    assert difference <= bound, f"{what}: |Δ| {difference:.3e} > {bound:.3e} ({corrections})"


# --------------------------------------------------------------------------------------------


def test_fluid_with_reused_jacobians_finds_newtons_solution(whole):
    """Rigid-wall Carreau stenosis: at every step, from Newton's state at its start, the
    solvers with reuse step and run reach Newton's solution, assembling fewer Jacobians than
    they take iterations and factorising exactly once per assembly."""
    comm = whole.comm
    PETSc.Log.begin()
    part = mesh.restrict(whole, Region.FLUID)
    solvers = {}
    for reuse in ("none", "step", "run"):
        case = case_with("structure.mode=rigid", f"fluid.solver.jacobian_reuse={reuse}")
        solvers[reuse] = fluid.FluidSolver(
            part.mesh, part.facet_tags, case.fluid, fluid_conditions(case)
        )
    newton = solvers["none"]
    iterations = {"step": 0, "run": 0}
    for st in steps(case_with().time):
        state = newton.save_state()
        assert newton.step(st.t, st.dt).converged
        for reuse in ("step", "run"):
            s = solvers[reuse]
            s.restore_state(state)
            jacobians, factorisations = s.newton.callbacks.jacobian_assemblies, lu_factorisations()
            result = s.step(st.t, st.dt)
            assert result.converged
            iterations[reuse] += result.iterations
            # An unchanged matrix keeps its factorisation: one LU per assembled Jacobian.
            assert (
                lu_factorisations() - factorisations
                == s.newton.callbacks.jacobian_assemblies - jacobians
            )
            assert_same_solution(
                s.U,
                newton.U,
                [(s.problem, s.U), (newton.problem, newton.U)],
                comm,
                f"{reuse}, step {st.index}",
            )
        for s in solvers.values():
            s.advance()
    for reuse in ("step", "run"):
        callbacks = solvers[reuse].newton.callbacks
        assert callbacks.retries == 0
        # Measured over the 4 steps: step 7 assemblies for 14 iterations, run 5 for 15.
        assert callbacks.jacobian_assemblies < iterations[reuse]
    assert (
        solvers["run"].newton.callbacks.jacobian_assemblies
        <= solvers["step"].newton.callbacks.jacobian_assemblies
    )


def test_structure_with_reused_jacobians_finds_newtons_solution(whole):
    """The moving wall and plaque alone under the inlet pulse as a follower pressure."""
    comm = whole.comm
    pressure = inlet_pressure(case_with().fluid.inlet)
    solvers = {
        reuse: solid.build(
            case_with(
                "structure.interface_load=inlet_pressure",
                f"structure.solver.jacobian_reuse={reuse}",
            ),
            whole,
            comm,
            pressure,
        )
        for reuse in ("none", "step", "run")
    }
    newton = solvers["none"]
    iterations = {"step": 0, "run": 0}
    for st in steps(case_with().time):
        state = newton.save_state()
        assert newton.step(st.t, st.dt).converged
        for reuse in ("step", "run"):
            s = solvers[reuse]
            s.restore_state(state)
            result = s.step(st.t, st.dt)
            assert result.converged
            iterations[reuse] += result.iterations
            assert_same_solution(
                s.eta,
                newton.eta,
                [(s.problem, s.eta), (newton.problem, newton.eta)],
                comm,
                f"{reuse}, step {st.index}",
            )
        for s in solvers.values():
            s.advance()
    # Measured: step 4 assemblies for 14 iterations, run 2 for 14 (Newton: 12 for 12).
    for reuse in ("step", "run"):
        assert solvers[reuse].newton.callbacks.jacobian_assemblies < iterations[reuse]


def test_coupled_run_with_reuse_matches_plain_newton():
    """Moving-wall Carreau, IQN-ILS, 3 steps: the same peaks and interface displacement to the
    coupling tolerance (measured ≤ 1e-8 relative)."""
    comm = MPI.COMM_WORLD
    steppers, rows = {}, {}
    for reuse in ("none", "step"):
        case = case_with(
            "time.end=0.00075",
            "coupling.acceleration=iqn-ils",
            f"fluid.solver.jacobian_reuse={reuse}",
            f"structure.solver.jacobian_reuse={reuse}",
        )
        steppers[reuse] = CoupledStepper(case, comm)
        rows[reuse] = [steppers[reuse].step(st) for st in steps(case.time)]
    tolerance = case.coupling.tolerance
    for a, b in zip(rows["step"], rows["none"]):
        for key in ("peak_velocity", "peak_pressure", "peak_displacement", "max_sss"):
            assert a[key] == pytest.approx(b[key], rel=tolerance), key
    # Each run built its own mesh (on several ranks, another partition): compare by position.
    x = {
        r: gathered_by_position(
            comm, s.problem.solid.interface_points, s.problem.solid.interface_displacement()
        )
        for r, s in steppers.items()
    }
    assert np.linalg.norm(x["step"] - x["none"]) <= tolerance * np.linalg.norm(x["none"])
    # The point of it: far fewer fluid Jacobians (and factorisations) than Newton iterations.
    fluid_side = steppers["step"].problem.fluid
    newton_iterations = sum(r["newton_iterations"] for r in rows["step"])
    assert fluid_side.newton.callbacks.jacobian_assemblies < newton_iterations / 2


def test_step_reuse_makes_a_step_depend_only_on_its_start(whole):
    """With reuse ``step`` a solver that starts from the state after step 2 solves step 3 with
    the very arithmetic of the solver that ran steps 1–3 (what makes restarts exact; on several
    ranks up to MUMPS's round-off, see :func:`assert_equal_arrays`)."""
    part = mesh.restrict(whole, Region.FLUID)
    case = case_with("structure.mode=rigid", "fluid.solver.jacobian_reuse=step")
    schedule = list(steps(case.time))
    runs = [
        fluid.FluidSolver(part.mesh, part.facet_tags, case.fluid, fluid_conditions(case))
        for _ in range(2)
    ]
    through, restarted = runs
    for st in schedule[:2]:
        assert through.step(st.t, st.dt).converged
        through.advance()
    restarted.restore_state(through.save_state())
    for s in runs:
        assert s.step(schedule[2].t, schedule[2].dt).converged
    assert_equal_arrays(through.U.x.array, restarted.U.x.array, whole.comm)


def test_a_failed_solve_with_a_reused_jacobian_is_repeated_with_fresh_ones(whole):
    """Step 1 from rest with at most 4 iterations: modified Newton does not get there (measured
    on 1 and 2 ranks), plain Newton does (in 4). The repeat is plain Newton from the same guess,
    so the answer is Newton's (to the bit on one rank) and both attempts' iterations count."""
    part = mesh.restrict(whole, Region.FLUID)
    solvers = {}
    for reuse in ("none", "run"):
        case = case_with(
            "structure.mode=rigid",
            "fluid.solver.max_iterations=4",
            f"fluid.solver.jacobian_reuse={reuse}",
        )
        solvers[reuse] = fluid.FluidSolver(
            part.mesh, part.facet_tags, case.fluid, fluid_conditions(case)
        )
    st = next(iter(steps(case.time)))
    results = {reuse: s.step(st.t, st.dt) for reuse, s in solvers.items()}
    assert results["none"].converged and results["run"].converged
    assert solvers["run"].newton.callbacks.retries == 1
    assert results["run"].iterations == 4 + results["none"].iterations
    assert_equal_arrays(solvers["run"].U.x.array, solvers["none"].U.x.array, whole.comm)


@pytest.mark.parametrize("reuse", ["none", "run"])
def test_a_solve_after_a_failed_factorisation_is_not_accepted_untried(reuse):
    """F(u) = (u² − 4) v: at u = 0 the Jacobian is the zero matrix, MUMPS's factorisation fails
    and PETSc's failed preconditioner returns an infinite increment. dolfinx's NewtonSolver kept
    that |δx_1| as the reference of its relative test, so the next solve, from u = 1, passed the
    test at iteration 0 and returned u = 1 as converged (residual 0.66). The failed solve now
    replaces the solver: the next one iterates to u = 2."""
    domain = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    V = compat.function_space(domain, "Lagrange", 1)
    u, v = dolfinx.fem.Function(V), ufl.TestFunction(V)
    problem = dolfinx.fem.petsc.NonlinearProblem((u * u - 4.0) * v * ufl.dx, u)
    newton = Newton(domain.comm, problem, SolverSettings(jacobian_reuse=reuse), "failed_lu_")
    first = newton.solve(u, lambda: newton.solver.b.norm())
    assert not first.converged and "PETSc" in first.reason
    assert np.all(u.x.array == 0.0)  # put back to the guess
    u.x.array[:] = 1.0
    second = newton.solve(u, lambda: newton.solver.b.norm())
    assert second.converged and second.iterations >= 3, second
    assert np.allclose(u.x.array, 2.0, rtol=1e-8)  # Newton's tolerance (chord iterations: run)


@pytest.mark.parametrize("reuse", ["none", "run"])
def test_a_solve_from_near_the_answer_iterates_to_its_tolerance(reuse):
    """F(u) = (u² − 4) v, solved from u = 1000 (its first increment ~500 a dof), then from the
    answer 2 perturbed by 1e-6: |F(x_0)| ~ 1e-7 is above atol 1e-10, but below rtol × the
    *previous* solve's |δx_1|, which dolfinx's relative test divides by at x_0, and the guess
    was returned as converged after 0 iterations. The first test is now absolute: the solve
    iterates to |F| < atol."""
    domain = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    V = compat.function_space(domain, "Lagrange", 1)
    u, v = dolfinx.fem.Function(V), ufl.TestFunction(V)
    problem = dolfinx.fem.petsc.NonlinearProblem((u * u - 4.0) * v * ufl.dx, u)
    settings = SolverSettings(rtol=1e-9, atol=1e-10, jacobian_reuse=reuse)
    newton = Newton(domain.comm, problem, settings, "near_answer_")
    u.x.array[:] = 1000.0
    assert newton.solve(u, lambda: newton.solver.b.norm()).converged
    u.x.array[:] = 2.0 + 1e-6
    initial = newton.solve(u, lambda: newton.solver.b.norm())  # evaluates F(x_0) first
    assert initial.converged and initial.iterations >= 1, initial
    assert initial.residual < 1e-10
    assert np.allclose(u.x.array, 2.0, rtol=1e-12)
    assert (newton.solver.rtol, newton.solver.atol) == (1e-9, 1e-10)  # put back


def test_a_forced_solve_stops_at_its_forcing_with_newtons_solution(whole):
    """A coupling iteration's fluid solve after the first (fsi/coupled/partitioned.py), mimicked
    on the rigid-wall Carreau stenosis: at each step, from a warm start 1 % of the step's change
    off its solution, the solve forced with η = 1e-2 and the first solve's final residual as
    ceiling stops at the first iterate with |F| <= max(atol, min(ceiling, η |F(x_0)|)), takes
    fewer iterations than the unforced solve from the same start (measured 4 against 11 over
    the 4 steps, 1 and 2 ranks), and reaches its solution to the Newton correction (module
    docstring)."""
    comm = whole.comm
    part = mesh.restrict(whole, Region.FLUID)
    case = case_with("structure.mode=rigid", "fluid.solver.jacobian_reuse=run")
    solvers = [
        fluid.FluidSolver(part.mesh, part.facet_tags, case.fluid, fluid_conditions(case))
        for _ in range(2)
    ]
    first, s = solvers
    iterations = {"forced": 0, "unforced": 0}
    for st in steps(case.time):
        state = first.save_state()
        start = first.U.x.array.copy()
        first_result = first.step(st.t, st.dt)
        assert first_result.converged
        guess = first.U.x.array + 1e-2 * (first.U.x.array - start)
        forcing = Forcing(1e-2, ceiling=first_result.residual)
        answers = {}
        for name, f in (("unforced", None), ("forced", forcing)):
            s.restore_state(state)
            s.U.x.array[:] = guess
            result = s.step(st.t, st.dt, forcing=f)
            assert result.converged, result
            iterations[name] += result.iterations
            answers[name] = s.U.x.array.copy()
        norms = s.newton.callbacks._norms
        stop = forcing.atol(case.fluid.solver.atol, norms[0])
        assert norms[-1] <= stop < min(norms[:-1]), (norms, stop)
        # Newton corrections of both answers, on s's forms (set for this step by its solves).
        corrections = []
        for answer in answers.values():
            s.U.x.array[:] = answer
            corrections.append(newton_correction(s.problem, s.U))
        size = s.U.function_space.dofmap.index_map.size_local
        difference = global_norm(comm, answers["forced"][:size] - answers["unforced"][:size])
        bound = 1.1 * sum(corrections) + 1e-12 * global_norm(comm, answers["unforced"][:size])
        assert difference <= bound, (st.index, difference, corrections)
        first.advance()
    assert iterations["forced"] < iterations["unforced"], iterations


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("fluid.solver.jacobian_reuse", "true", "one of 'none', 'step', 'run'"),
        ("structure.solver.jacobian_reuse", "yes", "one of 'none', 'step', 'run'"),
        ("fluid.solver.jacobian_reuse_rate", "1.0", "a number in (0.0, 1.0)"),
        ("structure.solver.jacobian_reuse_rate", "0", "a number in (0.0, 1.0)"),
    ],
)
def test_reuse_settings_are_checked(key, value, expected):
    with pytest.raises(config.ConfigError, match=key.replace(".", r"\.")) as e:
        config.load(CASE, [f"{key}={value}"])
    assert expected in str(e.value)
    reused = config.load(
        CASE, ["fluid.solver.jacobian_reuse=run", "structure.solver.jacobian_reuse_rate=0.5"]
    )
    assert reused.fluid.solver.jacobian_reuse == "run"
    assert reused.structure.solver.jacobian_reuse_rate == 0.5


@pytest.mark.parametrize("side", ["fluid", "structure"])
def test_the_lifting_comes_from_the_jacobian_and_is_skipped_where_it_is_zero(whole, side):
    """Both solvers' problems against dolfinx's ``NonlinearProblem``: the Jacobian is dolfinx's
    (the conditions' rows and columns the identity's) to the bit; at an iterate off the Dirichlet
    values the residual, its lifting J (g − x) taken from the columns kept by the Jacobian at
    that iterate (:class:`fsi.numerics.newton.DirichletLifting`), is dolfinx's to round-off on
    every owned entry; at one exactly on them it skips the lifting and is dolfinx's to the bit;
    and a step's solve skips it at its later iterations (measured: the fluid 2 of 3 residual
    evaluations in step 1, the structure every one, its clamped dofs staying at 0)."""
    st = next(iter(steps(case_with().time)))
    if side == "fluid":
        part = mesh.restrict(whole, Region.FLUID)
        case = case_with("structure.mode=rigid")
        s = fluid.FluidSolver(part.mesh, part.facet_tags, case.fluid, fluid_conditions(case))
        unknown = s.U
    else:
        case = case_with("structure.interface_load=inlet_pressure")
        s = solid.build(case, whole, whole.comm, inlet_pressure(case.fluid.inlet))
        unknown = s.eta
    problem = s.problem
    assert problem.bcs, "the case has no Dirichlet condition to lift"
    assert s.step(st.t, st.dt).converged
    assert problem.dirichlet.skipped > 0

    x = compat.petsc_vector(unknown).copy()
    rng = np.random.default_rng(1 + whole.comm.rank)
    with x.localForm() as local:
        local.array[:] += 1e-3 * rng.standard_normal(local.array.shape)
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    problem.form(x)
    A, theirs = (dolfinx.fem.petsc.create_matrix(problem.a) for _ in range(2))
    problem.J(x, A)
    dolfinx.fem.petsc.NonlinearProblem.J(problem, x, theirs)
    theirs.axpy(-1.0, A)
    assert theirs.norm(PETSc.NormType.NORM_INFINITY) == 0.0
    b, reference = (dolfinx.fem.petsc.create_vector(problem.L) for _ in range(2))
    for on_the_conditions in (False, True):
        if on_the_conditions:  # x = g at the Dirichlet dofs, exactly
            dolfinx.fem.petsc.set_bc(x, problem.bcs)
            x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
            problem.form(x)
        skipped = problem.dirichlet.skipped
        problem.F(x, b)
        dolfinx.fem.petsc.NonlinearProblem.F(problem, x, reference)
        assert problem.dirichlet.skipped == skipped + on_the_conditions
        if on_the_conditions:
            assert np.array_equal(b.array_r, reference.array_r)
        else:
            scale = reference.norm(PETSc.NormType.NORM_INFINITY)
            assert np.allclose(b.array_r, reference.array_r, rtol=0, atol=1e-12 * scale)
    for obj in (x, b, reference, A, theirs):
        obj.destroy()
