"""Fluid metrics (docs/model.md, What the study reports): peaks, wall shear stress,
recirculation, the hemodynamic indices TAWSS, OSI and RRT, flow rates, mean boundary pressures,
and the shear rate, effective viscosity and wall shear stress as fields.

Every function here is collective over the mesh's communicator and returns the same value on
every rank (peaks and flow rates are reduced, wall samples are gathered); the per-rank
exceptions say so (:meth:`WallSampler.local`, :class:`WallIndices` of a rank's samples).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import ufl

from fsi import compat
from fsi.physics import rheology
from fsi.physics.coordinates import Coordinates


def _owned_blocks(u: dolfinx.fem.Function) -> np.ndarray:
    """The owned nodal values of ``u``, one row per node (block)."""
    index_map, bs = u.function_space.dofmap.index_map, u.function_space.dofmap.index_map_bs
    return u.x.array[: index_map.size_local * bs].reshape(-1, bs)


def peak_velocity(u: dolfinx.fem.Function) -> float:
    """max |u| over the velocity nodes (P2: vertices and edge midpoints), over all ranks (m/s)."""
    values = _owned_blocks(u)
    local = float(np.linalg.norm(values, axis=1).max(initial=0.0))
    return u.function_space.mesh.comm.allreduce(local, op=MPI.MAX)


def peak_pressure(p: dolfinx.fem.Function) -> float:
    """max p over the pressure nodes, over all ranks (Pa)."""
    local = float(_owned_blocks(p).max(initial=-np.inf))
    return p.function_space.mesh.comm.allreduce(local, op=MPI.MAX)


def nodal_value(f: dolfinx.fem.Function, point: Sequence[float]) -> np.ndarray:
    """The value of a Lagrange function at ``point``, which must be one of its nodes (the
    Turek–Hron point A is a mesh vertex); the same on every rank. On a submesh of a moving
    problem ``point`` is in the reference configuration."""
    V = f.function_space
    n, bs = V.dofmap.index_map.size_local, V.dofmap.index_map_bs
    x = V.tabulate_dof_coordinates()[:n, : len(point)]
    hit = np.flatnonzero(
        np.linalg.norm(x - np.asarray(point), axis=1) < 1e-10 * (1 + np.linalg.norm(point))
    )
    found = np.concatenate(V.mesh.comm.allgather(_owned_blocks(f)[hit])).reshape(-1, bs)
    if len(found) != 1:
        raise ValueError(f"{len(found)} nodes of {f.name!r} at {list(point)} (expected one)")
    return found[0]


# --------------------------------------------------------------------------------------------
# Wall shear stress and recirculation


@dataclass(frozen=True)
class WallFlow:
    """A fluid solution at tagged boundary facets of its mesh (the walls, or a body's
    surface): the velocity ``u``, the pressure ``p`` and the viscosity ``law``, whose Cauchy
    stress σ = −p I + 2 μ(s(u)) D(u) (:meth:`stress`) the wall quantities read, and the facets
    ``tags`` of ``facet_tags``."""

    u: dolfinx.fem.Function
    p: dolfinx.fem.Function
    law: rheology.ViscosityLaw
    facet_tags: dolfinx.mesh.MeshTags
    tags: Sequence[int]
    coordinates: Coordinates | None = None  # None: plane

    @property
    def mesh(self) -> dolfinx.mesh.Mesh:
        return self.u.function_space.mesh

    @property
    def _axisymmetric(self) -> bool:
        return self.coordinates is not None and self.coordinates.axisymmetric

    def shear_rate(self) -> ufl.core.expr.Expr:
        """s(u) as a UFL expression (with the hoop strain rate when axisymmetric)."""
        if self._axisymmetric:
            return rheology.shear_rate_of(self.coordinates.strain_rate(self.u))
        return rheology.shear_rate(self.u)

    def stress(self) -> ufl.core.expr.Expr:
        """σ(u, p) as a UFL expression: in the meridian plane when axisymmetric (the in-plane
        block, which is all a traction σ n with n in that plane reads), μ of the full s(u)."""
        if self._axisymmetric:
            mu = self.law.mu(self.shear_rate())
            return -self.p * ufl.Identity(2) + 2 * mu * rheology.strain_rate(self.u)
        return rheology.cauchy_stress(self.u, self.p, self.law)

    def measure(self, quadrature_degree: int) -> ufl.Measure:
        """ds over the facets ``tags``, at ``quadrature_degree``."""
        return boundary_measure(self.mesh, self.facet_tags, self.tags, quadrature_degree)


@dataclass(frozen=True)
class WallShearStress:
    """Samples along a wall (gathered on every rank), ordered by ``s``, the position along the
    flow ``direction``: points ``x`` (n, gdim), ``tau`` the signed wall shear stress (Pa),
    ``normal`` the wall's unit normal into the fluid (n, gdim); in 3D also ``vector``, the
    wall shear stress vector (n, 3), the tangential part of the traction (None in 2D)."""

    s: np.ndarray
    x: np.ndarray
    tau: np.ndarray
    normal: np.ndarray
    vector: np.ndarray | None = None

    def where(self, mask: np.ndarray) -> WallShearStress:
        vector = None if self.vector is None else self.vector[mask]
        return WallShearStress(
            self.s[mask], self.x[mask], self.tau[mask], self.normal[mask], vector
        )

    @property
    def indexed(self) -> np.ndarray:
        """What the hemodynamic indices average: the signed τ_w in 2D, the vector in 3D."""
        return self.tau if self.vector is None else self.vector


# Gauss points on each facet of the reference cell, facet k opposite vertex k: two per edge of
# the triangle, three per face of the tetrahedron (degree 2; barycentric 2/3, 1/6, 1/6).
_GAUSS = np.array([0.5 - 0.5 / np.sqrt(3), 0.5 + 0.5 / np.sqrt(3)])
_FACE_GAUSS = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


def _facet_points(tdim: int = 2) -> np.ndarray:
    """The sample points of every facet of the reference triangle (``tdim`` 2: (6, 2), facet
    k's in rows 2k, 2k + 1) or tetrahedron (3: (12, 3), facet k's in rows 3k to 3k + 2)."""
    vertices = np.vstack([np.zeros(tdim), np.eye(tdim)])
    points = []
    for k in range(tdim + 1):
        corners = [vertices[j] for j in range(tdim + 1) if j != k]
        if tdim == 2:
            a, b = corners
            points.extend(a + g * (b - a) for g in _GAUSS)
        else:
            points.extend(weights @ np.array(corners) for weights in _FACE_GAUSS)
    return np.array(points)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class WallSampler:
    """The wall shear stress τ_w = t·(σ n) at two Gauss points of every facet of the walls
    ``flow.tags`` that this rank owns, always in the same order: this rank's wall facets in
    facet-tag order, two points each. The Gauss points are fixed in the reference cell, so on a
    moving mesh (affine cells) each sample stays at the same fraction of its facet: it follows
    the same material wall point.

    ``n`` is the wall's unit normal pointing into the fluid, so σ n is the traction the blood
    exerts on the wall, and ``t`` the unit tangent with t·direction ≥ 0: τ_w > 0 where the flow
    next to the wall goes along ``direction``, < 0 where it reverses (recirculation).
    σ = −p I + 2 μ(s(u)) D(u) is evaluated inside each wall cell (gradients are per cell).

    Built once per solver (the expression is compiled here); :meth:`local` and :meth:`gather`
    read the solution and the mesh coordinates as they are when called. ``walls`` holds each
    local sample's facet tag, ``reference`` its coordinates when the sampler was built (the
    reference configuration if built before the mesh moves), both (size,) and (size, 2)."""

    def __init__(self, flow: WallFlow, direction: Sequence[float] = (1.0, 0.0)):
        mesh, facet_tags = flow.mesh, flow.facet_tags
        self.mesh, self.comm = mesh, mesh.comm
        tdim = mesh.topology.dim
        fdim = tdim - 1
        mesh.topology.create_connectivity(fdim, tdim)
        mesh.topology.create_connectivity(tdim, fdim)
        chosen = np.isin(facet_tags.values, [int(t) for t in flow.tags])
        facets, values = facet_tags.indices[chosen], facet_tags.values[chosen]
        owned = facets < mesh.topology.index_map(fdim).size_local
        self.facets = facets[owned].astype(np.int32)
        f2c = mesh.topology.connectivity(fdim, tdim)
        c2f = mesh.topology.connectivity(tdim, fdim)
        self.cells = np.array([f2c.links(f)[0] for f in self.facets], dtype=np.int32)
        local_facet = np.array(
            [int(np.flatnonzero(c2f.links(c) == f)[0]) for c, f in zip(self.cells, self.facets)],
            dtype=np.int64,
        )
        self.gdim = gdim = mesh.geometry.dim
        self.per_facet = per = gdim  # samples per facet: 2 on a segment, 3 on a triangle
        self._rows = per * local_facet[:, None] + np.arange(per)  # (nf, per)
        x = ufl.SpatialCoordinate(mesh)
        sigma = flow.stress()
        values_at = ufl.as_vector(
            [sigma[i, j] for i in range(gdim) for j in range(gdim)] + [x[i] for i in range(gdim)]
        )
        self._expression = dolfinx.fem.Expression(values_at, _facet_points(tdim))
        e = np.zeros(gdim)  # the default (1, 0) is e_x in 3D too
        e[: len(direction)] = direction
        self._direction = e / np.linalg.norm(e)
        self.walls = np.repeat(values[owned].astype(np.int64), per)
        self.reference = self.local().x.copy()

    @property
    def size(self) -> int:
        """The number of samples on this rank (two per owned wall facet in 2D, three in 3D)."""
        return self.per_facet * len(self.facets)

    def local(self) -> WallShearStress:
        """This rank's samples in the sampler's fixed order (not sorted by ``s``)."""
        mesh, tdim = self.mesh, self.mesh.topology.dim
        nf, gdim, per = len(self.facets), self.gdim, self.per_facet
        width = gdim * gdim + gdim
        data = compat.eval_expression(self._expression, mesh, self.cells)
        data = data.reshape(nf, (tdim + 1) * per, width)
        data = np.take_along_axis(data, self._rows[:, :, None], axis=1)  # (nf, per, width)
        if gdim == 3:
            return self._local_3d(data)
        fdim = tdim - 1

        # Normal into the fluid: from the facet towards the cell's centroid (affine triangles).
        nodes = compat.entities_to_geometry(mesh, fdim, self.facets).reshape(nf, 2)
        ends = mesh.geometry.x[nodes][:, :, :2]
        tangent = ends[:, 1] - ends[:, 0]
        tangent /= np.linalg.norm(tangent, axis=1)[:, None]
        cell_nodes = compat.entities_to_geometry(mesh, tdim, self.cells).reshape(nf, 3)
        centroid = mesh.geometry.x[cell_nodes][:, :, :2].mean(axis=1)
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        inward = np.sign(np.einsum("ij,ij->i", centroid - ends.mean(axis=1), normal))
        normal *= inward[:, None]
        e = self._direction
        tangent *= np.where(tangent @ e >= 0, 1.0, -1.0)[:, None]

        sigma_pts = data[:, :, :4].reshape(-1, 2, 2, 2)  # (nf, point, i, j)
        traction = np.einsum("fpij,fj->fpi", sigma_pts, normal)
        tau = np.einsum("fpi,fi->fp", traction, tangent).ravel()
        points = data[:, :, 4:].reshape(-1, 2)
        return WallShearStress(points @ e, points, tau, np.repeat(normal, 2, axis=0))

    def _local_3d(self, data: np.ndarray) -> WallShearStress:
        """The samples of a 3D wall from ``data`` (nf, 3 points, σ's 9 entries then x's 3): the
        vector τ = σm − (σm·n) n, the traction's tangential part, and its signed component
        τ_w = τ·t along the wall's tangent t nearest the flow ``direction`` e,
        t = (e − (e·n) n)/|e − (e·n) n| (the 2D convention; t is undefined where the wall is
        normal to e, where τ_w is taken as 0)."""
        mesh, nf = self.mesh, len(self.facets)
        nodes = compat.entities_to_geometry(mesh, 2, self.facets).reshape(nf, 3)
        corners = mesh.geometry.x[nodes]
        normal = _unit(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
        cell_nodes = compat.entities_to_geometry(mesh, 3, self.cells).reshape(nf, 4)
        centroid = mesh.geometry.x[cell_nodes].mean(axis=1)
        inward = np.sign(np.einsum("ij,ij->i", centroid - corners.mean(axis=1), normal))
        normal *= inward[:, None]
        e = self._direction
        along = e[None, :] - (normal @ e)[:, None] * normal
        length = np.linalg.norm(along, axis=1, keepdims=True)
        tangent = np.divide(along, length, out=np.zeros_like(along), where=length > 1e-12)

        sigma_pts = data[:, :, :9].reshape(nf, 3, 3, 3)  # (nf, point, i, j)
        traction = np.einsum("fpij,fj->fpi", sigma_pts, normal)
        vector = traction - np.einsum("fpi,fi->fp", traction, normal)[:, :, None] * normal[:, None]
        tau = np.einsum("fpi,fi->fp", vector, tangent).ravel()
        points = data[:, :, 9:].reshape(-1, 3)
        return WallShearStress(
            points @ e, points, tau, np.repeat(normal, 3, axis=0), vector.reshape(-1, 3)
        )

    def gather(self, samples: WallShearStress | None = None) -> WallShearStress:
        """Every rank's samples (``samples``, default :meth:`local`), on every rank, ordered by
        ``s``. Collective."""
        samples = self.local() if samples is None else samples
        gdim = self.gdim
        points = np.concatenate(self.comm.allgather(samples.x)).reshape(-1, gdim)
        tau = np.concatenate(self.comm.allgather(samples.tau))
        normal = np.concatenate(self.comm.allgather(samples.normal)).reshape(-1, gdim)
        s = points @ self._direction
        order = np.argsort(s, kind="stable")
        vector = None
        if samples.vector is not None:
            vector = np.concatenate(self.comm.allgather(samples.vector)).reshape(-1, gdim)[order]
        return WallShearStress(s[order], points[order], tau[order], normal[order], vector)


def wall_shear_stress(flow: WallFlow, direction: Sequence[float] = (1.0, 0.0)) -> WallShearStress:
    """τ_w = t·(σ n) at two Gauss points of every facet of the walls ``flow.tags``, gathered on
    every rank and ordered by ``s`` (:class:`WallSampler`, built for this one call: a loop
    keeps a sampler instead). Collective."""
    return WallSampler(flow, direction).gather()


SECTORS = 36
"""The angular sectors (10° each, about the x axis) in which a 3D lumen's reversed-flow zones
are found (:func:`lumen_sides`)."""


def lumen_sides(wss: WallShearStress) -> dict[str, WallShearStress]:
    """The samples of the lower (``bottom``: normal into the fluid pointing up) and upper
    (``top``) walls of a channel-like lumen, each a graph over x, so that reversed-flow zones
    are found along one wall at a time. A 3D lumen about the x axis: its :data:`SECTORS`
    angular sectors (``sector k`` from φ = 10 k degrees, φ measured from +y towards +z), each
    a strip along x."""
    if wss.x.shape[1] == 3:
        phi = np.degrees(np.arctan2(wss.x[:, 2], wss.x[:, 1])) % 360.0
        sector = np.minimum((phi // (360.0 / SECTORS)).astype(int), SECTORS - 1)
        return {f"sector {k}": wss.where(sector == k) for k in range(SECTORS)}
    return {"bottom": wss.where(wss.normal[:, 1] > 0), "top": wss.where(wss.normal[:, 1] < 0)}


def wall_shear_summary(wss: WallShearStress) -> dict[str, float]:
    """``min_wss``, ``max_wss`` (Pa) over the walls and ``recirculation_length`` (m), the
    longest reversed-flow zone along either wall of the lumen (docs/model.md, What the study
    reports)."""
    length = max(
        (
            recirculation_length(side.s, side.tau)
            for side in lumen_sides(wss).values()
            if len(side.s)
        ),
        default=0.0,
    )
    return {
        "min_wss": float(wss.tau.min(initial=np.inf)),
        "max_wss": float(wss.tau.max(initial=-np.inf)),
        "recirculation_length": float(length),
    }


def recirculation_zones(s: np.ndarray, tau: np.ndarray) -> list[tuple[float, float]]:
    """The intervals of ``s`` where τ_w < 0 (reversed flow), each from its separation point to
    its reattachment point (zero crossings, linearly interpolated; an interval reaching an end
    of the samples stops there)."""
    s, tau = np.asarray(s, dtype=float), np.asarray(tau, dtype=float)
    negative = tau < 0
    zones = []
    i = 0
    while i < len(s):
        if not negative[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(s) and negative[j + 1]:
            j += 1

        def crossing(a: int, b: int) -> float:
            return float(s[a] + (s[b] - s[a]) * tau[a] / (tau[a] - tau[b]))

        start = crossing(i - 1, i) if i > 0 else float(s[0])
        end = crossing(j, j + 1) if j + 1 < len(s) else float(s[-1])
        zones.append((start, end))
        i = j + 1
    return zones


def recirculation_length(s: np.ndarray, tau: np.ndarray) -> float:
    """Length of the longest reversed-flow zone along the wall (0 if none)."""
    return max((b - a for a, b in recirculation_zones(s, tau)), default=0.0)


# --------------------------------------------------------------------------------------------
# Forces


def boundary_measure(
    mesh: dolfinx.mesh.Mesh,
    facet_tags: dolfinx.mesh.MeshTags,
    tags: Sequence[int],
    quadrature_degree: int,
) -> ufl.Measure:
    """ds over the facets tagged with any of ``tags`` (at least one), at ``quadrature_degree``."""
    ds = ufl.Measure(
        "ds",
        domain=mesh,
        subdomain_data=facet_tags,
        metadata={"quadrature_degree": quadrature_degree},
    )
    tags = [int(t) for t in tags]
    return sum((ds(t) for t in tags[1:]), ds(tags[0]))


# --------------------------------------------------------------------------------------------
# Flow rates


def weighted_boundary_measure(
    mesh: dolfinx.mesh.Mesh,
    facet_tags: dolfinx.mesh.MeshTags,
    tags: Sequence[int],
    quadrature_degree: int,
    coordinates: Coordinates | None,
):
    """:func:`boundary_measure`, weighted by 2π r when ``coordinates`` are axisymmetric (one
    quadrature degree more for the factor r): the integrals are over the body's surface."""
    if coordinates is None or not coordinates.axisymmetric:
        return boundary_measure(mesh, facet_tags, tags, quadrature_degree)
    return coordinates.measure(boundary_measure(mesh, facet_tags, tags, quadrature_degree + 1))


def flow_rate_form(
    u: dolfinx.fem.Function,
    facet_tags: dolfinx.mesh.MeshTags,
    tags: Sequence[int],
    quadrature_degree: int = 2,
    coordinates: Coordinates | None = None,
) -> dolfinx.fem.Form:
    """The compiled form ∫_Γ u·n ds over the facets ``tags`` of ``u``'s mesh (n the outward
    unit normal; ∫_Γ u·n 2π r ds when ``coordinates`` are axisymmetric), for :func:`total`:
    compile it once, assemble it every step (it reads the mesh's current coordinates, so it
    follows a moving mesh). The default degree 2 integrates a P2 velocity exactly on straight
    facets (n is constant), and 3 its product with r."""
    mesh = u.function_space.mesh
    measure = weighted_boundary_measure(mesh, facet_tags, tags, quadrature_degree, coordinates)
    return dolfinx.fem.form(ufl.dot(u, ufl.FacetNormal(mesh)) * measure)


def total(form: dolfinx.fem.Form, comm: MPI.Comm) -> float:
    """A scalar form assembled over the owned cells or facets of every rank and summed: the
    same value on every rank."""
    return comm.allreduce(dolfinx.fem.assemble_scalar(form), op=MPI.SUM)


def flow_rate(
    u: dolfinx.fem.Function,
    facet_tags: dolfinx.mesh.MeshTags,
    tags: Sequence[int],
    sign: float = 1.0,
    quadrature_degree: int = 2,
    coordinates: Coordinates | None = None,
) -> float:
    """Q = sign ∫_Γ u·n ds over the facets ``tags`` of ``u``'s mesh, n the outward unit normal:
    the volume flow rate per unit depth (m²/s) through Γ (m³/s, ∫_Γ u·n 2π r ds, when
    ``coordinates`` are axisymmetric), on the mesh as it is now (moved or not). ``sign`` = +1
    counts outflow as positive (an outlet), −1 inflow (an inlet), so that Q_in = −∫_inlet u·n ds
    and Q_out = ∫_outlet u·n ds are both positive downstream. Compiles the form at every call: a
    loop keeps :func:`flow_rate_form` instead."""
    form = flow_rate_form(u, facet_tags, tags, quadrature_degree, coordinates)
    return sign * total(form, u.function_space.mesh.comm)


# --------------------------------------------------------------------------------------------
# Mean boundary pressures


class BoundaryMean:
    """The mean of a scalar ``f`` over the facets ``tags`` of its mesh,
    f̄ = ∫_Γ f ds / ∫_Γ 1 ds (in 2D the length average; the area average of a 3D boundary, and
    of an axisymmetric one with ``coordinates``: ∫_Γ f 2π r ds / ∫_Γ 2π r ds), on
    the mesh as it is when :meth:`value` is called (the forms are compiled once and read the
    current coordinates, so the mean follows a moving mesh). The default degree 2 integrates a
    P1 or P2 ``f`` exactly on straight facets."""

    def __init__(
        self,
        f: dolfinx.fem.Function,
        facet_tags: dolfinx.mesh.MeshTags,
        tags: Sequence[int],
        quadrature_degree: int = 2,
        coordinates: Coordinates | None = None,
    ):
        mesh = f.function_space.mesh
        self.comm = mesh.comm
        measure = weighted_boundary_measure(mesh, facet_tags, tags, quadrature_degree, coordinates)
        self._integral = dolfinx.fem.form(f * measure)
        one = dolfinx.fem.Constant(mesh, PETSc.ScalarType(1.0))
        self._size = dolfinx.fem.form(one * measure)

    def value(self) -> float:
        """f̄ over Γ, the same on every rank; NaN if Γ has no facets. Collective."""
        size = total(self._size, self.comm)
        return total(self._integral, self.comm) / size if size > 0 else math.nan


# --------------------------------------------------------------------------------------------
# Fields for output


class FluidFields:
    """The shear rate s(u) (1/s), the effective viscosity μ(s) (Pa s) and the signed wall shear
    stress τ_w (Pa) on the walls ``flow.tags`` of a fluid solution as fields for output;
    :meth:`update` recomputes them in place (also on a moved mesh).

    s and μ are cell values (DG0, at each cell's midpoint). τ_w is a P1 field that is zero off the
    walls: at a wall vertex i, τ_i = ∫_Γ τ_w φ_i ds / ∫_Γ φ_i ds (the lumped L² projection onto
    the walls' P1 nodes) with τ_w = t·(σ m), m = −n the wall's normal into the fluid and t the
    tangent with t·e_x ≥ 0, the sign convention of :func:`wall_shear_stress`.
    """

    def __init__(self, flow: WallFlow, quadrature_degree: int = 2):
        mesh = flow.mesh
        cells = compat.function_space(mesh, "DG", 0)
        self.shear_rate = dolfinx.fem.Function(cells, name="shear_rate")
        self.viscosity = dolfinx.fem.Function(cells, name="viscosity")
        points = compat.interpolation_points(cells)
        s = flow.shear_rate()
        mu = flow.law.mu(s)
        self._expressions = [(self.shear_rate, dolfinx.fem.Expression(s, points))]
        if isinstance(mu, ufl.constantvalue.ConstantValue):  # Newtonian: set once
            self.viscosity.x.array[:] = float(mu)
        else:
            self._expressions.append((self.viscosity, dolfinx.fem.Expression(mu, points)))
        self.wall_shear_stress = dolfinx.fem.Function(
            compat.function_space(mesh, "Lagrange", 1), name="wall_shear_stress"
        )
        on_walls = flow.measure(quadrature_degree)
        n = ufl.FacetNormal(mesh)
        if mesh.geometry.dim == 3:  # t = (e_x − n_x n)/|e_x − n_x n| (WallSampler._local_3d)
            along = ufl.as_vector((1.0, 0.0, 0.0)) - n[0] * n
            t = along / ufl.sqrt(ufl.dot(along, along) + 1e-24)
        else:
            along = ufl.as_vector((n[1], -n[0]))
            t = ufl.conditional(ufl.ge(along[0], 0.0), 1.0, -1.0) * along
        tau = -ufl.dot(t, ufl.dot(flow.stress(), n))
        v = ufl.TestFunction(self.wall_shear_stress.function_space)
        self._weighted = dolfinx.fem.form(tau * v * on_walls)
        self._mass = dolfinx.fem.form(v * on_walls)

    @property
    def fields(self) -> list[dolfinx.fem.Function]:
        return [self.viscosity, self.shear_rate, self.wall_shear_stress]

    def update(self) -> None:
        for target, expression in self._expressions:
            target.interpolate(expression)
        weighted, mass = (
            dolfinx.fem.petsc.assemble_vector(f) for f in (self._weighted, self._mass)
        )
        for vec in (weighted, mass):
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        tau = self.wall_shear_stress
        n = tau.function_space.dofmap.index_map.size_local
        on_wall = mass.array[:n] > 0
        tau.x.array[:] = 0.0
        tau.x.array[:n][on_wall] = weighted.array[:n][on_wall] / mass.array[:n][on_wall]
        tau.x.scatter_forward()
        weighted.destroy()
        mass.destroy()
