"""A structure drawn under load: the stress-free reference that the drawn geometry is in
equilibrium from (``structure.prestress``; docs/arterial-wall.md).

An artery's geometry is imaged under the blood pressure: drawn as it is, it is already loaded.
The structure is then solved on the drawn mesh with a stress-free reference X* that it does
not draw: ``U₀(x) = x − X*(x)``, a displacement field on the drawn mesh, maps the reference to
the drawn geometry, ``F₀ = ∂x/∂X* = (I − ∇U₀)⁻¹``. The displacement η of the solvers stays
the one from the drawn geometry (so the interface, the fluid mesh and every output keep their
meaning) and the material sees the whole deformation from X*::

    F_total = F F₀,   F = I + ∇η,   P = J₀⁻¹ F F₀ Σ(F F₀) F₀ᵀ,   ρ_drawn = ρ / J₀,   J₀ = det F₀

(the first Piola stress and the density per unit drawn volume: the energy ∫_{Ω*} W dX* written
on the drawn mesh). A structure without a prestress builds none of this: its forms are the
plain ones.

:func:`solve_reference` finds U₀ by inverse elastostatics (Govindjee & Mihalic 1996): the
structure's residual at η = 0, the drawn geometry, solved for U₀, the load raised from 0 in
steps. At its solution the drawn geometry is in equilibrium with the load and the stress is the
one of a body whose stress-free state is X*, exactly. Sellier's backward-displacement fixed point
(Sellier 2011; Bols et al. 2013), which moves the reference back by a forward solve's
displacement and repeats, was tried first and failed on a soft HGO tube: the reference its first
iteration makes is one from which the next forward solve cannot start (docs/arterial-wall.md).
A MULF prestress tensor (Gee et al. 2010) is path-dependent and not the gradient of a map.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import ufl

from fsi.numerics.newton import Newton

log = logging.getLogger(__name__)


class StressFreeReference:
    """``U₀`` (:attr:`offset`, in the displacement space V) and the UFL of ``F₀⁻¹ = I − ∇U₀``
    (:attr:`F0_inv`), ``F₀`` and ``1/J₀ = det F₀⁻¹`` (:attr:`volume_ratio`, drawn over
    reference volume's inverse: ρ_drawn = ρ · volume_ratio)."""

    def __init__(self, V: dolfinx.fem.FunctionSpace, coordinates):
        self.offset = dolfinx.fem.Function(V)
        self.offset.name = "reference_offset"
        self.F0_inv = coordinates.identity() - coordinates.grad(self.offset)
        self.F0 = ufl.inv(self.F0_inv)
        self.volume_ratio = ufl.det(self.F0_inv)

    def total(self, F):
        """The deformation gradient from the stress-free reference, ``F F₀``."""
        return F * self.F0

    def first_piola(self, F, S):
        """``J₀⁻¹ F F₀ S F₀ᵀ``: the first Piola stress per unit drawn area of the second Piola
        stress S of the reference."""
        return self.volume_ratio * F * self.F0 * S * self.F0.T

    def pull_back(self, S_drawn):
        """A second Piola stress of the drawn configuration as one of the reference,
        ``J₀ F₀⁻¹ S F₀⁻ᵀ`` (so that :meth:`first_piola` gives it back as ``F S``)."""
        return self.F0_inv * S_drawn * self.F0_inv.T / self.volume_ratio


@dataclass(frozen=True)
class PrestressResult:
    """The inverse solve's outcome: ``converged``; ``iterations``, the load steps taken;
    ``mismatch``, max |U₀| (m), how far the stress-free reference is from the drawn geometry."""

    converged: bool
    iterations: int
    mismatch: float


def solve_reference(solver, load_steps: int = 20) -> PrestressResult:
    """U₀ such that the drawn geometry (η = 0) is in equilibrium with ``solver``'s loads at
    t = 1 (the follower pressure ``P(t) = P_ref t`` on the drawn interface): the structure's
    residual at η = 0 solved for U₀ by Newton (the solver's settings, options prefix
    ``solid_prestress_``), the load raised from 0 in ``load_steps`` equal steps (at P = 0, U₀ = 0
    is the answer). Dirichlet rows hold U₀ = 0 (the reference is the drawn geometry where the
    structure is held). Collective; ``mismatch`` is max |U₀| (m).
    """
    _reset(solver)
    residual = solver.residual
    offset = solver.prestress.offset
    jacobian = ufl.derivative(residual.form, offset, ufl.TrialFunction(solver.V))
    problem = dolfinx.fem.petsc.NonlinearProblem(
        residual.form, offset, bcs=solver.dirichlet.homogeneous, J=jacobian
    )
    norm = [float("nan")]
    assemble = problem.F

    def F(x, b):  # the residual norm, for Newton's report
        assemble(x, b)
        norm[0] = b.norm()

    problem.F = F
    newton = Newton(
        solver.comm, problem, solver.newton.settings, solver.prefix + "prestress_", "incremental"
    )
    for j in range(1, load_steps + 1):
        t = j / load_steps
        residual.pressure.value = residual.pressure_n.value = solver.bcs_data.pressure(t)
        result = newton.solve(offset, lambda: norm[0], step=j)
        if not result.converged:
            log.warning(
                "prestress: the inverse solve failed at %g of the load: %s", t, result.reason
            )
            return PrestressResult(False, j, solver.max_norm(offset))
        log.info("prestress: %g of the load, max |U0| = %.3g m", t, solver.max_norm(offset))
    return PrestressResult(True, load_steps, solver.max_norm(offset))


def _reset(solver) -> None:
    """η and the committed state back to the drawn geometry at rest, t = 0."""
    for f in (solver.eta, solver.eta_n, solver.v_n, solver.a_n, solver.v, solver.a):
        f.x.array[:] = 0.0
    solver.t = 0.0
