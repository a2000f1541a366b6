"""The Turek–Hron benchmark mesh: tags, exact areas, conformity, point A, 1 rank = 2 ranks."""

import json
import math

from mpi4py import MPI

import numpy as np
import pytest
import support_run
from mesh_checks import boundary_vertices

from fsi import cli, config
from fsi.config import reader
from fsi.geometry import turek_hron
from fsi.geometry.tags import Boundary, Region
from fsi.physics import mesh

CONFIGS = [f"configs/turek_hron_{name}.yaml" for name in
           ("cfd1", "cfd2", "cfd3", "csm1", "csm2", "csm3", "fsi1", "fsi3")]  # fmt: skip
TH_REGIONS = (Region.FLUID, Region.FLAG)
TH_BOUNDARIES = (
    Boundary.INLET,
    Boundary.OUTLET,
    Boundary.RIGID_WALL,
    Boundary.OBSTACLE,
    Boundary.INTERFACE,
    Boundary.CLAMPED,
)
assert (turek_hron.REGIONS, turek_hron.BOUNDARIES) == (TH_REGIONS, TH_BOUNDARIES)


def _build(level: str, comm: MPI.Comm = MPI.COMM_WORLD):
    case = config.load("configs/turek_hron_cfd1.yaml", [f"mesh.level={level}"])
    tagged = mesh.build(case, comm)
    return case, tagged, mesh.summary(tagged, case)


@pytest.fixture(scope="module")
def coarse():
    return _build("coarse")


@pytest.fixture(scope="module")
def fine():
    return _build("fine")


def _level(request, level):
    return request.getfixturevalue(level)


def test_every_benchmark_region_and_boundary_is_tagged_and_nothing_else(coarse):
    _, tagged, s = coarse
    assert set(s["cells"]) == {r.label for r in TH_REGIONS} | {"total"}
    assert set(s["facets"]) == {b.label for b in TH_BOUNDARIES}
    for region in TH_REGIONS:
        assert s["cells"][region.label] > 0, region
    for boundary in TH_BOUNDARIES:
        assert s["facets"][boundary.label] > 0, boundary
    assert sum(s["cells"][r.label] for r in TH_REGIONS) == s["cells"]["total"]
    # No cell or facet carries any other tag.
    comm = tagged.comm
    cell_values = set(np.concatenate(comm.allgather(tagged.cell_tags.values)).tolist())
    facet_values = set(np.concatenate(comm.allgather(tagged.facet_tags.values)).tolist())
    assert cell_values == {int(r) for r in TH_REGIONS}
    assert facet_values == {int(b) for b in TH_BOUNDARIES}


def test_exact_areas():
    g = config.TurekHronGeometry()
    a = turek_hron.analytic_areas(g)
    # Independent check of the flag area: integrate the strip's width outside the circle in y.
    y = np.linspace(0.19, 0.21, 200001)
    x_left = 0.2 + np.sqrt(0.05**2 - (y - 0.2) ** 2)
    width = 0.6 - x_left
    flag = float(np.sum((width[1:] + width[:-1]) / 2 * np.diff(y)))  # trapezoids, error ~1e-15
    assert a["flag"] == pytest.approx(flag, rel=1e-10)
    assert a["fluid"] == pytest.approx(2.5 * 0.41 - math.pi * 0.05**2 - flag, rel=1e-12)
    assert 0.02 * 0.35 < a["flag"] < 0.02 * (0.35 + 0.05 - math.sqrt(0.05**2 - 0.01**2))


def _chord_deficit(tagged, boundary: Boundary, r: float) -> float:
    """Σ over the facets on a cylinder arc of the circular segment between arc and chord,
    r²/2 (α − sin α) with α = 2 asin(ℓ / 2r): what a polygon with vertices on the arc misses."""
    segments = mesh.facet_segments(tagged, boundary)
    length = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    alpha = 2 * np.arcsin(length / (2 * r))
    return float(np.sum(r**2 / 2 * (alpha - np.sin(alpha))))


@pytest.mark.parametrize("level", ["coarse", "fine"])
def test_areas_equal_the_exact_ones_up_to_the_cylinder_chords(request, level):
    case, tagged, s = _level(request, level)
    g = case.geometry
    exact = turek_hron.analytic_areas(g)
    r = g.cylinder_radius
    # The chords of the wetted arc cut into the cylinder (the fluid gains those segments); the
    # chords of the clamped arc do the same on the flag's side. Everything else is straight, so
    # with every arc vertex on the circle the mesh areas are exact up to round-off.
    fluid = exact["fluid"] + _chord_deficit(tagged, Boundary.OBSTACLE, r)
    flag = exact["flag"] + _chord_deficit(tagged, Boundary.CLAMPED, r)
    assert s["area_m2"]["fluid"] == pytest.approx(fluid, rel=1e-10)
    assert s["area_m2"]["flag"] == pytest.approx(flag, rel=1e-10)
    assert s["area_m2"]["total"] == pytest.approx(fluid + flag, rel=1e-10)


@pytest.mark.parametrize("level,fluid_tolerance,flag_tolerance", [
    # A chord of angle α misses r² α³ / 12 of its arc. Coarse: ~65 segments of α ≈ 0.1 around
    # the cylinder (fluid 1.2e-5 measured), the 5 segments of the clamped arc (flag 7.8e-5
    # measured); each refinement halves α: ÷16 for two. Tolerances ≈ 2× the coarse estimates.
    ("coarse", 3e-5, 1.6e-4),
    ("fine", 3e-5 / 16, 1.6e-4 / 16),
])  # fmt: skip
def test_areas_converge_to_the_exact_ones(request, level, fluid_tolerance, flag_tolerance):
    case, _, s = _level(request, level)
    exact = turek_hron.analytic_areas(case.geometry)
    assert s["area_m2"]["fluid"] == pytest.approx(exact["fluid"], rel=fluid_tolerance)
    assert s["area_m2"]["flag"] == pytest.approx(exact["flag"], rel=flag_tolerance)
    # Polygons inscribed in the circle: both areas can only be too large.
    assert s["area_m2"]["fluid"] > exact["fluid"] and s["area_m2"]["flag"] > exact["flag"]


@pytest.mark.parametrize("level", ["coarse", "fine"])
def test_cylinder_vertices_lie_on_the_circle_and_a_is_a_vertex(request, level):
    case, tagged, s = _level(request, level)
    g = case.geometry
    for boundary in (Boundary.OBSTACLE, Boundary.CLAMPED):
        x = mesh.facet_segments(tagged, boundary).reshape(-1, 2)
        radius = np.linalg.norm(x - np.array(g.cylinder_centre), axis=1)
        # uniform refinement puts the new vertices on the circle, not on the old chords
        assert np.abs(radius - g.cylinder_radius).max() < 1e-12
    assert s["measures"]["point_a_distance_m"] == 0.0
    tip = mesh.facet_segments(tagged, Boundary.INTERFACE).reshape(-1, 2)
    assert np.any(np.all(tip == np.array(turek_hron.point_a(g)), axis=1))  # A is on the interface


def _vertices(tagged, boundary: Boundary) -> set[tuple[float, float]]:
    return {tuple(x) for x in mesh.facet_segments(tagged, boundary).reshape(-1, 2)}


def test_fluid_and_flag_meshes_share_the_interface_vertices_exactly(coarse):
    _, tagged, s = coarse
    fluid, _ = mesh.extract(tagged, Region.FLUID)
    flag, _ = mesh.extract(tagged, Region.FLAG)
    interface = _vertices(tagged, Boundary.INTERFACE)
    on_fluid, on_flag = boundary_vertices(fluid), boundary_vertices(flag)
    assert interface <= on_fluid and interface <= on_flag  # bitwise-equal coordinates
    assert on_fluid & on_flag == interface  # and no other boundary vertex is shared
    assert len(interface) == s["facets"]["interface"] + 1  # one open polyline, joint to joint
    # The flag's boundary is the interface and the clamped arc, which meet at the two joints.
    clamped = _vertices(tagged, Boundary.CLAMPED)
    assert on_flag == interface | clamped and len(interface & clamped) == 2
    # The obstacle arc closes the interface into the hole of the fluid domain.
    obstacle = _vertices(tagged, Boundary.OBSTACLE)
    assert len(obstacle | interface) == s["facets"]["obstacle"] + s["facets"]["interface"]
    assert not (clamped - interface) & on_fluid  # the joint arc is not wetted


def test_default_sizes_resolve_the_cylinder_and_the_flag(coarse, fine):
    _, _, s = coarse
    # Few thousand triangles, >= 60 segments around the cylinder, >= 4 cells across the flag:
    # enough for CFD1 drag within ~1 % with P2/P1 (0.05 % measured with a steady solve).
    assert 3000 <= s["cells"]["total"] <= 8000
    assert s["measures"]["cylinder_segments"] >= 60
    assert s["measures"]["flag_tip_segments"] >= 4
    f = fine[2]
    assert f["cells"]["total"] == 16 * s["cells"]["total"]  # two uniform refinements
    assert f["measures"]["cylinder_segments"] == 4 * s["measures"]["cylinder_segments"]
    assert f["measures"]["flag_tip_segments"] == 4 * s["measures"]["flag_tip_segments"]


def test_totals_are_identical_on_one_and_all_ranks(coarse):
    case, _, s_world = coarse
    tagged = mesh.build(case, MPI.COMM_SELF)
    s_self = mesh.summary(tagged, case)
    assert s_self["cells"] == s_world["cells"]
    assert s_self["facets"] == s_world["facets"]
    assert s_self["measures"] == s_world["measures"]
    for name, area in s_self["area_m2"].items():
        assert s_world["area_m2"][name] == pytest.approx(area, rel=1e-12)


@pytest.mark.parametrize("path", CONFIGS)
def test_benchmark_configs_are_valid(path):
    case = config.load(path)
    assert isinstance(case.geometry, config.TurekHronGeometry)
    assert case.geometry == config.TurekHronGeometry()  # the benchmark's dimensions
    assert turek_hron.point_a(case.geometry) == pytest.approx((0.6, 0.2), abs=1e-15)
    assert (case.structure.mode == "rigid") == ("cfd" in path)


@pytest.mark.parametrize("text,key,expected", [
    ("geometry: {kind: turek_hron, flag_thickness: 0.1}", "geometry.flag_thickness", "diameter"),
    ("geometry: {kind: turek_hron, flag_length: 2.3}", "geometry.flag_length", "outlet"),
    ("geometry: {kind: turek_hron, cylinder_radius: 0.25}", "geometry.cylinder_radius", "inside"),
    ("geometry: {kind: turek_hron, cylinder_centre: [0.2]}", "geometry.cylinder_centre", "two"),
    ("geometry: {kind: turek_hron, height: -1}", "geometry.height", "positive"),
])  # fmt: skip
def test_invalid_geometry_is_rejected(text, key, expected):
    with pytest.raises(config.ConfigError) as e:
        config.from_dict(reader.parse_yaml(text + "\nstructure: {mode: rigid}"))
    assert e.value.key == key and expected in e.value.expected


def test_fsi_mesh_writes_the_benchmark_mesh(shared_tmp, coarse):
    out = shared_tmp / "th"
    assert cli.main(["mesh", "configs/turek_hron_fsi1.yaml", "--out", str(out)]) == 0
    summary = json.loads((out / "mesh.json").read_text())
    assert summary["cells"] == coarse[2]["cells"]
    assert summary["facets"] == coarse[2]["facets"]
    assert summary["measures"]["point_a_distance_m"] == 0.0
    msh, _, facet_tags = support_run.read_mesh_with_tags(MPI.COMM_WORLD, str(out / "mesh.xdmf"))
    tags = set(np.unique(np.concatenate(MPI.COMM_WORLD.allgather(facet_tags.values))))
    assert tags == {int(b) for b in TH_BOUNDARIES}
