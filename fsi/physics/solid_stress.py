"""The structure's Cauchy stress as DG fields on its current configuration, with their maxima
per region and where they are attained (the study's stress measures; docs/model.md, Structure).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import numpy as np
import ufl

from fsi import compat
from fsi.physics.materials import HyperelasticLaw, cauchy, cauchy_zz

# --------------------------------------------------------------------------------------------
# Stresses


class SolidDisplacement(Protocol):
    """What the stresses read from the solver (fsi.physics.solid.SolidSolver): the tagged
    mesh and its coordinates (plane or axisymmetric), the displacement η and its degree, the
    regions and each cell's region."""

    domain: Any
    coordinates: Any
    degree: int
    eta: dolfinx.fem.Function
    comm: Any
    regions: Any
    cell_region: Any


@dataclass(frozen=True)
class RegionStress:
    """Maxima over one region (Pa): von Mises, largest principal, largest |σ₁₂| (the SSS;
    σ_zr when axisymmetric)."""

    max_von_mises: float
    max_principal: float
    max_abs_shear: float


class StressFields:
    """Cauchy stress of the current η as DG fields, and their per-region maxima.

    ``σ = J⁻¹ P Fᵀ`` (in-plane) on the current configuration, plane strain with
    ``σ₃₃ = J⁻¹ Σ₃₃``; the study's structural shear stress ``σ₁₂``; von Mises
    ``sqrt(((σ₁₁−σ₂₂)² + (σ₂₂−σ₃₃)² + (σ₃₃−σ₁₁)²)/2 + 3σ₁₂²)``; the largest principal stress
    ``max((σ₁₁+σ₂₂)/2 + sqrt(((σ₁₁−σ₂₂)/2)² + σ₁₂²), σ₃₃)``. Fields are interpolated into DG
    of degree ``max(k − 1, 0)`` for P``k`` displacements (the degree of ∇η), at its points.

    Axisymmetric (x = z, y = r): ``σ = J⁻¹ F Σ Fᵀ`` with the 3×3 F of the hoop stretch
    (:attr:`sigma` is 3×3, its [2, 2] entry the hoop stress σ_θθ), and σ_θθ takes the place of
    σ₃₃ above: it is a principal stress (no swirl: σ_zθ = σ_rθ = 0), so von Mises and the
    largest principal stress are the formulas above with σ₃₃ = σ_θθ; the SSS is σ_zr.

    :attr:`cell_fields` are what the field files hold (XDMF stores one value per cell): each
    cell's extreme of the fields above (``sss``: the value of largest magnitude, sign kept;
    ``von_mises`` and ``max_principal``: the largest), so their maxima over a region are the
    :meth:`region_maxima`; and ``region``, the cell's region tag (geometry/tags.py ``Region``).
    """

    def __init__(self, solver: SolidDisplacement, law: HyperelasticLaw, prestress=None):
        self.solver = solver
        mesh = solver.domain.mesh
        degree = max(solver.degree - 1, 0)
        self.S = compat.function_space(mesh, "DG", degree)
        sigma, s33 = self._cauchy(solver.coordinates, law, solver.eta, prestress)
        self.T = compat.function_space(mesh, "DG", degree, sigma.ufl_shape)
        s11, s22, s12 = sigma[0, 0], sigma[1, 1], sigma[0, 1]
        von_mises = ufl.sqrt(
            ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2) / 2 + 3 * s12**2
        )
        in_plane = (s11 + s22) / 2 + ufl.sqrt(((s11 - s22) / 2) ** 2 + s12**2)
        principal = ufl.max_value(in_plane, s33)
        self.sigma = dolfinx.fem.Function(self.T)
        self.sigma.name = "sigma"
        self.fields = {}
        self._expressions = [
            (self.sigma, dolfinx.fem.Expression(sigma, compat.interpolation_points(self.T)))
        ]
        for name, expr in (("sss", s12), ("von_mises", von_mises), ("max_principal", principal)):
            f = dolfinx.fem.Function(self.S)
            f.name = name
            self.fields[name] = f
            self._expressions.append(
                (f, dolfinx.fem.Expression(expr, compat.interpolation_points(self.S)))
            )
        dofs = compat.cell_dofs(self.S)
        self._dof_points = self.S.tabulate_dof_coordinates()[:, :2].copy()  # reference config.
        n_owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self._all_cell_dofs = dofs
        self._cell_dofs = dofs[:n_owned]
        self._cell_region = solver.cell_region[:n_owned]
        S0 = compat.function_space(mesh, "DG", 0)
        self._cell_value = compat.cell_dofs(S0)[:, 0]  # cell → its DG0 dof
        self.cell_fields = {}
        for name in (*self.fields, "region"):
            f = dolfinx.fem.Function(S0)
            f.name = name
            self.cell_fields[name] = f
        region = self.cell_fields["region"].x.array
        region[self._cell_value] = solver.cell_region[: len(self._cell_value)]

    @staticmethod
    def _cauchy(coordinates, law: HyperelasticLaw, eta, prestress=None):
        """The Cauchy stress of η and its out-of-plane principal component: plane, the 2×2
        in-plane σ and the plane-strain ``σ₃₃ = J⁻¹ Σ₃₃``; axisymmetric, the 3×3 σ and σ_θθ.
        ``prestress`` (fsi/physics/prestress.py): of the deformation ``F F₀`` from the
        stress-free reference."""
        F = coordinates.identity() + coordinates.grad(eta)
        if prestress is not None:
            F = prestress.total(F)
        sigma = cauchy(law, F)
        if coordinates.axisymmetric:
            return sigma, sigma[2, 2]
        return sigma, cauchy_zz(law, F)

    def update(self) -> None:
        """Interpolate the stresses of the current η; their cell extremes."""
        for f, expr in self._expressions:
            f.interpolate(expr)
        for name, f in self.fields.items():
            values = f.x.array[self._all_cell_dofs]  # (cells, dofs per cell)
            if name == "sss":  # signed: the value of largest magnitude
                extreme = np.take_along_axis(
                    values, np.abs(values).argmax(axis=1)[:, None], axis=1
                )[:, 0]
            else:
                extreme = values.max(axis=1)
            self.cell_fields[name].x.array[self._cell_value] = extreme

    def region_maxima(self) -> dict[str, RegionStress]:
        """Per region (and ``"all"``): the maxima over the region's cells on all ranks.

        Call :meth:`update` first.
        """
        out = {}
        comm = self.solver.comm
        vm = self.fields["von_mises"].x.array
        pr = self.fields["max_principal"].x.array
        sh = np.abs(self.fields["sss"].x.array)
        regions = [(r.label, [int(r)]) for r in self.solver.regions]
        regions.append(("all", [int(r) for r in self.solver.regions]))
        for label, values in regions:
            dofs = self._cell_dofs[np.isin(self._cell_region, values)].ravel()
            local = [float(a[dofs].max(initial=-np.inf)) for a in (vm, pr, sh)]
            out[label] = RegionStress(*(float(comm.allreduce(v, op=MPI.MAX)) for v in local))
        return out

    def location_of_max(self, name: str, region: int) -> tuple[float, float, float]:
        """(value, x, y): the largest value of the stress field ``name`` (``max_principal``,
        ``von_mises``) over the cells of ``region`` on all ranks (the value
        :meth:`region_maxima` reports) and where it is attained: the point (m, reference
        configuration) of the field's DG node that holds it (for P2 displacements a vertex of
        the cell, for P1 its midpoint). Ties go to the smallest x, then y, so the point does not
        depend on the partition; (NaN, NaN, NaN) for an empty region. Call :meth:`update`
        first. Collective."""
        values = self.fields[name].x.array
        dofs = self._cell_dofs[np.isin(self._cell_region, [int(region)])].ravel()
        best = (-np.inf, np.nan, np.nan)
        if len(dofs):
            top = values[dofs].max()
            points = self._dof_points[dofs[values[dofs] == top]]
            x, y = min(map(tuple, points))
            best = (float(top), float(x), float(y))
        found = [b for b in self.solver.comm.allgather(best) if b[0] > -np.inf]
        if not found:
            return (np.nan, np.nan, np.nan)
        top = max(b[0] for b in found)
        return min((b for b in found if b[0] == top), key=lambda b: (b[1], b[2]))
