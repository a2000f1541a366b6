"""Plane or axisymmetric: the weight of every integral and the operators with a hoop part.

A plane case (the default) is a slab of unit depth: its integrals are ∫ f dx over the mesh,
per metre of depth (forces in N/m, flow rates in m²/s).

An axisymmetric case (``geometry.axisymmetric: true``, docs/axisymmetric.md) is the meridian
half-plane of a body of revolution: the mesh's x is the axial coordinate z, its y the radius
r ≥ 0 (the axis is y = 0), there is no swirl (every vector's θ component is 0) and nothing
depends on θ. Its integrals are over the whole body, ∫ f 2π r dx, so that forces are in N and
flow rates in m³/s, and the gradient of a vector u = (u_z, u_r) has the hoop component:

    ∇u = [[∂u_z/∂z, ∂u_z/∂r, 0], [∂u_r/∂z, ∂u_r/∂r, 0], [0, 0, u_r/r]],
    ∇·u = ∂u_z/∂z + ∂u_r/∂r + u_r/r.

The in-plane block of ∇u is the plane gradient, so whatever only needs that block (the
convection (a·∇)u without swirl, a traction σ n with n in the meridian plane) is written as in
the plane; the hoop part enters through :meth:`Coordinates.grad`, :meth:`~Coordinates.div`,
:meth:`~Coordinates.strain_rate` and :meth:`~Coordinates.div_symmetric`. A plane
:class:`Coordinates` returns exactly the UFL of ``ufl.grad``, ``ufl.div``, and the measures
themselves, so plane forms are unchanged bit for bit.
"""

from __future__ import annotations

import math

import dolfinx
import ufl


class _Weighted:
    """A UFL measure whose integrals carry the weight 2π r: ``f * measure`` is
    ``(f 2π r) * measure``; ``measure(tag)`` and sums of weighted measures stay weighted."""

    def __init__(self, measure, weight):
        self.measure, self.weight = measure, weight

    def __rmul__(self, integrand):
        return (integrand * self.weight) * self.measure

    def __call__(self, *args, **kwargs) -> _Weighted:
        return _Weighted(self.measure(*args, **kwargs), self.weight)

    def __add__(self, other: _Weighted) -> _Weighted:
        return _Weighted(self.measure + other.measure, self.weight)


class Coordinates:
    """The coordinate system of a mesh: plane (``axisymmetric`` false) or the meridian
    half-plane of a body of revolution (the module docstring)."""

    def __init__(self, mesh: dolfinx.mesh.Mesh, axisymmetric: bool = False):
        self.mesh, self.axisymmetric = mesh, bool(axisymmetric)
        self.r = ufl.SpatialCoordinate(mesh)[1]

    @property
    def weight(self):
        """The factor of an integrand: 2π r (axisymmetric) or 1 (plane)."""
        return 2 * math.pi * self.r if self.axisymmetric else 1

    def measure(self, measure):
        """``measure`` (a UFL measure, or a sum of them) with the weight of its integrals."""
        return _Weighted(measure, 2 * math.pi * self.r) if self.axisymmetric else measure

    def grad(self, u):
        """∇u of a vector ``u``: 2×2, or 3×3 with the hoop part u_r/r."""
        g = ufl.grad(u)
        if not self.axisymmetric:
            return g
        return ufl.as_tensor([[g[0, 0], g[0, 1], 0], [g[1, 0], g[1, 1], 0], [0, 0, u[1] / self.r]])

    def div(self, u):
        """∇·u of a vector ``u`` (with u_r/r when axisymmetric)."""
        return ufl.div(u) + u[1] / self.r if self.axisymmetric else ufl.div(u)

    def strain_rate(self, u):
        """D(u) = (∇u + ∇uᵀ)/2 (with the hoop strain u_r/r when axisymmetric)."""
        return ufl.sym(self.grad(u))

    def identity(self):
        """The identity of the tensors of :meth:`grad`: the mesh's dimension (2×2 plane, 3×3
        in 3D), or 3×3 when axisymmetric."""
        return ufl.Identity(3 if self.axisymmetric else self.mesh.geometry.dim)

    def div_symmetric(self, T, hoop=None):
        """∇·T of a symmetric tensor field given by its in-plane block ``T`` (2×2) and, when
        axisymmetric, its hoop component ``hoop`` = T_θθ:

            (∇·T)_z = ∂T_zz/∂z + ∂T_zr/∂r + T_zr/r,
            (∇·T)_r = ∂T_rz/∂z + ∂T_rr/∂r + (T_rr − T_θθ)/r.
        """
        d = ufl.div(T)
        if not self.axisymmetric:
            return d
        return d + ufl.as_vector([T[0, 1], T[1, 1] - hoop]) / self.r
