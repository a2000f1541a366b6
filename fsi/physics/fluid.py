"""Incompressible generalized Navier–Stokes in ALE form (MODEL.md §2), Taylor–Hood P2/P1, Newton.

    ρ (∂u/∂t|_X + ((u − w)·∇)u) − ∇·(2 μ(s(u)) D(u)) + ∇p = f,   ∇·u = 0   in Ωf(t),

with ``D(u) = sym ∇u``, ``s(u) = sqrt(2 D:D)`` (fsi/physics/rheology.py), ``w`` the mesh velocity
and ``f`` an optional body force (manufactured solutions). Weak form on the current configuration
(residual ``F((u, p); (v, q))``):

    ρ (Σ_k a_k u^{n+1−k}, v) + ρ (((u − w)·∇)u, v) + (2 μ D(u), D(v)) − (p, ∇·v) − (q, ∇·u)
        − (f, v) − ⟨σ n, v⟩_natural = 0.

The time derivative ``∂u/∂t|_X ≈ Σ_k a_k u^{n+1−k}`` acts on the nodal values (which move with
the mesh, i.e. at fixed X); the weights ``a_k`` come from
:func:`fsi.numerics.timestepping.bdf_weights` (backward Euler, variable-step BDF2; all zero in
steady mode), so the physics never names a scheme. Everything is evaluated on Ωf(t_{n+1})
(non-conservative ALE form): a uniform flow stays uniform on any mesh motion (the discrete geometric
conservation law of this form), and the mesh velocity is by default the same BDF derivative of the
mesh displacement, ``w = Σ_k a_k d^{n+1−k}``. The accepted levels u^n, u^{n−1} are a
:class:`fsi.numerics.timestepping.BdfHistory`; the mesh, its displacement history and w are the
solver's :class:`fsi.physics.mesh_motion.AleMesh` (``ale``).

:class:`FluidResidual` builds F as this sum, one method per term (inertia, convection,
viscous stress, pressure, continuity, body force, SUPG). Boundary conditions are data
(:class:`NoSlip`, :class:`Velocity`, :class:`Inflow`, :class:`Outflow`, :class:`Slip`,
:class:`Traction`; :func:`boundary_conditions` builds a case's), each turned into its Dirichlet
conditions and boundary terms by one function found in :attr:`FluidResidual.BOUNDARY_KINDS`. An
outlet with a lumped model (resistance, RCR Windkessel; fsi/physics/outlets.py) takes its pressure
from its flow rate, implicitly (:class:`LumpedOutlet`). The coupler drives the solver through
``set_mesh_displacement``, ``boundary_velocity``, ``step``, ``advance``,
``save_state``/``restore_state`` and ``interface_force``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
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
from fsi.config import boundary_data
from fsi.numerics.newton import Forcing, Newton, SolveResult
from fsi.numerics.timestepping import BdfHistory, bdf_weights
from fsi.physics import outlets, rheology
from fsi.physics.mesh_motion import AleMesh
from geometry.tags import Boundary

log = logging.getLogger(__name__)

Scheme = Literal["backward_euler", "bdf2", "steady"]
TractionFunction = Callable[
    [ufl.core.expr.Expr, ufl.core.expr.Expr, dolfinx.fem.Constant], ufl.core.expr.Expr
]
"""``g(x, n, t)``: a UFL vector of the spatial coordinate, the outward normal and the time."""
BodyForce = Callable[[ufl.core.expr.Expr, dolfinx.fem.Constant], ufl.core.expr.Expr]
"""``f(x, t)``: a UFL vector (N/m³) of the spatial coordinate and the time."""

NITSCHE_PENALTY = 100.0
"""γ of the Nitsche term γ μ/h (u·n)(v·n) on slip walls; ≳ 10 (k + 1)² for P2 keeps it coercive."""


def _tags(tags) -> tuple[int, ...]:
    return (int(tags),) if isinstance(tags, (int, np.integer)) else tuple(int(t) for t in tags)


def facets_of(facet_tags: dolfinx.mesh.MeshTags, tags: Sequence[int]) -> np.ndarray:
    """The local facets tagged with any of ``tags``."""
    return facet_tags.indices[np.isin(facet_tags.values, list(tags))].astype(np.int32)


# --------------------------------------------------------------------------------------------
# Boundary conditions (data)


@dataclass(frozen=True)
class NoSlip:
    """u = 0 on ``tags``."""

    tags: tuple[int, ...]

    def __post_init__(self):
        object.__setattr__(self, "tags", _tags(self.tags))


@dataclass(frozen=True)
class Velocity:
    """u = the solver's :attr:`FluidSolver.boundary_velocity` on ``tags`` (the FSI interface:
    the coupler writes ∂η/∂t there)."""

    tags: tuple[int, ...]

    def __post_init__(self):
        object.__setattr__(self, "tags", _tags(self.tags))


@dataclass(frozen=True)
class Inflow:
    """The configured inlet on ``tags``: a normal traction σ n = −P(t) n (``traction_pulse``,
    ``pressure``, ``pressure_table``, ``pressure_file``; in the ``do_nothing`` form
    μ∇u n − p n = −P n) or a parabolic velocity (``parabolic_velocity``). A traction inlet with
    ``inflow_stabilization`` β > 0 adds −β/2 ρ min(u·n, 0) u to σ n (as :class:`Outflow`)."""

    tags: tuple[int, ...]
    spec: config.Inlet
    inflow_stabilization: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "tags", _tags(self.tags))


@dataclass(frozen=True)
class Outflow:
    """An open outlet on ``tags``: σ n = −P n + β/2 ρ min(u·n, 0) u (in the ``open_boundary``
    form), P = 0 (traction-free, the study's) or, with a lumped ``model`` (fsi/physics/outlets.py:
    resistance, RCR Windkessel), the model's pressure at the outlet's flow rate
    (:class:`LumpedOutlet`); the β term removes the energy that backflow would carry in
    (Bazilevs et al. 2009)."""

    tags: tuple[int, ...]
    backflow_stabilization: float = 1.0
    model: outlets.OutletModel | None = None

    def __post_init__(self):
        object.__setattr__(self, "tags", _tags(self.tags))


@dataclass(frozen=True)
class Slip:
    """The study's alternative wall condition: u·n = 0 (Nitsche) with a prescribed tangential
    traction (σ n)_t = g_t, ``g`` a :data:`TractionFunction` (None: g = 0, perfect slip). The
    normal part of g is ignored: the normal traction is the reaction to u·n = 0."""

    tags: tuple[int, ...]
    traction: TractionFunction | None = None

    def __post_init__(self):
        object.__setattr__(self, "tags", _tags(self.tags))


@dataclass(frozen=True)
class Traction:
    """σ n = g(x, n, t) on ``tags``."""

    tags: tuple[int, ...]
    traction: TractionFunction

    def __post_init__(self):
        object.__setattr__(self, "tags", _tags(self.tags))


BoundaryCondition = NoSlip | Velocity | Inflow | Outflow | Slip | Traction


def walls(boundaries: Sequence[Boundary], moving_interface: bool = False) -> tuple[Boundary, ...]:
    """The fluid's walls among a geometry's ``boundaries``, in their order: the rigid wall
    (Γw2), the Turek–Hron obstacle and the interface Γw1, unless it moves (a coupled run gives
    it :class:`Velocity`). The one list of walls: no-slip conditions and wall shear stress."""
    kinds = (
        Boundary.RIGID_WALL,
        Boundary.OBSTACLE,
        *(() if moving_interface else (Boundary.INTERFACE,)),
    )
    return tuple(b for b in boundaries if b in kinds)


def boundary_conditions(
    fluid: config.Fluid, boundaries: Sequence[Boundary], moving_interface: bool
) -> tuple[BoundaryCondition, ...]:
    """The fluid's boundary conditions in every mode (MODEL.md §2), for a geometry with
    ``boundaries``: the configured inlet, the configured outlet, u = ∂η/∂t on the interface if
    it moves (a coupled run), no-slip on the :func:`walls`."""
    inlet = Inflow(Boundary.INLET, fluid.inlet, fluid.inflow_stabilization)
    outlet = Outflow(
        Boundary.OUTLET, fluid.outlet.backflow_stabilization, outlets.from_config(fluid.outlet)
    )
    moving = (Velocity(Boundary.INTERFACE),) if moving_interface else ()
    return (inlet, outlet, *moving, NoSlip(walls(boundaries, moving_interface)))


def inlet_pressure(spec: config.Inlet) -> Callable[[float], float]:
    """P(t) (Pa) of a traction inlet, σ n = −P n: the study's pulse (A/2)(1 − cos(2πt/T)) on
    [0, T] and 0 after, a formula in t, or a table, inline or read from a CSV file (linear
    between rows; with a period T > 0, P(t) = P_table(t mod T), else constant beyond its ends).
    A ``pressure_file`` inlet must come from :func:`config.load` (which reads its rows)."""
    if isinstance(spec, config.InletPulse):
        A, T = spec.amplitude, spec.duration
        return lambda t: A / 2 * (1 - math.cos(2 * math.pi * t / T)) if 0 <= t <= T else 0.0
    if isinstance(spec, config.InletPressure):
        return boundary_data.time_function(spec.formula)
    if isinstance(spec, (config.InletPressureTable, config.InletPressureFile)):
        if not spec.table:
            raise ValueError(
                f"fluid.inlet ({spec.kind}) has no rows (a pressure_file inlet "
                "is read by config.load or config.from_dict)"
            )
        times, values = np.array(spec.table, dtype=float).T
        period = spec.period
        if period > 0:
            return lambda t: float(np.interp(t % period, times, values))
        return lambda t: float(np.interp(t, times, values))
    raise TypeError(f"{type(spec).__name__} is not a traction inlet")


def inflow_ramp(t: float, ramp_time: float) -> float:
    """(1 − cos(π t / T_r)) / 2 for t < T_r, 1 after (Turek–Hron: T_r = 2 s)."""
    return 1.0 if t >= ramp_time else 0.5 * (1 - math.cos(math.pi * t / ramp_time))


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


# --------------------------------------------------------------------------------------------
# Lumped outlets: a pressure from the outlet's flow rate (fsi/physics/outlets.py)


class LumpedOutlet:
    """An :class:`Outflow` whose pressure P comes from a lumped model (resistance, RCR
    Windkessel): σ n = −P n with, within a step, P = P₀' + R' Q (the model's
    :meth:`~fsi.physics.outlets.OutletModel.pressure_law`) and Q = ∫_Γ u·n ds the step's own flow
    rate.

    Q is linear in the unknowns, Q = b · U with b_i = ∫_Γ φ_i·n ds, so the residual's term
    ∫_Γ P n·v ds has the Jacobian R' b bᵀ: :class:`_FluidProblem` sets P from each Newton
    iterate (:meth:`update`) and adds that rank-one block, dense among the outlet's dofs, to
    each Jacobian (:meth:`add_to_jacobian`). Newton stays Newton, and P = P₀' + R' Q holds at
    the converged solution to the solver's tolerance, however large R' is. The model's state
    (the Windkessel's P_c^n, P_c^{n−1}) advances with the accepted step's Q (:meth:`advance`).
    """

    def __init__(self, model: outlets.OutletModel, tags: Sequence[int], W, ds_outlet, normal):
        self.model, self.tags = model, tuple(tags)
        self.state = model.initial_state()
        self.pressure = dolfinx.fem.Constant(W.mesh, PETSc.ScalarType(0.0))
        self.flow_rate = 0.0
        self._law = (0.0, 0.0)  # (P₀', R') of the step being solved
        v, _ = ufl.TestFunctions(W)
        self._flux = dolfinx.fem.form(ufl.dot(v, normal) * ds_outlet)
        self._b = dolfinx.fem.petsc.create_vector(self._flux)

    def begin_step(self, weights: Sequence[float]) -> None:
        """The step's law P = P₀' + R' Q, for the time weights (a₀, a₁, a₂) of the step."""
        self._law = self.model.pressure_law(self.state, weights)

    def update(self, x: PETSc.Vec) -> None:
        """P = P₀' + R' Q at the iterate ``x`` (Q = b · x, b on the current mesh). Collective."""
        with self._b.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(self._b, self._flux)
        self._b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.flow_rate = self._b.dot(x)
        base, slope = self._law
        self.pressure.value = base + slope * self.flow_rate

    def add_to_jacobian(self, A: PETSc.Mat, bcs) -> None:
        """A += R' b bᵀ, without the Dirichlet rows and columns. Collective."""
        b = self._b.copy()
        dolfinx.fem.petsc.set_bc(b, bcs, None, 0.0)  # b = 0 at Dirichlet dofs
        owned = b.array
        local = np.flatnonzero(owned)
        rows = (local + b.getOwnershipRange()[0]).astype(PETSc.IntType)
        values = owned[local]
        comm = A.getComm().tompi4py()
        columns = np.concatenate(comm.allgather(rows)).astype(PETSc.IntType)
        column_values = np.concatenate(comm.allgather(values))
        b.destroy()
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        A.setValues(
            rows,
            columns,
            self._law[1] * np.outer(values, column_values),
            addv=PETSc.InsertMode.ADD_VALUES,
        )
        A.assemble()

    def advance(self, weights: Sequence[float]) -> None:
        """Accept the step: the model's state after a step with flow rate Q."""
        self.state = self.model.advance(self.state, self.flow_rate, weights)

    def values(self) -> dict[str, float]:
        """``outlet_pressure`` P (Pa) at the last flow rate, and the model's state values."""
        return {
            "outlet_pressure": float(self.pressure.value),
            **self.model.state_values(self.state),
        }


class _FluidProblem(dolfinx.fem.petsc.NonlinearProblem):
    """The fluid's nonlinear problem; with lumped outlets, each residual evaluation first sets
    their pressures from the iterate, and each Jacobian gets their rank-one blocks
    (:class:`LumpedOutlet`). Without them it is dolfinx's problem unchanged."""

    def __init__(
        self, F: ufl.Form, U: dolfinx.fem.Function, bcs: list, lumped: Sequence[LumpedOutlet]
    ):
        dU = ufl.TrialFunction(U.function_space)
        super().__init__(F, U, bcs, J=ufl.derivative(F, U, dU))
        self.lumped = tuple(lumped)

    def F(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        for outlet in self.lumped:
            outlet.update(x)
        super().F(x, b)

    def J(self, x: PETSc.Vec, A: PETSc.Mat) -> None:
        super().J(x, A)
        for outlet in self.lumped:
            outlet.add_to_jacobian(A, self.bcs)


# --------------------------------------------------------------------------------------------
# The pieces of the residual


@dataclass(frozen=True)
class _WeakForm:
    """The symbols the residual's terms share: the unknowns (u, p) = split(U), the test
    functions (v, q), the viscosity μ(s(u)), the BDF derivative ∂u/∂t, the measures (with the
    configured quadrature degree), the coordinate x, the outward normal n, the cell diameter h."""

    u: ufl.core.expr.Expr
    p: ufl.core.expr.Expr
    v: ufl.core.expr.Expr
    q: ufl.core.expr.Expr
    mu: ufl.core.expr.Expr
    dudt: ufl.core.expr.Expr
    dx: ufl.Measure
    ds: ufl.Measure
    x: ufl.core.expr.Expr
    n: ufl.core.expr.Expr
    h: ufl.core.expr.Expr

    def ds_of(self, tags: Sequence[int]) -> ufl.Measure:
        """The boundary measure over the facets of ``tags``."""
        return sum((self.ds(t) for t in tags[1:]), self.ds(tags[0]))


_NORMAL_FLOW, _PRESCRIBED, _WALL = 0, 1, 2
"""The precedence of Dirichlet conditions: they are applied in this order, so at a dof two of
them share (a corner) the later one wins: walls over inlets and the interface, both over the
normal-flow condition u·t = 0."""


@dataclass
class _Contribution:
    """What one boundary condition adds to the problem: residual terms (forms added to F) and
    Dirichlet conditions, each with its precedence."""

    terms: list = field(default_factory=list)
    dirichlet: list = field(default_factory=list)


# --------------------------------------------------------------------------------------------
# The geometry of straight open boundaries (normal flow, the parabolic inflow profile)


def boundary_points(mesh, facet_tags, tags: Sequence[int], comm: MPI.Comm) -> np.ndarray:
    """The (x, y) of the vertices of the facets ``tags``, gathered from every rank (the same
    array on each; vertices shared by facets repeat). Collective."""
    nodes = compat.entities_to_geometry(
        mesh, mesh.topology.dim - 1, facets_of(facet_tags, tags)
    ).ravel()
    return np.concatenate(comm.allgather(mesh.geometry.x[nodes, :2]))


def parabolic_profile(points: np.ndarray, mesh, comm: MPI.Comm, mean_velocity: float):
    """The interpolation function of 1.5 Ū 4 s (H − s)/H² (−n) on the straight inlet whose
    vertices are ``points`` (:func:`boundary_points`): H its width, s the distance along it,
    n its outward normal (towards the inside of ``mesh``: the side of its centroid).
    Collective (the centroid)."""
    # The inlet's end points: the pair of its vertices farthest apart.
    ends = points[
        [np.argmin(points @ d) for d in ((1, 0), (0, 1))]
        + [np.argmax(points @ d) for d in ((1, 0), (0, 1))]
    ]
    i, j = np.unravel_index(np.argmax(np.linalg.norm(ends[:, None] - ends[None], axis=2)), (4, 4))
    start, tangent = ends[i], ends[j] - ends[i]
    width = np.linalg.norm(tangent)
    tangent = tangent / width
    normal = np.array([tangent[1], -tangent[0]])
    centre = comm.allreduce(mesh.geometry.x[:, :2].sum(axis=0))
    centre /= comm.allreduce(len(mesh.geometry.x))
    if normal @ (centre - start) < 0:
        normal = -normal  # inward
    peak = 1.5 * mean_velocity

    def profile(xx):
        s = np.clip((xx[:2].T - start) @ tangent, 0, width)
        values = peak * 4 * s * (width - s) / width**2
        return np.outer(normal, values)

    return profile


# --------------------------------------------------------------------------------------------
# The residual


class FluidResidual:
    """The residual F((u, p); (v, q)) of a :class:`FluidSolver`, the module docstring's weak
    form as a sum of named terms (:meth:`_residual`), and what the boundary conditions add:
    Dirichlet conditions (:attr:`bcs`), time-dependent boundary data (:attr:`updates`, each
    called with the time of a step before it is solved) and lumped outlets (:attr:`lumped`).

    It uses the solver's spaces, functions and constants (the unknown U, u^n, u^{n−1}, the
    boundary and mesh velocities, the BDF weights a_k, ρ and t), and is not kept after the
    solver has taken :attr:`form` and the three lists."""

    def __init__(self, solver: FluidSolver, body_force: BodyForce | None):
        s = solver
        self.mesh, self.facet_tags, self.comm = s.mesh, s.facet_tags, s.comm
        self.config, self.scheme, self.law = s.config, s.scheme, s.law
        self.boundaries = s.boundaries
        self.W, self.V, self.U, self.u_n, self.u_nm1 = s.W, s.V, s.U, s.u_n, s.u_nm1
        self.boundary_velocity, self.ale = s.boundary_velocity, s.ale
        self.t, self._a, self._rho = s.t, s._a, s._rho  # the solver's constants
        self.bcs: list = []
        self.updates: list[Callable[[float], None]] = []
        self.lumped: list[LumpedOutlet] = []
        self.form = self._residual(body_force)

    def _dirichlet(self, value: dolfinx.fem.Function, tags: Sequence[int]):
        fdim = self.mesh.topology.dim - 1
        dofs = dolfinx.fem.locate_dofs_topological(
            (self.W.sub(0), self.V), fdim, facets_of(self.facet_tags, tags)
        )
        return dolfinx.fem.dirichletbc(value, dofs, self.W.sub(0))

    # ---- the residual, term by term (the module docstring's weak form)

    def _residual(self, body_force: BodyForce | None) -> ufl.Form:
        """F((u, p); (v, q)) of the module docstring, one named term per line of it:

            inertia + convection (ALE) + viscous stress − pressure − continuity − body force
            + SUPG + the boundary terms of each condition (:attr:`BOUNDARY_KINDS`),

        and the Dirichlet conditions of the boundaries (in ``self.bcs``, ordered by
        :data:`_Contribution` precedence: later ones win at shared corner dofs)."""
        s = self._weak_form()
        F = (
            self._inertia(s)
            + self._convection(s)
            + self._viscous_stress(s)
            - self._pressure(s)
            - self._continuity(s)
        ) * s.dx
        if body_force is not None:
            F -= self._body_force(s, body_force) * s.dx
        if self.config.supg:
            F += self._supg(s, body_force) * s.dx
        dirichlet = []
        for bc in self.boundaries:
            kind = self.BOUNDARY_KINDS.get(type(bc))
            if kind is None:
                raise TypeError(f"unknown boundary condition {bc!r}")
            contribution = kind(self, bc, s)
            for term in contribution.terms:
                F += term
            dirichlet += contribution.dirichlet
        # A stable sort: normal flow first, then prescribed velocities, walls last.
        self.bcs.extend(bc for _, bc in sorted(dirichlet, key=lambda pair: pair[0]))
        return F

    def _weak_form(self) -> _WeakForm:
        mesh, cfg = self.mesh, self.config
        metadata = {"quadrature_degree": cfg.quadrature_degree}
        u, p = ufl.split(self.U)
        v, q = ufl.TestFunctions(self.W)
        a0, a1, a2 = self._a
        return _WeakForm(
            u=u,
            p=p,
            v=v,
            q=q,
            mu=self.law.mu(rheology.shear_rate(u)),
            dudt=a0 * u + a1 * self.u_n + a2 * self.u_nm1,
            dx=ufl.Measure("dx", domain=mesh, metadata=metadata),
            ds=ufl.Measure("ds", domain=mesh, subdomain_data=self.facet_tags, metadata=metadata),
            x=ufl.SpatialCoordinate(mesh),
            n=ufl.FacetNormal(mesh),
            h=ufl.CellDiameter(mesh),
        )

    def _inertia(self, s: _WeakForm):
        """ρ (Σ_k a_k u^{n+1−k}) · v: the BDF derivative at fixed reference position X."""
        return self._rho * ufl.dot(s.dudt, s.v)

    def _convection(self, s: _WeakForm):
        """ρ ((u − w)·∇)u · v: convection relative to the mesh velocity w (ALE)."""
        return self._rho * ufl.dot(ufl.grad(s.u) * (s.u - self.ale.w), s.v)

    def _viscous_stress(self, s: _WeakForm):
        """2 μ(s(u)) D(u) : D(v), the viscous part of σ(u, p) : ∇v (rheology.cauchy_stress)."""
        D = rheology.strain_rate
        return 2 * s.mu * ufl.inner(D(s.u), D(s.v))

    def _pressure(self, s: _WeakForm):
        """p ∇·v, the pressure part of σ(u, p) : ∇v (subtracted)."""
        return s.p * ufl.div(s.v)

    def _continuity(self, s: _WeakForm):
        """q ∇·u (subtracted: the symmetric saddle-point form)."""
        return s.q * ufl.div(s.u)

    def _body_force(self, s: _WeakForm, body_force: BodyForce):
        """f(x, t) · v (subtracted)."""
        return ufl.dot(body_force(s.x, self.t), s.v)

    # ---- boundary terms: one function per kind of condition (BOUNDARY_KINDS)

    def _no_slip(self, bc: NoSlip, s: _WeakForm) -> _Contribution:
        """u = 0, applied last so that walls win at the corners they share."""
        zero = dolfinx.fem.Function(self.V)
        return _Contribution(dirichlet=[(_WALL, self._dirichlet(zero, bc.tags))])

    def _velocity(self, bc: Velocity, s: _WeakForm) -> _Contribution:
        """u = :attr:`boundary_velocity` (the coupler's ∂η/∂t on the interface)."""
        return _Contribution(
            dirichlet=[(_PRESCRIBED, self._dirichlet(self.boundary_velocity, bc.tags))]
        )

    def _inflow(self, bc: Inflow, s: _WeakForm) -> _Contribution:
        """A parabolic velocity inlet (Dirichlet), or a traction inlet: σ n = −P(t) n as an
        open boundary (:meth:`_open_boundary`), its inflow energy term, and u·t = 0 with
        ``normal_flow`` (first, so that walls and the interface win at the corners)."""
        if isinstance(bc.spec, config.ParabolicInflow):
            return _Contribution(dirichlet=[(_PRESCRIBED, self._parabolic_inflow(bc))])
        pressure = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        law = inlet_pressure(bc.spec)
        self.updates.append(lambda t, c=pressure, law=law: c.value.fill(law(t)))
        terms = [
            *self._open_boundary(s, pressure, bc.tags),
            self._inflow_energy_balance(s, bc.inflow_stabilization, bc.tags),
        ]
        dirichlet = [(_NORMAL_FLOW, self._normal_flow(bc.tags))] if self.config.normal_flow else []
        return _Contribution(terms, dirichlet)

    def _outflow(self, bc: Outflow, s: _WeakForm) -> _Contribution:
        """An outlet σ n = −P n (in the configured open-boundary form; P = 0 traction-free, or
        a lumped model's pressure, :class:`LumpedOutlet`) with the backflow energy term."""
        pressure = None
        if bc.model is not None:
            outlet = LumpedOutlet(bc.model, bc.tags, self.W, s.ds_of(bc.tags), s.n)
            self.lumped.append(outlet)
            pressure = outlet.pressure
        return _Contribution(
            [
                *self._open_boundary(s, pressure, bc.tags),
                self._inflow_energy_balance(s, bc.backflow_stabilization, bc.tags),
            ]
        )

    def _slip(self, bc: Slip, s: _WeakForm) -> _Contribution:
        """u·n = 0 by Nitsche's method (consistency, symmetry and penalty γ μ/h terms) and the
        tangential part of the prescribed traction g."""
        u, v, n = s.u, s.v, s.n
        sigma = rheology.cauchy_stress(u, s.p, self.law)
        sigma_v = -s.q * ufl.Identity(len(u)) + 2 * s.mu * rheology.strain_rate(v)
        un, vn = ufl.dot(u, n), ufl.dot(v, n)
        terms = [
            (
                -ufl.dot(n, sigma * n) * vn
                - ufl.dot(n, sigma_v * n) * un
                + NITSCHE_PENALTY * s.mu / s.h * un * vn
            )
            * s.ds_of(bc.tags)
        ]
        if bc.traction is not None:
            g = bc.traction(s.x, n, self.t)
            terms.append(-(ufl.dot(g - ufl.dot(g, n) * n, v) * s.ds_of(bc.tags)))
        return _Contribution(terms)

    def _traction(self, bc: Traction, s: _WeakForm) -> _Contribution:
        """σ n = g(x, n, t): −∫ g · v."""
        return _Contribution([-(ufl.dot(bc.traction(s.x, s.n, self.t), s.v) * s.ds_of(bc.tags))])

    BOUNDARY_KINDS: dict[type, Callable] = {
        NoSlip: _no_slip,
        Velocity: _velocity,
        Inflow: _inflow,
        Outflow: _outflow,
        Slip: _slip,
        Traction: _traction,
    }
    """The function that turns each kind of boundary condition into its residual terms and
    Dirichlet conditions."""

    def _open_boundary(self, s: _WeakForm, pressure, tags: Sequence[int]) -> list:
        """−∫ σn·v with σn = −P n (P = 0 if ``pressure`` is None), plus −∫ μ (∇u)ᵀn·v in the
        do-nothing form μ∇u n − p n = −P n."""
        terms = [] if pressure is None else [pressure * ufl.dot(s.n, s.v) * s.ds_of(tags)]
        if self.config.open_boundary == "do_nothing":
            terms.append(-s.mu * ufl.dot(ufl.grad(s.u).T * s.n, s.v) * s.ds_of(tags))
        return terms

    def _inflow_energy_balance(self, s: _WeakForm, beta: float, tags: Sequence[int]):
        """−β/2 ρ min(u·n, 0) u·v on an open boundary: balances the kinetic energy that inflow
        (u·n < 0) carries into the domain (Bazilevs et al. 2009); 0 for β = 0."""
        return -(
            beta
            / 2
            * self._rho
            * ufl.min_value(ufl.dot(s.u, s.n), 0.0)
            * ufl.dot(s.u, s.v)
            * s.ds_of(tags)
        )

    def _supg(self, s: _WeakForm, body_force: BodyForce | None):
        """SUPG: τ ((u − w)·∇)v · R with the strong momentum residual

            R = ρ (∂u/∂t + ((u − w)·∇)u) + ∇p − ∇·(2 μ(s) D(u)) − f

        (zero for the exact solution: the method is consistent; P2 velocities make the viscous
        term exact for Poiseuille flow, which stays a discrete solution) and
        τ = ((2 a₀)² + (2|u − w|/h)² + (4 μ/(ρ h²))²)^(−1/2) (Tezduyar & Osawa 2000; a₀ the
        BDF weight of u^{n+1}, 1/Δt for backward Euler, 0 when steady; u and μ of the last
        accepted step, so that τ is a coefficient of the step, not a function of its unknown;
        the residual R is the step's own). It adds the streamline
        diffusion ≈ ρ|u − w|h/2 that the Galerkin form lacks where the cell Reynolds number is
        large, in particular in the cells of an open inlet (docs/boundary-conditions.md)."""
        rho, w, u, h = self._rho, self.ale.w, s.u, s.h
        a = u - w
        residual = (
            rho * s.dudt
            + rho * ufl.grad(u) * a
            + ufl.grad(s.p)
            - ufl.div(2 * s.mu * rheology.strain_rate(u))
        )
        if body_force is not None:
            residual -= body_force(s.x, self.t)
        a_n = self.u_n - w
        mu_n = self.law.mu(rheology.shear_rate(self.u_n))
        speed = ufl.sqrt(ufl.dot(a_n, a_n))
        tau = (
            (2 * self._a[0]) ** 2 + (2 * speed / h) ** 2 + (4 * mu_n / (rho * h**2)) ** 2
        ) ** -0.5
        return tau * ufl.dot(ufl.grad(s.v) * a, residual)

    # ---- Dirichlet conditions

    def _normal_flow(self, tags: Sequence[int]):
        """u·t = 0 on the open boundary ``tags``, which must be a straight segment parallel to a
        coordinate axis (every inlet and outlet of the shipped geometries): the velocity
        component along it is 0, the normal one stays free."""
        points = boundary_points(self.mesh, self.facet_tags, tags, self.comm)
        extent = points.max(axis=0) - points.min(axis=0)
        normal_axis = int(np.argmin(extent))
        if extent[normal_axis] > 1e-9 * extent.max():
            raise ValueError(
                f"fluid.normal_flow needs straight open boundaries parallel to an "
                f"axis; boundary {list(tags)} spans {extent[0]:g} x {extent[1]:g} m"
            )
        component = self.W.sub(0).sub(1 - normal_axis)
        dofs = dolfinx.fem.locate_dofs_topological(
            component, self.mesh.topology.dim - 1, facets_of(self.facet_tags, tags)
        )
        zero = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        return dolfinx.fem.dirichletbc(zero, dofs, component)

    def _parabolic_inflow(self, bc: Inflow):
        """u = ramp(t) 1.5 Ū 4 s (H − s)/H² (−n) on a straight inlet of width H."""
        spec: config.ParabolicInflow = bc.spec
        points = boundary_points(self.mesh, self.facet_tags, bc.tags, self.comm)
        shape = dolfinx.fem.Function(self.V)
        shape.interpolate(parabolic_profile(points, self.mesh, self.comm, spec.mean_velocity))
        inflow = dolfinx.fem.Function(self.V, name="inflow")

        ramped = self.scheme != "steady" and spec.ramp_time > 0

        def update(t: float) -> None:  # no reference to self: no cycle for the GC to break
            factor = inflow_ramp(t, spec.ramp_time) if ramped else 1.0
            inflow.x.array[:] = factor * shape.x.array

        self.updates.append(update)
        return self._dirichlet(inflow, bc.tags)


# --------------------------------------------------------------------------------------------
# The solver


def _subspace_map(W, i: int, V) -> np.ndarray:
    """The local dof of ``W`` behind each local (unrolled) dof of ``V``, a standalone space with
    the element of ``W.sub(i)`` (what ``W.sub(i).collapse()`` gives), from the cell dofmaps.

    A blocked sub-element lists its dofs node by node (x0, y0, x1, y1, ...), as V unrolls its
    blocks. −1 marks a ghost dof on no local cell: dolfinx 0.5.2's submeshes have such orphan
    ghost vertices in parallel, and its ``collapse()`` then corrupts the heap (``malloc():
    invalid size``, intermittently), hence this map. Copy owned values and scatter forward.
    """
    V_cells = compat.cell_dofs(V)
    W_cells = compat.cell_dofs(W.sub(i)).reshape(len(V_cells), -1)
    bs = V.dofmap.index_map_bs
    unrolled = (V_cells[:, :, None] * bs + np.arange(bs)).reshape(len(V_cells), -1)
    index_map = V.dofmap.index_map
    V_to_W = np.full((index_map.size_local + index_map.num_ghosts) * bs, -1, dtype=np.int32)
    V_to_W[unrolled.ravel()] = W_cells.ravel()
    if (V_to_W[: index_map.size_local * bs] < 0).any():
        raise RuntimeError("an owned dof of the subspace lies on no local cell")
    return V_to_W


def _copy_from_mixed(
    target: dolfinx.fem.Function, U: dolfinx.fem.Function, target_to_U: np.ndarray
) -> None:
    owned = target_to_U >= 0
    target.x.array[owned] = U.x.array[target_to_U[owned]]
    target.x.scatter_forward()


def _copy_to_mixed(
    U: dolfinx.fem.Function, source: dolfinx.fem.Function, source_to_U: np.ndarray
) -> None:
    owned = source_to_U >= 0
    U.x.array[source_to_U[owned]] = source.x.array[owned]
    U.x.scatter_forward()


class FluidSolver:
    """Generalized Navier–Stokes on a (moving) fluid mesh; see the module docstring.

    Args:
        mesh: the fluid mesh (e.g. ``fsi.physics.mesh.restrict(tagged, Region.FLUID).mesh``).
        facet_tags: its boundary tags (``.facet_tags`` of the same).
        fluid: the ``fluid`` section (density, rheology, quadrature, Newton and PETSc options).
        boundaries: which tags get which condition (e.g. :func:`boundary_conditions`); tags without
            a condition are traction-free (σ n = 0).
        scheme: ``backward_euler``, ``bdf2`` (backward Euler on the first step) or ``steady``.
        body_force: optional f(x, t).
    """

    def __init__(
        self,
        mesh: dolfinx.mesh.Mesh,
        facet_tags: dolfinx.mesh.MeshTags,
        fluid: config.Fluid,
        boundaries: Sequence[BoundaryCondition],
        scheme: Scheme = "bdf2",
        body_force: BodyForce | None = None,
    ):
        if scheme not in ("backward_euler", "bdf2", "steady"):
            raise ValueError(f"unknown time scheme {scheme!r}")
        self.mesh, self.facet_tags, self.config, self.scheme = mesh, facet_tags, fluid, scheme
        self.comm: MPI.Comm = mesh.comm
        self.law = rheology.from_config(fluid.rheology)
        self.boundaries = tuple(boundaries)
        gdim = mesh.geometry.dim
        fdim = mesh.topology.dim - 1
        mesh.topology.create_connectivity(fdim, mesh.topology.dim)

        self.W = compat.mixed_space(mesh, [("Lagrange", 2, (gdim,)), ("Lagrange", 1, ())])
        self.V = compat.function_space(mesh, "Lagrange", 2, (gdim,))
        self.Q = compat.function_space(mesh, "Lagrange", 1)
        self._V_to_W = _subspace_map(self.W, 0, self.V)
        self._Q_to_W = _subspace_map(self.W, 1, self.Q)
        self.U = dolfinx.fem.Function(self.W, name="fluid")
        self.u = dolfinx.fem.Function(self.V, name="velocity")
        self.p = dolfinx.fem.Function(self.Q, name="pressure")
        self.u_n = dolfinx.fem.Function(self.V)
        self.u_nm1 = dolfinx.fem.Function(self.V)
        # u^n, u^{n−1}: the history writes the arrays of the Functions the residual uses.
        self.velocity_history = BdfHistory(self.u.x.array, self.u_n.x.array, self.u_nm1.x.array)
        self.boundary_velocity = dolfinx.fem.Function(self.V, name="boundary_velocity")
        self.ale = AleMesh(mesh)

        self.time = 0.0
        self.dt_previous: float | None = None
        self._dt: float | None = None
        self.accepted_steps = 0
        self._mesh_velocity_given = False
        self._saved: FluidState | None = None

        def constant(value: float) -> dolfinx.fem.Constant:
            return dolfinx.fem.Constant(mesh, PETSc.ScalarType(value))

        self.t = constant(0.0)  # the time of the step being solved, for g(x, n, t) and f(x, t)
        self._a = [constant(0.0) for _ in range(3)]  # BDF weights
        self._rho = constant(fluid.density)

        self._check_tags()
        residual = FluidResidual(self, body_force)
        self.residual_form: ufl.Form = residual.form
        self._bcs, self._updates, self.lumped = residual.bcs, residual.updates, residual.lumped
        self.problem = _FluidProblem(residual.form, self.U, self._bcs, self.lumped)
        self.newton = Newton(self.comm, self.problem, self.config.solver, "fluid_")
        self._residual_vector = dolfinx.fem.Function(self.W)

    # ---- set-up

    def _check_tags(self) -> None:
        present = set(np.unique(self.facet_tags.values).tolist())
        present = set().union(*self.comm.allgather(present))
        seen: dict[int, str] = {}
        for bc in self.boundaries:
            for tag in bc.tags:
                if tag in seen:
                    raise ValueError(
                        f"boundary tag {tag} has two conditions: {seen[tag]} and"
                        f" {type(bc).__name__}"
                    )
                if tag not in present:
                    raise ValueError(
                        f"boundary tag {tag} ({type(bc).__name__}) is not on the fluid mesh"
                    )
                seen[tag] = type(bc).__name__

    # ---- the coupler's interface

    def set_mesh_displacement(
        self, d: dolfinx.fem.Function, w: dolfinx.fem.Function | None = None
    ) -> None:
        """Move the mesh to x = X + d. The mesh velocity is ``w`` if given, else (at :meth:`step`)
        the scheme's derivative of the displacement history."""
        self.ale.move(d)
        self._mesh_velocity_given = w is not None
        if w is not None:
            self.ale.w.interpolate(w)
            self.ale.w.x.scatter_forward()

    def initialize(self, u=None, p=None) -> None:
        """Initial velocity (and pressure, a Newton initial guess): Functions or callables x ↦
        values as for ``Function.interpolate``; u^n = u^{n−1} = u. Default: rest."""
        if u is not None:
            self.u.interpolate(u)
            self.velocity_history.start()
            _copy_to_mixed(self.U, self.u, self._V_to_W)
        if p is not None:
            self.p.interpolate(p)
            _copy_to_mixed(self.U, self.p, self._Q_to_W)

    def time_weights(self, dt: float) -> tuple[float, float, float]:
        """(a0, a1, a2) of ∂u/∂t ≈ a0 u^{n+1} + a1 u^n + a2 u^{n−1} for the next step."""
        if self.scheme == "steady":
            return (0.0, 0.0, 0.0)
        if self.scheme == "bdf2" and self.accepted_steps > 0:
            return tuple(bdf_weights(2, dt, self.dt_previous))  # type: ignore[return-value]
        return (*bdf_weights(1, dt), 0.0)  # type: ignore[return-value]

    def step(self, t: float, dt: float, forcing: Forcing | None = None) -> SolveResult:
        """Solve for (u, p) at time ``t`` = t_n + dt on the current mesh, Newton starting from
        the current (u, p) and stopping on the solver's tolerance or at ``forcing``. On failure
        (Newton not converged, PETSc error, non-finite values) the solution is reset to its
        value before the step and the result says why; nothing non-finite is left behind."""
        weights = self.time_weights(dt)
        self._dt = dt
        for c, a in zip(self._a, weights):
            c.value = a
        self.t.value = t
        for update in self._updates:
            update(t)
        for outlet in self.lumped:
            outlet.begin_step(weights)
        if not self._mesh_velocity_given:
            self.ale.set_velocity(weights)
        self.ale.w.x.scatter_forward()
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
        self.time = float(self.t.value)
        self.accepted_steps += 1
        self._mesh_velocity_given = False

    def save_state(self) -> FluidState:
        """Snapshot of the solution, the time history and the mesh (also kept for
        :meth:`restore_state`)."""
        self._saved = FluidState(
            self.time,
            self.dt_previous,
            self.accepted_steps,
            self.U.x.array.copy(),
            *self.velocity_history.save(),  # u_n, u_nm1
            *self.ale.save(),  # d, d_n, d_nm1, w
            self._mesh_velocity_given,
            np.concatenate([np.zeros(0), *(outlet.state for outlet in self.lumped)]),
        )
        return self._saved

    def restore_state(self, state: FluidState | None = None) -> None:
        """Return to ``state`` (default: the last :meth:`save_state`), mesh position included."""
        s = state or self._saved
        if s is None:
            raise RuntimeError("restore_state before any save_state")
        self._restore_outlets(s.outlet_state)  # first: it checks the state's size
        self.time, self.dt_previous, self.accepted_steps = s.time, s.dt_previous, s.accepted_steps
        self.U.x.array[:] = s.U
        self.velocity_history.restore(s.u_n, s.u_nm1)
        self.ale.restore(s.d, s.d_n, s.d_nm1, s.w)  # and moves the mesh to X + d
        self._mesh_velocity_given = s.mesh_velocity_given
        self._sync_outputs()

    def _restore_outlets(self, state: np.ndarray) -> None:
        sizes = [len(outlet.state) for outlet in self.lumped]
        if len(state) != sum(sizes):
            raise ValueError(
                f"an outlet state of {len(state)} values for lumped outlets of {sum(sizes)}"
            )
        start = 0
        for outlet, size in zip(self.lumped, sizes, strict=True):
            outlet.state = np.array(state[start : start + size], dtype=float)
            start += size

    def outlet_values(self) -> dict[str, float]:
        """The lumped outlets' pressures (Pa) for the metrics: ``outlet_pressure`` P, the
        pressure the outlet imposes at the last step's flow rate, and for a Windkessel
        ``windkessel_pressure`` P_c after the last accepted step (names suffixed ``_<tag>``
        when there are several lumped outlets); empty without one."""
        several = len(self.lumped) > 1
        return {
            name + (f"_{outlet.tags[0]}" if several else ""): value
            for outlet in self.lumped
            for name, value in outlet.values().items()
        }

    def _sync_outputs(self) -> None:
        _copy_from_mixed(self.u, self.U, self._V_to_W)
        _copy_from_mixed(self.p, self.U, self._Q_to_W)

    def mixed_dofs(self) -> tuple[np.ndarray, np.ndarray]:
        """The local dof of ``U`` (space W) behind each local (unrolled) dof of ``u`` (V) and of
        ``p`` (Q), −1 where there is none (for checkpoints: which W value is which node's)."""
        return self._V_to_W, self._Q_to_W

    # ---- forces

    def _reaction(self) -> np.ndarray:
        """−R at every local W dof: the residual at the current solution, no Dirichlet rows."""
        R = self._residual_vector
        b = compat.petsc_vector(R)
        with b.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, self.problem.L)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        R.x.scatter_forward()
        return -R.x.array

    def _owned_nodes(self, tags: Sequence[int]) -> np.ndarray:
        fdim = self.mesh.topology.dim - 1
        nodes = dolfinx.fem.locate_dofs_topological(self.V, fdim, facets_of(self.facet_tags, tags))
        return nodes[nodes < self.V.dofmap.index_map.size_local]

    def interface_force(self, tags: Sequence[int] | None = None) -> NodalForces:
        """Nodal forces the fluid exerts on the boundary ``tags`` (default: the :class:`Velocity`
        boundaries) from the variational residual: at node i, f_i = −R_i = −∫_Γ σ n φ_i ds for
        the discrete solution (n the fluid's outward normal), consistent with the discrete
        momentum balance. Owned nodes only; gather them if needed. Call it after :meth:`step`
        and before :meth:`advance` (the residual's inertia uses the step's time history)."""
        if tags is None:
            tags = [t for bc in self.boundaries if isinstance(bc, Velocity) for t in bc.tags]
        gdim = self.mesh.geometry.dim
        nodes = self._owned_nodes(tags)
        minus_R = self._reaction()
        W_dofs = self._V_to_W.reshape(-1, gdim)[nodes]
        coordinates = self.V.tabulate_dof_coordinates()[nodes, :gdim]
        return NodalForces(coordinates, minus_R[W_dofs], nodes)

    def boundary_force(self, tags: Sequence[int]) -> np.ndarray:
        """Total force (N/m) of the fluid on ``tags``, Σ_i f_i over :meth:`interface_force`'s
        nodes (the residual form of ∫ σ n_obstacle ds: drag and lift)."""
        local = self.interface_force(_tags(tags)).force.sum(axis=0)
        return self.comm.allreduce(local, op=MPI.SUM)

    def traction(self, tags: Sequence[int] | None = None) -> dolfinx.fem.Function:
        """For post-processing: the traction the fluid exerts on ``tags`` as a P2 field, nodal
        force / lumped boundary mass (f_i / ∫_Γ φ_i ds; exact for a constant traction), 0 off
        the boundary."""
        if tags is None:
            tags = [t for bc in self.boundaries if isinstance(bc, Velocity) for t in bc.tags]
        tags = list(_tags(tags))
        ds = ufl.Measure(
            "ds",
            domain=self.mesh,
            subdomain_data=self.facet_tags,
            metadata={"quadrature_degree": 2},
        )
        v = ufl.TestFunction(self.V)
        one = ufl.as_vector([1.0] * self.mesh.geometry.dim)
        mass = dolfinx.fem.petsc.assemble_vector(
            dolfinx.fem.form(
                sum((ufl.dot(one, v) * ds(t) for t in tags[1:]), ufl.dot(one, v) * ds(tags[0]))
            )
        )
        mass.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        traction = dolfinx.fem.Function(self.V, name="traction")
        gdim = self.mesh.geometry.dim
        nodes = self._owned_nodes(tags)
        minus_R = self._reaction()
        values = traction.x.array.reshape(-1, gdim)
        lumped = mass.array.reshape(-1, gdim)[nodes]
        values[nodes] = minus_R[self._V_to_W.reshape(-1, gdim)[nodes]] / lumped
        traction.x.scatter_forward()
        mass.destroy()
        return traction
