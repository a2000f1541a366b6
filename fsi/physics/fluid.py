"""The fluid solver: generalized Navier–Stokes in ALE form, Taylor–Hood P2/P1 (or stabilized
equal-order P1/P1, ``fluid.element``), Newton.

    ρ (∂u/∂t|_X + ((u − w)·∇)u) − ∇·(2 μ(s(u)) D(u)) + ∇p = f,   ∇·u = 0   in Ωf(t)

(docs/model.md, Fluid), ``D(u) = sym ∇u``, ``s(u) = sqrt(2 D:D)`` (fsi/physics/rheology.py), ``w``
the mesh velocity. :class:`FluidSolver` owns the unknowns, the time history, the moving mesh
(:class:`fsi.physics.mesh_motion.AleMesh`) and Newton; the residual is
fsi/physics/fluid_residual.py, the boundary conditions fsi/physics/fluid_boundaries.py.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc
import numpy as np
import ufl

from fsi import compat, config
from fsi.numerics.newton import DirichletLifting, Forcing, Newton, SolveResult
from fsi.numerics.timestepping import BdfHistory, bdf_weights
from fsi.physics import rheology
from fsi.physics.coordinates import Coordinates
from fsi.physics.fluid_boundaries import (
    BoundaryCondition,
    Robin,
    Velocity,
    as_tags,
    facets_of,
)
from fsi.physics.fluid_boundary_terms import (
    BoundaryTerms,
    outlet_values,
    restore_outlet_states,
)
from fsi.physics.fluid_residual import BodyForce, FluidFields, FluidResidual
from fsi.physics.mesh_motion import AleMesh

log = logging.getLogger(__name__)

Scheme = Literal["backward_euler", "bdf2", "steady"]

MOVING_WALLS = (Velocity, Robin)
"""The conditions of a wall that moves with the structure: the fluid's forces act on it."""

VELOCITY_DEGREE = {"p2p1": 2, "p1p1": 1}
"""The velocity's Lagrange degree of each ``fluid.element``; the pressure is P1 in both."""


# --------------------------------------------------------------------------------------------
# Results and state


@dataclass
class FluidState:
    """Everything :meth:`FluidSolver.restore_state` needs to re-solve a step (local arrays)."""

    time: float
    dt_previous: float | None
    accepted_steps: int
    U: np.ndarray
    u_n: np.ndarray
    u_nm1: np.ndarray
    d: np.ndarray
    d_n: np.ndarray
    d_nm1: np.ndarray
    w: np.ndarray
    mesh_velocity_given: bool
    outlet_state: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """The lumped outlets' states, concatenated (a Windkessel's P_c^n, P_c^{n−1})."""


@dataclass(frozen=True)
class NodalForces:
    """Forces (N per unit depth) the fluid exerts on the boundary at its owned velocity nodes:
    ``force[i] = −R_i``, R the Navier–Stokes residual at the solution without the Dirichlet
    rows (the reaction of the Dirichlet condition). ``x`` are the nodes' current coordinates and
    ``dofs`` their (block) indices in :attr:`FluidSolver.V`."""

    x: np.ndarray
    force: np.ndarray
    dofs: np.ndarray = field(repr=False)


class _FluidProblem(dolfinx.fem.petsc.NonlinearProblem):
    """The fluid's nonlinear problem: dolfinx's, but each residual evaluation also keeps the
    residual before its Dirichlet rows are set (:meth:`unconstrained_residual`, the nodal forces'
    source), and with lumped outlets each residual evaluation first sets their pressures from
    the iterate and each Jacobian gets their rank-one blocks (:class:`LumpedOutlet`). A Robin
    interface (:class:`RobinInterface`) adds its term and nodal forces to the residual after
    the kept part, so the nodal forces are −R of the Navier–Stokes residual alone."""

    def __init__(self, F: ufl.Form, U: dolfinx.fem.Function, boundary: BoundaryTerms):
        dU = ufl.TrialFunction(U.function_space)
        # F stays the residual whose −R is the nodal forces; a Robin interface's term and
        # nodal forces are added to each evaluation after it (:meth:`F`), its term's derivative
        # to the Jacobian.
        robin = self.robin = boundary.robin
        whole = F if robin is None else F + robin.form
        super().__init__(F, U, boundary.bcs, J=ufl.derivative(whole, U, dU))
        self._robin_form = None if robin is None else dolfinx.fem.form(robin.form)
        self.lumped = tuple(boundary.lumped)
        self.comm: MPI.Comm = U.function_space.mesh.comm
        self._unconstrained = dolfinx.fem.Function(U.function_space)
        self._evaluated_at: np.ndarray | None = None  # the iterate of the last residual
        self.dirichlet = DirichletLifting(self.a, self.bcs)

    def F(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """dolfinx's residual (Dirichlet rows x − g, lifted when x is not already g there:
        :class:`fsi.numerics.newton.DirichletLifting`), keeping R(x) before the rows are set."""
        for outlet in self.lumped:
            outlet.update(x)
        kept = self._assemble_unconstrained()
        with kept.localForm() as source, b.localForm() as target:
            source.copy(target)  # before the kept vector's ghost contributions are summed
        self._finish_unconstrained()
        with x.localForm() as local:
            self._evaluated_at = local.array_r.copy()
        if self.robin is not None:
            dolfinx.fem.petsc.assemble_vector(b, self._robin_form)
            self.robin.add_to(b)
        self.dirichlet.apply(b, x)

    def _assemble_unconstrained(self) -> PETSc.Vec:
        """R(x) into the kept vector, each rank's own cells' contributions (ghosts unsummed)."""
        vector = compat.petsc_vector(self._unconstrained)
        with vector.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(vector, self.L)
        return vector

    def _finish_unconstrained(self) -> None:
        vector = compat.petsc_vector(self._unconstrained)
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self._unconstrained.x.scatter_forward()

    def unconstrained_residual(self, x: PETSc.Vec) -> np.ndarray:
        """R(x) at every local dof (owned and ghost) with no Dirichlet row set: the last residual
        evaluation's when it was at this very x on every rank (a converged solve's last), else
        assembled now. Collective."""
        with x.localForm() as local:
            same = self._evaluated_at is not None and np.array_equal(
                self._evaluated_at, local.array_r
            )
        if not self.comm.allreduce(same, op=MPI.LAND):
            self._assemble_unconstrained()
            self._finish_unconstrained()
            self._evaluated_at = None
        return self._unconstrained.x.array

    def J(self, x: PETSc.Vec, A: PETSc.Mat) -> None:
        self.dirichlet.jacobian(A)  # dolfinx's, and the lifting's columns kept
        for outlet in self.lumped:
            outlet.add_to_jacobian(A, self.bcs)


# --------------------------------------------------------------------------------------------
# The solver


def _owned_rows(W, to_W: np.ndarray) -> PETSc.IS:
    """The global indices of the owned dofs of ``W`` that ``to_W`` (a subspace's map into W,
    :func:`fsi.compat.subspace_map`) reaches: the rows of one field of the fluid's matrix, for a
    fieldsplit preconditioner (docs/3d.md, solver presets)."""
    index_map = W.dofmap.index_map
    local = np.unique(to_W[to_W >= 0])
    local = local[local < index_map.size_local * W.dofmap.index_map_bs]
    start = index_map.local_range[0] * W.dofmap.index_map_bs
    return PETSc.IS().createGeneral((local + start).astype(PETSc.IntType), comm=W.mesh.comm)


def _copy_from_mixed(
    target: dolfinx.fem.Function, U: dolfinx.fem.Function, target_to_U: np.ndarray
) -> None:
    owned = target_to_U >= 0
    target.x.array[owned] = U.x.array[target_to_U[owned]]
    target.x.scatter_forward()


class FluidSolver:
    """Generalized Navier–Stokes on a (moving) fluid mesh; see the module docstring.

    ``∂u/∂t|_X`` and ``w`` are BDF derivatives (:func:`fsi.numerics.timestepping.bdf_weights`) of
    the nodal values of u and of the mesh displacement, all evaluated on Ωf(t_{n+1})
    (non-conservative ALE form: a uniform flow stays uniform on any mesh motion).

    Args:
        mesh: the fluid mesh (e.g. ``fsi.physics.mesh.restrict(tagged, Region.FLUID).mesh``).
        facet_tags: its boundary tags (``.facet_tags`` of the same).
        fluid: the ``fluid`` section (density, rheology, quadrature, Newton and PETSc options).
        boundaries: which tags get which condition (e.g.
            :func:`fsi.physics.fluid_boundaries.boundary_conditions`); others are traction-free.
        scheme: ``backward_euler``, ``bdf2`` (backward Euler on the first step) or ``steady``.
        body_force: optional f(x, t).
        axisymmetric: the mesh is the meridian half-plane of a body of revolution
            (fsi/physics/coordinates.py; its integrals, forces and flow rates are the body's).
    """

    def __init__(
        self,
        mesh: dolfinx.mesh.Mesh,
        facet_tags: dolfinx.mesh.MeshTags,
        fluid: config.Fluid,
        boundaries: Sequence[BoundaryCondition],
        scheme: Scheme = "bdf2",
        body_force: BodyForce | None = None,
        axisymmetric: bool = False,
    ):
        if scheme not in ("backward_euler", "bdf2", "steady"):
            raise ValueError(f"unknown time scheme {scheme!r}")
        self.mesh, self.facet_tags, self.config, self.scheme = mesh, facet_tags, fluid, scheme
        self.comm: MPI.Comm = mesh.comm
        self.law = rheology.from_config(fluid.rheology)
        self.boundaries = tuple(boundaries)
        mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
        self._create_functions(VELOCITY_DEGREE[fluid.element])
        self.ale = AleMesh(mesh)
        self.coordinates = Coordinates(mesh, axisymmetric)

        self.time = 0.0
        self.dt_previous: float | None = None
        self._dt: float | None = None
        self.accepted_steps = 0
        self._mesh_velocity_given = False

        # What the forms read: the functions above, the mesh velocity and the constants t (the
        # time of the step being solved, for g(x, n, t) and f(x, t)), ρ and the time weights.
        self.fields = FluidFields(
            self.W,
            self.V,
            self.U,
            self.u_n,
            self.u_nm1,
            self.ale.w,
            self.boundary_velocity,
            **FluidFields.constants(mesh, fluid.density),
        )
        # F = the interior terms + what each boundary condition adds, in this order.
        interior = FluidResidual(
            self.fields, facet_tags, fluid, self.law, self.coordinates, scheme, body_force
        )
        boundary = BoundaryTerms(
            self.fields, interior.symbols, facet_tags, fluid, scheme, self.boundaries
        )
        self.residual_form: ufl.Form = interior.form
        for term in boundary.terms:
            self.residual_form += term
        self._bcs, self._updates, self.lumped = boundary.bcs, boundary.updates, boundary.lumped
        self.step_coefficients = interior.step_coefficients  # SUPG's τ, held per solve
        self.robin = boundary.robin  # the Robin–Neumann interface's data, or None
        self.problem = _FluidProblem(self.residual_form, self.U, boundary)
        split = {"u": _owned_rows(self.W, self._V_to_W), "p": _owned_rows(self.W, self._Q_to_W)}
        self.newton = Newton(self.comm, self.problem, self.config.solver, "fluid_", fields=split)
        # −R of the last step's solution, kept from before advance() (the residual needs the
        # step's time history), and whether the step has been accepted since.
        self._step_reaction: np.ndarray | None = None
        self._advanced = False

    # ---- set-up

    def _create_functions(self, degree: int) -> None:
        """The spaces (W = V × Q, Pk/P1), the unknown U, its outputs u and p, the time history
        u^n, u^{n−1} and the boundary velocity."""
        mesh, gdim = self.mesh, self.mesh.geometry.dim
        self.W = compat.mixed_space(mesh, [("Lagrange", degree, (gdim,)), ("Lagrange", 1, ())])
        self.V = compat.function_space(mesh, "Lagrange", degree, (gdim,))
        self.Q = compat.function_space(mesh, "Lagrange", 1)
        self._V_to_W = compat.subspace_map(self.W, 0, self.V)
        self._Q_to_W = compat.subspace_map(self.W, 1, self.Q)
        self.U = dolfinx.fem.Function(self.W, name="fluid")
        self.u = dolfinx.fem.Function(self.V, name="velocity")
        self.p = dolfinx.fem.Function(self.Q, name="pressure")
        self.u_n = dolfinx.fem.Function(self.V)
        self.u_nm1 = dolfinx.fem.Function(self.V)
        # u^n, u^{n−1}: the history writes the arrays of the Functions the residual uses.
        self.velocity_history = BdfHistory(self.u.x.array, self.u_n.x.array, self.u_nm1.x.array)
        self.boundary_velocity = dolfinx.fem.Function(self.V, name="boundary_velocity")

    # ---- the coupler's interface

    def set_mesh_displacement(self, d: dolfinx.fem.Function) -> None:
        """Move the mesh to x = X + d (``d`` in m, interpolated into P1 if it lives elsewhere).
        The mesh velocity of the step follows from :meth:`mesh_velocity` or, if that is not
        called, at :meth:`step`."""
        self.ale.move(d)
        self._mesh_velocity_given = False

    def mesh_velocity(self, dt: float) -> dolfinx.fem.Function:
        """The mesh velocity w = Σ_k a_k d^{n+1−k} (m/s, P1) of the step of ``dt`` (s) to the
        current mesh, computed now; :meth:`step` with the same ``dt`` uses it as it is."""
        self.ale.set_velocity(self.time_weights(dt))
        self._mesh_velocity_given = True
        return self.ale.w

    def set_boundary_velocity(self, value: dolfinx.fem.Function) -> None:
        """u on the :class:`Velocity` boundaries (m/s): ``value`` (a Function, e.g. the
        :meth:`mesh_velocity`, or x ↦ values) interpolated into the velocity space."""
        self.boundary_velocity.interpolate(value)
        self.boundary_velocity.x.scatter_forward()

    def time_weights(self, dt: float) -> tuple[float, float, float]:
        """(a0, a1, a2) of ∂u/∂t ≈ a0 u^{n+1} + a1 u^n + a2 u^{n−1} for the next step."""
        if self.scheme == "steady":
            return (0.0, 0.0, 0.0)
        if self.scheme == "bdf2" and self.accepted_steps > 0:
            return tuple(bdf_weights(2, dt, self.dt_previous))  # type: ignore[return-value]
        return (*bdf_weights(1, dt), 0.0)  # type: ignore[return-value]

    def extrapolation(self, dt: float) -> tuple[float, float]:
        """(e1, e2) of the extrapolation u* = e1 u^n + e2 u^{n−1} to the next step: second order,
        (1 + r, −r) with r = dt/dt_prev, after a BDF2 step; u^n on a first step (and for backward
        Euler, first order anyway). Used by ``fluid.solver.linearization: extrapolated``."""
        if self.scheme == "bdf2" and self.accepted_steps > 0:
            r = dt / self.dt_previous
            return (1 + r, -r)
        return (1.0, 0.0)

    def step(self, t: float, dt: float, forcing: Forcing | None = None) -> SolveResult:
        """Solve for (u, p) at time ``t`` = t_n + dt on the current mesh, Newton starting from
        the current (u, p) and stopping on the solver's tolerance or at ``forcing``. On failure
        (Newton not converged, PETSc error, non-finite values) the solution is reset to its
        value before the step and the result says why; nothing non-finite is left behind."""
        weights = self.time_weights(dt)
        self._dt = dt
        self._step_reaction, self._advanced = None, False
        for c, a in zip(self.fields.bdf_weights, weights):
            c.value = a
        for c, e in zip(self.fields.extrapolation_weights, self.extrapolation(dt)):
            c.value = e
        self.fields.t.value = t
        for update in self._updates:
            update(t)
        for outlet in self.lumped:
            outlet.begin_step(weights)
        if not self._mesh_velocity_given:  # else mesh_velocity(dt) computed it
            self.ale.set_velocity(weights)
        self.ale.w.x.scatter_forward()
        for coefficient in self.step_coefficients:
            coefficient.evaluate()
        result = self.newton.solve(
            self.U,
            lambda: self.newton.solver.b.norm(),  # the solver's b: a failed attempt renews it
            step=self.accepted_steps,
            forcing=forcing,
        )
        if not result.converged:
            result = replace(
                result, reason=f"fluid step to t = {t:g} s (dt = {dt:g} s): {result.reason}"
            )
            log.warning(result.reason)
        self._sync_outputs()
        return result

    def advance(self) -> None:
        """Accept the last step: shift u^n → u^{n−1}, u → u^n and the displacement history;
        the lumped outlets' states advance with the step's flow rates."""
        for outlet in self.lumped:
            outlet.advance(self.time_weights(self._dt))
        self.velocity_history.advance()  # u is U's velocity after every step/restore
        self.ale.advance()
        self.dt_previous = self._dt
        self.time = float(self.fields.t.value)
        self.accepted_steps += 1
        self._mesh_velocity_given = False
        self._advanced = True  # the step's reaction, if taken, stays what _reaction returns

    def set_initial_state(self, u, p=None) -> None:
        """Start from a state other than rest: the velocity ``u`` (and the pressure ``p``, a
        first guess for Newton) interpolated from callables x ↦ values as for
        ``Function.interpolate``; u^n = u^{n−1} = u (a verification case started from its exact
        solution)."""
        self.u.interpolate(u)
        self.velocity_history.start()
        owned = self._V_to_W >= 0
        self.U.x.array[self._V_to_W[owned]] = self.u.x.array[owned]
        if p is not None:
            self.p.interpolate(p)
            owned = self._Q_to_W >= 0
            self.U.x.array[self._Q_to_W[owned]] = self.p.x.array[owned]
        self.U.x.scatter_forward()

    def save_state(self) -> FluidState:
        """Snapshot of the solution, the time history and the mesh (local arrays)."""
        return FluidState(
            self.time,
            self.dt_previous,
            self.accepted_steps,
            self.U.x.array.copy(),
            *self.velocity_history.save(),  # u_n, u_nm1
            *self.ale.save(),  # d, d_n, d_nm1, w
            self._mesh_velocity_given,
            np.concatenate([np.zeros(0), *(outlet.state for outlet in self.lumped)]),
        )

    def restore_state(self, state: FluidState, warm_start: bool = False) -> None:
        """Return to ``state``, mesh position included. With ``warm_start`` the current
        solution (u, p) stays as Newton's initial guess of the next :meth:`step` (the outputs
        ``u``, ``p`` and the time history are the state's)."""
        guess = self.U.x.array.copy() if warm_start else None
        s = state
        restore_outlet_states(self.lumped, s.outlet_state)  # first: it checks the size
        self.time, self.dt_previous, self.accepted_steps = s.time, s.dt_previous, s.accepted_steps
        self.U.x.array[:] = s.U
        self.velocity_history.restore(s.u_n, s.u_nm1)
        self.ale.restore(s.d, s.d_n, s.d_nm1, s.w)  # and moves the mesh to X + d
        self._mesh_velocity_given = s.mesh_velocity_given
        self._step_reaction, self._advanced = None, False
        self._sync_outputs()
        if guess is not None:  # U is only Newton's initial guess: u^n, u^{n−1} are separate
            self.U.x.array[:] = guess

    def outlet_values(self) -> dict[str, float]:
        """The lumped outlets' pressures (Pa) for the metrics (:func:`~fsi.physics.
        fluid_boundary_terms.outlet_values`); empty without one."""
        return outlet_values(self.lumped)

    def _sync_outputs(self) -> None:
        _copy_from_mixed(self.u, self.U, self._V_to_W)
        _copy_from_mixed(self.p, self.U, self._Q_to_W)

    def mixed_dofs(self) -> tuple[np.ndarray, np.ndarray]:
        """The local dof of ``U`` (space W) behind each local (unrolled) dof of ``u`` (V) and of
        ``p`` (Q), −1 where there is none (for checkpoints: which W value is which node's)."""
        return self._V_to_W, self._Q_to_W

    # ---- forces

    def _reaction(self) -> np.ndarray:
        """−R at every local W dof: the residual at the current solution, no Dirichlet rows.
        After :meth:`advance` it is the accepted step's, kept from a call before it: the
        residual of a step needs that step's time history (u^n, u^{n−1}, the extrapolation),
        which advance shifts."""
        if self._advanced:
            if self._step_reaction is None:
                raise RuntimeError(
                    "the fluid's forces of a step are taken between step() and advance()"
                )
            return self._step_reaction.copy()
        self._step_reaction = -self.problem.unconstrained_residual(compat.petsc_vector(self.U))
        return self._step_reaction.copy()

    def _owned_nodes(self, tags: Sequence[int]) -> np.ndarray:
        fdim = self.mesh.topology.dim - 1
        nodes = dolfinx.fem.locate_dofs_topological(self.V, fdim, facets_of(self.facet_tags, tags))
        return nodes[nodes < self.V.dofmap.index_map.size_local]

    def interface_force(self, tags: Sequence[int] | None = None) -> NodalForces:
        """Nodal forces the fluid exerts on the boundary ``tags`` (default: the :class:`Velocity`
        boundaries) from the variational residual: at node i, f_i = −R_i = −∫_Γ σ n φ_i ds for
        the discrete solution (n the fluid's outward normal), consistent with the discrete
        momentum balance. Owned nodes only; gather them if needed. Take it after :meth:`step`:
        before :meth:`advance`, or after it once it was taken before (the residual's inertia
        uses the step's time history; :meth:`_reaction`)."""
        if tags is None:
            tags = [t for bc in self.boundaries if isinstance(bc, MOVING_WALLS) for t in bc.tags]
        gdim = self.mesh.geometry.dim
        nodes = self._owned_nodes(tags)
        minus_R = self._reaction()
        W_dofs = self._V_to_W.reshape(-1, gdim)[nodes]
        coordinates = self.V.tabulate_dof_coordinates()[nodes, :gdim]
        return NodalForces(coordinates, minus_R[W_dofs], nodes)

    def boundary_force(self, tags: Sequence[int]) -> np.ndarray:
        """Total force (N/m; N when axisymmetric) of the fluid on ``tags``, Σ_i f_i over
        :meth:`interface_force`'s nodes (the residual form of ∫ σ n_obstacle ds: drag, lift)."""
        local = self.interface_force(as_tags(tags)).force.sum(axis=0)
        return self.comm.allreduce(local, op=MPI.SUM)

    def nodal_forces(self, tags: Sequence[int]) -> np.ndarray:
        """:meth:`interface_force` on ``tags`` (N/m; N when axisymmetric) as an array over every
        owned velocity node, shape (n_owned, gdim) in the order of the owned (block) dofs of
        :attr:`V`, zero off the boundary."""
        nodal = self.interface_force(tags)
        values = np.zeros((self.V.dofmap.index_map.size_local, self.mesh.geometry.dim))
        values[nodal.dofs] = nodal.force
        return values
