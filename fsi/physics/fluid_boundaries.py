"""The fluid's boundary conditions as data, and the boundary data they need.

One small frozen class per kind (:class:`NoSlip`, :class:`Velocity`, :class:`Robin`,
:class:`Inflow`, :class:`Outflow`, :class:`Slip`, :class:`Traction`, :class:`Axis`,
:class:`SymmetryPlane`,
:class:`PrescribedVelocity`, :class:`PrescribedTraction`), a case's set of them
(:func:`boundary_conditions`, :func:`walls`), the inlet's pressure P(t)
(:func:`inlet_pressure`), the Turek–Hron inflow ramp and the parabolic inflow profile on a
straight inlet. :class:`fsi.physics.fluid_boundary_terms.BoundaryTerms` turns each condition
into its Dirichlet conditions and boundary terms (docs/model.md, Fluid).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import dolfinx.mesh
import numpy as np
import ufl

from fsi import compat, config
from fsi.config import boundary_data
from fsi.geometry.tags import Boundary
from fsi.physics import inflow_profiles, outlets

log = logging.getLogger(__name__)

TractionFunction = Callable[
    [ufl.core.expr.Expr, ufl.core.expr.Expr, dolfinx.fem.Constant], ufl.core.expr.Expr
]
"""``g(x, n, t)``: a UFL vector of the spatial coordinate, the outward normal and the time."""


def as_tags(tags) -> tuple[int, ...]:
    """``tags`` (one tag or several) as a tuple of ints."""
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
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Velocity:
    """u = the solver's :attr:`FluidSolver.boundary_velocity` on ``tags`` (the FSI interface:
    the coupler writes ∂η/∂t there)."""

    tags: tuple[int, ...]

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Robin:
    """The Robin–Neumann coupling's interface condition on ``tags``:

        α (u − u_Γ) − σ n = t_k   (weakly: f = α M_Γ (u − u_Γ) + f_k at the nodes),

    u_Γ the solver's :attr:`FluidSolver.boundary_velocity` (the wall's velocity), α and the
    nodal forces f_k of the last coupling iteration set by the coupler (the fluid's
    :class:`~fsi.physics.fluid_boundary_terms.RobinInterface`). At a fixed point u = u_Γ: the
    solution of :class:`Velocity`. Nodes the interface shares with another boundary keep
    u = u_Γ."""

    tags: tuple[int, ...]

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Inflow:
    """The configured inlet on ``tags``: a normal traction σ n = −P(t) n (``traction_pulse``,
    ``pressure``, ``pressure_table``, ``pressure_file``; in the ``do_nothing`` form
    μ∇u n − p n = −P n) or a velocity (``parabolic_velocity``, the flow-rate inlets). A
    traction inlet with ``inflow_stabilization`` β > 0 adds the backflow term in the
    ``inflow_form`` (as :class:`Outflow`)."""

    tags: tuple[int, ...]
    spec: config.Inlet
    inflow_stabilization: float = 0.0
    inflow_form: str = "tangential_velocity"

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Outflow:
    """An open outlet on ``tags``: σ n = −P n (in the ``open_boundary`` form), P = 0
    (traction-free, the study's) or, with a lumped ``model`` (fsi/config/outlet_section.py:
    resistance, RCR Windkessel), the model's pressure at the outlet's flow rate
    (:class:`LumpedOutlet`); where blood re-enters, the backflow term of weight β
    (``backflow_stabilization``) in the ``backflow_form`` (fsi.config.outlet_section.BackflowForm)
    damps what the inflow would carry in."""

    tags: tuple[int, ...]
    backflow_stabilization: float = 1.0
    model: outlets.OutletModel | None = None
    backflow_form: str = "tangential"

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Slip:
    """The study's alternative wall condition: u·n = 0 (Nitsche) with a prescribed tangential
    traction (σ n)_t = g_t, ``g`` a :data:`TractionFunction` (None: g = 0, perfect slip). The
    normal part of g is ignored: the normal traction is the reaction to u·n = 0."""

    tags: tuple[int, ...]
    traction: TractionFunction | None = None

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Traction:
    """σ n = g(x, n, t) on ``tags``."""

    tags: tuple[int, ...]
    traction: TractionFunction

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class Axis:
    """u_r = 0 on ``tags``: the axis of an axisymmetric domain, or a plane symmetry line
    y = const (the velocity's y component is 0, the traction along the line is 0)."""

    tags: tuple[int, ...]

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class SymmetryPlane:
    """u_``component`` = 0 at every velocity node on the plane x_``component`` = 0, the other
    components free with no traction: a mirror plane of the flow, such as a quarter tube's cuts
    (``geometry.sector: 90``), which carry no tag."""

    component: int
    tags: tuple[int, ...] = ()


@dataclass(frozen=True)
class PrescribedVelocity:
    """u = ``value(x, t)`` on ``tags``: a velocity field given in Python, not by a case file
    (an exact solution imposed at the ends of a verification case, e.g. the deformable tube's
    Womersley flow, scripts/benchmark_tube.py). ``value`` maps the points x (3, n) and the time
    t (s) to the velocity (2, n) (m/s), as for ``Function.interpolate``."""

    tags: tuple[int, ...]
    value: Callable[[np.ndarray, float], np.ndarray]

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


@dataclass(frozen=True)
class PrescribedTraction:
    """σ n = ``value(x, t)`` on ``tags``, a traction field given in Python (Pa; the points x
    (3, n) and the time t to (2, n)), interpolated at each step's time: an exact solution's
    traction at an open end of a verification case (:class:`Traction` takes a UFL expression
    instead)."""

    tags: tuple[int, ...]
    value: Callable[[np.ndarray, float], np.ndarray]

    def __post_init__(self):
        object.__setattr__(self, "tags", as_tags(self.tags))


BoundaryCondition = (
    NoSlip
    | Velocity
    | Robin
    | SymmetryPlane
    | Inflow
    | Outflow
    | Slip
    | Traction
    | Axis
    | PrescribedVelocity
    | PrescribedTraction
)


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
    fluid: config.Fluid,
    boundaries: Sequence[Boundary],
    moving_interface: bool,
    robin: bool = False,
    symmetry_planes: Sequence[int] = (),
) -> tuple[BoundaryCondition, ...]:
    """The fluid's boundary conditions in every mode (docs/model.md, Fluid), for a geometry with
    ``boundaries``: the configured inlet, the configured outlet, u = ∂η/∂t on the interface if
    it moves (a coupled run; with ``robin`` the Robin–Neumann coupling's :class:`Robin`
    condition), no-slip on the :func:`walls`, u_r = 0 on a tube's axis, the normal velocity 0
    on the planes x_c = 0 of ``symmetry_planes`` (a quarter tube's cuts)."""
    inlet = Inflow(Boundary.INLET, fluid.inlet, fluid.inflow_stabilization, fluid.inflow_form)
    outlet = Outflow(
        Boundary.OUTLET,
        fluid.outlet.backflow_stabilization,
        outlets.from_config(fluid.outlet),
        fluid.outlet.backflow_form,
    )
    interface = Robin if robin else Velocity
    moving = (interface(Boundary.INTERFACE),) if moving_interface else ()
    axis = (Axis(Boundary.AXIS),) if Boundary.AXIS in boundaries else ()
    mirrors = tuple(SymmetryPlane(c) for c in symmetry_planes)
    walls_ = NoSlip(walls(boundaries, moving_interface))
    return (*mirrors, inlet, outlet, *moving, walls_, *axis)


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
        return boundary_data.table_function(spec.table, spec.period)
    raise TypeError(f"{type(spec).__name__} is not a traction inlet")


def inlet_flow_rate(spec: config.Inlet) -> Callable[[float], float]:
    """Q(t) (m²/s per unit depth, into the domain) of a flow-rate inlet, before its ramp: a
    formula in t or a table (inline or from a CSV file, linear between rows), of t mod T with a
    period T > 0 (a table is constant beyond its ends without one)."""
    if isinstance(spec, config.InletFlowRate):
        return boundary_data.periodic(boundary_data.time_function(spec.formula), spec.period)
    if isinstance(spec, (config.InletFlowRateTable, config.InletFlowRateFile)):
        if not spec.table:
            raise ValueError(f"fluid.inlet ({spec.kind}) has no rows (read by config.load)")
        return boundary_data.table_function(spec.table, spec.period)
    raise TypeError(f"{type(spec).__name__} is not a flow-rate inlet")


def inflow_ramp(t: float, ramp_time: float) -> float:
    """(1 − cos(π t / T_r)) / 2 for t < T_r, 1 after (Turek–Hron: T_r = 2 s)."""
    return 1.0 if t >= ramp_time else 0.5 * (1 - math.cos(math.pi * t / ramp_time))


# --------------------------------------------------------------------------------------------
# The geometry of straight open boundaries (normal flow, the velocity inlets' profiles)


def boundary_points(mesh, facet_tags, tags: Sequence[int], comm: MPI.Comm) -> np.ndarray:
    """The (x, y) (in 3D (x, y, z)) of the vertices of the facets ``tags``, gathered from every
    rank (the same array on each; vertices shared by facets repeat). Collective."""
    gdim = mesh.geometry.dim
    nodes = compat.entities_to_geometry(
        mesh, mesh.topology.dim - 1, facets_of(facet_tags, tags)
    ).ravel()
    return np.concatenate(comm.allgather(mesh.geometry.x[nodes, :gdim])).reshape(-1, gdim)


def inlet_frame(points: np.ndarray, mesh, comm: MPI.Comm) -> InletFrame | DiskInlet:
    """The frame of a straight inlet (:class:`InletFrame`) or, on a 3D mesh, of a flat circular
    one (:class:`DiskInlet`), whose vertices are ``points`` (:func:`boundary_points`).
    Collective."""
    if mesh.geometry.dim == 3:
        return DiskInlet.of(points, mesh, comm)
    return InletFrame.of(points, mesh, comm)


@dataclass(frozen=True)
class InletFrame:
    """A straight inlet: its end ``start``, unit ``tangent`` and ``width`` H (m) along it, and
    its inward unit ``normal`` (towards the inside of the mesh)."""

    start: np.ndarray
    tangent: np.ndarray
    width: float
    normal: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, mesh, comm: MPI.Comm) -> InletFrame:
        """The frame of the straight inlet whose vertices are ``points``
        (:func:`boundary_points`); inward: the side of the centroid of ``mesh``. Collective."""
        # The inlet's end points: the pair of its vertices farthest apart.
        ends = points[
            [np.argmin(points @ d) for d in ((1, 0), (0, 1))]
            + [np.argmax(points @ d) for d in ((1, 0), (0, 1))]
        ]
        i, j = np.unravel_index(
            np.argmax(np.linalg.norm(ends[:, None] - ends[None], axis=2)), (4, 4)
        )
        start, tangent = ends[i], ends[j] - ends[i]
        width = np.linalg.norm(tangent)
        tangent = tangent / width
        normal = np.array([tangent[1], -tangent[0]])
        centre = comm.allreduce(mesh.geometry.x[:, :2].sum(axis=0))
        centre /= comm.allreduce(len(mesh.geometry.x))
        if normal @ (centre - start) < 0:
            normal = -normal  # inward
        return cls(start, tangent, width, normal)

    def distance(self, x: np.ndarray) -> np.ndarray:
        """s (m), the distance along the inlet from ``start`` of the points ``x`` (one per row,
        their first two columns (x, y)), clipped to [0, H]."""
        return np.clip((x[:, :2] - self.start) @ self.tangent, 0, self.width)

    def radius(self, x: np.ndarray) -> np.ndarray:
        """r (m), the distance from the axis y = 0 of the points ``x`` (an axisymmetric inlet
        from the axis to the wall: ``width`` is the pipe's radius), clipped to [0, H]."""
        return np.clip(x[:, 1], 0, self.width)


@dataclass(frozen=True)
class DiskInlet:
    """A flat circular inlet of a 3D vessel (a pipe's cross-section): its ``centre``, inward
    unit ``normal`` and radius ``width`` R (m). Its profiles are the pipe's, as across an
    axisymmetric inlet, with r the distance from the centre (:meth:`radius`)."""

    centre: np.ndarray
    normal: np.ndarray
    width: float

    FLATNESS = 1e-9
    """The largest distance of a vertex from the inlet's plane, relative to its radius."""

    @classmethod
    def of(cls, points: np.ndarray, mesh, comm: MPI.Comm) -> DiskInlet:
        """The disk whose boundary vertices ``points`` (:func:`boundary_points`) lie on a
        circle: its centre the middle of their bounding box (a circle's is its centre), its
        plane the least-squares plane through them, inward: the side of the centroid of
        ``mesh``. Raises ValueError for an inlet that is not flat. Collective."""
        centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
        radius = float(np.linalg.norm(points - centre, axis=1).max())
        normal = np.linalg.svd(points - centre, full_matrices=False)[2][-1]
        off_plane = float(np.abs((points - centre) @ normal).max())
        if off_plane > cls.FLATNESS * radius:
            raise ValueError(
                f"a 3D inlet must be flat; its vertices lie up to {off_plane:g} m off their "
                f"plane (radius {radius:g} m)"
            )
        x = mesh.geometry.x
        inside = comm.allreduce(x.sum(axis=0)) / comm.allreduce(len(x))
        if normal @ (inside - centre) < 0:
            normal = -normal  # inward
        return cls(centre, normal, radius)

    def radius(self, x: np.ndarray) -> np.ndarray:
        """r (m), the distance of the points ``x`` (one per row) from the inlet's centre in its
        plane, clipped to [0, R]."""
        offset = x[:, :3] - self.centre
        in_plane = offset - np.outer(offset @ self.normal, self.normal)
        return np.clip(np.linalg.norm(in_plane, axis=1), 0, self.width)


def parabolic_profile(
    frame: InletFrame | DiskInlet, mean_velocity: float, axisymmetric: bool = False
):
    """The interpolation function of :func:`~fsi.physics.inflow_profiles.parabola` (a pipe's
    :func:`~fsi.physics.inflow_profiles.pipe_parabola` when ``axisymmetric``) of mean velocity
    Ū (m/s) times the inward normal on the inlet ``frame``."""

    def profile(xx):
        if axisymmetric:
            r = frame.radius(xx.T)
            values = inflow_profiles.pipe_parabola(r, frame.width, mean_velocity)
        else:
            values = inflow_profiles.parabola(frame.distance(xx.T), frame.width, mean_velocity)
        return np.outer(frame.normal, values)

    return profile


def parabolic_values(
    V: dolfinx.fem.FunctionSpace,
    spec: config.ParabolicInflow,
    frame: InletFrame | DiskInlet,
    axisymmetric: bool = False,
):
    """The function of t giving the ``parabolic_velocity`` inlet's array in V's layout
    (constant: the parabola times −n, interpolated into V)."""
    shape = dolfinx.fem.Function(V)
    shape.interpolate(parabolic_profile(frame, spec.mean_velocity, axisymmetric))
    return lambda t: shape.x.array


WOMERSLEY_FLUX_TOLERANCE = 1e-3
"""The largest flux error of a Womersley inlet's interpolated velocity, relative to the peak of
|Q|, that goes without a warning (:func:`womersley_flux_error`)."""


def womersley_flux_error(
    s: np.ndarray, modes: np.ndarray, degree: int, axisymmetric: bool = False
) -> float:
    """The largest |flux − Q(t)| over a period (m²/s; m³/s when ``axisymmetric``) of the
    velocity interpolated at the inlet's nodes: Σ_k |∫ I(mode_k)|, where ``modes`` are
    :class:`~fsi.physics.inflow_profiles.FlowRateProfile`'s (2 Q̂_k (φ_k − φ₀) at the distances
    ``s`` of every node of the inlet, each once; their exact flux is 0) and I the interpolant
    of ``degree`` 1 or 2 on the straight inlet's edges, integrated exactly (Simpson's rule on
    each edge, with the midpoint's linear value for degree 1; ∫ ... 2π r dr, a cubic, when
    ``axisymmetric``). At a high Womersley number α the profile's boundary layers, H/(2α)
    thick, are thinner than the cells, and the interpolant's flux falls short of Q."""
    order = np.argsort(s)
    s, modes = s[order], modes[:, order]
    if degree == 2:
        left, middle, right = s[:-2:2], s[1:-1:2], s[2::2]
        values = modes[:, :-2:2], modes[:, 1:-1:2], modes[:, 2::2]
    else:
        left, right = s[:-1], s[1:]
        middle = (left + right) / 2
        values = modes[:, :-1], (modes[:, :-1] + modes[:, 1:]) / 2, modes[:, 1:]
    weights = [2 * np.pi * x if axisymmetric else np.ones_like(x) for x in (left, middle, right)]
    integrand = values[0] * weights[0] + 4 * values[1] * weights[1] + values[2] * weights[2]
    fluxes = (integrand * (right - left) / 6).sum(axis=1)
    return float(np.abs(fluxes).sum())


def flow_rate_values(
    V: dolfinx.fem.FunctionSpace,
    nodes: np.ndarray,
    spec: config.Inlet,
    frame: InletFrame | DiskInlet,
    density: float,
    viscosity: float | None,
    axisymmetric: bool = False,
    degree: int = 2,
):
    """The function of t giving a flow-rate inlet's velocity array in V's layout: the
    :class:`~fsi.physics.inflow_profiles.FlowRateProfile` speed (m/s) times −n at the inlet's
    ``nodes``, 0 elsewhere; ``density`` (kg/m³) and ``viscosity`` (Pa s) shape a
    ``womersley`` profile (None for ``parabolic``); ``axisymmetric``: a pipe's profiles, Q in
    m³/s. A Womersley profile whose interpolant (V's ``degree``) carries a flux more than
    :data:`WOMERSLEY_FLUX_TOLERANCE` of the peak |Q| off Q is warned of on rank 0
    (:func:`womersley_flux_error`; not on a 3D inlet, :class:`DiskInlet`). Collective."""
    x = V.tabulate_dof_coordinates()[nodes]
    s = frame.radius(x) if axisymmetric else frame.distance(x)
    speed = inflow_profiles.FlowRateProfile(
        inlet_flow_rate(spec), s, frame.width, spec.period, density, viscosity, axisymmetric
    )
    # The check integrates along one radius of a 2D inlet; a 3D disk's nodes are not on one.
    if viscosity is not None and not isinstance(frame, DiskInlet):
        _warn_of_womersley_flux(
            V.mesh.comm, spec, s, speed, frame.width, degree, axisymmetric, density, viscosity
        )
    index_map, bs = V.dofmap.index_map, V.dofmap.index_map_bs
    array = np.zeros((index_map.size_local + index_map.num_ghosts) * bs)
    block = array.reshape(-1, bs)
    normal = frame.normal

    def values(t: float) -> np.ndarray:
        block[nodes] = np.outer(speed(t), normal)
        return array

    return values


def _warn_of_womersley_flux(
    comm: MPI.Comm,
    spec: config.Inlet,
    s: np.ndarray,
    speed: inflow_profiles.FlowRateProfile,
    width: float,
    degree: int,
    axisymmetric: bool,
    density: float,
    viscosity: float,
) -> None:
    """Warn (rank 0) when the Womersley inlet's interpolated velocity carries a flux more than
    :data:`WOMERSLEY_FLUX_TOLERANCE` of the peak |Q| off Q (docs/boundary-conditions.md says
    its flux is Q: it is on a mesh that resolves the boundary layers). Collective."""
    gathered_s = np.concatenate(comm.allgather(s))
    gathered = np.concatenate(comm.allgather(speed.modes), axis=1)
    # A node on two ranks (owned, ghost) comes twice, its s computed on each to the last bit.
    unique, first = np.unique(np.round(gathered_s / width, 12), return_index=True)
    unique = gathered_s[first]
    error = womersley_flux_error(unique, gathered[:, first], degree, axisymmetric)
    peak = max(abs(speed.flow_rate(t)) for t in boundary_data.sample_times(spec.period))
    if comm.rank != 0 or not peak > 0 or error <= WOMERSLEY_FLUX_TOLERANCE * peak:
        return
    layer = math.sqrt(viscosity / (speed.omega * density))  # (μ/ωρ)^½: the Stokes layer
    alpha = (width if axisymmetric else width / 2) / layer
    cells = np.diff(unique).max() * degree
    unit = "m^3/s" if axisymmetric else "m^2/s"
    log.warning(
        "fsi: warning: fluid.inlet.profile womersley: on this mesh the inlet's velocity carries "
        "a flux up to %.2g %s (%.2g %% of the peak |Q|) off Q: the boundary layers of its first "
        "harmonic (Womersley number %.3g, %.2g mm thick) are thinner than the inlet's cells "
        "(%.2g mm); refine the mesh at the inlet (mesh.size, mesh.level) or use profile "
        "parabolic",
        error,
        unit,
        100 * error / peak,
        alpha,
        1e3 * layer,
        1e3 * cells,
    )
