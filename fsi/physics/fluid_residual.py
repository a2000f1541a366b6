"""The fluid's residual F((u, p); (v, q)) as a sum of named terms (docs/model.md, Fluid).

:class:`FluidResidual` builds, on the current configuration,

    ρ (Σ_k a_k u^{n+1−k}, v) + ρ (((u − w)·∇)u, v) + (2 μ D(u), D(v)) − (p, ∇·v) − (q, ∇·u)
        − (f, v) − ⟨σ n, v⟩_natural [+ SUPG (+ PSPG, LSIC for P1–P1)] = 0,

one method per term, in plane or axisymmetric coordinates (fsi/physics/coordinates.py: there
the integrals carry 2π r, and D, ∇· and the shear rate the hoop part u_r/r), and turns each
boundary condition (fsi/physics/fluid_boundaries.py) into its Dirichlet conditions and boundary
terms. :class:`LumpedOutlet` is an outlet whose pressure
comes from its flow rate through a lumped model (fsi/physics/outlets.py).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import ufl

from fsi import compat, config
from fsi.config.rheology_section import womersley_viscosity
from fsi.physics import outlets, rheology
from fsi.physics.coordinates import Coordinates
from fsi.physics.fluid_boundaries import (
    Axis,
    BoundaryCondition,
    Inflow,
    NoSlip,
    Outflow,
    PrescribedTraction,
    PrescribedVelocity,
    Slip,
    Traction,
    Velocity,
    boundary_points,
    facets_of,
    flow_rate_values,
    inflow_ramp,
    inlet_frame,
    inlet_pressure,
    parabolic_values,
)

BACKFLOW_LENGTH = 0.5
"""ℓ/h of the ``tangential`` backflow term's regularization ℓ² ∇_Γu : ∇_Γv (h the cell
diameter). Measured (docs/boundary-conditions.md): ℓ = h/2 keeps the rigid stenosis at a
0.8 m/s inflow stable (as ℓ = h and h/4 do; ℓ = 0 fails at t = 0.07 s) and moves the plane
Womersley flow's peak velocity by 0.4 % (0.25 mm cells; the distortion ∝ ℓ²)."""

VISCOUS_CONSTANT = {"p2p1": 96.0, "p1p1": 4.0}
"""C in the viscous limit τ = ρ h²/(C μ) of the stabilization parameter, per ``fluid.element``.
Tezduyar & Osawa's 4 is made for linear elements, whose strong viscous term vanishes (P1–P1
keeps it). With P2 velocities the term τ ((u − w)·∇)v · ∇·(2 μ D(u)) stays, and it
destabilizes unless τ is small enough where the flow is viscous (the inverse estimate of P2:
‖Δv‖ ≲ C_I h⁻¹ ‖∇v‖). Measured on the Carreau channel at 300 Pa/m (μ up to 0.056 Pa s near
the centreline; docs/boundary-conditions.md): C = 4 fails at t = 0.68 s, 16 at 1.1 s, 48
runs; 96 is twice the smallest that runs."""

SUPG_SPEED_FLOOR = 1e-12
"""(m/s) inside τ's |u − w| = sqrt(|u − w|² + floor²): keeps its derivative finite at rest, where
a steady solve differentiates τ. Far below any speed of interest."""

BodyForce = Callable[[ufl.core.expr.Expr, dolfinx.fem.Constant], ufl.core.expr.Expr]
"""``f(x, t)``: a UFL vector (N/m³) of the spatial coordinate and the time."""

NITSCHE_PENALTY = 100.0
"""γ of the Nitsche term γ μ/h (u·n)(v·n) on slip walls; ≳ 10 (k + 1)² for P2 keeps it coercive."""


# --------------------------------------------------------------------------------------------
# Lumped outlets: a pressure from the outlet's flow rate (fsi/physics/outlets.py)


class LumpedOutlet:
    """An :class:`Outflow` whose pressure P comes from a lumped model (resistance, RCR
    Windkessel): σ n = −P n with, within a step, P = P₀' + R' Q (the model's
    :meth:`~fsi.physics.outlets.OutletModel.pressure_law`) and Q = ∫_Γ u·n ds the step's own flow
    rate.

    Q is linear in the unknowns, Q = b · U with b_i = ∫_Γ φ_i·n ds, so the residual's term
    ∫_Γ P n·v ds has the Jacobian R' b bᵀ: the solver's nonlinear problem (fsi/physics/fluid.py)
    sets P from each Newton iterate (:meth:`update`) and adds that rank-one block, dense among
    the outlet's dofs, to each Jacobian (:meth:`add_to_jacobian`). Newton stays Newton, and
    P = P₀' + R' Q holds at the converged solution to the solver's tolerance, however large R'
    is. The model's state (the Windkessel's P_c^n, P_c^{n−1}) advances with the accepted step's
    Q (:meth:`advance`).
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


# --------------------------------------------------------------------------------------------
# The pieces of the residual


@dataclass(frozen=True)
class _WeakForm:
    """The symbols the residual's terms share: the unknowns (u, p) = split(U), the velocity
    that advects and sets the viscosity (``advecting``: u itself, or with
    ``fluid.solver.linearization: extrapolated`` the extrapolation u* of the accepted steps,
    which makes the residual linear in (u, p)), the test functions (v, q), the viscosity
    μ(s(advecting)), the BDF derivative ∂u/∂t, the measures (with the configured quadrature
    degree, weighted by 2π r when axisymmetric), the coordinate x, the outward normal n, the
    cell diameter h, and the coordinate system (``coords``: the hoop parts of D and ∇·)."""

    u: ufl.core.expr.Expr
    advecting: ufl.core.expr.Expr
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
    coords: Coordinates

    def ds_of(self, tags: Sequence[int]) -> ufl.Measure:
        """The boundary measure over the facets of ``tags``."""
        return sum((self.ds(t) for t in tags[1:]), self.ds(tags[0]))


class StepCoefficient:
    """An expression that does not change during a step's solve (it reads the step's constants,
    u^n, u^{n−1}, the mesh and its velocity, not the unknown), held as a Function of its values
    at the quadrature points of ``dx`` (quadrature ``degree``): the form reads the values
    instead of evaluating the expression at every assembly, and :meth:`evaluate` sets them once
    the step's mesh and mesh velocity are (the solver calls it before each solve). For SUPG's τ,
    whose square root and powers were ~30 % of the residual's and the Jacobian's assembly
    (docs/performance.md); the form is the expression's to round-off (tests/test_fluid.py)."""

    def __init__(self, mesh: dolfinx.mesh.Mesh, value: ufl.core.expr.Expr, degree: int):
        space, points = compat.quadrature_space(mesh, degree)
        self.mesh, self.value = mesh, value
        self.function = dolfinx.fem.Function(space)
        self._expression = dolfinx.fem.Expression(value, points)
        index_map = mesh.topology.index_map(mesh.topology.dim)
        self._cells = np.arange(index_map.size_local + index_map.num_ghosts, dtype=np.int32)
        self._dofs = compat.cell_dofs(space)[self._cells]

    def evaluate(self) -> None:
        """Set the values from the expression (every local cell, ghosts too: no scatter)."""
        values = compat.eval_expression(self._expression, self.mesh, self._cells)
        self.function.x.array[self._dofs] = values


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
# The residual


class FluidUnknowns(Protocol):
    """What the residual reads from its solver (fsi.physics.fluid.FluidSolver): the mesh, its
    facet tags and communicator, the fluid's settings, time scheme, viscosity law and boundary
    conditions, the mixed space W with its velocity space V, the unknown U = (u, p), u^n and
    u^{n−1}, the boundary and ALE mesh velocities, the coordinate system (plane or
    axisymmetric), and the constants t, ρ, the BDF weights and the weights (e1, e2) of the
    extrapolation u* = e1 u^n + e2 u^{n−1}."""

    mesh: dolfinx.mesh.Mesh
    facet_tags: dolfinx.mesh.MeshTags
    comm: Any
    config: config.Fluid
    scheme: str
    law: rheology.ViscosityLaw
    boundaries: Sequence[BoundaryCondition]
    W: dolfinx.fem.FunctionSpace
    V: dolfinx.fem.FunctionSpace
    U: dolfinx.fem.Function
    u_n: dolfinx.fem.Function
    u_nm1: dolfinx.fem.Function
    boundary_velocity: dolfinx.fem.Function
    ale: Any
    coordinates: Coordinates
    t: dolfinx.fem.Constant
    rho: dolfinx.fem.Constant
    bdf_weights: Sequence[dolfinx.fem.Constant]
    extrapolation_weights: Sequence[dolfinx.fem.Constant]


class FluidResidual:
    """The residual F((u, p); (v, q)) of a fluid solver (:class:`FluidUnknowns`), the module
    docstring's weak form as a sum of named terms (:meth:`_residual`), and what the boundary
    conditions add: Dirichlet conditions (:attr:`bcs`), time-dependent boundary data
    (:attr:`updates`, each called with the time of a step before it is solved) and lumped outlets
    (:attr:`lumped`).

    It uses the solver's spaces, functions and constants (the unknown U, u^n, u^{n−1}, the
    boundary and mesh velocities, the BDF weights a_k, ρ and t), and is not kept after the
    solver has taken :attr:`form` and the three lists."""

    def __init__(self, solver: FluidUnknowns, body_force: BodyForce | None):
        s = solver
        self.mesh, self.facet_tags, self.comm = s.mesh, s.facet_tags, s.comm
        self.config, self.scheme, self.law = s.config, s.scheme, s.law
        self.boundaries = s.boundaries
        self.W, self.V, self.U, self.u_n, self.u_nm1 = s.W, s.V, s.U, s.u_n, s.u_nm1
        self.boundary_velocity, self.ale = s.boundary_velocity, s.ale
        self.coordinates = s.coordinates
        self.t, self._a, self._rho = s.t, s.bdf_weights, s.rho  # the solver's constants
        self._extrapolation = s.extrapolation_weights
        self.bcs: list = []
        self.updates: list[Callable[[float], None]] = []
        self.step_coefficients: list[StepCoefficient] = []
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
            + stabilization + the boundary terms of each condition (:attr:`BOUNDARY_KINDS`),

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
            F += self._stabilization(s, body_force) * s.dx
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
        if cfg.solver.linearization == "extrapolated":
            e1, e2 = self._extrapolation
            advecting = e1 * self.u_n + e2 * self.u_nm1
        else:
            advecting = u
        coords = self.coordinates
        return _WeakForm(
            u=u,
            advecting=advecting,
            p=p,
            v=v,
            q=q,
            mu=self.law.mu(rheology.shear_rate_of(coords.strain_rate(advecting))),
            dudt=a0 * u + a1 * self.u_n + a2 * self.u_nm1,
            dx=coords.measure(ufl.Measure("dx", domain=mesh, metadata=metadata)),
            ds=coords.measure(
                ufl.Measure("ds", domain=mesh, subdomain_data=self.facet_tags, metadata=metadata)
            ),
            x=ufl.SpatialCoordinate(mesh),
            n=ufl.FacetNormal(mesh),
            h=ufl.CellDiameter(mesh),
            coords=coords,
        )

    def _inertia(self, s: _WeakForm):
        """ρ (Σ_k a_k u^{n+1−k}) · v: the BDF derivative at fixed reference position X."""
        return self._rho * ufl.dot(s.dudt, s.v)

    def _convection(self, s: _WeakForm):
        """ρ ((a − w)·∇)u · v: convection relative to the mesh velocity w (ALE) by the
        advecting velocity a (u, or its extrapolation u*: :class:`_WeakForm`)."""
        return self._rho * ufl.dot(ufl.grad(s.u) * (s.advecting - self.ale.w), s.v)

    def _viscous_stress(self, s: _WeakForm):
        """2 μ(s(u)) D(u) : D(v), the viscous part of σ(u, p) : ∇v (rheology.cauchy_stress)."""
        D = s.coords.strain_rate
        return 2 * s.mu * ufl.inner(D(s.u), D(s.v))

    def _pressure(self, s: _WeakForm):
        """p ∇·v, the pressure part of σ(u, p) : ∇v (subtracted)."""
        return s.p * s.coords.div(s.v)

    def _continuity(self, s: _WeakForm):
        """q ∇·u (subtracted: the symmetric saddle-point form)."""
        return s.q * s.coords.div(s.u)

    def _body_force(self, s: _WeakForm, body_force: BodyForce):
        """f(x, t) · v (subtracted)."""
        return ufl.dot(body_force(s.x, self.t), s.v)

    # ---- boundary terms: one function per kind of condition (BOUNDARY_KINDS)

    def _axis(self, bc: Axis, s: _WeakForm) -> _Contribution:
        """u_r = 0 on the axis (or the plane symmetry line): the radial component alone; the
        axial one is free, its traction 0 (the symmetry)."""
        component = self.W.sub(0).sub(1)
        dofs = dolfinx.fem.locate_dofs_topological(
            component, self.mesh.topology.dim - 1, facets_of(self.facet_tags, bc.tags)
        )
        zero = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        return _Contribution(
            dirichlet=[(_PRESCRIBED, dolfinx.fem.dirichletbc(zero, dofs, component))]
        )

    def _prescribed_velocity(self, bc: PrescribedVelocity, s: _WeakForm) -> _Contribution:
        """u = value(x, t), interpolated at the time of each step before it is solved."""
        given = dolfinx.fem.Function(self.V, name="prescribed_velocity")

        def update(t: float, value=bc.value) -> None:
            given.interpolate(lambda x: value(x, t))

        self.updates.append(update)
        return _Contribution(dirichlet=[(_PRESCRIBED, self._dirichlet(given, bc.tags))])

    def _prescribed_traction(self, bc: PrescribedTraction, s: _WeakForm) -> _Contribution:
        """σ n = value(x, t), interpolated at the time of each step: −∫ g · v."""
        given = dolfinx.fem.Function(self.V, name="prescribed_traction")

        def update(t: float, value=bc.value) -> None:
            given.interpolate(lambda x: value(x, t))

        self.updates.append(update)
        return _Contribution([-(ufl.dot(given, s.v) * s.ds_of(bc.tags))])

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
        """A velocity inlet (Dirichlet: parabolic, flow rate), or a traction inlet: σ n = −P(t) n
        as an open boundary (:meth:`_open_boundary`), its backflow term (:meth:`_backflow`), and
        u·t = 0 with ``normal_flow`` (first, so that walls and the interface win at the
        corners)."""
        if isinstance(bc.spec, (config.ParabolicInflow, *config.FLOW_RATE_INLETS)):
            return _Contribution(dirichlet=[(_PRESCRIBED, self._velocity_inflow(bc))])
        pressure = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        law = inlet_pressure(bc.spec)
        self.updates.append(lambda t, c=pressure, law=law: c.value.fill(law(t)))
        terms = [
            *self._open_boundary(s, pressure, bc.tags, self._inlet_form()),
            self._backflow(s, bc.inflow_stabilization, bc.inflow_form, bc.tags),
        ]
        dirichlet = (
            [(_NORMAL_FLOW, bc_) for bc_ in self._normal_flow(bc.tags)]
            if self.config.normal_flow
            else []
        )
        return _Contribution(terms, dirichlet)

    def _outflow(self, bc: Outflow, s: _WeakForm) -> _Contribution:
        """An outlet σ n = −P n (in the configured open-boundary form; P = 0 traction-free, or
        a lumped model's pressure, :class:`LumpedOutlet`) with the backflow term
        (:meth:`_backflow`)."""
        pressure = None
        if bc.model is not None:
            outlet = LumpedOutlet(bc.model, bc.tags, self.W, s.ds_of(bc.tags), s.n)
            self.lumped.append(outlet)
            pressure = outlet.pressure
        return _Contribution(
            [
                *self._open_boundary(s, pressure, bc.tags, self.config.open_boundary),
                self._backflow(s, bc.backflow_stabilization, bc.backflow_form, bc.tags),
            ]
        )

    def _slip(self, bc: Slip, s: _WeakForm) -> _Contribution:
        """u·n = 0 by Nitsche's method (consistency, symmetry and penalty γ μ/h terms) and the
        tangential part of the prescribed traction g."""
        u, v, n = s.u, s.v, s.n
        sigma = -s.p * ufl.Identity(len(u)) + 2 * s.mu * rheology.strain_rate(u)
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
        Axis: _axis,
        NoSlip: _no_slip,
        Velocity: _velocity,
        Inflow: _inflow,
        Outflow: _outflow,
        Slip: _slip,
        Traction: _traction,
        PrescribedVelocity: _prescribed_velocity,
        PrescribedTraction: _prescribed_traction,
    }
    """The function that turns each kind of boundary condition into its residual terms and
    Dirichlet conditions."""

    def _inlet_form(self) -> str:
        """The traction inlet's open-boundary form: ``inlet_open_boundary``, unless ``same``."""
        form = self.config.inlet_open_boundary
        return self.config.open_boundary if form == "same" else form

    def _open_boundary(self, s: _WeakForm, pressure, tags: Sequence[int], form: str) -> list:
        """−∫ σn·v with σn = −P n (P = 0 if ``pressure`` is None), plus −∫ μ (∇u)ᵀn·v in the
        do-nothing form μ∇u n − p n = −P n."""
        terms = [] if pressure is None else [pressure * ufl.dot(s.n, s.v) * s.ds_of(tags)]
        if form == "do_nothing":
            terms.append(-s.mu * ufl.dot(ufl.grad(s.u).T * s.n, s.v) * s.ds_of(tags))
        return terms

    def _backflow(self, s: _WeakForm, beta: float, form: str, tags: Sequence[int]):
        """An open boundary's backflow term, nonzero only where blood enters (u·n < 0):

        ``full``: −β/2 ρ min(u·n, 0) u·v (Bazilevs et al. 2009), which balances all the kinetic
        energy ½ ρ |u|² |u·n| the inflow carries in, but also lowers the pressure of the inflow
        by β ρ (u·n)²/2: a full reversal meets a total-pressure outlet;

        ``tangential``: −β/2 ρ min(u·n, 0) (u_t·v_t + ℓ² ∇_Γu : ∇_Γv) with u_t = u − (u·n) n,
        ∇_Γ = ∇(I − n⊗n) the derivative along the outlet and ℓ = :data:`BACKFLOW_LENGTH` h:
        it balances the energy of the tangential inflow and of the velocity's variation along
        the outlet on the scale of the mesh (the modes that grow; a tangential regularization in
        the spirit of Bertoglio & Caiazzo 2014), and leaves a plug-like normal inflow alone, so
        a reversing flow keeps the prescribed traction (docs/boundary-conditions.md);

        ``tangential_velocity``: −β/2 ρ min(u·n, 0) u_t·v_t, the tangential part alone (a traction
        inlet's: a normal inflow of any profile keeps the prescribed traction)."""
        along = ufl.Identity(len(s.u)) - ufl.outer(s.n, s.n)
        if form == "full":
            damped = ufl.dot(s.u, s.v)
        else:
            damped = ufl.dot(along * s.u, along * s.v)
        if form == "tangential":
            ell = BACKFLOW_LENGTH * s.h
            damped += ell**2 * ufl.inner(ufl.grad(s.u) * along, ufl.grad(s.v) * along)
        inflow = ufl.min_value(ufl.dot(s.advecting, s.n), 0.0)
        return -(beta / 2 * self._rho * inflow * damped * s.ds_of(tags))

    def _stabilization(self, s: _WeakForm, body_force: BodyForce | None):
        """The residual-based stabilization: SUPG (:meth:`_supg`) and, for equal-order P1–P1,
        PSPG and LSIC (:meth:`_pspg`, :meth:`_lsic`), with the strong momentum residual

            R = ρ (∂u/∂t + ((u − w)·∇)u) + ∇p − ∇·(2 μ(s) D(u)) − f

        (zero for the exact solution: the terms are consistent) and one parameter
        τ = ((2 a₀)² + (2|u − w|/h)² + (C μ/(ρ h²))²)^(−1/2) (Tezduyar & Osawa 2000; a₀ the BDF
        weight of u^{n+1}, 1/Δt for backward Euler, 0 when steady; C the element's
        :data:`VISCOUS_CONSTANT`). τ takes u and μ(s(u)) of the last accepted step, so that it
        is a coefficient of the step, not a function of its unknown; a steady solve has no last
        step and takes them from its unknown (Newton differentiates), the extrapolated
        linearization from u*; fixed during a solve, it is held at the quadrature points
        (:class:`StepCoefficient`) except when steady; R is the step's own (advected by u*,
        with μ(s(u*)), when extrapolated)."""
        rho, w, u, h = self._rho, self.ale.w, s.u, s.h
        residual = (
            rho * s.dudt
            + rho * ufl.grad(u) * (s.advecting - w)
            + ufl.grad(s.p)
            - s.coords.div_symmetric(2 * s.mu * rheology.strain_rate(u), hoop=self._hoop(s))
        )
        if body_force is not None:
            residual -= body_force(s.x, self.t)
        if self.scheme == "steady" or self.config.solver.linearization == "extrapolated":
            u_tau, mu_tau = s.advecting, s.mu
        else:
            shear_n = rheology.shear_rate_of(s.coords.strain_rate(self.u_n))
            u_tau, mu_tau = self.u_n, self.law.mu(shear_n)
        a_tau = u_tau - w
        speed = ufl.sqrt(ufl.dot(a_tau, a_tau) + SUPG_SPEED_FLOOR**2)
        viscous = VISCOUS_CONSTANT[self.config.element]
        tau = (
            (2 * self._a[0]) ** 2 + (2 * speed / h) ** 2 + (viscous * mu_tau / (rho * h**2)) ** 2
        ) ** -0.5
        if self.scheme != "steady":
            tau = self._step_coefficient(tau)
        terms = self._supg(s, tau, residual)
        if self.config.element == "p1p1":
            terms = terms - self._pspg(s, tau, residual) + self._lsic(s, tau)
        return terms

    def _step_coefficient(self, value) -> dolfinx.fem.Function:
        """``value`` held at the quadrature points of ``dx`` (:class:`StepCoefficient`, added to
        :attr:`step_coefficients`)."""
        held = StepCoefficient(self.mesh, value, self.config.quadrature_degree)
        self.step_coefficients.append(held)
        return held.function

    @staticmethod
    def _hoop(s: _WeakForm):
        """The hoop viscous stress 2 μ u_r/r (axisymmetric; None in the plane)."""
        return 2 * s.mu * s.u[1] / s.coords.r if s.coords.axisymmetric else None

    def _supg(self, s: _WeakForm, tau, residual):
        """SUPG: τ ((u − w)·∇)v · R. It adds the streamline diffusion ≈ ρ|u − w|h/2 that the
        Galerkin form lacks where the cell Reynolds number is large, in particular in the cells
        of an open inlet (docs/boundary-conditions.md). With P2 velocities the strong viscous
        term is exact for Poiseuille flow, which stays a discrete solution."""
        return tau * ufl.dot(ufl.grad(s.v) * (s.advecting - self.ale.w), residual)

    def _pspg(self, s: _WeakForm, tau, residual):
        """PSPG (subtracted, as the continuity term): (τ/ρ) ∇q · R (Hughes, Franca & Balestra
        1986; Tezduyar 1992): a pressure Laplacian −(τ/ρ)(∇q, ∇p) that circumvents the inf-sup
        condition equal-order P1–P1 fails, made consistent by the rest of R."""
        return tau / self._rho * ufl.dot(ufl.grad(s.q), residual)

    def _lsic(self, s: _WeakForm, tau):
        """LSIC: ρ τ_C (∇·u)(∇·v) with τ_C = h²/(4 d τ) (the VMS τ_C = (τ tr G)^(−1) with the
        metric G = 4/h² I of a cell of dimension d: h²/(8 τ) in 2D, h²/(12 τ) in 3D; Bazilevs
        et al. 2007): least squares on the continuity residual, which P1–P1 does not satisfy
        pointwise; zero on a solenoidal velocity."""
        tau_c = s.h**2 / (4 * self.mesh.topology.dim * tau)
        return self._rho * tau_c * s.coords.div(s.u) * s.coords.div(s.v)

    # ---- Dirichlet conditions

    def _normal_flow(self, tags: Sequence[int]) -> list:
        """u·t = 0 on the open boundary ``tags``, which must be a straight segment (a flat
        face in 3D) normal to a coordinate axis (every inlet and outlet of the shipped
        geometries): the velocity components along it are 0, the normal one stays free."""
        points = boundary_points(self.mesh, self.facet_tags, tags, self.comm)
        extent = points.max(axis=0) - points.min(axis=0)
        normal_axis = int(np.argmin(extent))
        if extent[normal_axis] > 1e-9 * extent.max():
            raise ValueError(
                f"fluid.normal_flow needs straight open boundaries parallel to an "
                f"axis; boundary {list(tags)} spans {' x '.join(f'{e:g}' for e in extent)} m"
            )
        facets = facets_of(self.facet_tags, tags)
        zero = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        conditions = []
        for axis in range(len(extent)):
            if axis == normal_axis:
                continue
            component = self.W.sub(0).sub(axis)
            dofs = dolfinx.fem.locate_dofs_topological(
                component, self.mesh.topology.dim - 1, facets
            )
            conditions.append(dolfinx.fem.dirichletbc(zero, dofs, component))
        return conditions

    def _velocity_inflow(self, bc: Inflow):
        """u = ramp(t) g(s, t) (−n) on a straight inlet of width H (s along it, n its outward
        normal): ``parabolic_velocity`` g = 1.5 Ū 4 s (H − s)/H² (a pipe's 2 Ū (1 − r²/R²)
        when axisymmetric), or a flow-rate inlet's
        :class:`~fsi.physics.inflow_profiles.FlowRateProfile`; the ramp (1 − cos(π t/T_r))/2
        for t < T_r (none when steady)."""
        spec = bc.spec
        points = boundary_points(self.mesh, self.facet_tags, bc.tags, self.comm)
        frame = inlet_frame(points, self.mesh, self.comm)
        inflow = dolfinx.fem.Function(self.V, name="inflow")
        # A pipe's profiles across an axisymmetric inlet and a 3D (circular) one.
        axisymmetric = self.coordinates.axisymmetric or self.mesh.geometry.dim == 3
        if isinstance(spec, config.ParabolicInflow):
            values = parabolic_values(self.V, spec, frame, axisymmetric)
        else:
            nodes = dolfinx.fem.locate_dofs_topological(
                self.V, self.mesh.topology.dim - 1, facets_of(self.facet_tags, bc.tags)
            )
            womersley = spec.profile == "womersley"
            viscosity = womersley_viscosity(self.config.rheology) if womersley else None
            degree = 1 if self.config.element == "p1p1" else 2
            values = flow_rate_values(
                self.V, nodes, spec, frame, self.config.density, viscosity, axisymmetric, degree
            )

        ramped = self.scheme != "steady" and spec.ramp_time > 0

        def update(t: float) -> None:  # no reference to self: no cycle for the GC to break
            factor = inflow_ramp(t, spec.ramp_time) if ramped else 1.0
            inflow.x.array[:] = factor * values(t)

        self.updates.append(update)
        return self._dirichlet(inflow, bc.tags)
