"""The case's tagged mesh: gmsh builds it on rank 0, dolfinx distributes it, and its measures.

The geometry builders (``geometry/``) add entities and physical groups to a gmsh model; this
module meshes that model at the configured level (coarse, then uniform refinements; in 3D meshed
anew with smaller sizes), hands it to dolfinx, and measures the distributed mesh: cell and facet
counts, region areas (volumes in 3D, :mod:`fsi.physics.mesh_3d`), the stenosis degree and the
thinnest fibrous cap. Every function here is collective.
"""

from __future__ import annotations

import contextlib
import logging
import signal
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import dolfinx.mesh
import numpy as np
import ufl

from fsi import compat, config
from fsi.config import Case, ChannelGeometry, StenosisGeometry, TubeGeometry, TurekHronGeometry
from fsi.geometry import channel, stenosis, tube, turek_hron, vessel_3d
from fsi.geometry.tags import Boundary, Region
from fsi.physics import mesh_3d

log = logging.getLogger(__name__)


@dataclass
class TaggedMesh:
    """A mesh with its region and boundary tags: the whole system's, or a region's submesh."""

    mesh: dolfinx.mesh.Mesh
    cell_tags: dolfinx.mesh.MeshTags
    facet_tags: dolfinx.mesh.MeshTags
    parent_cells: np.ndarray | None = None  # for a submesh: its cells' indices in the parent

    @property
    def comm(self) -> MPI.Comm:
        return self.mesh.comm

    def cells(self, *regions: Region) -> np.ndarray:
        """Local indices of the cells in ``regions`` (owned and ghost)."""
        mask = np.isin(self.cell_tags.values, [int(r) for r in regions])
        return self.cell_tags.indices[mask]

    def facets(self, *boundaries: Boundary) -> np.ndarray:
        """Local indices of the facets on ``boundaries``."""
        mask = np.isin(self.facet_tags.values, [int(b) for b in boundaries])
        return self.facet_tags.indices[mask]


def build(case: Case, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """Mesh the case's geometry with gmsh on rank 0 and distribute it over ``comm``."""
    with _sigint_kept():
        return _build(case, comm)


@contextlib.contextmanager
def _sigint_kept():
    """Keep the process's SIGINT handler across a gmsh session: gmsh's Python API sets SIGINT
    to its default (4.8 when imported, 4.13 in ``initialize``) and at ``finalize`` puts back
    the handler of its import (4.8) or none (4.13), so Ctrl-C would kill a run instead of
    reaching its checkpointing handler (fsi/cli.py)."""
    handler = signal.getsignal(signal.SIGINT)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)


def _build(case: Case, comm: MPI.Comm) -> TaggedMesh:
    error = None
    dim = config.dimension(case.geometry)
    if comm.rank == 0:
        gmsh = _start_gmsh()
        try:
            _build_model(case)
            gmsh.model.mesh.generate(dim)
            if dim == 2:  # a 3D level is meshed anew with smaller sizes (_build_model)
                for _ in range(case.mesh.refinements):
                    gmsh.model.mesh.refine()
        except Exception as e:  # reported on every rank below, before any collective
            error = f"gmsh failed to mesh the geometry: {e}"
    error = comm.bcast(error, root=0)
    if error is not None:
        if comm.rank == 0:
            gmsh.finalize()
        raise RuntimeError(error)
    try:
        mesh, cell_tags, facet_tags = compat.model_to_mesh(comm, 0, gdim=dim)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    mesh.topology.create_connectivity(dim - 1, dim)
    mesh.topology.create_entities(dim - 1)
    cell_tags.name, facet_tags.name = "cell_tags", "facet_tags"
    return TaggedMesh(mesh, cell_tags, facet_tags)


def _start_gmsh():
    """Import and initialise gmsh so that it reads and writes no file of its own: not the
    user's ``~/.gmshrc`` and ``~/.gmsh-options`` (their options would change the mesh), and not
    FLTK's preference files. Returns the module.

    gmsh hands its GUI option defaults to FLTK even without a GUI (General.Tooltips), and
    FLTK's first look at its options opens and rewrites ``$HOME/.fltk/fltk.org/fltk.prefs``
    and, as root, ``/etc/fltk/fltk.org/fltk.prefs``. Marking FLTK's options as already read
    (``Fl::options_read_``) skips that; they keep FLTK's defaults, which only a GUI uses."""
    import gmsh

    _skip_fltk_preferences()
    gmsh.initialize(readConfigFiles=False)  # gmsh 4.8 (Debian 12) to 4.13 (Debian 13)
    gmsh.option.setNumber("General.Terminal", 0)
    return gmsh


def _skip_fltk_preferences() -> bool:
    """Set FLTK's ``Fl::options_read_`` in the libfltk that gmsh loaded; False if this process
    has none (gmsh built without FLTK) or it has no such symbol."""
    import ctypes

    try:  # the files mapped into this process (Linux)
        mapped = Path("/proc/self/maps").read_text().split()
    except OSError:
        return False
    for library in {p for p in mapped if Path(p).name.startswith("libfltk.so")}:
        try:
            ctypes.c_ubyte.in_dll(ctypes.CDLL(library), "_ZN2Fl13options_read_E").value = 1
            return True
        except (OSError, ValueError):
            pass
    return False


def _build_model(case: Case) -> None:
    g, m = case.geometry, case.mesh
    if config.dimension(g) == 3:
        # Each level halves the size field (the sizes and the grading's slope, so the graded
        # band keeps its width) and meshes anew, rather than splitting every tetrahedron in
        # eight as the 2D levels split triangles (docs/3d.md: the 2D levels' sizes, and
        # Delaunay-quality tetrahedra at every level).
        scale = 0.5**m.refinements
        if isinstance(g, StenosisGeometry):
            grading = vessel_3d.GRADING * scale
            lumen = None if m.lumen_size is None else m.lumen_size * scale
            vessel_3d.build_stenosis(
                g, m.size * scale, m.local_size * scale, grading, lumen_size=lumen
            )
        else:
            vessel_3d.build_tube(g, size=m.size * scale)
    elif isinstance(g, StenosisGeometry):
        stenosis.build(g, size=m.size, local_size=m.local_size)
    elif isinstance(g, ChannelGeometry):
        channel.build(g, size=m.size)
    elif isinstance(g, TubeGeometry):
        tube.build(g, size=m.size)
    elif isinstance(g, TurekHronGeometry):
        turek_hron.build(g, size=m.size, local_size=m.local_size)
    else:  # pragma: no cover - the config admits no other kind
        raise ValueError(f"unknown geometry kind {g.kind!r}")


def regions(case: Case) -> tuple[Region, ...]:
    """The region tags of the case's mesh (the geometry module's ``REGIONS``)."""
    if config.dimension(case.geometry) == 3:
        return mesh_3d.regions(case.geometry)
    return geometry_module(case).REGIONS


def geometry_module(case: Case):
    """The module of geometry/ that builds the case's (plane or axisymmetric) geometry."""
    return {
        StenosisGeometry: stenosis,
        ChannelGeometry: channel,
        TubeGeometry: tube,
        TurekHronGeometry: turek_hron,
    }[type(case.geometry)]


def boundaries(case: Case) -> tuple[Boundary, ...]:
    """The boundary tags of the case's mesh (the geometry module's ``BOUNDARIES``; an
    axisymmetric stenosis has the axis in place of the rigid wall; geometry/vessel_3d.py's in
    3D)."""
    if config.dimension(case.geometry) == 3:
        return mesh_3d.boundaries(case.geometry)
    if isinstance(case.geometry, StenosisGeometry):
        return stenosis.boundaries(case.geometry)
    return geometry_module(case).BOUNDARIES


def extract(tagged: TaggedMesh, *regions: Region):
    """The submesh of ``regions`` (e.g. the fluid, or wall + cap + lipid), its parent-cell map."""
    return compat.create_submesh(tagged.mesh, tagged.mesh.topology.dim, tagged.cells(*regions))


def restrict(tagged: TaggedMesh, *regions: Region) -> TaggedMesh:
    """The submesh of ``regions`` with the parent's cell and facet tags carried over (a facet
    keeps its tag on each side that has it); ``parent_cells`` maps its cells to the parent's."""
    mesh = tagged.mesh
    tdim = mesh.topology.dim
    submesh, parent_cells = extract(tagged, *regions)
    submesh.topology.create_connectivity(tdim, tdim - 1)
    submesh.topology.create_connectivity(tdim - 1, tdim)
    mesh.topology.create_connectivity(tdim, tdim - 1)

    # A submesh cell keeps its parent's vertex order, so local facet k is the parent's facet k.
    n_sub = (
        submesh.topology.index_map(tdim).size_local + submesh.topology.index_map(tdim).num_ghosts
    )
    sub_c2f = _cell_facets(submesh, n_sub)
    parent_c2f = _cell_facets(
        mesh, mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
    )[parent_cells[:n_sub]]
    n_parent_facets = (
        mesh.topology.index_map(tdim - 1).size_local + mesh.topology.index_map(tdim - 1).num_ghosts
    )
    parent_to_sub = np.full(n_parent_facets, -1, dtype=np.int32)
    parent_to_sub[parent_c2f.ravel()] = sub_c2f.ravel()

    facet_values = np.full(n_parent_facets, -1, dtype=np.int32)
    facet_values[tagged.facet_tags.indices] = tagged.facet_tags.values
    keep = (parent_to_sub >= 0) & (facet_values >= 0)
    sub_facets, values = parent_to_sub[keep], facet_values[keep]
    order = np.argsort(sub_facets)
    sub_facets, values = sub_facets[order], values[order]
    parent_facets = np.flatnonzero(keep)[order].astype(np.int32)
    if not np.allclose(
        _midpoints(submesh, sub_facets),
        _midpoints(mesh, parent_facets),
        rtol=0.0,
        atol=1e-12 * _extent(mesh),
    ):
        raise RuntimeError("restrict: the submesh's facets do not match the parent's")
    facet_tags = dolfinx.mesh.meshtags(submesh, tdim - 1, sub_facets, values)

    parent_cell_values = np.full(
        mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts,
        -1,
        dtype=np.int32,
    )
    parent_cell_values[tagged.cell_tags.indices] = tagged.cell_tags.values
    cell_values = parent_cell_values[parent_cells]
    cell_tags = dolfinx.mesh.meshtags(
        submesh, tdim, np.arange(len(parent_cells), dtype=np.int32), cell_values
    )
    cell_tags.name, facet_tags.name = "cell_tags", "facet_tags"
    return TaggedMesh(submesh, cell_tags, facet_tags, parent_cells)


def owned_facet_dofs(V, facets: np.ndarray) -> np.ndarray:
    """The owned (block) dofs of ``V`` on the given local facets (e.g. the interface)."""
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    dofs = dolfinx.fem.locate_dofs_topological(V, fdim, facets)
    return dofs[dofs < V.dofmap.index_map.size_local]


def _midpoints(mesh, facets: np.ndarray) -> np.ndarray:
    nodes = compat.entities_to_geometry(mesh, mesh.topology.dim - 1, facets).reshape(
        len(facets), -1
    )
    return mesh.geometry.x[nodes].mean(axis=1)


def _extent(mesh) -> float:
    x = mesh.geometry.x
    return float(np.ptp(x, axis=0).max()) if len(x) else 1.0


def _cell_facets(mesh, n_cells: int) -> np.ndarray:
    """Facet indices of the first ``n_cells`` cells, shape (n_cells, facets per cell)."""
    tdim = mesh.topology.dim
    c2f = mesh.topology.connectivity(tdim, tdim - 1)
    return c2f.array.reshape(-1, tdim + 1)[:n_cells]


def _owned_count(indices: np.ndarray, index_map) -> int:
    return int(np.count_nonzero(indices < index_map.size_local))


def summary(tagged: TaggedMesh, case: Case) -> dict:
    """Cell counts and areas (``area_m2``; volumes, ``volume_m3``, in 3D) per region, facet
    counts per boundary and geometric measures.

    Counts cover owned entities only, so they are the same on any number of ranks.
    """
    mesh, comm = tagged.mesh, tagged.comm
    tdim = mesh.topology.dim
    cell_map, facet_map = mesh.topology.index_map(tdim), mesh.topology.index_map(tdim - 1)
    dx = ufl.Measure("dx", domain=mesh, subdomain_data=tagged.cell_tags)
    one = dolfinx.fem.Constant(mesh, 1.0)

    def area(measure) -> float:
        local = dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * measure))
        return float(comm.allreduce(local, op=MPI.SUM))

    cells = {
        r.label: comm.allreduce(_owned_count(tagged.cells(r), cell_map)) for r in regions(case)
    }
    cells["total"] = cell_map.size_global
    if tdim == 3:  # summed exactly rounded: the same bits on any number of ranks
        areas = mesh_3d.region_volumes(tagged, regions(case))
    else:
        areas = {r.label: area(dx(int(r))) for r in regions(case)}
        areas["total"] = area(dx)
    facets = {
        b.label: comm.allreduce(_owned_count(tagged.facets(b), facet_map)) for b in boundaries(case)
    }
    measure = "volume_m3" if tdim == 3 else "area_m2"
    result = {"cells": cells, measure: areas, "facets": facets}
    if tdim == 3:
        result["measures"] = mesh_3d.measures(tagged, case.geometry)
    elif isinstance(case.geometry, StenosisGeometry):
        result["measures"] = stenosis_measures(tagged, case.geometry)
    elif isinstance(case.geometry, TurekHronGeometry):
        result["measures"] = turek_hron_measures(tagged, case.geometry)
    return result


def facet_segments(tagged: TaggedMesh, boundary: Boundary) -> np.ndarray:
    """End points (n, 2, 2) of every facet on ``boundary``, gathered on all ranks."""
    mesh = tagged.mesh
    facets = tagged.facets(boundary)
    facets = facets[facets < mesh.topology.index_map(1).size_local]
    nodes = compat.entities_to_geometry(mesh, 1, facets).reshape(-1, 2)
    local = mesh.geometry.x[nodes][:, :, :2]
    return np.concatenate(tagged.comm.allgather(local)).reshape(-1, 2, 2)


def turek_hron_measures(tagged: TaggedMesh, g: TurekHronGeometry) -> dict:
    """How finely the benchmark's obstacle is resolved, and whether point A is a mesh vertex.

    ``cylinder_segments``: facets around the whole cylinder (obstacle + clamped arc);
    ``flag_tip_segments``: facets across the flag at its tip; ``point_a_distance_m``: distance
    from point A to the nearest mesh vertex (0 when A is a vertex).
    """
    cylinder = len(facet_segments(tagged, Boundary.OBSTACLE)) + len(
        facet_segments(tagged, Boundary.CLAMPED)
    )
    interface = facet_segments(tagged, Boundary.INTERFACE)
    on_tip = np.abs(interface[:, :, 0] - turek_hron.tip_x(g)) <= 1e-12 * g.length
    a = np.array(turek_hron.point_a(g))
    x = tagged.mesh.geometry.x[:, :2]
    nearest = float(np.sqrt(((x - a) ** 2).sum(axis=1)).min(initial=np.inf))
    return {
        "cylinder_segments": cylinder,
        "flag_tip_segments": int(np.count_nonzero(on_tip.all(axis=1))),
        "point_a_distance_m": float(tagged.comm.allreduce(nearest, op=MPI.MIN)),
    }


def stenosis_measures(tagged: TaggedMesh, g: StenosisGeometry) -> dict:
    """The stenosis degree and the thinnest fibrous cap, measured on the mesh.

    Degree: the fraction of the lumen height the plaques occlude at their apex. Cap thickness:
    the smallest distance from a cap–lipid vertex to the lumen boundary (the interface facets).
    """
    interface = facet_segments(tagged, Boundary.INTERFACE)
    y = interface[:, :, 1].ravel()
    # With plaque on both sides each is lower than half the lumen; with one, all is that side's.
    sides = stenosis.sides(g)
    split = g.height / 2 if len(sides) == 2 else (np.inf if "bottom" in sides else -np.inf)
    bottom = y[y < split].max(initial=0.0)
    top = (g.height - y[y >= split]).max(initial=0.0)
    lipid_vertices = facet_segments(tagged, Boundary.CAP_LIPID).reshape(-1, 2)
    thinnest = stenosis.distance_to_segments(lipid_vertices, interface[:, 0], interface[:, 1])
    return {
        "stenosis_degree": float((bottom + top) / g.height),
        "min_cap_thickness_m": float(thinnest.min()),
    }


def _plane_tolerance(mesh) -> float:
    """A millionth of the mesh's extent (every rank's)."""
    x = mesh.geometry.x
    return 1e-6 * float(mesh.comm.allreduce(np.ptp(x, axis=0).max(initial=0.0), op=MPI.MAX))


def bounding_plane_dofs(mesh, space, component: int) -> np.ndarray:
    """The dofs of ``space`` (a space or a subspace) on the boundary's facets in the plane
    x_``component`` = 0 (to :func:`_plane_tolerance`): a mirror plane that bounds the mesh, such
    as a quarter tube's cuts, whose dofs are those facets'. (A plane through the body would need
    the dofs of its vertices and edges: dolfinx 0.5 crashed now and then locating a submesh's
    dofs on those on 2 ranks, so fsi has none.)"""
    tolerance = _plane_tolerance(mesh)
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, mesh.topology.dim)
    facets = dolfinx.mesh.locate_entities_boundary(
        mesh, fdim, lambda p: np.abs(p[component]) <= tolerance
    )
    return dolfinx.fem.locate_dofs_topological(space, fdim, facets)
