"""The tagged stenosis mesh: tags, sizes, areas, conformity, measures, 1 rank = 2 ranks."""

import json
import subprocess
import sys

from mpi4py import MPI

import numpy as np
import pytest
import support_run
from mesh_checks import boundary_vertices

from fsi import cli, config
from fsi.config import reader
from fsi.geometry import stenosis
from fsi.geometry.tags import STRUCTURE_REGIONS, Boundary, Region
from fsi.physics import mesh

STUDY_COARSE_TRIANGLES = 3272  # docs/model.md §1
STENOSIS_REGIONS = (Region.FLUID, Region.WALL, Region.CAP, Region.LIPID)
STENOSIS_BOUNDARIES = (
    Boundary.INLET,
    Boundary.OUTLET,
    Boundary.INTERFACE,
    Boundary.RIGID_WALL,
    Boundary.CLAMPED,
    Boundary.EXTERIOR,
    Boundary.CAP_LIPID,
    Boundary.PLAQUE_BASE,
)


@pytest.fixture(scope="module")
def coarse():
    case = config.from_dict({})
    tagged = mesh.build(case)
    return case, tagged, mesh.summary(tagged, case)


@pytest.fixture(scope="module")
def fine():
    case = config.from_dict({"mesh": {"level": "fine"}})
    tagged = mesh.build(case)
    return case, tagged, mesh.summary(tagged, case)


def test_every_region_and_boundary_is_tagged_and_non_empty(coarse):
    _, _, s = coarse
    for region in STENOSIS_REGIONS:
        assert s["cells"][region.label] > 0, region
    for boundary in STENOSIS_BOUNDARIES:
        assert s["facets"][boundary.label] > 0, boundary
    assert sum(s["cells"][r.label] for r in STENOSIS_REGIONS) == s["cells"]["total"]


def test_mesh_sizes_match_the_study(coarse, fine):
    n_coarse, n_fine = coarse[2]["cells"]["total"], fine[2]["cells"]["total"]
    assert abs(n_coarse / STUDY_COARSE_TRIANGLES - 1) < 0.10
    assert n_fine == 16 * n_coarse  # two uniform refinements, as the study's 3,272 -> 52,352


@pytest.mark.parametrize("level,tolerance", [("coarse", 5e-3), ("fine", 5e-4)])
def test_region_areas_match_the_cosine_integrals(coarse, fine, level, tolerance):
    case, _, s = coarse if level == "coarse" else fine
    exact = stenosis.analytic_areas(case.geometry)
    for name, area in exact.items():
        assert s["area_m2"][name] == pytest.approx(area, rel=tolerance), name


@pytest.mark.parametrize("level,tolerance", [("coarse", 5e-3), ("fine", 5e-4)])
def test_measured_stenosis_degree_and_cap_thickness(coarse, fine, level, tolerance):
    case, _, s = coarse if level == "coarse" else fine
    g = case.geometry
    # The apexes are gmsh points, so the degree is exact; the thinnest cap is measured from the
    # cap–lipid vertices to the lumen facets, whose chords lie slightly inside the curve.
    assert s["measures"]["stenosis_degree"] == pytest.approx(g.stenosis_degree, rel=1e-12)
    assert s["measures"]["min_cap_thickness_m"] == pytest.approx(g.cap_thickness, rel=tolerance)
    assert s["measures"]["min_cap_thickness_m"] <= g.cap_thickness * (1 + 1e-12)


def test_fluid_and_structure_meshes_share_the_interface_vertices_exactly(coarse):
    _, tagged, s = coarse
    fluid, _ = mesh.extract(tagged, Region.FLUID)
    solid, _ = mesh.extract(tagged, *STRUCTURE_REGIONS)
    interface = {tuple(x) for x in mesh.facet_segments(tagged, Boundary.INTERFACE).reshape(-1, 2)}
    on_fluid, on_solid = boundary_vertices(fluid), boundary_vertices(solid)
    assert interface <= on_fluid and interface <= on_solid  # bitwise-equal coordinates
    assert on_fluid & on_solid == interface  # and no other boundary vertex is shared
    assert len(interface) == s["facets"]["interface"] + 1  # one open polyline


def test_totals_are_identical_on_one_and_all_ranks(coarse):
    case, _, s_world = coarse
    tagged = mesh.build(case, MPI.COMM_SELF)
    s_self = mesh.summary(tagged, case)
    assert s_self["cells"] == s_world["cells"]
    assert s_self["facets"] == s_world["facets"]
    for name, area in s_self["area_m2"].items():
        assert s_world["area_m2"][name] == pytest.approx(area, rel=1e-12)
    for name, value in s_self["measures"].items():
        assert s_world["measures"][name] == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize("sides", [["top"], ["bottom", "top"]])
def test_plaque_on_the_top_or_both_sides(sides):
    case = config.from_dict({"geometry": {"plaque_sides": sides}})
    tagged = mesh.build(case)
    s = mesh.summary(tagged, case)
    exact = stenosis.analytic_areas(case.geometry)
    for name, area in exact.items():
        assert s["area_m2"][name] == pytest.approx(area, rel=5e-3), name
    assert s["measures"]["stenosis_degree"] == pytest.approx(0.5, rel=1e-12)
    assert (
        s["facets"].get("rigid_wall", 0) > 0 if len(sides) == 1 else "rigid_wall" not in s["facets"]
    )
    assert s["measures"]["min_cap_thickness_m"] == pytest.approx(0.0005, rel=5e-3)


def test_the_axisymmetric_stenosis_is_a_ring_on_the_wall_above_the_axis():
    """``axisymmetric``: the bottom side is the axis (tag ``axis``, no rigid wall), the plaque a
    ring on the top wall closing ``stenosis_degree`` of the radius (``height``), the meridian
    areas the plane one-sided plaque's (the top's mirror of the default)."""
    case = config.from_dict({"geometry": {"axisymmetric": True, "height": 0.0035}})
    tagged = mesh.build(case)
    s = mesh.summary(tagged, case)
    assert s["facets"]["axis"] > 0 and "rigid_wall" not in s["facets"]
    for name, area in stenosis.analytic_areas(case.geometry).items():
        assert s["area_m2"][name] == pytest.approx(area, rel=5e-3), name
    assert s["measures"]["stenosis_degree"] == pytest.approx(0.5, rel=1e-12)
    assert s["measures"]["min_cap_thickness_m"] == pytest.approx(0.0005, rel=5e-3)
    axis = mesh.facet_segments(tagged, Boundary.AXIS)
    assert np.abs(axis[:, :, 1]).max() == 0.0
    interface = mesh.facet_segments(tagged, Boundary.INTERFACE).reshape(-1, 2)
    assert interface[:, 1].min() == pytest.approx(0.0035 / 2, rel=1e-9)  # the apex, r = R/2


def test_the_plaque_placed_upstream_in_a_longer_segment():
    """``stenosis_centre`` moves the plaque: at 1 cm of a 4 cm segment (2 cm more downstream than
    the study's) the areas are the cosine integrals, the apex is at x = 1 cm, and the plaque in
    the middle given explicitly has the default mesh's vertices, bit for bit."""
    case = config.from_dict({"geometry": {"length": 0.04, "stenosis_centre": 0.01}})
    tagged = mesh.build(case)
    s = mesh.summary(tagged, case)
    for name, area in stenosis.analytic_areas(case.geometry).items():
        assert s["area_m2"][name] == pytest.approx(area, rel=5e-3), name
    assert s["measures"]["stenosis_degree"] == pytest.approx(0.5, rel=1e-12)
    assert s["measures"]["min_cap_thickness_m"] == pytest.approx(0.0005, rel=5e-3)
    interface = mesh.facet_segments(tagged, Boundary.INTERFACE).reshape(-1, 2)
    apex = interface[np.argmax(interface[:, 1])]
    assert apex[0] == pytest.approx(0.01, abs=1e-12)
    middle = mesh.build(config.from_dict({"geometry": {"stenosis_centre": 0.01}}))
    default = mesh.build(config.from_dict({}))
    assert np.array_equal(_vertices(middle), _vertices(default))


def _vertices(tagged: mesh.TaggedMesh) -> np.ndarray:
    """Every vertex of the mesh (owned ones gathered from all ranks), sorted: independent of
    the partition."""
    m = tagged.mesh
    owned = m.geometry.x[: m.geometry.index_map().size_local, :2]
    every = np.concatenate(tagged.comm.allgather(owned))
    return every[np.lexsort(every.T)]


def test_channel_mesh():
    case = config.from_dict(
        reader.parse_yaml(
            "geometry: {kind: channel, length: 0.02, height: 0.007}\nstructure: {mode: rigid}"
        )
    )
    tagged = mesh.build(case)
    s = mesh.summary(tagged, case)
    assert s["area_m2"]["fluid"] == pytest.approx(0.02 * 0.007, rel=1e-12)
    assert s["cells"]["total"] == s["cells"]["fluid"] > 0
    assert set(s["facets"]) == {"inlet", "outlet", "rigid_wall"}
    assert min(s["facets"].values()) > 0
    assert "measures" not in s


def test_fsi_mesh_writes_xdmf_and_json(shared_tmp, coarse):
    out = shared_tmp / "mesh"
    assert cli.main(["mesh", "configs/stenosis_fixed_newtonian.yaml", "--out", str(out)]) == 0
    summary = json.loads((out / "mesh.json").read_text())
    assert set(summary["cells"]) == {"fluid", "wall", "cap", "lipid", "total"}
    assert set(summary["area_m2"]) == {"fluid", "wall", "cap", "lipid", "total"}
    assert {"inlet", "outlet", "interface", "rigid_wall", "clamped", "exterior"} <= set(
        summary["facets"]
    )
    assert set(summary["measures"]) == {"stenosis_degree", "min_cap_thickness_m"}
    assert summary["cells"] == coarse[2]["cells"]

    # The XDMF file reads back with the same tags.
    msh, cell_tags, facet_tags = support_run.read_mesh_with_tags(
        MPI.COMM_WORLD, str(out / "mesh.xdmf")
    )
    n_cells = msh.topology.index_map(2).size_local
    owned = cell_tags.indices < n_cells
    fluid = MPI.COMM_WORLD.allreduce(int(np.count_nonzero(cell_tags.values[owned] == Region.FLUID)))
    assert fluid == summary["cells"]["fluid"]
    assert set(np.unique(np.concatenate(MPI.COMM_WORLD.allgather(facet_tags.values)))) == {
        int(b) for b in STENOSIS_BOUNDARIES
    }


def test_geometry_is_installed_under_the_project_name(tmp_path):
    """The geometry/ folder is the package fsi.geometry; no top-level ``geometry`` is installed
    (a name any other project may also use). Run outside the checkout, whose folder would
    otherwise be on the path."""
    probe = (
        "import fsi.geometry.stenosis\n"
        "try:\n    import geometry\nexcept ImportError:\n    print('absent')"
    )
    result = subprocess.run(
        [sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "absent"


@pytest.mark.parametrize("degree", [0.3, 0.5, 0.8])
@pytest.mark.parametrize("lipid_length", [0.002, 0.006, 0.0095])
def test_the_thinnest_cap_is_the_minimum_over_every_sample(degree, lipid_length):
    """min_cap_thickness searches every 10th lipid sample, then around those that may hold the
    minimum: the same value as the distance of every sample to the cap (exactly), and the
    apex's cap_thickness while the pool is short."""
    import dataclasses

    g = config.load("configs/stenosis_fixed_newtonian.yaml").geometry
    p = dataclasses.replace(g, stenosis_degree=degree, lipid_length=lipid_length)
    samples, xc = 801, p.length / 2
    x_lipid = np.linspace(xc - p.lipid_length / 2, xc + p.lipid_length / 2, samples)
    x_cap = np.linspace(xc - p.stenosis_length / 2, xc + p.stenosis_length / 2, 2 * samples)
    lipid = np.column_stack([x_lipid, stenosis.lipid_profile(p, x_lipid)])
    cap = np.column_stack([x_cap, stenosis.plaque_profile(p, x_cap)])
    every = float(stenosis.distance_to_polyline(lipid, cap).min())
    assert stenosis.min_cap_thickness(p) == every
    if lipid_length <= 0.006:
        assert every == pytest.approx(p.cap_thickness, rel=2e-5)  # chords of 6 µm: ~5e-9 m
