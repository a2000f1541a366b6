"""The 3D vessels (geometry.dimension 3, geometry/vessel_3d.py): tags, volumes against the exact
ones, the eccentric plaque's span, the lumen's area, point A, mesh.json on 1 and 2 ranks, and
the inputs refused before any computation."""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import support_run

from fsi import cli, compat, config
from fsi.config import run_size
from fsi.geometry import stenosis, vessel_3d
from fsi.geometry.tags import Region
from fsi.physics import mesh, mesh_3d

SAMPLE = Path(__file__).parents[1] / "configs/3d/stenosis_eccentric_mesh.yaml"
GEOMETRY = {
    "kind": "stenosis",
    "dimension": 3,
    "length": 0.02,
    "height": 0.0035,
    "wall_thickness": 0.001,
}
# Coarser than the sample's (0.8 mm, 0.35 mm) to keep these tests to a few seconds.
CONCENTRIC = {"geometry": {**GEOMETRY, "plaque_angle": 360}, "mesh": {"size": 1.2e-3,
              "local_size": 6e-4}}  # fmt: skip
TUBE = {
    "geometry": {"kind": "tube", "dimension": 3, "axisymmetric": False, "length": 0.02,
                 "radius": 0.0035, "wall_thickness": 0.001},
    "mesh": {"size": 1e-3},
    "structure": {"mode": "moving_wall"},
}  # fmt: skip


def _built(case: config.Case, comm: MPI.Comm = MPI.COMM_WORLD):
    tagged = mesh.build(case, comm)
    return case, tagged, mesh.summary(tagged, case)


@pytest.fixture(scope="module")
def eccentric():
    """The sample's 120° plaque as ``fsi mesh`` writes it (into a folder shared by the ranks):
    the case, the mesh read back from mesh.xdmf with its tags, mesh.json, and the folder."""
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    out = folder / "mesh3d"
    assert cli.main(["mesh", str(SAMPLE), "--out", str(out)]) == 0
    msh, cell_tags, facet_tags = support_run.read_mesh_with_tags(comm, str(out / "mesh.xdmf"))
    tagged = mesh.TaggedMesh(msh, cell_tags, facet_tags)
    yield config.load(SAMPLE), tagged, json.loads((out / "mesh.json").read_text()), out
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="module")
def concentric():
    return _built(config.from_dict(CONCENTRIC))


@pytest.fixture(scope="module")
def quarter():
    """The concentric case's quarter (``sector: 90``), between the mirror planes y = 0, z = 0."""
    return _built(config.from_dict({**CONCENTRIC, "geometry": {**GEOMETRY, "sector": 90}}))


@pytest.fixture(scope="module")
def tube():
    return _built(config.from_dict(TUBE))


def test_every_region_and_boundary_is_tagged_and_non_empty(eccentric, quarter, tube):
    for case, _, s, *_ in (eccentric, quarter, tube):
        for region in mesh.regions(case):
            assert s["cells"][region.label] > 0, region
        assert sum(s["cells"][r.label] for r in mesh.regions(case)) == s["cells"]["total"]
        assert set(s["facets"]) == {b.label for b in mesh.boundaries(case)}
        for boundary in mesh.boundaries(case):
            assert s["facets"][boundary.label] > 0, boundary
    assert set(eccentric[2]["cells"]) == {"fluid", "wall", "cap", "lipid", "total"}
    assert set(tube[2]["facets"]) == {"inlet", "outlet", "interface", "clamped", "exterior"}


def _inscribed_loss(size: float, radius: float) -> float:
    """The relative area a circle of ``radius`` loses to an inscribed polygon of chords at most
    ``size``: 1 − sin(θ)/θ with θ = 2 asin(size / 2r), ≈ size² / (6 r²)."""
    theta = 2 * math.asin(size / (2 * radius))
    return 1 - math.sin(theta) / theta


def test_tube_volumes_and_lumen_area_are_the_cylinders(tube):
    """The lumen πR²L and the wall π((R + t)² − R²)L: the mesh's boundary vertices lie on the
    circles, so its sections are inscribed polygons of chords up to ~size. The lumen loses at
    most the fraction :func:`_inscribed_loss` (1.4 % at 1 mm on R = 3.5 mm; measured 0.6 %);
    the wall loses it on its outer circle and gains it back on its inner one (bounded by
    πL size²/6 in all: 2 % of it; measured 0.1 %). The lumen's surface, 2πRL, loses what an
    inscribed polygon's perimeter does, ≈ size²/(24 R²) = 0.34 %."""
    case, _, s = tube
    g, h = case.geometry, case.mesh.size
    exact = vessel_3d.analytic_volumes(g)
    R, t, L = g.radius, g.wall_thickness, g.length
    assert exact["fluid"] == pytest.approx(math.pi * R**2 * L, rel=1e-15)
    assert exact["wall"] == pytest.approx(math.pi * ((R + t) ** 2 - R**2) * L, rel=1e-15)
    volume = s["volume_m3"]
    assert 1 - _inscribed_loss(h, R) <= volume["fluid"] / exact["fluid"] <= 1
    assert abs(volume["wall"] - exact["wall"]) <= math.pi * L * h**2 / 6
    assert volume["total"] == pytest.approx(volume["fluid"] + volume["wall"], rel=1e-12)
    area = s["measures"]["interface_area_m2"]
    assert 1 - _inscribed_loss(h, R) / 4 <= area / vessel_3d.interface_area(g) <= 1


def _stenosis(which: str, concentric, eccentric, quarter):
    return {"concentric": concentric, "eccentric": eccentric, "quarter": quarter}[which]


@pytest.mark.parametrize("which", ["concentric", "eccentric", "quarter"])
def test_stenosis_volumes_match_pappus(which, concentric, eccentric, quarter):
    """The plaque's cap and lipid pool are the meridian areas of geometry/stenosis.py revolved
    over their spans: by Pappus, the angle times ∫ (R s − s²/2) dx. The mesh's volumes meet
    them within the inscribed-polygon loss at the local size on the smallest radius there,
    R − A (2.0 % at 0.6 mm for the concentric case, 0.7 % at 0.35 mm for the sample's; the
    B-spline profiles add less than 0.01 %, allowed 0.1 %); the lumen and the wall as for the
    tube, at the size. The concentric quarter's exact volumes are a quarter of the whole's."""
    case, _, s, *_ = _stenosis(which, concentric, eccentric, quarter)
    g, m = case.geometry, case.mesh
    exact = vessel_3d.analytic_volumes(g)
    R, A = g.height, stenosis.plaque_height(g)
    plaque_tolerance = _inscribed_loss(m.local_size, R - A) + 1e-3
    for name in ("cap", "lipid"):
        assert s["volume_m3"][name] == pytest.approx(exact[name], rel=plaque_tolerance), name
    assert s["volume_m3"]["fluid"] == pytest.approx(exact["fluid"], rel=_inscribed_loss(m.size, R))
    wall_tolerance = math.pi * g.length * m.size**2 / 6
    assert s["volume_m3"]["wall"] == pytest.approx(exact["wall"], abs=wall_tolerance)
    if which == "quarter":
        whole = vessel_3d.analytic_volumes(concentric[0].geometry)
        for name in ("fluid", "wall", "cap", "lipid"):
            assert exact[name] == pytest.approx(whole[name] / 4, rel=1e-14), name
    if which == "concentric":  # the revolved axisymmetric plaque: the whole ring
        plaque = exact["cap"] + exact["lipid"]
        meridian = stenosis.analytic_areas(
            config.from_dict({"geometry": {"axisymmetric": True, "height": R}}).geometry
        )
        # Pappus with the meridian areas' centroids: the cosine bump's is at s̄ = 3A/8 from
        # the wall, so the plaque's path is 2π(R − 3A/8).
        pappus = (meridian["cap"] + meridian["lipid"]) * 2 * math.pi * (R - 3 * A / 8)
        assert plaque == pytest.approx(pappus, rel=1e-12)


def test_the_eccentric_plaque_stays_in_its_span(eccentric):
    """Every vertex of the cap lies within the plaque's angle |φ| <= 120°/2 and its axial
    extent, every vertex of the pool within the pool's narrower angle; the two halves φ < 0
    and φ > 0 hold (nearly) the same volume."""
    case, tagged, _, _ = eccentric
    g = case.geometry
    m = tagged.mesh
    nodes = compat.geometry_dofmap(m)[: m.topology.index_map(3).size_local]
    x = m.geometry.x
    for region, span in ((Region.CAP, vessel_3d.plaque_angle(g)),
                         (Region.LIPID, vessel_3d.lipid_angle(g))):  # fmt: skip
        cells = tagged.cells(region)
        cells = cells[cells < len(nodes)]  # the owned ones
        points = x[nodes[cells]].reshape(-1, 3)
        phi = np.arctan2(points[:, 2], points[:, 1])
        assert np.abs(phi).max() <= span / 2 + 1e-9, region
        half = g.stenosis_length / 2
        assert np.abs(points[:, 0] - stenosis.apex_x(g)).max() <= half * (1 + 1e-9)
        centres = x[nodes[cells]].mean(axis=1)
        v = np.abs(np.linalg.det(x[nodes[cells]][:, 1:] - x[nodes[cells]][:, :1])) / 6
        upper = m.comm.allreduce(v[centres[:, 2] > 0].sum())
        lower = m.comm.allreduce(v[centres[:, 2] < 0].sum())
        assert upper == pytest.approx(lower, rel=0.02), region
    assert vessel_3d.lipid_angle(g) < vessel_3d.plaque_angle(g) == pytest.approx(math.radians(120))


@pytest.mark.parametrize("which", ["concentric", "eccentric", "quarter"])
def test_lumen_area_and_the_plaque_measures(which, concentric, eccentric, quarter):
    """The lumen surface's area against :func:`vessel_3d.interface_area` (the revolved cap's
    by quadrature, the eccentric plaque's flat ends); the stenosis degree exact (the apex is a
    circle of mesh vertices); the area reduction 1 − (1 − d)² over the plaque's share of the
    circle, measured from two polygonal sections (within 1 %); the thinnest cap within the
    local size's chord error of cap_thickness; point A a vertex. The quarter's area a quarter
    of the concentric vessel's, its area reduction the same."""
    case, _, s, *_ = _stenosis(which, concentric, eccentric, quarter)
    if which == "quarter":
        whole = vessel_3d.interface_area(concentric[0].geometry)
        assert vessel_3d.interface_area(case.geometry) == pytest.approx(whole / 4, rel=1e-12)
    g, measures = case.geometry, s["measures"]
    assert measures["interface_area_m2"] == pytest.approx(vessel_3d.interface_area(g), rel=5e-3)
    assert measures["stenosis_degree"] == pytest.approx(g.stenosis_degree, rel=1e-12)
    share = g.plaque_angle / 360
    assert vessel_3d.area_reduction(g) == pytest.approx(share * (1 - 0.5**2), rel=1e-12)
    assert measures["area_reduction"] == pytest.approx(vessel_3d.area_reduction(g), rel=1e-2)
    assert measures["min_cap_thickness_m"] == pytest.approx(g.cap_thickness, rel=1e-2)
    assert measures["point_a_distance_m"] == 0.0


def test_the_quarters_cuts_carry_no_tag(quarter):
    """No tagged face of the concentric quarter lies on its cuts y = 0 and z = 0 (every tagged
    face's centroid off them: no traction, support or clamp acts there; fsi/physics holds the
    normal components), and they are its mirror planes."""
    case, tagged, _ = quarter
    for boundary in mesh.boundaries(case):
        centroids = mesh_3d.facet_triangles(tagged, boundary).mean(axis=1)
        assert centroids[:, 1:].min(initial=np.inf) > 0, boundary
    assert config.symmetry_planes(case.geometry) == (1, 2)


def test_point_a_is_a_vertex_of_the_tube(tube):
    case, tagged, s = tube
    assert s["measures"]["point_a_distance_m"] == 0.0
    assert vessel_3d.point_a(case.geometry) == (0.01, 0.0035, 0.0)


def test_the_cell_estimate_is_near_the_count(eccentric, concentric, quarter, tube):
    """Validation's estimate (mesh.max_cells) within a factor 1.5 of gmsh's count."""
    for case, _, s, *_ in (eccentric, concentric, quarter, tube):
        ratio = run_size.estimated_cells(case) / s["cells"]["total"]
        assert 1 / 1.5 < ratio < 1.5, (case.geometry.kind, ratio)


def test_fsi_mesh_writes_the_same_json_on_every_rank(eccentric):
    """``fsi mesh`` writes the summary of its mesh, the same as of the mesh read back from its
    mesh.xdmf (the tags survive), and on several ranks the mesh.json of the serial mesh, bit
    for bit."""
    case, tagged, written, _ = eccentric
    assert tagged.mesh.topology.dim == 3
    assert written == json.loads(json.dumps(mesh.summary(tagged, case)))
    assert set(written["measures"]) == {
        "interface_area_m2",
        "point_a_distance_m",
        "stenosis_degree",
        "area_reduction",
        "min_cap_thickness_m",
    }
    comm = MPI.COMM_WORLD
    tags = set(np.unique(np.concatenate(comm.allgather(tagged.facet_tags.values))))
    assert tags == {int(b) for b in vessel_3d.STENOSIS_BOUNDARIES}
    if comm.size > 1:  # the serial mesh's summary, made on rank 0 alone
        serial = _built(case, MPI.COMM_SELF)[2] if comm.rank == 0 else None
        assert written == json.loads(json.dumps(comm.bcast(serial, root=0)))


@pytest.mark.parametrize(
    "overrides,key",
    [
        (["geometry.plaque_angle=0"], "geometry.plaque_angle"),
        (["geometry.plaque_angle=361"], "geometry.plaque_angle"),
        (["geometry.plaque_angle=20"], "geometry.plaque_angle"),  # too narrow for its pool
        (["geometry.plaque_angle=359.9"], "geometry.plaque_angle"),  # a healthy strip of 6 µm
        (["geometry.stenosis_degree=1.0"], "geometry.stenosis_degree"),  # the whole lumen
        (["geometry.cap_thickness=0.002"], "geometry.cap_thickness"),  # thicker than the plaque
        (["geometry.axisymmetric=true"], "geometry.axisymmetric"),
        (["geometry.plaque_sides=[top]"], "geometry.plaque_sides"),
        (["geometry.dimension=2"], "geometry.plaque_angle"),  # a 2D plaque spans no angle
        (["geometry.dimension=4"], "geometry.dimension"),
        (["geometry.sector=90"], "geometry.sector"),  # an eccentric plaque's is no mirror
        (["mesh.lumen_size=0"], "mesh.lumen_size"),
        (["mesh.lumen_size=0.001"], "mesh.lumen_size"),  # coarser than mesh.size
    ],
)
def test_bad_3d_inputs_exit_2_naming_the_key(shared_tmp, capsys, overrides, key):
    out = shared_tmp / "refused"
    args = [a for o in overrides for a in ("--set", o)]
    assert cli.main(["mesh", str(SAMPLE), "--out", str(out), *args]) == cli.EXIT_USAGE
    if MPI.COMM_WORLD.rank == 0:
        assert f"{key}:" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("kind", ["turek_hron", "channel"])
def test_a_3d_benchmark_or_channel_is_refused(shared_tmp, capsys, kind):
    data = {"geometry": {"kind": kind, "dimension": 3}, "structure": {"mode": "rigid"}}
    with pytest.raises(config.ConfigError) as refused:
        config.from_dict(data)
    assert refused.value.key == "geometry.dimension"


def test_a_lumen_size_is_only_for_a_3d_stenosis():
    with pytest.raises(config.ConfigError) as refused:
        config.from_dict({"geometry": {"kind": "stenosis"}, "mesh": {"lumen_size": 2e-4}})
    assert refused.value.key == "mesh.lumen_size"


def _throat_edges(built) -> np.ndarray:
    """The mean edge (m) of each fluid tetrahedron whose centroid lies in the throat's core:
    the middle half of the plaque's length, r < (R − A)/2 (every rank's)."""
    case, tagged, _ = built
    g, msh = case.geometry, tagged.mesh
    R, A, xc = g.height, stenosis.plaque_height(g), stenosis.apex_x(g)
    n_owned = msh.topology.index_map(3).size_local
    tags = tagged.cell_tags
    fluid = tags.indices[(tags.values == int(Region.FLUID)) & (tags.indices < n_owned)]
    points = msh.geometry.x[compat.geometry_dofmap(msh)[fluid]]  # (cells, 4, 3)
    centre = points.mean(axis=1)
    core = (np.abs(centre[:, 0] - xc) < g.stenosis_length / 4) & (
        np.hypot(centre[:, 1], centre[:, 2]) < (R - A) / 2
    )
    pairs = [(i, j) for i in range(4) for j in range(i + 1, 4)]
    edges = np.mean([np.linalg.norm(points[:, i] - points[:, j], axis=1) for i, j in pairs], axis=0)
    return np.concatenate(MPI.COMM_WORLD.allgather(edges[core]))


def test_a_lumen_size_refines_the_throat(concentric):
    """``mesh.lumen_size`` sets the size in the throat's core (r ≤ R − A over the plaque's
    length), which the plaque's box alone leaves graded: there the tetrahedra's mean edges
    shrink to about the lumen size (measured 1.02 → 0.39 mm), and the estimate follows."""
    lumen = 3e-4
    refined = _built(config.from_dict({**CONCENTRIC, "mesh": {**CONCENTRIC["mesh"],
                                                              "lumen_size": lumen}}))  # fmt: skip
    before, after = _throat_edges(concentric), _throat_edges(refined)
    assert np.median(before) > 2 * lumen  # graded from the plaque's box
    assert np.median(after) < 1.5 * lumen
    assert refined[2]["cells"]["fluid"] > 1.5 * concentric[2]["cells"]["fluid"]
    ratio = run_size.estimated_cells(refined[0]) / refined[2]["cells"]["total"]
    assert 1 / 1.5 < ratio < 1.5, ratio


@pytest.mark.slow
def test_each_level_halves_the_sizes():
    """``medium`` meshes the sample anew at half the sizes: ~8× the tetrahedra, the volumes
    closer to the exact ones."""
    coarse = _built(config.load(SAMPLE))[2]
    medium = _built(config.load(SAMPLE, ["mesh.level=medium"]))[2]
    ratio = medium["cells"]["total"] / coarse["cells"]["total"]
    assert 5 < ratio < 8.5  # measured 6.3: the coarse mesh is denser near its boundaries
    exact = vessel_3d.analytic_volumes(config.load(SAMPLE).geometry)
    for name in ("fluid", "cap", "lipid"):
        e0 = abs(coarse["volume_m3"][name] / exact[name] - 1)
        e1 = abs(medium["volume_m3"][name] / exact[name] - 1)
        assert e1 < e0, name
