"""The structure's boundary conditions and loads as data (:class:`SolidBoundaryConditions`: the
clamps, held regions, prescribed displacements, rollers, symmetry planes and the tissue's
support; :func:`boundary_conditions` makes a case's) and the Dirichlet conditions they become on
the displacement space (:class:`DirichletConditions`). fsi/physics/solid.py's solver applies
them.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc
import numpy as np
import ufl

from fsi.config import (
    Case,
    Material,
    StenosisGeometry,
    TubeGeometry,
    symmetry_planes,
)
from fsi.geometry.tags import Boundary, Region
from fsi.physics.mesh import TaggedMesh, bounding_plane_dofs

log = logging.getLogger(__name__)


DisplacementValue = Callable[[np.ndarray, float], np.ndarray]
"""``value(x, t)``: x of shape (3, n) → displacement of shape (2, n)."""


# --------------------------------------------------------------------------------------------
# Boundary conditions and loads as data


@dataclass(frozen=True)
class Clamp:
    """η = 0 on the facets of ``boundaries``."""

    boundaries: tuple[Boundary, ...] = (Boundary.CLAMPED,)


@dataclass(frozen=True)
class HoldRegions:
    """η = 0 on every dof of the cells of ``regions`` (the fixed-wall mode holds the wall)."""

    regions: tuple[Region, ...] = (Region.WALL,)


@dataclass(frozen=True)
class PrescribedDisplacement:
    """η = ``value(x, t)`` on ``boundaries`` (``None``: the whole boundary of the structure)."""

    value: DisplacementValue
    boundaries: tuple[Boundary, ...] | None = None


@dataclass(frozen=True)
class Roller:
    """η_``component`` = 0 on the facets of ``boundaries``, the other component free: a
    boundary that slides along itself (``component`` its normal's axis, 0 for x, 1 for y),
    e.g. the ends z = const of a tube section in plane strain (ε_zz = 0), or η_r = 0 where
    an axisymmetric solid meets its axis. ``value`` (m, default 0) moves the boundary along its
    normal by that much: the end of a tube stretched axially."""

    boundaries: tuple[Boundary, ...]
    component: int
    value: float = 0.0


@dataclass(frozen=True)
class SymmetryPlane:
    """η_``component`` = 0 at every node on the plane x_``component`` = 0 that bounds the body:
    a plane of mirror symmetry of the problem, such as a quarter tube's cuts (its nodes those
    of the boundary's facets in it: :func:`fsi.physics.mesh.bounding_plane_dofs`). A tube's
    pressure load has the planes through its axis as such planes; holding them removes the
    rigid motions that rollers on its ends leave free (the rotation about the axis, the
    translations across it)."""

    component: int


Dirichlet = Clamp | HoldRegions | PrescribedDisplacement | Roller | SymmetryPlane


@dataclass(frozen=True)
class Support:
    """The surrounding tissue as a spring–dashpot on ``boundaries`` (a Robin condition,
    Moireau et al. 2012), normal direction only::

        P N = −(k_s η·N + c_s η̇·N) N     (first Piola traction, per reference length)

    ``stiffness`` k_s (Pa/m), ``damping`` c_s (Pa·s/m), N the reference outward normal.
    Normal only: the tissue around an artery resists its radial motion (it is compressed or
    pulled), while the wall slides along it almost freely; the axial motion is in any case
    held by the clamped ends here. It is also what svMultiPhysics' "apply along normal
    direction" Robin condition does."""

    stiffness: float = 0.0
    damping: float = 0.0
    boundaries: tuple[Boundary, ...] = (Boundary.EXTERIOR,)


@dataclass(frozen=True)
class SolidBoundaryConditions:
    """Dirichlet conditions, the interface where the fluid's loads act, and the loads.

    ``body_force``: force per unit mass (gravity), m/s² (axisymmetric: along the axis only).
    ``pressure(t)``: a follower pressure on the interface (Pa; its traction is ``−p J F⁻ᵀ N``
    per reference area). ``source(x)``: a force per unit reference volume as a UFL expression
    of the spatial coordinate (for manufactured solutions). ``support``: the tissue's
    spring–dashpot on the exterior. Everything not named is traction-free.
    """

    dirichlet: tuple[Dirichlet, ...] = (Clamp(),)
    interface: tuple[Boundary, ...] = (Boundary.INTERFACE,)
    body_force: tuple[float, float] = (0.0, 0.0)
    pressure: Callable[[float], float] | None = None
    source: Callable[[ufl.SpatialCoordinate], ufl.core.expr.Expr] | None = None
    support: Support | None = None


def boundary_conditions(
    case: Case, pressure: Callable[[float], float] | None = None
) -> SolidBoundaryConditions:
    """The case's conditions: ``moving_wall`` clamps ΓD (the wall ends, or the flag's joint);
    ``fixed_wall`` also holds every dof of the vessel wall, so only the plaque moves. A quarter
    tube holds the normal displacement on its symmetry planes (:class:`SymmetryPlane`).

    ``structure.support`` (if not 0 and 0) supports the stenosis wall's exterior ΓN; in the
    fixed-wall mode ΓN belongs to the held wall and the term has no effect. The Turek–Hron
    flag has no ΓN: there it is ignored, with a warning."""
    s = case.structure
    if s.mode == "rigid":
        raise ValueError("structure.mode 'rigid' has no structure to solve")
    dirichlet: tuple[Dirichlet, ...] = (Clamp((Boundary.CLAMPED,)),)
    dirichlet += tuple(SymmetryPlane(c) for c in symmetry_planes(case.geometry))
    stenosis = isinstance(case.geometry, StenosisGeometry)
    if s.mode == "fixed_wall" and stenosis:
        dirichlet += (HoldRegions((Region.WALL,)),)
    support = None
    if s.support.stiffness > 0 or s.support.damping > 0:
        if stenosis or isinstance(case.geometry, TubeGeometry):
            support = Support(s.support.stiffness, s.support.damping, (Boundary.EXTERIOR,))
        else:
            log.warning(
                "structure.support is ignored: geometry.kind '%s' has no exterior boundary",
                case.geometry.kind,
            )
    return SolidBoundaryConditions(
        dirichlet=dirichlet, body_force=tuple(s.body_force), pressure=pressure, support=support
    )


def region_materials(case: Case) -> dict[Region, Material]:
    """The ``structure`` section's material of each region (wall, cap, lipid, flag)."""
    s = case.structure
    return {Region.WALL: s.wall, Region.CAP: s.cap, Region.LIPID: s.lipid, Region.FLAG: s.flag}


# --------------------------------------------------------------------------------------------
# Dirichlet conditions on the displacement space


def _facets(domain: TaggedMesh, boundaries: Sequence[Boundary] | None) -> np.ndarray:
    """The local facets of ``boundaries`` (``None``: the whole boundary of the mesh)."""
    if boundaries is None:
        return dolfinx.mesh.exterior_facet_indices(domain.mesh.topology)
    return domain.facets(*boundaries)


class DirichletConditions:
    """The structure's :data:`Dirichlet` conditions on the displacement space ``V``.

    :attr:`bcs`: as Newton solves with them (η = 0, or the prescribed value that
    :meth:`update` sets); :attr:`homogeneous`: the same dofs held at 0 (the initial
    acceleration's mass matrix); :attr:`constrained`: every constrained row, the local
    unrolled index ``block × block size + component`` of each constrained component, sorted
    (a :class:`Roller` constrains one component of its blocks, the others all of them).
    """

    def __init__(
        self, domain: TaggedMesh, V: dolfinx.fem.FunctionSpace, conditions: Sequence[Dirichlet]
    ):
        tdim = domain.mesh.topology.dim
        bs = V.dofmap.index_map_bs
        self.bcs, self._prescribed, self.homogeneous = [], [], []
        constrained = [np.zeros(0, dtype=np.int32)]
        zero = np.zeros(domain.mesh.geometry.dim, dtype=PETSc.ScalarType)
        for item in conditions:
            if isinstance(item, Roller):
                # dofs of a subspace: unrolled rows of V.
                sub = V.sub(item.component)
                rows = dolfinx.fem.locate_dofs_topological(
                    sub, tdim - 1, _facets(domain, item.boundaries)
                )
                bc = dolfinx.fem.dirichletbc(PETSc.ScalarType(item.value), rows, sub)
                self.bcs.append(bc)
                if item.value != 0:
                    bc = dolfinx.fem.dirichletbc(PETSc.ScalarType(0), rows, sub)
                self.homogeneous.append(bc)
                constrained.append(rows)
                continue
            if isinstance(item, SymmetryPlane):
                sub = V.sub(item.component)
                rows = bounding_plane_dofs(domain.mesh, sub, item.component)
                bc = dolfinx.fem.dirichletbc(PETSc.ScalarType(0), rows, sub)
                self.bcs.append(bc)
                self.homogeneous.append(bc)
                constrained.append(rows)
                continue
            if isinstance(item, HoldRegions):
                dofs = dolfinx.fem.locate_dofs_topological(V, tdim, domain.cells(*item.regions))
                self.bcs.append(dolfinx.fem.dirichletbc(zero, dofs, V))
            elif isinstance(item, Clamp):
                dofs = dolfinx.fem.locate_dofs_topological(
                    V, tdim - 1, _facets(domain, item.boundaries)
                )
                self.bcs.append(dolfinx.fem.dirichletbc(zero, dofs, V))
            elif isinstance(item, PrescribedDisplacement):
                dofs = dolfinx.fem.locate_dofs_topological(
                    V, tdim - 1, _facets(domain, item.boundaries)
                )
                g = dolfinx.fem.Function(V)
                self.bcs.append(dolfinx.fem.dirichletbc(g, dofs))
                self._prescribed.append((item.value, g))
            else:  # pragma: no cover
                raise TypeError(f"unknown Dirichlet condition {item!r}")
            self.homogeneous.append(dolfinx.fem.dirichletbc(zero, dofs, V))
            constrained.append((dofs[:, None] * bs + np.arange(bs)).ravel())
        self.constrained = np.unique(np.concatenate(constrained))

    def update(self, t: float) -> None:
        """The prescribed displacements at time ``t``."""
        for value, g in self._prescribed:
            g.interpolate(lambda x, value=value: value(x, t))
            g.x.scatter_forward()  # a ghost dof may lie in no local cell of a submesh
