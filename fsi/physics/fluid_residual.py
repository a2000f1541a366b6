"""The fluid's residual F((u, p); (v, q)) as a sum of named terms (docs/model.md, Fluid).

:class:`FluidResidual` builds, on the current configuration, the interior part of

    ρ (Σ_k a_k u^{n+1−k}, v) + ρ (((u − w)·∇)u, v) + (2 μ D(u), D(v)) − (p, ∇·v) − (q, ∇·u)
        − (f, v) − ⟨σ n, v⟩_natural [+ SUPG (+ PSPG, LSIC for P1–P1)] = 0,

one method per term, in plane, axisymmetric or 3D coordinates (fsi/physics/coordinates.py:
axisymmetric integrals carry 2π r, and D, ∇· and the shear rate the hoop part u_r/r), from the
fields it reads (:class:`FluidFields`); the boundary terms ⟨σ n, v⟩ and the Dirichlet
conditions of each boundary condition are fsi/physics/fluid_boundary_terms.py's, written with
the same symbols (:class:`WeakForm`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import numpy as np
import ufl

from fsi import compat, config
from fsi.physics import rheology
from fsi.physics.coordinates import Coordinates

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


@dataclass(frozen=True)
class FluidFields:
    """The fluid's unknowns and the data of the step being solved, as its forms read them; the
    solver owns them and sets their values before each solve (fsi/physics/fluid.py): the mixed
    space W = V × Q and its velocity space V, the unknown U = (u, p), u^n and u^{n−1}, the mesh
    velocity w, the velocity of the :class:`~fsi.physics.fluid_boundaries.Velocity` boundaries,
    and the constants t (the step's time), ρ, the BDF weights (a0, a1, a2) and the weights
    (e1, e2) of the extrapolation u* = e1 u^n + e2 u^{n−1}."""

    W: dolfinx.fem.FunctionSpace
    V: dolfinx.fem.FunctionSpace
    U: dolfinx.fem.Function
    u_n: dolfinx.fem.Function
    u_nm1: dolfinx.fem.Function
    w: dolfinx.fem.Function
    boundary_velocity: dolfinx.fem.Function
    t: dolfinx.fem.Constant
    rho: dolfinx.fem.Constant
    bdf_weights: Sequence[dolfinx.fem.Constant]
    extrapolation_weights: Sequence[dolfinx.fem.Constant]

    @classmethod
    def constants(cls, mesh: dolfinx.mesh.Mesh, density: float) -> dict:
        """The constants of a new solver: t = 0, ρ = ``density`` (kg/m³), a_k = 0, (e1, e2) =
        (1, 0); their keyword arguments."""

        def constant(value: float) -> dolfinx.fem.Constant:
            return dolfinx.fem.Constant(mesh, PETSc.ScalarType(value))

        return dict(
            t=constant(0.0),
            rho=constant(density),
            bdf_weights=[constant(0.0) for _ in range(3)],
            extrapolation_weights=[constant(1.0), constant(0.0)],
        )


@dataclass(frozen=True)
class WeakForm:
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


# --------------------------------------------------------------------------------------------
# The residual


class FluidResidual:
    """The interior part of the residual F((u, p); (v, q)) on ``fields``: the module
    docstring's weak form as a sum of named terms (:meth:`_residual`) in :attr:`form`, its
    symbols in :attr:`symbols` (for the boundary terms), and the coefficients held per step
    (:attr:`step_coefficients`: SUPG's τ, which the solver evaluates before each solve).

    Args:
        fields: the unknowns and the step's data (:class:`FluidFields`).
        facet_tags: the mesh's boundary tags (the measure ``ds``'s subdomains).
        settings: the ``fluid`` section (element, quadrature, SUPG, linearization).
        law: the viscosity law μ(s) (fsi/physics/rheology.py).
        coordinates: plane (or 3D) or axisymmetric (fsi/physics/coordinates.py).
        scheme: the time scheme (``steady`` has no τ held per step).
        body_force: optional f(x, t).
    """

    def __init__(
        self,
        fields: FluidFields,
        facet_tags: dolfinx.mesh.MeshTags,
        settings: config.Fluid,
        law: rheology.ViscosityLaw,
        coordinates: Coordinates,
        scheme: str,
        body_force: BodyForce | None = None,
    ):
        self.fields, self.facet_tags, self.config = fields, facet_tags, settings
        self.law, self.coordinates, self.scheme = law, coordinates, scheme
        self.mesh = fields.W.mesh
        self.step_coefficients: list[StepCoefficient] = []
        self.symbols = self._weak_form()
        self.form = self._residual(self.symbols, body_force)

    # ---- the residual, term by term (the module docstring's weak form)

    def _residual(self, s: WeakForm, body_force: BodyForce | None) -> ufl.Form:
        """F((u, p); (v, q)) in the interior, one named term per line of the module docstring:

        inertia + convection (ALE) + viscous stress − pressure − continuity − body force
        + stabilization."""
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
        return F

    def _weak_form(self) -> WeakForm:
        mesh, cfg = self.mesh, self.config
        metadata = {"quadrature_degree": cfg.quadrature_degree}
        u, p = ufl.split(self.fields.U)
        v, q = ufl.TestFunctions(self.fields.W)
        a0, a1, a2 = self.fields.bdf_weights
        if cfg.solver.linearization == "extrapolated":
            e1, e2 = self.fields.extrapolation_weights
            advecting = e1 * self.fields.u_n + e2 * self.fields.u_nm1
        else:
            advecting = u
        coords = self.coordinates
        return WeakForm(
            u=u,
            advecting=advecting,
            p=p,
            v=v,
            q=q,
            mu=self.law.mu(rheology.shear_rate_of(coords.strain_rate(advecting))),
            dudt=a0 * u + a1 * self.fields.u_n + a2 * self.fields.u_nm1,
            dx=coords.measure(ufl.Measure("dx", domain=mesh, metadata=metadata)),
            ds=coords.measure(
                ufl.Measure("ds", domain=mesh, subdomain_data=self.facet_tags, metadata=metadata)
            ),
            x=ufl.SpatialCoordinate(mesh),
            n=ufl.FacetNormal(mesh),
            h=ufl.CellDiameter(mesh),
            coords=coords,
        )

    def _inertia(self, s: WeakForm):
        """ρ (Σ_k a_k u^{n+1−k}) · v: the BDF derivative at fixed reference position X."""
        return self.fields.rho * ufl.dot(s.dudt, s.v)

    def _convection(self, s: WeakForm):
        """ρ ((a − w)·∇)u · v: convection relative to the mesh velocity w (ALE) by the
        advecting velocity a (u, or its extrapolation u*: :class:`WeakForm`)."""
        return self.fields.rho * ufl.dot(ufl.grad(s.u) * (s.advecting - self.fields.w), s.v)

    def _viscous_stress(self, s: WeakForm):
        """2 μ(s(u)) D(u) : D(v), the viscous part of σ(u, p) : ∇v (rheology.cauchy_stress)."""
        D = s.coords.strain_rate
        return 2 * s.mu * ufl.inner(D(s.u), D(s.v))

    def _pressure(self, s: WeakForm):
        """p ∇·v, the pressure part of σ(u, p) : ∇v (subtracted)."""
        return s.p * s.coords.div(s.v)

    def _continuity(self, s: WeakForm):
        """q ∇·u (subtracted: the symmetric saddle-point form)."""
        return s.q * s.coords.div(s.u)

    def _body_force(self, s: WeakForm, body_force: BodyForce):
        """f(x, t) · v (subtracted)."""
        return ufl.dot(body_force(s.x, self.fields.t), s.v)

    def _stabilization(self, s: WeakForm, body_force: BodyForce | None):
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
        rho, w, u, h = self.fields.rho, self.fields.w, s.u, s.h
        residual = (
            rho * s.dudt
            + rho * ufl.grad(u) * (s.advecting - w)
            + ufl.grad(s.p)
            - s.coords.div_symmetric(2 * s.mu * rheology.strain_rate(u), hoop=self._hoop(s))
        )
        if body_force is not None:
            residual -= body_force(s.x, self.fields.t)
        if self.scheme == "steady" or self.config.solver.linearization == "extrapolated":
            u_tau, mu_tau = s.advecting, s.mu
        else:
            shear_n = rheology.shear_rate_of(s.coords.strain_rate(self.fields.u_n))
            u_tau, mu_tau = self.fields.u_n, self.law.mu(shear_n)
        a_tau = u_tau - w
        speed = ufl.sqrt(ufl.dot(a_tau, a_tau) + SUPG_SPEED_FLOOR**2)
        viscous = VISCOUS_CONSTANT[self.config.element]
        tau = (
            (2 * self.fields.bdf_weights[0]) ** 2
            + (2 * speed / h) ** 2
            + (viscous * mu_tau / (rho * h**2)) ** 2
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
    def _hoop(s: WeakForm):
        """The hoop viscous stress 2 μ u_r/r (axisymmetric; None in the plane)."""
        return 2 * s.mu * s.u[1] / s.coords.r if s.coords.axisymmetric else None

    def _supg(self, s: WeakForm, tau, residual):
        """SUPG: τ ((u − w)·∇)v · R. It adds the streamline diffusion ≈ ρ|u − w|h/2 that the
        Galerkin form lacks where the cell Reynolds number is large, in particular in the cells
        of an open inlet (docs/boundary-conditions.md). With P2 velocities the strong viscous
        term is exact for Poiseuille flow, which stays a discrete solution."""
        return tau * ufl.dot(ufl.grad(s.v) * (s.advecting - self.fields.w), residual)

    def _pspg(self, s: WeakForm, tau, residual):
        """PSPG (subtracted, as the continuity term): (τ/ρ) ∇q · R (Hughes, Franca & Balestra
        1986; Tezduyar 1992): a pressure Laplacian −(τ/ρ)(∇q, ∇p) that circumvents the inf-sup
        condition equal-order P1–P1 fails, made consistent by the rest of R."""
        return tau / self.fields.rho * ufl.dot(ufl.grad(s.q), residual)

    def _lsic(self, s: WeakForm, tau):
        """LSIC: ρ τ_C (∇·u)(∇·v) with τ_C = h²/(4 d τ) (the VMS τ_C = (τ tr G)^(−1) with the
        metric G = 4/h² I of a cell of dimension d: h²/(8 τ) in 2D, h²/(12 τ) in 3D; Bazilevs
        et al. 2007): least squares on the continuity residual, which P1–P1 does not satisfy
        pointwise; zero on a solenoidal velocity."""
        tau_c = s.h**2 / (4 * self.mesh.topology.dim * tau)
        return self.fields.rho * tau_c * s.coords.div(s.u) * s.coords.div(s.v)
