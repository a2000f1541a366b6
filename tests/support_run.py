"""Helpers of the tests of the run, its outputs and compat: what they compute beside the
package's own code (moved out of fsi, where nothing but the tests used them)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import dolfinx.io
import numpy as np
import ufl

from fsi import cli, compat
from fsi.output import metrics, metrics_csv, report_figures, report_runs
from fsi.physics import rheology


def fsi_run(case_file: str, out: Path, overrides: Sequence[str] = ()) -> tuple[int, list[dict]]:
    """``fsi run case_file --out out --set ...`` (fields written rarely): the exit status and the
    complete metrics rows as numbers (those written before a failure)."""
    settings = ["output.fields_every=100000", *overrides]
    args = ["run", case_file, "--out", str(out), *sum((["--set", s] for s in settings), [])]
    status = cli.main(args)
    return status, metrics_csv.read_metrics(out / "metrics.csv")


def reattachment_point(s: np.ndarray, tau: np.ndarray) -> float | None:
    """Where the longest reversed-flow zone ends (the flow reattaches), or None."""
    zones = metrics.recirculation_zones(s, tau)
    return max(zones, key=lambda z: z[1] - z[0])[1] if zones else None


def surface_force(flow: metrics.WallFlow, quadrature_degree: int = 4) -> np.ndarray:
    """(F_x, F_y) = ∫ σ n_b ds over ``flow.tags``, the force of the fluid on a body whose outward
    normal n_b = −n points into the fluid (Turek–Hron's drag and lift, N/m). The residual-based
    :meth:`fsi.physics.fluid.FluidSolver.boundary_force` is the more accurate variant."""
    mesh, measure = flow.mesh, flow.measure(quadrature_degree)
    traction = -flow.stress() * ufl.FacetNormal(mesh)
    force = [
        dolfinx.fem.assemble_scalar(dolfinx.fem.form(traction[i] * measure))
        for i in range(mesh.geometry.dim)
    ]
    return mesh.comm.allreduce(np.array(force, dtype=float), op=MPI.SUM)


def _field(expr, mesh, name: str, degree: int) -> dolfinx.fem.Function:
    space = compat.function_space(mesh, "DG", degree)
    f = dolfinx.fem.Function(space, name=name)
    if isinstance(expr, ufl.constantvalue.ConstantValue):  # e.g. a Newtonian viscosity
        f.x.array[:] = float(expr)
    else:
        f.interpolate(dolfinx.fem.Expression(expr, compat.interpolation_points(space)))
    return f


def shear_rate_field(u: dolfinx.fem.Function, degree: int = 1) -> dolfinx.fem.Function:
    """s(u) = sqrt(2 D(u):D(u)) (1/s) interpolated into discontinuous P``degree``."""
    return _field(rheology.shear_rate(u), u.function_space.mesh, "shear_rate", degree)


def viscosity_field(
    u: dolfinx.fem.Function, law: rheology.ViscosityLaw, degree: int = 1
) -> dolfinx.fem.Function:
    """The effective viscosity μ(s(u)) (Pa s) interpolated into discontinuous P``degree``."""
    return _field(law.mu(rheology.shear_rate(u)), u.function_space.mesh, "viscosity", degree)


def flow_rate_plot(runs: Sequence[report_runs.Run], path: Path) -> bool:
    """The inlet (solid) and outlet (dashed, same colour) flow rates per unit depth over time,
    in cm²/s, as a PNG; False if no run has them."""
    return (
        report_figures.draw(report_figures.flow_rate_groups(runs), "flow rate", "flow_rate", path)
        is not None
    )


def read_mesh_with_tags(comm: MPI.Comm, path: str):
    """Read ``mesh.xdmf`` as written by :func:`fsi.physics.mesh.write`: the mesh, cell and facet
    tags."""
    with dolfinx.io.XDMFFile(comm, path, "r") as xdmf:
        mesh = xdmf.read_mesh(name="mesh")
        tdim = mesh.topology.dim
        cell_tags = xdmf.read_meshtags(mesh, name="cell_tags")
        mesh.topology.create_connectivity(tdim - 1, tdim)
        facet_tags = xdmf.read_meshtags(mesh, name="facet_tags")
    return mesh, cell_tags, facet_tags
