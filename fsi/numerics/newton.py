"""Newton solves for the fluid and the solid: dolfinx's NewtonSolver with its PETSc options scoped
to one solver (:func:`petsc_options`), failures returned rather than raised (:class:`Newton`),
an optional inexact stop (:class:`Forcing`) and an optionally reused Jacobian (modified Newton,
:class:`NewtonCallbacks`): ``x_{k+1} = x_k − J̃⁻¹ F(x_k)`` with ``J̃`` (and its LU factorisation)
kept from the last assembly within the step (reuse ``step``) or the run (``run``), assembled
anew when there is none, at a step's first iteration (``step``) and when
``|F(x_k)| > max_rate · |F(x_{k−1})|``. The solver's own test still decides convergence, and a
failed reused-Jacobian solve is repeated with a fresh Jacobian at every iteration.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass
from typing import Literal

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.nls.petsc
import numpy as np

log = logging.getLogger(__name__)

Reuse = Literal["none", "step", "run"]


@dataclass(frozen=True)
class Forcing:
    """Stop a solve once |F(x_k)| <= max(atol, min(ceiling, eta · |F(x_0)|)), as well as on the
    solver's own test: ``eta`` in (0, 1) is the factor by which the solve reduces the residual it
    started from, ``ceiling`` (in F's units) the loosest residual accepted. For the coupling's
    fluid solves after a step's first (fsi/coupled/partitioned.py), which start near the answer.
    """

    eta: float
    ceiling: float

    def __post_init__(self):
        if not 0 < self.eta < 1:
            raise ValueError(f"forcing eta must be in (0, 1), got {self.eta}")

    def atol(self, atol: float, initial_residual: float) -> float:
        return max(atol, min(self.ceiling, self.eta * initial_residual))


class NewtonCallbacks:
    """The residual and Jacobian callbacks of ``newton`` (registered here), with the reuse policy
    of the module docstring.

    Args:
        problem: the nonlinear problem (its ``F(x, b)`` and ``J(x, A)`` are looked up at every
            call, so a wrapper set on the instance is used).
        newton: the dolfinx NewtonSolver built for ``problem``.
        reuse: ``none``, ``step`` or ``run``: how long a Jacobian (and its factorisation) may
            be kept while it contracts the residual (see the module docstring).
        max_rate: the largest accepted ratio |F(x_k)| / |F(x_{k−1})| of a reused Jacobian.

    Counters: ``jacobian_assemblies``, ``residual_evaluations`` (since construction),
    ``retries`` (solves repeated with fresh Jacobians).
    """

    def __init__(self, problem, newton, reuse: Reuse = "none", max_rate: float = 0.3):
        if reuse not in ("none", "step", "run"):
            raise ValueError(f"reuse must be 'none', 'step' or 'run', got {reuse!r}")
        if not 0 < max_rate < 1:
            raise ValueError(f"max_rate must be in (0, 1), got {max_rate}")
        self.problem, self.reuse, self.max_rate = problem, reuse, float(max_rate)
        self.jacobian_assemblies = 0
        self.residual_evaluations = 0
        self.retries = 0
        self._fresh = reuse == "none"
        self._step: Hashable = None
        self._norms: list[float] = []
        self._evaluations = 0  # residuals evaluated in this solve (attempt)
        self.before_test: Callable[[int, PETSc.Vec], None] | None = None
        """Called with (k, F(x_k)) at each residual of a solve, before the solver tests it."""
        self.attach(newton)  # also: no Jacobian kept yet

    def attach(self, newton) -> None:
        """Be ``newton``'s residual and Jacobian callbacks (also a new solver's, replacing a
        failed one: the kept Jacobian lived in the old solver's matrix and is dropped)."""
        newton.setF(self.F, newton.b)
        newton.setJ(self.J, newton.A)
        self._have_jacobian = False

    def F(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        self.problem.F(x, b)
        self.residual_evaluations += 1
        if self.before_test is not None:
            self.before_test(self._evaluations, b)
        self._evaluations += 1
        if not self._fresh:
            self._norms.append(b.norm())  # a global norm: every rank decides alike

    def J(self, x: PETSc.Vec, A: PETSc.Mat) -> None:
        if not self._fresh and self._have_jacobian and self._contracting():
            return  # A and its factorisation stay as they are
        self.problem.J(x, A)
        self.jacobian_assemblies += 1
        self._have_jacobian = True

    def forget(self) -> None:
        """Drop the kept Jacobian: the next Jacobian call assembles (and the solve factorises)
        anew, as a solver built at this point would, and the next lifting comes from the form
        (:class:`DirichletLifting`). With reuse ``run``, a restart repeats the run's arithmetic
        only from checkpoints after this call (fsi/run/simulation.py).
        """
        self._have_jacobian = False
        self._forget_lifting()

    def _forget_lifting(self) -> None:
        lifting = getattr(self.problem, "dirichlet", None)
        if isinstance(lifting, DirichletLifting):
            lifting.forget()

    def _contracting(self) -> bool:
        """The last iteration (if any in this solve) reduced |F| by at least ``max_rate``."""
        if len(self._norms) < 2:
            return True
        previous, current = self._norms[-2], self._norms[-1]
        return current <= self.max_rate * previous

    def solve(
        self,
        newton,
        u: dolfinx.fem.Function,
        step: Hashable = None,
        renew: Callable[[], object] | None = None,
    ) -> tuple[int, bool]:
        """``newton.solve(u)``; with reuse, if that fails, again from the same initial guess with
        a fresh Jacobian at every iteration, on the new solver ``renew()`` returns (see
        :meth:`Newton._renew`). ``step`` identifies the time step (anything that changes when
        the solver advances): with reuse ``step`` a new value means a fresh Jacobian. Returns
        (iterations of both attempts, converged).
        """
        self._norms, self._evaluations = [], 0
        if self.reuse != "run" and step != self._step:
            # a new step starts as a restarted run's would: without the last step's Jacobian
            self._have_jacobian = False
            self._forget_lifting()
        self._step = step
        if self.reuse == "none":
            return newton.solve(u)
        start = u.x.array.copy()
        try:
            iterations, converged = newton.solve(u)
        except RuntimeError:  # a PETSc error, raised on every rank: try plain Newton
            iterations, converged = newton.max_it, False
        if converged:
            return iterations, converged
        self.retries += 1
        u.x.array[:] = start
        u.x.scatter_forward()
        if renew is not None:
            newton = renew()
        self._fresh, self._evaluations = True, 0
        try:
            more, converged = newton.solve(u)
        finally:
            self._fresh = False
            self._norms = []
        return iterations + more, converged


class DirichletLifting:
    """The Dirichlet conditions of a Newton solve, as dolfinx's ``NonlinearProblem`` has them,
    with the lifting taken from the Jacobian instead of assembled.

    :meth:`jacobian` assembles J without the conditions, keeps its columns of the constrained
    dofs (a thin matrix C), then sets the constrained rows and columns to the identity's: the
    matrix dolfinx assembles with the conditions. :meth:`apply` makes a residual: ``b ← b +
    C (g − x)`` on the free rows (the lifting), then ``b = x − g`` on the constrained rows.

    dolfinx assembles the lifting J(x) (g − x) from the Jacobian form, the element matrices of
    every cell with a constrained dof: as much as a third of a 3D moving-wall fluid solve, whose
    interface velocity changes at every coupling iteration (docs/performance.md). C is the
    Jacobian the Newton step is solved with, assembled at that iterate or, with a kept Jacobian
    (:class:`NewtonCallbacks`), earlier: the step is then the chord step of the whole system,
    its known constrained part moved to the right-hand side, where dolfinx's pairs the kept
    free-row block with a fresh lifting. Either way the converged solution is the same; with C
    assembled at x the residual is dolfinx's to round-off. Before any Jacobian, and after
    :meth:`forget` (at a new step unless Jacobians are kept across steps, and where they are
    dropped for a checkpoint: a restarted run has none), the lifting is assembled from the form,
    as dolfinx does. It is skipped where x = g at every constrained dof on every rank: it is
    zero then, at every Newton iterate after a solve's first (the update sets x = g there; the
    structure's clamped dofs stay at 0).
    """

    def __init__(self, a, bcs: list):
        self.a, self.bcs = a, bcs
        self._gap: PETSc.Vec | None = None  # g − x at the owned constrained dofs, else 0
        self._columns: PETSc.Mat | None = None  # C: the last Jacobian's constrained columns
        self._constrained: PETSc.IS | None = None  # the owned constrained dofs (global)
        self._rows: PETSc.IS | None = None  # every owned row (global)
        self.skipped = 0  # liftings not needed (counter, for the benchmarks)

    def jacobian(self, A: PETSc.Mat) -> None:
        """``A``: J without the conditions, its constrained columns kept as C, then the
        constrained rows and columns the identity's. Collective."""
        A.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(A, self.a)
        A.assemble()
        if self._constrained is None:
            self._constrained, self._rows = self._index_sets(A)
        if self._columns is not None:
            self._columns.destroy()
        self._columns = A.createSubMatrix(self._rows, self._constrained)
        A.zeroRowsColumns(self._constrained, diag=1.0)

    def _index_sets(self, A: PETSc.Mat) -> tuple[PETSc.IS, PETSc.IS]:
        space = self.a.function_spaces[0]
        index_map, bs = space.dofmap.index_map, space.dofmap.index_map_bs
        start = index_map.local_range[0] * bs
        local = np.unique(
            np.concatenate([np.zeros(0, np.int32)] + [bc.dof_indices()[0] for bc in self.bcs])
        )
        local = local[local < index_map.size_local * bs]  # the owned ones (blocked spaces unrolled)
        comm = A.getComm()
        constrained = PETSc.IS().createGeneral((local + start).astype(PETSc.IntType), comm=comm)
        first, last = A.getOwnershipRange()
        rows = PETSc.IS().createStride(last - first, first, 1, comm=comm)
        return constrained, rows

    def forget(self) -> None:
        """Drop C: the next lifting (until a Jacobian is assembled) comes from the form, as in a
        run restarted here (:meth:`NewtonCallbacks.forget`)."""
        if self._columns is not None:
            self._columns.destroy()
            self._columns = None

    def apply(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """``b``, the assembled residual with its ghost contributions not yet summed: lifted
        when needed, ghosts summed, constrained rows set. Collective."""
        if self._gap is None:
            self._gap = x.duplicate()
        with self._gap.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.set_bc(self._gap, self.bcs, x, 1.0)
        lift = self._gap.norm(PETSc.NormType.NORM_INFINITY) != 0.0  # NaN: lift, as before
        self.skipped += not lift
        if lift and self._columns is None:
            dolfinx.fem.petsc.apply_lifting(b, [self.a], [self.bcs], [x], -1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        if lift and self._columns is not None:
            gap = self._gap.getSubVector(self._constrained)
            lifting = self._columns.createVecLeft()
            self._columns.mult(gap, lifting)
            self._gap.restoreSubVector(self._constrained, gap)
            b.axpy(1.0, lifting)
            lifting.destroy()
        dolfinx.fem.petsc.set_bc(b, self.bcs, x, -1.0)


# --------------------------------------------------------------------------------------------
# One Newton solver for every nonlinear problem (fluid, structure), and its PETSc options


@dataclass(frozen=True)
class SolveResult:
    """Outcome of one nonlinear solve: whether it converged, Newton iterations (linear solves),
    the ℓ² norm of the residual vector at the final iterate, and why it failed (``reason``)."""

    converged: bool
    iterations: int
    residual: float
    reason: str = ""

    def raise_if_failed(self) -> None:
        if not self.converged:
            raise SolveFailed(self.reason or "the Newton solve did not converge")


class SolveFailed(RuntimeError):
    """A nonlinear solve failed (no convergence, a PETSc error, non-finite values, an inverted
    element); the message says which solve and why."""


@contextlib.contextmanager
def petsc_options(prefix: str, options: dict) -> Iterator[None]:
    """``options`` in PETSc's options database under ``prefix`` while the block runs, removed
    after it: a solver's options are read (at ``setFromOptions`` and, for a factorisation
    package such as MUMPS, at the set-up inside a solve) only while they are there, so they
    never leak to another solver with the same prefix."""
    database = PETSc.Options(prefix)
    for key, value in options.items():
        database[key] = value
    try:
        yield
    finally:
        for key in options:
            database.delValue(key)


def set_fields(ksp: PETSc.KSP, fields: dict[str, PETSc.IS] | None) -> None:
    """Give a ``pc_type: fieldsplit`` preconditioner its blocks (the system's ``fields``: name →
    index set); other preconditioners are left alone. After ``setFromOptions``."""
    pc = ksp.getPC()
    if fields and pc.getType() == PETSc.PC.Type.FIELDSPLIT:
        pc.setFieldSplitIS(*fields.items())


class Newton:
    """dolfinx's Newton solver for ``problem`` with the settings of a config
    :class:`fsi.config.SolverSettings` and its PETSc options under ``prefix`` (``fluid_``,
    ``solid_``): tolerances, iteration limit, Jacobian reuse (:class:`NewtonCallbacks`), and a
    :meth:`solve` that never leaves a failed or non-finite iterate behind.

    ``criterion``: dolfinx's convergence test, ``residual`` (|F(x_k)|) or ``incremental``
    (|δx_k|), against ``atol`` or ``rtol`` times the first one. ``near_nullspace``: set on the
    Jacobian (:mod:`fsi.numerics.nullspace`; used by GAMG, ignored by LU). ``fields``: the
    unknowns' split, name → the owned rows' global indices, given to a ``pc_type: fieldsplit``
    preconditioner (its options name them: ``fieldsplit_<name>_pc_type``; ignored by others).
    """

    def __init__(
        self,
        comm: MPI.Comm,
        problem,
        settings,
        prefix: str,
        criterion: Literal["residual", "incremental"] = "residual",
        near_nullspace: PETSc.NullSpace | None = None,
        fields: dict[str, PETSc.IS] | None = None,
    ):
        self.comm, self.prefix, self.problem = comm, prefix, problem
        self.settings, self.criterion = settings, criterion
        self.near_nullspace, self.fields = near_nullspace, fields or {}
        self.options = dict(settings.petsc_options)
        self.solver = self._new_solver()
        # Residual and Jacobian through one object: Jacobian (and LU) reuse, counters.
        self.callbacks = NewtonCallbacks(
            problem, self.solver, settings.jacobian_reuse, settings.jacobian_reuse_rate
        )

    def _new_solver(self) -> dolfinx.nls.petsc.NewtonSolver:
        solver = dolfinx.nls.petsc.NewtonSolver(self.comm, self.problem)
        solver.convergence_criterion = self.criterion
        solver.rtol, solver.atol = self.settings.rtol, self.settings.atol
        solver.max_it = self.settings.max_iterations
        solver.error_on_nonconvergence = False
        solver.report = False
        ksp = solver.krylov_solver
        ksp.setOptionsPrefix(self.prefix)
        solver.A.setOptionsPrefix(self.prefix)
        if self.near_nullspace is not None:  # for an algebraic multigrid (GAMG) preset
            solver.A.setNearNullSpace(self.near_nullspace)
        with petsc_options(self.prefix, self.options):
            ksp.setFromOptions()
        set_fields(ksp, self.fields)
        return solver

    def _renew(self) -> dolfinx.nls.petsc.NewtonSolver:
        """Replace the solver after a failed solve: a NewtonSolver carries the reference of its
        relative test (|δx_1|) from one solve to the next, and a failed solve can leave it infinite.
        """
        self.solver = self._new_solver()
        self.callbacks.attach(self.solver)
        return self.solver

    def _tolerances(
        self, forcing: Forcing | None, atol: float, rtol: float
    ) -> Callable[[int, PETSc.Vec], None]:
        """The hook that sets the solver's tolerances for its test of F(x_k) (it reads them at
        every test). At x_0 the test is |F| < atol alone (or the forcing's): dolfinx's relative
        test divides by |δx_1|, which there is the *previous* solve's, and took an unsolved
        guess as converged (tests/test_newton.py)."""

        def tolerances(k: int, b: PETSc.Vec) -> None:
            if k == 0:
                self.solver.rtol = 0.0
                if forcing is not None:
                    self.solver.atol = forcing.atol(atol, b.norm())
            elif k == 1:
                self.solver.rtol = rtol

        return tolerances

    def solve(
        self,
        u: dolfinx.fem.Function,
        residual: Callable[[], float],
        step: Hashable = None,
        forcing: Forcing | None = None,
    ) -> SolveResult:
        """Solve for ``u`` from its current value. Collective.

        Args:
            u: the unknown, updated in place; on failure (no convergence, a PETSc error, a
                non-finite residual or ``u``) reset to its value before the solve.
            residual: gives the residual norm after the solve (F's units).
            step: identifies the time step, for Jacobian reuse.
            forcing: also stop at this :class:`Forcing` (residual criterion only).

        Returns:
            Converged or not, the iterations, the residual norm and why it failed.
        """
        guess = u.x.array.copy()
        reason = ""
        atol, rtol = self.solver.atol, self.solver.rtol
        if forcing is not None and self.criterion != "residual":
            raise ValueError("a forced solve needs the residual criterion")
        self.callbacks.before_test = self._tolerances(forcing, atol, rtol)
        try:
            with petsc_options(self.prefix, self.options):
                iterations, converged = self.callbacks.solve(
                    self.solver, u, step=step, renew=self._renew
                )
        except RuntimeError as e:  # a PETSc error, raised on every rank
            iterations, converged, reason = self.solver.max_it, False, f"PETSc: {e}"
        finally:
            self.solver.atol, self.solver.rtol = atol, rtol
            self.callbacks.before_test = None
        norm = float(residual())
        finite = bool(
            self.comm.allreduce(
                bool(np.isfinite(u.x.array).all()) and np.isfinite(norm), op=MPI.LAND
            )
        )
        if not finite:
            converged, reason = False, reason or "non-finite residual or solution"
        elif not converged and not reason:
            reason = (
                f"Newton did not converge in {iterations} iterations (residual"
                f" {norm:.3e}, atol {self.solver.atol:g}, rtol {self.solver.rtol:g})"
            )
        if not converged:
            u.x.array[:] = guess
            u.x.scatter_forward()
            self._renew()
        return SolveResult(bool(converged), int(iterations), norm, reason)
