"""Is the cap's stress resolved? The concentric plaque's structure alone under a uniform pressure
in its lumen (quasi-static, the study's moduli), axisymmetric or 3D (docs/3d.md, "3D against
axisymmetric"): the cap's largest principal stress read two ways, with where it is,

- ``nodal``: the largest value at the nodes of the DG stress field, what metrics.csv reports
  (``max_principal_cap``; fsi/physics/solid_stress.py);
- ``projected``: the largest nodal value of σ's L² projection onto continuous P1 over the cap's
  cells alone (each component; σ₁ from the projected tensor at each node: the hoop stress and
  the in-plane pair when axisymmetric, the eigenvalues in 3D).

Both read one converged field; where the field is resolved they agree (the axisymmetric coarse
mesh: within 0.5 %), and their spread measures how far a mesh is from resolving the cap.

Usage::

    mpirun -n 2 .venv/bin/python scripts/cap_resolution.py --model 3d [--pressure 1000]
        [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import json

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem.petsc
import numpy as np
import ufl

from fsi import compat, config
from fsi.geometry.tags import Region
from fsi.numerics.timestepping import NewmarkFamily
from fsi.physics import solid

CONFIGS = {
    "axisymmetric": "configs/axisymmetric/stenosis_moving_carreau.yaml",
    "3d": "configs/3d/stenosis_eccentric_moving_carreau.yaml",
}


def case_of(model: str, overrides: list[str]) -> config.Case:
    """The moving-wall Carreau case, the plaque concentric in 3D, its wall loaded by the inlet
    pressure alone."""
    common = ["structure.mode=moving_wall", "structure.interface_load=inlet_pressure"]
    if model == "3d":
        common.insert(0, "geometry.plaque_angle=360")
    return config.load(CONFIGS[model], [*common, *overrides])


def projected_principal(s: solid.SolidSolver, region: Region) -> tuple[float, np.ndarray]:
    """The largest σ₁ of σ's L² projection onto P1 over ``region``'s cells, and its node.
    Collective."""
    mesh = s.domain.mesh
    P1 = compat.function_space(mesh, "Lagrange", 1)
    dx = s.coordinates.measure(ufl.Measure("dx", domain=mesh))
    p, q = ufl.TrialFunction(P1), ufl.TestFunction(P1)
    inside = dolfinx.fem.Function(compat.function_space(mesh, "DG", 0))  # 1 in the region
    inside.x.array[
        compat.cell_dofs(inside.function_space)[s.domain.cell_tags.find(int(region)), 0]
    ] = 1.0
    inside.x.scatter_forward()
    M = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(inside * p * q * dx))
    M.assemble()
    unit = M.getDiagonal()  # 1 on the rows outside the region, whose mass is 0
    unit.array[:] = np.where(unit.array == 0, 1.0, 0.0)  # owned rows (not localForm: no ghosts)
    M.setDiagonal(unit, addv=PETSc.InsertMode.ADD_VALUES)
    ksp = PETSc.KSP().create(mesh.comm)
    ksp.setOperators(M)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    sigma = s.stress.sigma
    n = sigma.ufl_shape[0]
    owned = P1.dofmap.index_map.size_local
    tensors = np.zeros((owned, n, n))
    x = M.createVecRight()
    for i in range(n):
        for j in range(i, n):
            b = dolfinx.fem.petsc.assemble_vector(dolfinx.fem.form(inside * sigma[i, j] * q * dx))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            ksp.solve(b, x)
            tensors[:, i, j] = tensors[:, j, i] = x.array
    if s.coordinates.axisymmetric:  # (z, r, θ): the in-plane pair's larger and the hoop stress
        s1 = np.maximum(np.linalg.eigvalsh(tensors[:, :2, :2])[:, 1], tensors[:, 2, 2])
    else:
        s1 = np.linalg.eigvalsh(tensors)[:, -1]
    nodes = np.unique(compat.cell_dofs(P1)[s.domain.cell_tags.find(int(region))])
    nodes = nodes[nodes < owned]
    points = P1.tabulate_dof_coordinates()[:, : mesh.geometry.dim]
    best = (-np.inf, None)
    if len(nodes):
        k = nodes[np.argmax(s1[nodes])]
        best = (float(s1[k]), points[k])
    return max(mesh.comm.allgather(best), key=lambda b: b[0])


def measure(model: str, pressure: float, overrides: list[str]) -> dict:
    """The cap's largest σ₁ both ways (Pa) and where (mm), and the structure's cells."""
    case = case_of(model, overrides)
    s = solid.build(case, pressure=lambda t: pressure, scheme=NewmarkFamily.quasi_static())
    result = s.step(1.0, 1.0)
    if not result.converged:
        raise SystemExit(f"cap_resolution: the structure's solve failed: {result.reason}")
    s.stress.update()
    nodal, *where = s.stress.location_of_max("max_principal", Region.CAP)
    projected, node = projected_principal(s, Region.CAP)
    mesh = s.domain.mesh
    return {
        "model": model,
        "cells": mesh.topology.index_map(mesh.topology.dim).size_global,
        "nodal": nodal,
        "nodal_at_mm": [round(1e3 * c, 4) for c in where],
        "projected": projected,
        "projected_at_mm": [round(1e3 * float(c), 4) for c in node],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", choices=sorted(CONFIGS), required=True)
    parser.add_argument("--pressure", type=float, default=1000.0, help="Pa in the lumen")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    result = measure(args.model, args.pressure, args.set)
    if MPI.COMM_WORLD.rank == 0:
        print(
            f"{args.model} ({result['cells']} structure cells): the cap's largest σ₁ "
            f"{result['nodal'] / 1e3:.4f} kPa at the DG nodes, at {result['nodal_at_mm']} mm; "
            f"{result['projected'] / 1e3:.4f} kPa projected onto P1, at "
            f"{result['projected_at_mm']} mm"
        )
        print(json.dumps(result))
    return 0
