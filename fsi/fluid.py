"""Incompressible generalized Navier–Stokes in ALE form (MODEL.md §2), Taylor–Hood P2/P1, Newton.

    ρ (∂u/∂t|_X + ((u − w)·∇)u) − ∇·(2 μ(s(u)) D(u)) + ∇p = f,   ∇·u = 0   in Ωf(t),

with ``D(u) = sym ∇u``, ``s(u) = sqrt(2 D:D)`` (fsi/rheology.py), ``w`` the mesh velocity and
``f`` an optional body force (manufactured solutions). Weak form on the current configuration
(residual ``F((u, p); (v, q))``):

    ρ (Σ_k a_k u^{n+1−k}, v) + ρ (((u − w)·∇)u, v) + (2 μ D(u), D(v)) − (p, ∇·v) − (q, ∇·u)
        − (f, v) − ⟨σ n, v⟩_natural = 0.

The time derivative ``∂u/∂t|_X ≈ Σ_k a_k u^{n+1−k}`` acts on the nodal values (which move with
the mesh, i.e. at fixed X); the weights ``a_k`` come from :func:`fsi.timestepping.bdf_weights`
(backward Euler, variable-step BDF2; all zero in steady mode), so the physics never names a
scheme. Everything is evaluated on Ωf(t_{n+1}) (non-conservative ALE form): a uniform flow stays
uniform on any mesh motion (the discrete geometric conservation law of this form), and the mesh
velocity is by default the same BDF derivative of the mesh displacement, ``w = Σ_k a_k d^{n+1−k}``.

Boundary conditions are data (:class:`NoSlip`, :class:`Velocity`, :class:`Inflow`,
:class:`Outflow`, :class:`Slip`, :class:`Traction`) that :class:`FluidSolver` turns into Dirichlet
conditions and boundary terms. The coupler drives the solver through ``set_mesh_displacement``,
``boundary_velocity``, ``step``, ``advance``, ``save_state``/``restore_state`` and
``interface_force``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Callable, Literal, Sequence, Union

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc
import numpy as np
import ufl

from fsi import boundary_data, compat, config, rheology
from fsi.newton import NewtonCallbacks
from fsi.timestepping import bdf_weights
from geometry.tags import Boundary

log = logging.getLogger(__name__)

Scheme = Literal["backward_euler", "bdf2", "steady"]
TractionFunction = Callable[[ufl.core.expr.Expr, ufl.core.expr.Expr, dolfinx.fem.Constant],
                            ufl.core.expr.Expr]
"""``g(x, n, t)``: a UFL vector of the spatial coordinate, the outward normal and the time."""
BodyForce = Callable[[ufl.core.expr.Expr, dolfinx.fem.Constant], ufl.core.expr.Expr]
"""``f(x, t)``: a UFL vector (N/m³) of the spatial coordinate and the time."""

NITSCHE_PENALTY = 100.0
"""γ of the Nitsche term γ μ/h (u·n)(v·n) on slip walls; ≳ 10 (k + 1)² for P2 keeps it coercive."""


def _tags(tags) -> tuple[int, ...]:
    return (int(tags),) if isinstance(tags, (int, np.integer)) else tuple(int(t) for t in tags)


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
    """Traction-free σ n = β/2 ρ min(u·n, 0) u on ``tags`` (β = 0: σ n = 0, the study's); the
    β term removes the energy that backflow would carry in (Bazilevs et al. 2009)."""

    tags: tuple[int, ...]
    backflow_stabilization: float = 1.0

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


BoundaryCondition = Union[NoSlip, Velocity, Inflow, Outflow, Slip, Traction]


def study_boundaries(fluid: config.Fluid, walls: Sequence[Boundary] = (Boundary.RIGID_WALL,)
                     ) -> tuple[BoundaryCondition, ...]:
    """MODEL.md §2: the configured inlet, the outlet, no-slip on the rigid ``walls`` (Γw2; in
    the Turek–Hron benchmark also the cylinder), u = ∂η/∂t on Γw1."""
    return (Inflow(Boundary.INLET, fluid.inlet, fluid.inflow_stabilization),
            Outflow(Boundary.OUTLET, fluid.outlet.backflow_stabilization),
            Velocity(Boundary.INTERFACE),
            NoSlip(tuple(walls)))


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
            raise ValueError(f"fluid.inlet ({spec.kind}) has no rows (a pressure_file inlet "
                             "is read by config.load or config.from_dict)")
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
# Mesh


class AleMesh:
    """Moves a (P1-geometry) mesh by a vector P1 displacement d: x = X + d(X).

    Keeps the reference coordinates X, the displacement ``d`` (a Function on :attr:`space`),
    the accepted displacements d^n, d^{n−1} and the mesh velocity ``w``.
    """

    def __init__(self, mesh: dolfinx.mesh.Mesh):
        gdim = mesh.geometry.dim
        self.mesh = mesh
        self.space = compat.function_space(mesh, "Lagrange", 1, (gdim,))
        self.d = dolfinx.fem.Function(self.space, name="mesh_displacement")
        self.w = dolfinx.fem.Function(self.space, name="mesh_velocity")
        self.reference = mesh.geometry.x.copy()
        # Geometry node ↔ P1 dof: both follow the reference cell's vertex order.
        nodes = compat.geometry_dofmap(mesh)
        dofs = compat.cell_dofs(self.space)
        if nodes.shape != dofs.shape:
            raise ValueError("AleMesh needs an affine (P1) geometry")
        self._nodes, self._dofs = nodes.ravel(), dofs.ravel()
        coordinates = self.space.tabulate_dof_coordinates()
        if not np.allclose(coordinates[self._dofs, :gdim], self.reference[self._nodes, :gdim],
                           rtol=0, atol=1e-12 * (1 + np.abs(self.reference).max())):
            raise RuntimeError("AleMesh: P1 dofs and geometry nodes do not match")
        self.d_n = np.zeros_like(self.d.x.array)
        self.d_nm1 = np.zeros_like(self.d.x.array)

    def move(self, d: dolfinx.fem.Function | None = None) -> None:
        """Set the displacement (interpolated into P1 if it lives elsewhere) and move the mesh."""
        if d is not None and d is not self.d:
            if d.function_space == self.space:
                self.d.x.array[:] = d.x.array
            else:
                self.d.interpolate(d)
        self.d.x.scatter_forward()
        gdim = self.mesh.geometry.dim
        values = self.d.x.array.reshape(-1, gdim)
        self.mesh.geometry.x[self._nodes, :gdim] = (self.reference[self._nodes, :gdim]
                                                    + values[self._dofs])

    def set_velocity(self, weights: Sequence[float]) -> None:
        """w = Σ_k a_k d^{n+1−k} (the mesh velocity consistent with the fluid's time scheme)."""
        history = (self.d.x.array, self.d_n, self.d_nm1)
        self.w.x.array[:] = sum(a * h for a, h in zip(weights, history))

    def advance(self) -> None:
        self.d_nm1[:] = self.d_n
        self.d_n[:] = self.d.x.array


# --------------------------------------------------------------------------------------------
# Results and state


@dataclass(frozen=True)
class StepResult:
    """Newton's outcome for one step: linear solves, final residual norm (ℓ², Dirichlet rows
    included), convergence, and why it failed."""

    iterations: int
    residual: float
    converged: bool
    message: str = ""

    def raise_if_failed(self) -> None:
        if not self.converged:
            raise FluidSolveError(self.message or "the fluid Newton solve did not converge")


class FluidSolveError(RuntimeError):
    """The fluid Newton solve failed (no convergence, or a non-finite residual/solution)."""


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


def _copy_from_mixed(target: dolfinx.fem.Function, U: dolfinx.fem.Function,
                     target_to_U: np.ndarray) -> None:
    owned = target_to_U >= 0
    target.x.array[owned] = U.x.array[target_to_U[owned]]
    target.x.scatter_forward()


def _copy_to_mixed(U: dolfinx.fem.Function, source: dolfinx.fem.Function,
                   source_to_U: np.ndarray) -> None:
    owned = source_to_U >= 0
    U.x.array[source_to_U[owned]] = source.x.array[owned]
    U.x.scatter_forward()


class FluidSolver:
    """Generalized Navier–Stokes on a (moving) fluid mesh; see the module docstring.

    Args:
        mesh: the fluid mesh (e.g. ``fsi.mesh.restrict(tagged, Region.FLUID).mesh``).
        facet_tags: its boundary tags (``.facet_tags`` of the same).
        fluid: the ``fluid`` section (density, rheology, quadrature, Newton and PETSc options).
        boundaries: which tags get which condition (e.g. :func:`study_boundaries`); tags without
            a condition are traction-free (σ n = 0).
        scheme: ``backward_euler``, ``bdf2`` (backward Euler on the first step) or ``steady``.
        body_force: optional f(x, t).
    """

    def __init__(self, mesh: dolfinx.mesh.Mesh, facet_tags: dolfinx.mesh.MeshTags,
                 fluid: config.Fluid, boundaries: Sequence[BoundaryCondition],
                 scheme: Scheme = "bdf2", body_force: BodyForce | None = None):
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
        self._bcs, self._updates = [], []
        F = self._residual(body_force)
        dU = ufl.TrialFunction(self.W)
        self.problem = dolfinx.fem.petsc.NonlinearProblem(F, self.U, self._bcs,
                                                          J=ufl.derivative(F, self.U, dU))
        self.newton = self._newton()
        self._residual_vector = dolfinx.fem.Function(self.W)

    # ---- set-up

    def _check_tags(self) -> None:
        present = set(np.unique(self.facet_tags.values).tolist())
        present = set().union(*self.comm.allgather(present))
        seen: dict[int, str] = {}
        for bc in self.boundaries:
            for tag in bc.tags:
                if tag in seen:
                    raise ValueError(f"boundary tag {tag} has two conditions: {seen[tag]} and"
                                     f" {type(bc).__name__}")
                if tag not in present:
                    raise ValueError(f"boundary tag {tag} ({type(bc).__name__}) is not on the"
                                     " fluid mesh")
                seen[tag] = type(bc).__name__

    def _facets(self, tags: Sequence[int]) -> np.ndarray:
        ft = self.facet_tags
        return ft.indices[np.isin(ft.values, list(tags))].astype(np.int32)

    def _dirichlet(self, value: dolfinx.fem.Function, tags: Sequence[int]):
        fdim = self.mesh.topology.dim - 1
        dofs = dolfinx.fem.locate_dofs_topological((self.W.sub(0), self.V), fdim,
                                                   self._facets(tags))
        return dolfinx.fem.dirichletbc(value, dofs, self.W.sub(0))

    def _residual(self, body_force: BodyForce | None) -> ufl.Form:
        mesh, cfg = self.mesh, self.config
        metadata = {"quadrature_degree": cfg.quadrature_degree}
        dx = ufl.Measure("dx", domain=mesh, metadata=metadata)
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=self.facet_tags, metadata=metadata)
        x, n, h = ufl.SpatialCoordinate(mesh), ufl.FacetNormal(mesh), ufl.CellDiameter(mesh)
        u, p = ufl.split(self.U)
        v, q = ufl.TestFunctions(self.W)
        rho, w = self._rho, self.ale.w
        mu = self.law.mu(rheology.shear_rate(u))
        D = rheology.strain_rate
        sigma = -p * ufl.Identity(len(u)) + 2 * mu * D(u)
        a0, a1, a2 = self._a
        dudt = a0 * u + a1 * self.u_n + a2 * self.u_nm1

        F = (rho * ufl.dot(dudt, v) + rho * ufl.dot(ufl.grad(u) * (u - w), v)
             + 2 * mu * ufl.inner(D(u), D(v)) - p * ufl.div(v) - q * ufl.div(u)) * dx
        if body_force is not None:
            F -= ufl.dot(body_force(x, self.t), v) * dx
        if cfg.supg:
            F += self._supg(u, p, v, mu, dudt, h, body_force, x) * dx

        def ds_of(tags):
            return sum((ds(t) for t in tags[1:]), ds(tags[0]))

        def open_boundary(pressure, tags):
            # −∫ σn·v with σn = −P n (+ μ ∇uᵀn in the do-nothing form μ∇u n − p n = −P n)
            terms = [] if pressure is None else [pressure * ufl.dot(n, v) * ds_of(tags)]
            if cfg.open_boundary == "do_nothing":
                terms.append(-mu * ufl.dot(ufl.grad(u).T * n, v) * ds_of(tags))
            return terms

        def inflow_energy_balance(beta, tags):
            # −β/2 ρ min(u·n, 0) u·v on an open boundary: balances the kinetic energy that
            # inflow (u·n < 0) carries into the domain (Bazilevs et al. 2009); 0 for β = 0.
            return -(beta / 2 * rho * ufl.min_value(ufl.dot(u, n), 0.0) * ufl.dot(u, v)
                     * ds_of(tags))

        zero = dolfinx.fem.Function(self.V)
        for bc in self.boundaries:
            if isinstance(bc, NoSlip):
                continue  # applied last, below, so that walls win at shared corners
            if isinstance(bc, Velocity):
                self._bcs.append(self._dirichlet(self.boundary_velocity, bc.tags))
            elif isinstance(bc, Inflow) and isinstance(bc.spec, config.ParabolicInflow):
                self._bcs.append(self._parabolic_inflow(bc))
            elif isinstance(bc, Inflow):
                pressure = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
                law = inlet_pressure(bc.spec)
                self._updates.append(lambda t, c=pressure, law=law: c.value.fill(law(t)))
                for term in open_boundary(pressure, bc.tags):
                    F += term
                F += inflow_energy_balance(bc.inflow_stabilization, bc.tags)
                if cfg.normal_flow:  # first, so that walls and the interface win at corners
                    self._bcs.insert(0, self._normal_flow(bc.tags))
            elif isinstance(bc, Outflow):
                for term in open_boundary(None, bc.tags):
                    F += term
                F += inflow_energy_balance(bc.backflow_stabilization, bc.tags)
            elif isinstance(bc, Slip):
                sigma_v = -q * ufl.Identity(len(u)) + 2 * mu * D(v)
                un, vn = ufl.dot(u, n), ufl.dot(v, n)
                F += (-ufl.dot(n, sigma * n) * vn - ufl.dot(n, sigma_v * n) * un
                      + NITSCHE_PENALTY * mu / h * un * vn) * ds_of(bc.tags)
                if bc.traction is not None:
                    g = bc.traction(x, n, self.t)
                    F -= ufl.dot(g - ufl.dot(g, n) * n, v) * ds_of(bc.tags)
            elif isinstance(bc, Traction):
                F -= ufl.dot(bc.traction(x, n, self.t), v) * ds_of(bc.tags)
            else:
                raise TypeError(f"unknown boundary condition {bc!r}")
        for bc in self.boundaries:
            if isinstance(bc, NoSlip):
                self._bcs.append(self._dirichlet(zero, bc.tags))
        return F

    def _supg(self, u, p, v, mu, dudt, h, body_force, x):
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
        rho, w = self._rho, self.ale.w
        a = u - w
        residual = (rho * dudt + rho * ufl.grad(u) * a + ufl.grad(p)
                    - ufl.div(2 * mu * rheology.strain_rate(u)))
        if body_force is not None:
            residual -= body_force(x, self.t)
        a_n = self.u_n - w
        mu_n = self.law.mu(rheology.shear_rate(self.u_n))
        speed = ufl.sqrt(ufl.dot(a_n, a_n))
        tau = ((2 * self._a[0]) ** 2 + (2 * speed / h) ** 2
               + (4 * mu_n / (rho * h**2)) ** 2) ** -0.5
        return tau * ufl.dot(ufl.grad(v) * a, residual)

    def _boundary_points(self, tags: Sequence[int]) -> np.ndarray:
        """The (x, y) of the vertices of the facets ``tags``, gathered from every rank (the
        same array on each; vertices shared by facets repeat). Collective."""
        nodes = compat.entities_to_geometry(self.mesh, self.mesh.topology.dim - 1,
                                            self._facets(tags)).ravel()
        return np.concatenate(self.comm.allgather(self.mesh.geometry.x[nodes, :2]))

    def _normal_flow(self, tags: Sequence[int]):
        """u·t = 0 on the open boundary ``tags``, which must be a straight segment parallel to a
        coordinate axis (every inlet and outlet of the shipped geometries): the velocity
        component along it is 0, the normal one stays free."""
        points = self._boundary_points(tags)
        extent = points.max(axis=0) - points.min(axis=0)
        normal_axis = int(np.argmin(extent))
        if extent[normal_axis] > 1e-9 * extent.max():
            raise ValueError(f"fluid.normal_flow needs straight open boundaries parallel to an "
                             f"axis; boundary {list(tags)} spans {extent[0]:g} x {extent[1]:g} m")
        component = self.W.sub(0).sub(1 - normal_axis)
        dofs = dolfinx.fem.locate_dofs_topological(component, self.mesh.topology.dim - 1,
                                                   self._facets(tags))
        zero = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        return dolfinx.fem.dirichletbc(zero, dofs, component)

    def _parabolic_inflow(self, bc: Inflow):
        """u = ramp(t) 1.5 Ū 4 s (H − s)/H² (−n) on a straight inlet of width H."""
        spec: config.ParabolicInflow = bc.spec
        gathered = self._boundary_points(bc.tags)
        # The inlet's end points: the pair of its vertices farthest apart.
        ends = gathered[[np.argmin(gathered @ d) for d in ((1, 0), (0, 1))]
                        + [np.argmax(gathered @ d) for d in ((1, 0), (0, 1))]]
        i, j = np.unravel_index(np.argmax(np.linalg.norm(ends[:, None] - ends[None], axis=2)),
                                (4, 4))
        start, tangent = ends[i], ends[j] - ends[i]
        width = np.linalg.norm(tangent)
        tangent = tangent / width
        normal = np.array([tangent[1], -tangent[0]])
        centre = self.comm.allreduce(self.mesh.geometry.x[:, :2].sum(axis=0))
        centre /= self.comm.allreduce(len(self.mesh.geometry.x))
        if normal @ (centre - start) < 0:
            normal = -normal  # inward
        peak = 1.5 * spec.mean_velocity

        def profile(xx):
            s = np.clip((xx[:2].T - start) @ tangent, 0, width)
            values = peak * 4 * s * (width - s) / width**2
            return np.outer(normal, values)

        shape = dolfinx.fem.Function(self.V)
        shape.interpolate(profile)
        inflow = dolfinx.fem.Function(self.V, name="inflow")

        ramped = self.scheme != "steady" and spec.ramp_time > 0

        def update(t: float) -> None:  # no reference to self: no cycle for the GC to break
            factor = inflow_ramp(t, spec.ramp_time) if ramped else 1.0
            inflow.x.array[:] = factor * shape.x.array

        self._updates.append(update)
        return self._dirichlet(inflow, bc.tags)

    def _newton(self) -> dolfinx.nls.petsc.NewtonSolver:
        settings = self.config.solver
        newton = dolfinx.nls.petsc.NewtonSolver(self.comm, self.problem)
        newton.convergence_criterion = "residual"
        newton.rtol, newton.atol = settings.rtol, settings.atol
        newton.max_it = settings.max_iterations
        newton.error_on_nonconvergence = False
        ksp = newton.krylov_solver
        ksp.setOptionsPrefix("fluid_")
        options = PETSc.Options("fluid_")
        for key, value in settings.petsc_options.items():
            options[key] = value
        ksp.setFromOptions()
        newton.A.setOptionsPrefix("fluid_")
        # Residual and Jacobian through one object: Jacobian (and LU) reuse, counters.
        self.newton_callbacks = NewtonCallbacks(self.problem, newton, settings.jacobian_reuse,
                                                settings.jacobian_reuse_rate)
        return newton

    # ---- the coupler's interface

    def set_mesh_displacement(self, d: dolfinx.fem.Function,
                              w: dolfinx.fem.Function | None = None) -> None:
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
            self.u_n.x.array[:] = self.u.x.array
            self.u_nm1.x.array[:] = self.u.x.array
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

    def step(self, t: float, dt: float) -> StepResult:
        """Solve for (u, p) at time ``t`` = t_n + dt on the current mesh. On failure (Newton not
        converged, PETSc error, non-finite values) the solution is reset to its value before the
        step and the result says why; nothing non-finite is left behind."""
        weights = self.time_weights(dt)
        self._dt = dt
        for c, a in zip(self._a, weights):
            c.value = a
        self.t.value = t
        for update in self._updates:
            update(t)
        if not self._mesh_velocity_given:
            self.ale.set_velocity(weights)
        self.ale.w.x.scatter_forward()
        before = self.U.x.array.copy()
        message = ""
        try:
            iterations, converged = self.newton_callbacks.solve(self.newton, self.U,
                                                                  step=self.accepted_steps)
        except RuntimeError as e:  # PETSc errors surface here
            iterations, converged, message = self.newton.max_it, False, f"PETSc: {e}"
        residual = self.newton.b.norm()
        finite = bool(self.comm.allreduce(np.isfinite(self.U.x.array).all()
                                          and np.isfinite(residual), op=MPI.LAND))
        if not finite:
            converged = False
            message = message or "non-finite residual or solution"
        elif not converged and not message:
            message = (f"Newton did not converge in {iterations} iterations (residual"
                       f" {residual:.3e}, atol {self.newton.atol:g}, rtol {self.newton.rtol:g})")
        if not converged:
            self.U.x.array[:] = before
            self.U.x.scatter_forward()
            message = f"fluid step to t = {t:g} s (dt = {dt:g} s): {message}"
            log.warning(message)
        self._sync_outputs()
        return StepResult(int(iterations), float(residual), bool(converged), message)

    def advance(self) -> None:
        """Accept the last step: shift u^n → u^{n−1}, u → u^n and the displacement history."""
        self.u_nm1.x.array[:] = self.u_n.x.array
        self.u_n.x.array[:] = self.u.x.array  # u is U's velocity after every step/restore
        self.ale.advance()
        self.dt_previous = self._dt
        self.time = float(self.t.value)
        self.accepted_steps += 1
        self._mesh_velocity_given = False

    def save_state(self) -> FluidState:
        """Snapshot of the solution, the time history and the mesh (also kept for
        :meth:`restore_state`)."""
        self._saved = FluidState(
            self.time, self.dt_previous, self.accepted_steps, self.U.x.array.copy(),
            self.u_n.x.array.copy(), self.u_nm1.x.array.copy(), self.ale.d.x.array.copy(),
            self.ale.d_n.copy(), self.ale.d_nm1.copy(), self.ale.w.x.array.copy(),
            self._mesh_velocity_given)
        return self._saved

    def restore_state(self, state: FluidState | None = None) -> None:
        """Return to ``state`` (default: the last :meth:`save_state`), mesh position included."""
        s = state or self._saved
        if s is None:
            raise RuntimeError("restore_state before any save_state")
        self.time, self.dt_previous, self.accepted_steps = s.time, s.dt_previous, s.accepted_steps
        self.U.x.array[:] = s.U
        self.u_n.x.array[:] = s.u_n
        self.u_nm1.x.array[:] = s.u_nm1
        self.ale.d.x.array[:] = s.d
        self.ale.d_n[:] = s.d_n
        self.ale.d_nm1[:] = s.d_nm1
        self.ale.w.x.array[:] = s.w
        self._mesh_velocity_given = s.mesh_velocity_given
        self.ale.move()
        self._sync_outputs()

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
        nodes = dolfinx.fem.locate_dofs_topological(self.V, fdim, self._facets(tags))
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
        ds = ufl.Measure("ds", domain=self.mesh, subdomain_data=self.facet_tags,
                         metadata={"quadrature_degree": 2})
        v = ufl.TestFunction(self.V)
        one = ufl.as_vector([1.0] * self.mesh.geometry.dim)
        mass = dolfinx.fem.petsc.assemble_vector(dolfinx.fem.form(
            sum((ufl.dot(one, v) * ds(t) for t in tags[1:]), ufl.dot(one, v) * ds(tags[0]))))
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
