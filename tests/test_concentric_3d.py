"""The 3D-against-axisymmetric benchmark's pieces (fsi/benchmarks/concentric_3d.py): the runs'
settings load as the cases they say, and the table's differences and verdicts. The runs
themselves are the benchmark's (docs/3d.md: minutes to hours on 2 ranks)."""

from __future__ import annotations

import pytest

from fsi import config
from fsi.benchmarks import concentric_3d


def test_the_two_models_run_the_same_plaque():
    axisymmetric = config.load(
        concentric_3d.CONFIGS["axisymmetric"],
        concentric_3d.settings("axisymmetric", "moving_wall", 0.01, 2.5e-4),
    )
    three_d = config.load(
        concentric_3d.CONFIGS["3d"],
        concentric_3d.settings("3d", "moving_wall", 0.01, 2.5e-4, local_size=3e-4),
    )
    a, b = axisymmetric.geometry, three_d.geometry
    assert a.axisymmetric and b.dimension == 3 and b.plaque_angle == 360
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
