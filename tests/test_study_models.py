"""The study's cases side by side in the plane, axisymmetric and 3D models
(fsi/study/models.py, scripts/compare_models.py; docs/3d.md, "Plane, axisymmetric and 3D on the
same plaque"): the three models' configs describe the same vessel, plaque, materials, pulse and
schedule, and a case a model lacks is refused before any run."""

from __future__ import annotations

import dataclasses

import pytest

from fsi import config
from fsi.study import models

MOVING = ("moving_newtonian", "moving_carreau")


@pytest.mark.parametrize("name", MOVING)
def test_the_three_models_run_the_same_plaque_pulse_and_wall(name):
    cases = {model: config.load(models.config_file(model, name)) for model in models.MODELS}
    plane, axi, three = cases["plane"], cases["axisymmetric"], cases["3d"]
    # the plane channel's height is the tube's diameter; the plaque closes half the radius
    assert plane.geometry.height == pytest.approx(2 * axi.geometry.height)
    assert three.geometry.height == axi.geometry.height
    assert three.geometry.plaque_angle == 120
    for key in ("length", "wall_thickness", "stenosis_length", "stenosis_degree",
                "cap_thickness", "lipid_length"):  # fmt: skip
        values = {model: getattr(case.geometry, key) for model, case in cases.items()}
        assert len(set(values.values())) == 1, (key, values)
    for section in ("structure", "time"):
        a, b, c = (dataclasses.asdict(getattr(case, section)) for case in (plane, axi, three))
        if section == "structure":
            for d in (a, b, c):
                d.pop("solver", None)
        assert a == b == c, section
    assert plane.fluid.inlet == axi.fluid.inlet == three.fluid.inlet
    assert plane.fluid.rheology == axi.fluid.rheology == three.fluid.rheology


def test_a_case_a_model_does_not_have_is_refused_naming_its_config(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        models.main(["--out", str(tmp_path), "--models", "3d", "--cases", "fixed_newtonian"])
    assert exit_.value.code == 2
    assert "configs/3d/stenosis_eccentric_fixed_newtonian.yaml" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # nothing was run


def test_where_names_two_or_three_coordinates_in_mm():
    assert models._where({"cap_principal_at": [0.00915, 0.00187]}) == "(9.15, 1.87)"
    assert models._where({"cap_principal_at": [0.00733, 0.00175, 0.00303]}) == "(7.33, 1.75, 3.03)"
