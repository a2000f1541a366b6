"""The 3D-against-axisymmetric benchmark (fsi/benchmarks/concentric_3d.py, docs/3d.md): the
runs' settings load as the cases they say, the table's differences and verdicts, the rigid wall's
comparison as CI runs it (the concentric quarter against the axisymmetric model: the largest
velocity and the flow rate within 3 %), and the whole benchmark, rigid and moving wall (slow)."""

from __future__ import annotations

from pathlib import Path

from mpi4py import MPI

import pytest
from test_restart import fsi_run

from fsi import config
from fsi.benchmarks import concentric_3d


def test_the_two_models_run_the_same_plaque():
    axisymmetric = config.load(
        concentric_3d.CONFIGS["axisymmetric"],
        concentric_3d.settings("axisymmetric", "moving_wall", 0.01),
    )
    three_d = config.load(
        concentric_3d.CONFIGS["3d"],
        concentric_3d.settings("3d", "moving_wall", 0.01, 2.5e-4, local_size=3e-4),
    )
    a, b = axisymmetric.geometry, three_d.geometry
    assert a.axisymmetric and b.dimension == 3 and b.plaque_angle == 360 and b.sector == 90
    for key in ("length", "height", "wall_thickness", "stenosis_length", "stenosis_degree",
                "cap_thickness", "lipid_length"):  # fmt: skip
        assert getattr(a, key) == getattr(b, key), key
    assert axisymmetric.mesh.level == "fine" and three_d.mesh.lumen_size == 2.5e-4
    assert three_d.mesh.local_size == 3e-4
    assert axisymmetric.fluid.rheology == three_d.fluid.rheology
    assert axisymmetric.structure.mode == three_d.structure.mode == "moving_wall"
    assert axisymmetric.time.end == three_d.time.end == 0.01


def test_the_table_gives_each_difference_and_its_verdict():
    axisymmetric = {"peak_velocity": 0.4, "flow_rate": 3e-6, "cap_principal": 1000.0}
    three_d = {"peak_velocity": 0.41, "flow_rate": 2.97e-6, "cap_principal": 1040.0}
    difference = concentric_3d.compare(axisymmetric, three_d)
    assert difference == pytest.approx(
        {"peak_velocity": 0.025, "flow_rate": -0.01, "cap_principal": 0.04}
    )
    text = concentric_3d.table(
        {"moving_wall": {"axisymmetric": axisymmetric, "3d": three_d, "difference": difference}}
    )
    assert "| moving_wall | peak_velocity (m/s) | 0.4 | 0.41 | +2.50 % | yes |" in text
    assert "| moving_wall | cap_principal (kPa) | 1 | 1.04 | +4.00 % | **no** |" in text


def _values(model: str, mode: str, out: Path, end: float) -> dict[str, float]:
    """Run one model of the benchmark in this process (its ranks) and read its quantities."""
    overrides = concentric_3d.settings(model, mode, end)
    assert fsi_run(str(concentric_3d.CONFIGS[model]), out, overrides) == 0
    return concentric_3d.values(out, moving=mode != "rigid")


def test_the_rigid_concentric_quarter_meets_the_axisymmetric_model(shared_tmp):
    """The benchmark's rigid wall to 5 ms (the largest velocity's peak at 4.5–5 ms), at its
    sizes: the 3D quarter (0.18 mm at the plaque and in the throat; ~52,000 fluid tetrahedra)
    against the axisymmetric model's fine mesh, the largest velocity and the inlet's flow rate
    within the issue's 3 % (measured: −0.6 % and −1.1 %). At 0.25 mm the largest velocity was
    +3.9 %, at the config's 0.35 mm +4.5 % (docs/3d.md): the sizes are what this defends."""
    results = {
        model: _values(model, "rigid", shared_tmp / f"concentric_{model}", 0.005)
        for model in concentric_3d.CONFIGS
    }
    difference = concentric_3d.compare(results["axisymmetric"], results["3d"])
    assert set(difference) == {"peak_velocity", "flow_rate"}
    assert results["3d"]["cells"] > 40_000  # the benchmark's quarter, not a coarser mesh
    for name, value in difference.items():
        assert abs(value) <= concentric_3d.TOLERANCE, (name, value)


@pytest.mark.slow
def test_the_concentric_benchmark_is_within_three_percent(tmp_path):
    """``scripts/benchmark_concentric.py`` as shipped (rigid and moving wall to 6 ms, 2 ranks):
    every quantity within 3 % of the axisymmetric model's."""
    if MPI.COMM_WORLD.size > 1:
        pytest.skip("starts its own 2-rank runs")
    results = concentric_3d.results(tmp_path, ranks=2)
    for mode, result in results.items():
        assert set(result["difference"]) >= {"peak_velocity", "flow_rate"}, mode
        for name, value in result["difference"].items():
            assert abs(value) <= concentric_3d.TOLERANCE, (mode, name, value)
