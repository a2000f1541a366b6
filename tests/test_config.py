"""Configuration: defaults, YAML and --set precedence, and every bad-input case exits 2."""

from pathlib import Path

from mpi4py import MPI

import pytest
import yaml

from fsi import cli, config
from fsi.config import reader

CONFIGS = sorted((Path(__file__).parents[1] / "configs").glob("**/*.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_shipped_configs_are_valid(path):
    assert cli.main(["check", str(path)]) == 0


def test_defaults_are_the_study_values():
    case = config.from_dict({})
    assert case.fluid.density == 1060 and case.fluid.rheology.viscosity == 0.0035
    assert case.fluid.inlet.amplitude == 1200 and case.fluid.inlet.duration == 0.005
    assert case.structure.wall.young_modulus == 4e6 and case.structure.cap.young_modulus == 1.6e6
    assert case.structure.lipid.poisson_ratio == 0.45 and case.structure.wall.density == 1200
    assert [(s.until, s.dt) for s in case.time.schedule] == [(0.4, 5e-3), (0.8, 1e-2)]
    assert case.geometry.stenosis_degree == 0.5 and case.mesh.refinements == 0


def test_carreau_case_reads_its_parameters():
    case = config.load(Path(__file__).parents[1] / "configs/stenosis_moving_carreau.yaml")
    r = case.fluid.rheology
    assert (r.model, r.mu_0, r.mu_inf, r.relaxation_time, r.power_index) == (
        "carreau",
        0.0456,
        0.0032,
        10.03,
        0.344,
    )
    assert case.structure.mode == "moving_wall"


def test_overrides_take_precedence_and_parse_yaml(tmp_path):
    path = tmp_path / "case.yaml"
    path.write_text("mesh: {level: coarse}\ntime: {end: 0.8}\n")
    case = config.load(
        path,
        [
            "mesh.level=fine",
            "time.end=0.1",
            "geometry.plaque_sides=[bottom, top]",
            "fluid.rheology.model=carreau",
        ],
    )
    assert case.mesh.level == "fine" and case.mesh.refinements == 2
    assert case.time.end == 0.1
    assert case.geometry.plaque_sides == ("bottom", "top")
    assert case.fluid.rheology.model == "carreau" and case.fluid.rheology.mu_0 == 0.0456


def test_resolved_configuration_round_trips(tmp_path):
    case = config.from_dict({"fluid": {"rheology": {"model": "carreau"}}})
    config.dump(case, tmp_path / "config.yaml")
    again = config.load(tmp_path / "config.yaml")
    assert again == case


BAD = [
    # (YAML text, key named, words of the expectation)
    ("geometry: {cap_thickness: -0.001}", "geometry.cap_thickness", "positive"),
    ("geometry: {wall_thickness: 0}", "geometry.wall_thickness", "positive"),
    ("geometry: {stenosis_degree: 1.0}", "geometry.stenosis_degree", "(0.0, 1.0)"),
    ("geometry: {stenosis_degree: 1.2}", "geometry.stenosis_degree", "(0.0, 1.0)"),
    ("geometry: {cap_thickness: 0.004}", "geometry.cap_thickness", "plaque height"),
    ("geometry: {lipid_length: 0.009}", "geometry.lipid_length", "nowhere thinner"),
    ("geometry: {stenosis_length: 0.03}", "geometry.stenosis_length", "less than geometry.length"),
    ("geometry: {stenosis_centre: 0.004}", "geometry.stenosis_centre", "inside the segment"),
    ("geometry: {stenosis_centre: 0.0151}", "geometry.stenosis_centre", "0.015 m, got 0.0151"),
    ("geometry: {stenosis_centre: -0.01}", "geometry.stenosis_centre", "positive number, or null"),
    ("geometry: {stenosis_centre: centre}", "geometry.stenosis_centre", "a number or null"),
    ("geometry: {plaque_sides: [bottom, bottom]}", "geometry.plaque_sides", "once each"),
    ("geometry: {plaque_sides: [left]}", "geometry.plaque_sides[0]", "'bottom', 'top'"),
    ("structure: {wall: {poisson_ratio: 0.5}}", "structure.wall.poisson_ratio", "(-1.0, 0.5)"),
    ("structure: {cap: {young_modulus: -1.6e6}}", "structure.cap.young_modulus", "positive"),
    ("structure: {mode: flexible}", "structure.mode", "'moving_wall'"),
    ("fluid: {density: '1060'}", "fluid.density", "a number"),
    ("fluid: {rheology: {model: bingham}}", "fluid.rheology.model", "'carreau'"),
    (
        "fluid: {rheology: {model: carreau, viscosity: 0.0035}}",
        "fluid.rheology.viscosity",
        "one of the keys",
    ),
    ("fluid: {quadrature_degree: 4.5}", "fluid.quadrature_degree", "an integer"),
    ("fluid: {solver: {rtol: 1.0e-3}}", "fluid.solver.rtol", "coupling.tolerance / 10"),
    ("output: {fields_every: true}", "output.fields_every", "an integer"),
    ("coupling: {acceleration: anderson}", "coupling.acceleration", "'iqn-ils'"),
    ("coupling: {initial_relaxation: 1.5}", "coupling.initial_relaxation", "(0, 1]"),
    ("time: {end: 1.0}", "time.schedule[1].until", "at least time.end"),
    (
        "time: {schedule: [{until: 0.4, dt: 0.01}, {until: 0.3, dt: 0.01}]}",
        "time.schedule[1].until",
        "greater than",
    ),
    ("time: {schedule: [{until: 0.8, dt: -0.01}]}", "time.schedule[0].dt", "positive"),
    ("mesh: {level: ultra}", "mesh.level", "'fine'"),
    ("geometry: {kind: channel}", "structure.mode", "'rigid'"),
    ("geometry: {kind: tube}\nstructure: {mode: fixed_wall}", "structure.mode", "'moving_wall'"),
    (
        "geometry: {axisymmetric: true, plaque_sides: [bottom]}",
        "geometry.plaque_sides",
        "no plaque_sides with geometry.axisymmetric",
    ),
    ("geometry: {axisymmetric: true, stenosis_degree: 1.0}", "geometry.stenosis_degree", "1.0"),
    ("geometry: {kind: tube, radius: 0}", "geometry.radius", "positive"),
    ("geometry: {kind: tube, axisymmetric: 1}", "geometry.axisymmetric", "true or false"),
    (
        "geometry: {kind: turek_hron, axisymmetric: true}",
        "geometry.axisymmetric",
        "one of the keys",
    ),
    ("unknown_section: 1", "unknown_section", "one of the keys"),
    ("- just\n- a list", "<top level>", "a mapping"),
    ("geometry: [1, 2", "<file>", "valid YAML"),
]


@pytest.mark.parametrize("text,key,expected", BAD, ids=[b[1] + ":" + b[0][:20] for b in BAD])
def test_bad_configuration_exits_2_naming_file_and_key(shared_tmp, capsys, text, key, expected):
    comm = MPI.COMM_WORLD
    path = shared_tmp / "bad.yaml"
    out = shared_tmp / "out"
    if comm.rank == 0:
        path.write_text(text)
    comm.barrier()
    assert cli.main(["mesh", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    if comm.rank == 0:
        assert f"{path}: {key}: expected" in err and expected in err, err
    assert not out.exists(), "nothing may be written for a bad configuration"


def test_bad_override_names_the_command_line(capsys):
    path = Path(__file__).parents[1] / "configs/stenosis_fixed_newtonian.yaml"
    assert cli.main(["check", str(path), "--set", "geometry.stenosis_degree=1.5"]) == 2
    assert cli.main(["check", str(path), "--set", "no_equals_sign"]) == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert "--set: geometry.stenosis_degree: expected a number in (0.0, 1.0), got 1.5" in err
        assert "--set: no_equals_sign: expected key.path=value" in err


def test_strings_are_not_booleans_or_numbers():
    # turtleFSI's parser turned the string "false" into True; this one refuses it.
    with pytest.raises(config.ConfigError, match="mesh.size: expected a number"):
        config.from_dict({"mesh": {"size": "false"}})
    with pytest.raises(config.ConfigError, match="coupling.max_iterations: expected an integer"):
        config.from_dict({"coupling": {"max_iterations": True}})


def test_missing_file_and_bad_command_line_exit_2(tmp_path, capsys):
    assert cli.main(["check", str(tmp_path / "nope.yaml")]) == 2
    assert cli.main(["mesh", "configs/stenosis_fixed_newtonian.yaml"]) == 2  # --out missing
    assert cli.main(["frobnicate"]) == 2


def test_yaml_keys_mirror_the_dataclasses():
    """Every shipped config's keys exist in the schema (guards against silently ignored keys)."""
    for path in CONFIGS:
        config.from_dict(yaml.safe_load(path.read_text()), str(path))


def test_scientific_notation_without_a_dot_is_a_number():
    # PyYAML follows YAML 1.1, where a plain 4e6 is a string; the loader reads YAML 1.2 floats.
    case = config.from_dict(reader.parse_yaml("structure: {wall: {young_modulus: 4e6}}"))
    assert case.structure.wall.young_modulus == 4.0e6


def test_vtx_output_is_refused_by_check(capsys):
    """No VTX writer exists (Debian 12's dolfinx lacks ADIOS2): ``fsi check`` says so on both
    releases instead of a run failing, or silently writing XDMF, later."""
    assert cli.main(["check", "configs/channel_poiseuille.yaml", "--set", "output.fields=vtx"]) == 2
    if MPI.COMM_WORLD.rank == 0:  # the message comes from rank 0
        assert "output.fields: expected one of 'xdmf'" in capsys.readouterr().err
