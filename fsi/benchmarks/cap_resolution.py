"""Is the cap's stress resolved? The concentric plaque's structure alone under a uniform pressure
in its lumen (quasi-static, the study's moduli), axisymmetric or 3D (docs/3d.md, "3D against
axisymmetric"): the cap's largest principal stress read two ways,

- ``shipped``: as metrics.csv reports it (``max_principal_cap``, fsi/physics/solid_stress.py):
  at the DG nodes of σ in the plane and axisymmetric models, at the nodes of σ's per-region
  projection onto P1 in 3D (``RegionwiseProjection``), and where;
- ``dg_nodes``: at the nodes of σ's DG interpolant in every model (what 3D reported before the
  projection).

Where a mesh resolves the cap both agree (the axisymmetric coarse mesh: within 0.5 %).

Usage::

    mpirun -n 2 .venv/bin/python scripts/cap_resolution.py --model 3d [--pressure 1000]
        [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import json

from mpi4py import MPI

import numpy as np

from fsi import compat, config
from fsi.geometry.tags import Region
from fsi.numerics.timestepping import NewmarkFamily
from fsi.physics import solid
from fsi.physics.solid_stress import principal_measures

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


def dg_node_principal(s: solid.SolidSolver, region: Region) -> float:
    """The largest σ₁ over the DG nodes of ``region``'s cells, from σ's DG interpolant there
    (what the 3D measures read before the projection; the plane and axisymmetric ones read it
    still). Collective."""
    stress = s.stress
    if not stress.three_d:
        return stress.region_maxima()[region.label].max_principal
    nodes = np.unique(compat.cell_dofs(stress.T)[s.domain.cell_tags.find(int(region))])
    tensors = stress.sigma.x.array.reshape(-1, 3, 3)[nodes]
    s1 = principal_measures(tensors)["max_principal"]
    return s.comm.allreduce(float(s1.max(initial=-np.inf)), op=MPI.MAX)


def measure(model: str, pressure: float, overrides: list[str]) -> dict:
    """The cap's largest σ₁ both ways (Pa) and where (mm), and the structure's cells."""
    case = case_of(model, overrides)
    s = solid.build(case, pressure=lambda t: pressure, scheme=NewmarkFamily.quasi_static())
    result = s.step(1.0, 1.0)
    if not result.converged:
        raise SystemExit(f"cap_resolution: the structure's solve failed: {result.reason}")
    s.stress.update()
    shipped, *where = s.stress.location_of_max("max_principal", Region.CAP)
    mesh = s.domain.mesh
    return {
        "model": model,
        "cells": mesh.topology.index_map(mesh.topology.dim).size_global,
        "shipped": shipped,
        "shipped_at_mm": [round(1e3 * c, 4) for c in where],
        "dg_nodes": dg_node_principal(s, Region.CAP),
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
            f"{result['shipped'] / 1e3:.4f} kPa as fsi reports it, at {result['shipped_at_mm']} "
            f"mm; {result['dg_nodes'] / 1e3:.4f} kPa at σ's DG nodes"
        )
        print(json.dumps(result))
    return 0
