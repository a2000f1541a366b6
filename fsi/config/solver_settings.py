"""What the sub-solvers share in a case: Newton's settings and PETSc options
(:class:`SolverSettings`, the ``solver`` key of ``fluid`` and ``structure``), the default direct
solve, and the ceiling of a ``quadrature_degree``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from fsi.config.reader import at_least, checked, open_interval, positive

MAX_QUADRATURE_DEGREE = 20
"""The highest quadrature degree a case may set. The shipped cases use 4 (exact for the P2 SVK
residual); a triangle rule of degree q has about (q/2 + 1)² points, unrolled into the generated
C and visited in every cell, so cost grows as q². 20 leaves room for convergence studies."""


def quadrature(default: int) -> Any:
    """A quadrature degree in [1, :data:`MAX_QUADRATURE_DEGREE`]."""
    return checked(
        default,
        lambda v: 1 <= v <= MAX_QUADRATURE_DEGREE,
        f"an integer in [1, {MAX_QUADRATURE_DEGREE}]",
    )


def direct_solver_options() -> dict[str, str | int | float]:
    """The PETSc options of a direct solve, MUMPS's LU: every linear solver's default."""
    return {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}


@dataclass(frozen=True)
class SolverSettings:
    """Newton tolerances and the PETSc options of one sub-solver (its prefix is fixed).

    ``jacobian_reuse``: ``none`` assembles (and factorises) the Jacobian at every Newton
    iteration; ``step`` keeps the last one across the Newton and coupling iterations of a time
    step, ``run`` also across steps, while it still contracts the residual: it is re-assembled
    when ``|F(x_k)| > jacobian_reuse_rate · |F(x_{k−1})|`` (modified Newton,
    fsi/numerics/newton.py). The stopping test is unchanged, so is the converged answer (to the
    solver's tolerance); a failed solve with a reused Jacobian is repeated with fresh ones. ``step``
    keeps restarts exact (the path of a step depends only on the state at its start)."""

    rtol: float = positive(1.0e-9)
    atol: float = positive(1.0e-10)
    max_iterations: int = at_least(25, 1)
    jacobian_reuse: Literal["none", "step", "run"] = "none"
    jacobian_reuse_rate: float = open_interval(0.3, 0.0, 1.0)
    # Names and values are checked against an allow-list (check_petsc_options) in validate().
    petsc_options: dict[str, str | int | float] = field(default_factory=direct_solver_options)


@dataclass(frozen=True)
class FluidSolverSettings(SolverSettings):
    """The fluid's solver settings: :class:`SolverSettings` and the ``linearization`` of each
    time step. ``newton`` solves the step's nonlinear equations; ``extrapolated`` takes what
    makes them nonlinear (the advecting velocity u − w, the viscosity μ(s(u)), the backflow
    terms' u·n and the stabilization's τ) from the second-order extrapolation
    u* = (1 + r) u^n − r u^{n−1}, r = Δt/Δt_prev (u^n on a first step), so that each step is one
    linear (Oseen) problem: one Jacobian, one factorisation, one solve (Newton then converges in
    one iteration). BDF2's second order is kept (tests/test_linearization.py)."""

    linearization: Literal["newton", "extrapolated"] = "newton"
