"""What each fluid boundary condition adds to the fluid's problem (docs/boundary-conditions.md).

:class:`BoundaryTerms` turns the boundary conditions of fsi/physics/fluid_boundaries.py into
residual terms on the boundary (open boundaries and their backflow terms, Nitsche's slip, given
tractions), Dirichlet conditions (in an order of precedence: walls win at the corners they
share), time-dependent boundary data (``updates``, called with each step's time) and lumped
outlets. :class:`LumpedOutlet` is an outlet whose pressure comes from its flow rate through a
lumped model (fsi/physics/outlets.py). The terms are written with the symbols of the residual's
weak form (:class:`fsi.physics.fluid_residual.WeakForm`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import ufl

from fsi import config
from fsi.config.rheology_section import womersley_viscosity
from fsi.numerics.dense_block import add_dense_block
from fsi.physics import outlets, rheology
from fsi.physics.fluid_boundaries import (
    Axis,
    BoundaryCondition,
    Inflow,
    NoSlip,
    Outflow,
    PrescribedTraction,
    PrescribedVelocity,
    Robin,
    Slip,
    SymmetryPlane,
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
from fsi.physics.fluid_residual import FluidFields, WeakForm
from fsi.physics.mesh import bounding_plane_dofs

BACKFLOW_LENGTH = 0.5
"""ℓ/h of the ``tangential`` backflow term's regularization ℓ² ∇_Γu : ∇_Γv (h the cell
diameter). Measured (docs/boundary-conditions.md): ℓ = h/2 keeps the rigid stenosis at a
0.8 m/s inflow stable (as ℓ = h and h/4 do; ℓ = 0 fails at t = 0.07 s) and moves the plane
Womersley flow's peak velocity by 0.4 % (0.25 mm cells; the distortion ∝ ℓ²)."""


NITSCHE_PENALTY = 100.0
"""γ of the Nitsche term γ μ/h (u·n)(v·n) on slip walls; ≳ 10 (k + 1)² for P2 keeps it coercive."""


# --------------------------------------------------------------------------------------------
# Lumped outlets: a pressure from the outlet's flow rate (fsi/physics/outlets.py)

_OUTLET_NUMBERS = itertools.count()
"""Numbers the lumped outlets: a Jacobian carries each outlet's block under its own name
(``fsi_lumped_outlet_<n>``) once its pattern holds it."""


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
        self._dofs: np.ndarray | None = None  # the block's owned dofs (local), fixed at first use
        self._rows: np.ndarray | None = None  # the same, global
        self._columns: np.ndarray | None = None  # all ranks' block dofs (global)
        self._name = f"fsi_lumped_outlet_{next(_OUTLET_NUMBERS)}"  # marks a matrix holding it

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
        """A += R' b bᵀ, without the Dirichlet rows and columns: a block dense among the
        outlet's dofs, which the form's sparsity pattern does not hold
        (:func:`fsi.numerics.dense_block.add_dense_block`). Collective."""
        rows, row_values, columns, column_values = self._block(bcs)
        values = self._law[1] * np.outer(row_values, column_values)
        add_dense_block(A, rows, columns, values, self._name)

    def _block(self, bcs) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The block's owned rows (global), their b, all ranks' columns (global) and their b.
        The dofs are those where b ≠ 0 at the first call (above 1e-12 of its largest value:
        a P2 vertex function integrates to 0 over a flat facet, up to rounding), kept for
        the run so that the matrix's pattern stays the same as the mesh moves."""
        b = self._b.copy()
        dolfinx.fem.petsc.set_bc(b, bcs, None, 0.0)  # b = 0 at Dirichlet dofs
        owned = b.array.copy()
        start = b.getOwnershipRange()[0]
        b.destroy()
        comm = self._b.getComm().tompi4py()
        if self._dofs is None:
            largest = comm.allreduce(float(np.abs(owned).max(initial=0.0)), op=MPI.MAX)
            self._dofs = np.flatnonzero(np.abs(owned) > 1e-12 * largest)
            self._rows = (self._dofs + start).astype(PETSc.IntType)
            self._columns = np.concatenate(comm.allgather(self._rows)).astype(PETSc.IntType)
        row_values = owned[self._dofs]
        column_values = np.concatenate(comm.allgather(row_values))
        return self._rows, row_values, self._columns, column_values

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
# The Robin–Neumann coupling's interface condition


class RobinInterface:
    """The data of a :class:`Robin` interface: the residual's term α ∫_Γ (u − u_Γ)·v ds
    (:attr:`form`, kept apart from the residual whose −R gives the nodal forces) and the nodal
    forces f_k of the last coupling iteration added to the residual at the interface's velocity
    dofs (:attr:`load`, over the local dofs of W, owned ones only), so that the solution has
    −R = α M_Γ (u − u_Γ) + f_k there (fsi/physics/fluid.py, ``_FluidProblem``). :attr:`area` is
    the interface's measure in the forces' (m² in 3D and as a whole ring when axisymmetric; m per
    metre of depth in the plane)."""

    def __init__(self, fields: FluidFields, s: WeakForm, tags: Sequence[int]):
        mesh = fields.W.mesh
        self.coefficient = dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0))
        one = dolfinx.fem.Constant(mesh, PETSc.ScalarType(1.0))
        local = dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * s.ds_of(tags)))
        self.area = mesh.comm.allreduce(local, op=MPI.SUM)
        wall_velocity = fields.boundary_velocity
        self.form = self.coefficient * ufl.dot(s.u - wall_velocity, s.v) * s.ds_of(tags)
        index_map = fields.W.dofmap.index_map
        self.owned = index_map.size_local * fields.W.dofmap.index_map_bs
        self.load = np.zeros(self.owned)

    def set(self, coefficient: float, forces: np.ndarray, V_to_W: np.ndarray) -> None:
        """α (Pa·s/m) and the nodal forces, (n_owned, gdim) over the owned nodes of the
        velocity space V, whose dofs ``V_to_W`` maps into W (:func:`fsi.compat.subspace_map`)."""
        self.coefficient.value = coefficient
        forces = np.asarray(forces, dtype=float).ravel()
        to_W = V_to_W[: len(forces)]
        owned = (to_W >= 0) & (to_W < self.owned)
        self.load[:] = 0.0
        self.load[to_W[owned]] = forces[owned]

    def add_to(self, b: PETSc.Vec) -> None:
        """The nodal forces into ``b``'s owned entries (ghost contributions not yet summed)."""
        with b.localForm() as local:
            local.array[: self.owned] += self.load


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


def restore_outlet_states(lumped: Sequence[LumpedOutlet], state: np.ndarray) -> None:
    """Set the states of ``lumped`` from their concatenation ``state`` (a checkpoint's)."""
    sizes = [len(outlet.state) for outlet in lumped]
    if len(state) != sum(sizes):
        raise ValueError(
            f"an outlet state of {len(state)} values for lumped outlets of {sum(sizes)}"
        )
    start = 0
    for outlet, size in zip(lumped, sizes, strict=True):
        outlet.state = np.array(state[start : start + size], dtype=float)
        start += size


def outlet_values(lumped: Sequence[LumpedOutlet]) -> dict[str, float]:
    """The lumped outlets' pressures (Pa) for the metrics: ``outlet_pressure`` P, the pressure
    the outlet imposes at the last step's flow rate, and for a Windkessel
    ``windkessel_pressure`` P_c after the last accepted step (names suffixed ``_<tag>`` when
    there are several lumped outlets)."""
    several = len(lumped) > 1
    return {
        name + (f"_{outlet.tags[0]}" if several else ""): value
        for outlet in lumped
        for name, value in outlet.values().items()
    }


# --------------------------------------------------------------------------------------------
# The boundary conditions' terms


class BoundaryTerms:
    """What the boundary conditions ``boundaries`` add to the fluid's problem on the fields
    ``fields``, written with the weak form's symbols ``s``: residual terms (:attr:`terms`, forms
    to add to the residual in this order), Dirichlet conditions (:attr:`bcs`, ordered by
    precedence: later ones win at shared corner dofs), time-dependent boundary data
    (:attr:`updates`, each called with the time of a step before it is solved) and lumped
    outlets (:attr:`lumped`). Raises ValueError when a tag has two conditions or is not on the
    mesh."""

    def __init__(
        self,
        fields: FluidFields,
        s: WeakForm,
        facet_tags: dolfinx.mesh.MeshTags,
        settings: config.Fluid,
        scheme: str,
        boundaries: Sequence[BoundaryCondition],
    ):
        self.fields, self.facet_tags, self.config, self.scheme = (
            fields,
            facet_tags,
            settings,
            scheme,
        )
        self.mesh = fields.W.mesh
        self.comm = self.mesh.comm
        self.axisymmetric = s.coords.axisymmetric
        _check_tags(facet_tags, boundaries, self.comm)
        self.terms: list = []
        self.bcs: list = []
        self.updates: list[Callable[[float], None]] = []
        self.lumped: list[LumpedOutlet] = []
        self.robin: RobinInterface | None = None
        dirichlet = []
        for bc in boundaries:
            kind = self.BOUNDARY_KINDS.get(type(bc))
            if kind is None:
                raise TypeError(f"unknown boundary condition {bc!r}")
            contribution = kind(self, bc, s)
            self.terms += contribution.terms
            dirichlet += contribution.dirichlet
        # A stable sort: normal flow first, then prescribed velocities, walls last.
        self.bcs.extend(bc for _, bc in sorted(dirichlet, key=lambda pair: pair[0]))

    def _dirichlet(self, value: dolfinx.fem.Function, tags: Sequence[int]):
        fdim = self.mesh.topology.dim - 1
        dofs = dolfinx.fem.locate_dofs_topological(
            (self.fields.W.sub(0), self.fields.V), fdim, facets_of(self.facet_tags, tags)
        )
        return dolfinx.fem.dirichletbc(value, dofs, self.fields.W.sub(0))

    # ---- the residual, term by term (the module docstring's weak form)

    # ---- boundary terms: one function per kind of condition (BOUNDARY_KINDS)

    def _axis(self, bc: Axis, s: WeakForm) -> _Contribution:
        """u_r = 0 on the axis (or the plane symmetry line): the radial component alone; the
        axial one is free, its traction 0 (the symmetry)."""
        facets = facets_of(self.facet_tags, bc.tags)
        return _Contribution(dirichlet=[(_PRESCRIBED, self._zero(1, facets=facets))])

    def _symmetry_plane(self, bc: SymmetryPlane, s: WeakForm) -> _Contribution:
        """u_c = 0 on the plane x_c = 0; first, so that walls and the interface win where
        they meet it (their velocities have no normal component there)."""
        return _Contribution(dirichlet=[(_NORMAL_FLOW, self._zero(bc.component))])

    def _zero(self, c: int, facets: np.ndarray | None = None):
        """u_c = 0 on ``facets``, or (None) on the plane x_c = 0, which bounds the fluid."""
        component = self.fields.W.sub(0).sub(c)
        if facets is None:
            dofs = bounding_plane_dofs(self.mesh, component, c)
        else:
            dofs = dolfinx.fem.locate_dofs_topological(
                component, self.mesh.topology.dim - 1, facets
            )
        zero = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        return dolfinx.fem.dirichletbc(zero, dofs, component)

    def _prescribed_velocity(self, bc: PrescribedVelocity, s: WeakForm) -> _Contribution:
        """u = value(x, t), interpolated at the time of each step before it is solved."""
        given = dolfinx.fem.Function(self.fields.V, name="prescribed_velocity")

        def update(t: float, value=bc.value) -> None:
            given.interpolate(lambda x: value(x, t))

        self.updates.append(update)
        return _Contribution(dirichlet=[(_PRESCRIBED, self._dirichlet(given, bc.tags))])

    def _prescribed_traction(self, bc: PrescribedTraction, s: WeakForm) -> _Contribution:
        """σ n = value(x, t), interpolated at the time of each step: −∫ g · v."""
        given = dolfinx.fem.Function(self.fields.V, name="prescribed_traction")

        def update(t: float, value=bc.value) -> None:
            given.interpolate(lambda x: value(x, t))

        self.updates.append(update)
        return _Contribution([-(ufl.dot(given, s.v) * s.ds_of(bc.tags))])

    def _no_slip(self, bc: NoSlip, s: WeakForm) -> _Contribution:
        """u = 0, applied last so that walls win at the corners they share."""
        zero = dolfinx.fem.Function(self.fields.V)
        return _Contribution(dirichlet=[(_WALL, self._dirichlet(zero, bc.tags))])

    def _velocity(self, bc: Velocity, s: WeakForm) -> _Contribution:
        """u = :attr:`boundary_velocity` (the coupler's ∂η/∂t on the interface)."""
        return _Contribution(
            dirichlet=[(_PRESCRIBED, self._dirichlet(self.fields.boundary_velocity, bc.tags))]
        )

    def _robin(self, bc: Robin, s: WeakForm) -> _Contribution:
        """The Robin–Neumann interface (:class:`RobinInterface`, kept apart in :attr:`robin`);
        u = u_Γ where the interface meets another boundary (its corners, as with
        :class:`Velocity`, so that the fixed point is the Dirichlet–Neumann solution)."""
        if self.robin is not None:
            raise ValueError("one Robin interface per fluid")
        self.robin = RobinInterface(self.fields, s, bc.tags)
        corners = _shared_velocity_dofs(self.fields, self.facet_tags, bc.tags)
        condition = dolfinx.fem.dirichletbc(
            self.fields.boundary_velocity, corners, self.fields.W.sub(0)
        )
        return _Contribution(dirichlet=[(_PRESCRIBED, condition)])

    def _inflow(self, bc: Inflow, s: WeakForm) -> _Contribution:
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
            [(_NORMAL_FLOW, bc_) for bc_ in _normal_flow(self.fields, self.facet_tags, bc.tags)]
            if self.config.normal_flow
            else []
        )
        return _Contribution(terms, dirichlet)

    def _outflow(self, bc: Outflow, s: WeakForm) -> _Contribution:
        """An outlet σ n = −P n (in the configured open-boundary form; P = 0 traction-free, or
        a lumped model's pressure, :class:`LumpedOutlet`) with the backflow term
        (:meth:`_backflow`)."""
        pressure = None
        if bc.model is not None:
            outlet = LumpedOutlet(bc.model, bc.tags, self.fields.W, s.ds_of(bc.tags), s.n)
            self.lumped.append(outlet)
            pressure = outlet.pressure
        return _Contribution(
            [
                *self._open_boundary(s, pressure, bc.tags, self.config.open_boundary),
                self._backflow(s, bc.backflow_stabilization, bc.backflow_form, bc.tags),
            ]
        )

    def _slip(self, bc: Slip, s: WeakForm) -> _Contribution:
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
            g = bc.traction(s.x, n, self.fields.t)
            terms.append(-(ufl.dot(g - ufl.dot(g, n) * n, v) * s.ds_of(bc.tags)))
        return _Contribution(terms)

    def _traction(self, bc: Traction, s: WeakForm) -> _Contribution:
        """σ n = g(x, n, t): −∫ g · v."""
        return _Contribution(
            [-(ufl.dot(bc.traction(s.x, s.n, self.fields.t), s.v) * s.ds_of(bc.tags))]
        )

    BOUNDARY_KINDS: dict[type, Callable] = {
        Axis: _axis,
        NoSlip: _no_slip,
        Velocity: _velocity,
        Robin: _robin,
        SymmetryPlane: _symmetry_plane,
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

    def _open_boundary(self, s: WeakForm, pressure, tags: Sequence[int], form: str) -> list:
        """−∫ σn·v with σn = −P n (P = 0 if ``pressure`` is None), plus −∫ μ (∇u)ᵀn·v in the
        do-nothing form μ∇u n − p n = −P n."""
        terms = [] if pressure is None else [pressure * ufl.dot(s.n, s.v) * s.ds_of(tags)]
        if form == "do_nothing":
            terms.append(-s.mu * ufl.dot(ufl.grad(s.u).T * s.n, s.v) * s.ds_of(tags))
        return terms

    def _backflow(self, s: WeakForm, beta: float, form: str, tags: Sequence[int]):
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
        return -(beta / 2 * self.fields.rho * inflow * damped * s.ds_of(tags))

    # ---- Dirichlet conditions

    def _velocity_inflow(self, bc: Inflow):
        """u = ramp(t) g(s, t) (−n) on a straight inlet of width H (s along it, n its outward
        normal): ``parabolic_velocity`` g = 1.5 Ū 4 s (H − s)/H² (a pipe's 2 Ū (1 − r²/R²)
        when axisymmetric), or a flow-rate inlet's
        :class:`~fsi.physics.inflow_profiles.FlowRateProfile`; the ramp (1 − cos(π t/T_r))/2
        for t < T_r (none when steady)."""
        spec = bc.spec
        points = boundary_points(self.mesh, self.facet_tags, bc.tags, self.comm)
        frame = inlet_frame(points, self.mesh, self.comm)
        inflow = dolfinx.fem.Function(self.fields.V, name="inflow")
        # A pipe's profiles across an axisymmetric inlet and a 3D (circular) one.
        axisymmetric = self.axisymmetric or self.mesh.geometry.dim == 3
        if isinstance(spec, config.ParabolicInflow):
            values = parabolic_values(self.fields.V, spec, frame, axisymmetric)
        else:
            nodes = dolfinx.fem.locate_dofs_topological(
                self.fields.V, self.mesh.topology.dim - 1, facets_of(self.facet_tags, bc.tags)
            )
            womersley = spec.profile == "womersley"
            viscosity = womersley_viscosity(self.config.rheology) if womersley else None
            degree = 1 if self.config.element == "p1p1" else 2
            values = flow_rate_values(
                self.fields.V,
                nodes,
                spec,
                frame,
                self.config.density,
                viscosity,
                axisymmetric,
                degree,
            )

        ramped = self.scheme != "steady" and spec.ramp_time > 0

        def update(t: float) -> None:  # no reference to self: no cycle for the GC to break
            factor = inflow_ramp(t, spec.ramp_time) if ramped else 1.0
            inflow.x.array[:] = factor * values(t)

        self.updates.append(update)
        return self._dirichlet(inflow, bc.tags)


def _normal_flow(fields: FluidFields, facet_tags, tags: Sequence[int]) -> list:
    """u·t = 0 on the open boundary ``tags``, which must be a straight segment (a flat
    face in 3D) normal to a coordinate axis (every inlet and outlet of the shipped
    geometries): the velocity components along it are 0, the normal one stays free."""
    points = boundary_points(fields.W.mesh, facet_tags, tags, fields.W.mesh.comm)
    extent = points.max(axis=0) - points.min(axis=0)
    normal_axis = int(np.argmin(extent))
    if extent[normal_axis] > 1e-9 * extent.max():
        raise ValueError(
            f"fluid.normal_flow needs straight open boundaries parallel to an "
            f"axis; boundary {list(tags)} spans {' x '.join(f'{e:g}' for e in extent)} m"
        )
    facets = facets_of(facet_tags, tags)
    zero = dolfinx.fem.Constant(fields.W.mesh, PETSc.ScalarType(0.0))
    conditions = []
    for axis in range(len(extent)):
        if axis == normal_axis:
            continue
        component = fields.W.sub(0).sub(axis)
        dofs = dolfinx.fem.locate_dofs_topological(
            component, fields.W.mesh.topology.dim - 1, facets
        )
        conditions.append(dolfinx.fem.dirichletbc(zero, dofs, component))
    return conditions


def _shared_velocity_dofs(fields: FluidFields, facet_tags, tags: Sequence[int]) -> list:
    """The velocity dofs (W's and V's) of the facets of ``tags`` that other tags' facets share:
    where the boundary ``tags`` meets another."""
    mesh = fields.W.mesh
    spaces, fdim = (fields.W.sub(0), fields.V), mesh.topology.dim - 1
    own = dolfinx.fem.locate_dofs_topological(spaces, fdim, facets_of(facet_tags, tags))
    present = set(np.unique(facet_tags.values).tolist())
    present = set().union(*mesh.comm.allgather(present))
    others = sorted(present - set(tags))
    other = dolfinx.fem.locate_dofs_topological(spaces, fdim, facets_of(facet_tags, others))
    shared = np.isin(own[0], other[0])
    return [own[0][shared], own[1][shared]]


def _check_tags(facet_tags, boundaries: Sequence[BoundaryCondition], comm) -> None:
    """Every tag has one condition and is on the mesh (on some rank)."""
    present = set(np.unique(facet_tags.values).tolist())
    present = set().union(*comm.allgather(present))
    seen: dict[int, str] = {}
    for bc in boundaries:
        for tag in bc.tags:
            if tag in seen:
                raise ValueError(
                    f"boundary tag {tag} has two conditions: {seen[tag]} and {type(bc).__name__}"
                )
            if tag not in present:
                raise ValueError(
                    f"boundary tag {tag} ({type(bc).__name__}) is not on the fluid mesh"
                )
            seen[tag] = type(bc).__name__
