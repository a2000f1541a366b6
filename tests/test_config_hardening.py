"""Hostile and careless configurations (issue #14): each exits 2 with one line naming the file
(or --set) and the key, no traceback and nothing written; the limits that keep a valid-looking
case from exhausting memory or hanging (steps, cells, quadrature, formula length) are cheap to
check; inlet formulas fail validation, or raise FormulaError, never anything else."""

import copy
import dataclasses
import math
import time
import typing
from pathlib import Path
from types import UnionType
from typing import Union

from mpi4py import MPI

import pytest

from fsi import cli, config
from fsi.config import boundary_data, petsc_options, reader, run_size
from fsi.numerics.timestepping import steps

ROOT = Path(__file__).parents[1]
CHANNEL = ROOT / "configs/channel_poiseuille.yaml"
STENOSIS = ROOT / "configs/stenosis_fixed_newtonian.yaml"
TUREK_HRON = ROOT / "configs/turek_hron_fsi3.yaml"


def write(path: Path, content: str | bytes) -> Path:
    """Write ``content`` on rank 0; every rank returns once it is there."""
    if MPI.COMM_WORLD.rank == 0:
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
    MPI.COMM_WORLD.barrier()
    return path


def cli_error(capsys, *argv: str) -> tuple[int, str]:
    """Run ``fsi ARGV`` in-process: its exit status and rank 0's stderr ("" on other ranks)."""
    capsys.readouterr()  # only this command's output
    status = cli.main(list(argv))
    err = capsys.readouterr().err
    return status, err if MPI.COMM_WORLD.rank == 0 else ""


def seconds_since(start: float) -> float:
    """Wall time since ``start`` on the slowest rank: every rank takes the same branch of an
    assertion on it (one rank failing alone would leave the other waiting in a collective)."""
    return MPI.COMM_WORLD.allreduce(time.perf_counter() - start, op=MPI.MAX)


# A refusal "at once" is bounded by QUICK seconds: far above the check's time on a loaded
# machine with 2 ranks on 2 cores (well under a second alone), far below what the refused work
# would take (10⁹ YAML items, 10¹¹ time steps, a mesh of 10¹¹ triangles: hours, or memory).
QUICK = 20.0


def assert_refused(status: int, err: str, source: str, key: str, *words: str) -> None:
    """Exit 2 and, on rank 0, one line ``fsi: error: SOURCE: KEY...`` holding ``words``. Rank
    0's verdict is broadcast, so that every rank fails together (one rank failing alone would
    leave the others waiting in the next test's collectives, and the run would hang unreported:
    seen twice in 2-rank lanes, at about 16 % of the suite)."""
    assert status == 2
    problem = None
    if MPI.COMM_WORLD.rank == 0:
        lines = err.strip().splitlines()
        prefix = f"fsi: error: {source}: {key}" if key else f"fsi: error: {source}: "
        if "Traceback" in err or len(lines) != 1 or not lines[0].startswith(prefix):
            problem = f"not one line starting {prefix!r}: {err!r}"
        else:
            missing = [w for w in words if w not in err]
            problem = f"{missing} not in {err!r}" if missing else None
    problem = MPI.COMM_WORLD.bcast(problem, root=0)
    assert problem is None, problem


# --------------------------------------------------------------------------------------------
# One table of bad values: `fsi mesh` refuses each before writing anything

BAD = [
    # (YAML, key, words) -- every number finite and in range
    (
        "time: {schedule: [{until: 0.8, dt: .inf}]}",
        "time.schedule[0].dt",
        "expected a finite positive number (s), got inf",
    ),
    ("time: {end: .nan}", "time.end", "a finite positive number (s), got nan"),
    ("geometry: {length: .inf}", "geometry.length", "a finite positive number (m), got inf"),
    ("geometry: {stenosis_centre: .nan}", "geometry.stenosis_centre", "a finite number, got nan"),
    ("fluid: {rheology: {viscosity: .inf}}", "fluid.rheology.viscosity", "finite"),
    ("fluid: {rheology: {model: carreau, mu_0: .nan}}", "fluid.rheology.mu_0", "finite"),
    ("fluid: {density: -.inf}", "fluid.density", "got -inf"),
    ("structure: {body_force: [.inf, 0]}", "structure.body_force[0]", "a finite number, got inf"),
    (
        "structure: {wall: {poisson_ratio: .nan}}",
        "structure.wall.poisson_ratio",
        "a finite number in (-1.0, 0.5)",
    ),
    (
        "structure: {time_integration: {spectral_radius: .nan}}",
        "structure.time_integration.spectral_radius",
        "a finite number in [0, 1]",
    ),
    ("output: {report_times: [-1, .nan]}", "output.report_times[1]", "a finite number, got nan"),
    ("output: {report_times: [-1, 0.1]}", "output.report_times", "times >= 0"),
    ("coupling: {tolerance: .inf}", "coupling.tolerance", "finite"),
    # a length whose square overflows: a traceback in the cap's thickness check before
    ("geometry: {height: 1.7e308}", "geometry.height", "a length of at most 1e+100 m"),
    ("geometry: {kind: tube, radius: 1.0e+200}", "geometry.radius", "at most 1e+100 m"),
    (
        "geometry: {kind: turek_hron, cylinder_centre: [.nan, 0.2]}",
        "geometry.cylinder_centre[0]",
        "a finite number",
    ),
    (
        "fluid: {inlet: {kind: pressure_table, table: [[0, 0], [1, .inf]]}}",
        "fluid.inlet.table[1][1]",
        "a finite number",
    ),
    ("mesh: {size: " + "9" * 400 + "}", "mesh.size", "finite"),
    # quadrature ceiling
    ("fluid: {quadrature_degree: 100000}", "fluid.quadrature_degree", "an integer in [1, 20]"),
    ("structure: {quadrature_degree: 21}", "structure.quadrature_degree", "an integer in [1, 20]"),
    # PETSc options: viewers, monitors, Python, options files, paths
    (
        "fluid: {solver: {petsc_options: {ksp_view: 'ascii:/tmp/owned'}}}",
        "fluid.solver.petsc_options.ksp_view",
        "viewers write",
    ),
    (
        "fluid: {solver: {petsc_options: {KSP_VIEW: ''}}}",
        "fluid.solver.petsc_options.KSP_VIEW",
        "viewers",
    ),
    (
        "structure: {solver: {petsc_options: {pc_type: python}}}",
        "structure.solver.petsc_options.pc_type",
        "Python",
    ),
    (
        "structure: {solver: {petsc_options: {pc_python_type: 'os.system'}}}",
        "structure.solver.petsc_options.pc_python_type",
        "Python",
    ),
    (
        "mesh_motion: {petsc_options: {options_file: /etc/passwd}}",
        "mesh_motion.petsc_options.options_file",
        "options files",
    ),
    (
        "mesh_motion: {petsc_options: {ksp_monitor: 'ascii:/tmp/m'}}",
        "mesh_motion.petsc_options.ksp_monitor",
        "monitors",
    ),
    (
        "mesh_motion: {petsc_options: {fieldsplit_0_ksp_view: ''}}",
        "mesh_motion.petsc_options.fieldsplit_0_ksp_view",
        "viewers",
    ),
    (
        "fluid: {solver: {petsc_options: {ksp_converged_reason: ''}}}",
        "fluid.solver.petsc_options.ksp_converged_reason",
        "not an allowed PETSc option",
    ),
    (
        "fluid: {solver: {petsc_options: {mat_type: aij}}}",
        "fluid.solver.petsc_options.mat_type",
        "not an allowed PETSc option",
    ),
    (
        "fluid: {solver: {petsc_options: {mat_mumps_icntl_1: 6}}}",
        "fluid.solver.petsc_options.mat_mumps_icntl_1",
        "output streams",
    ),
    (
        "fluid: {solver: {petsc_options: {mat_mumps_icntl_22: 1}}}",
        "fluid.solver.petsc_options.mat_mumps_icntl_22",
        "out-of-core",
    ),
    (
        "fluid: {solver: {petsc_options: {pc_mg_log: ''}}}",
        "fluid.solver.petsc_options.pc_mg_log",
        "logging",
    ),
    (
        "fluid: {solver: {petsc_options: {'-ksp_type': cg}}}",
        "fluid.solver.petsc_options.-ksp_type",
        "without the leading '-'",
    ),
    (
        "fluid: {solver: {petsc_options: {'ksp_type -ksp_view': cg}}}",
        "fluid.solver.petsc_options.ksp_type -ksp_view",
        "not a PETSc option name",
    ),
    (
        "fluid: {solver: {petsc_options: {pc_factor_mat_solver_type: 'ascii:/tmp/x'}}}",
        "fluid.solver.petsc_options.pc_factor_mat_solver_type",
        "no file paths",
    ),
    (
        "fluid: {solver: {petsc_options: {pc_type: '../lu'}}}",
        "fluid.solver.petsc_options.pc_type",
        "no file paths",
    ),
    (
        "fluid: {solver: {petsc_options: {ksp_type: 'gmres -ksp_view'}}}",
        "fluid.solver.petsc_options.ksp_type",
        "a type name",
    ),
    (
        "fluid: {solver: {petsc_options: {ksp_type: PyThOn}}}",
        "fluid.solver.petsc_options.ksp_type",
        "Python",
    ),
    (
        "fluid: {solver: {petsc_options: {ksp_rtol: .nan}}}",
        "fluid.solver.petsc_options.ksp_rtol",
        "a finite number",
    ),
    # inlet formulas: too long, too deep, failing at a step time
    (
        "fluid: {inlet: {kind: pressure, formula: '" + "(" * 10000 + "t" + ")" * 10000 + "'}}",
        "fluid.inlet.formula",
        "longer than 2000 characters",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: '" + "-" * 1500 + "t'}}",  # the reason varies
        "fluid.inlet.formula",
        "expected an expression in t",
    ),  # with the Python version
    (
        "fluid: {inlet: {kind: pressure, formula: '" + "(" * 300 + "t" + ")" * 300 + "'}}",
        "fluid.inlet.formula",
        "too many nested parentheses",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: '" + "1" * 400 + "*t'}}",
        "fluid.inlet.formula",
        "too large",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: '1/(t-0.001)'}}\n"
        "time: {schedule: [{until: 0.8, dt: 0.001}]}",
        "fluid.inlet.formula",
        "evaluation fails at t = 0.001 s (division by zero)",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: 'log(0)'}}",
        "fluid.inlet.formula",
        "evaluation fails at t = 0 s (math domain error)",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: 'sqrt(-1-t)'}}",
        "fluid.inlet.formula",
        "at t = 0 s (math domain error)",
    ),
    ("fluid: {inlet: {kind: pressure, formula: '9**9**9'}}", "fluid.inlet.formula", "(overflow)"),
    (
        "fluid: {inlet: {kind: pressure, formula: 'exp(1e6*t)'}}",
        "fluid.inlet.formula",
        "at t = 0.005 s (overflow)",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: '(-1)**0.5'}}",
        "fluid.inlet.formula",
        "complex result",
    ),
    (
        "fluid: {inlet: {kind: pressure, formula: '1e308*10**(t > 0.312)'}}",
        "fluid.inlet.formula",
        "at t = 0.315 s (the result is inf)",
    ),
    ("fluid: {inlet: {kind: pressure, formula: 'min(t)'}}", "fluid.inlet.formula", "not iterable"),
]


@pytest.mark.parametrize("text,key,words", BAD, ids=[f"{b[1]}:{b[0][:30]}" for b in BAD])
def test_bad_values_exit_2_naming_file_and_key(shared_tmp, capsys, text, key, words):
    path = write(shared_tmp / "case.yaml", text)
    out = shared_tmp / "out"
    status, err = cli_error(capsys, "mesh", str(path), "--out", str(out))
    assert_refused(status, err, str(path), key, words)
    assert not out.exists(), "nothing may be written for a bad configuration"


# --------------------------------------------------------------------------------------------
# The file itself


def test_binary_and_non_utf8_files_exit_2_naming_the_file(shared_tmp, capsys):
    for name, content in [
        ("binary.yaml", bytes(range(256)) * 8),
        ("latin1.yaml", "name: caf\xe9\n".encode("latin-1")),
    ]:
        path = write(shared_tmp / name, content)
        assert_refused(*cli_error(capsys, "check", str(path)), str(path), "", "not UTF-8 text")


def test_a_fifo_or_a_folder_as_the_case_file_is_refused_without_blocking(shared_tmp, capsys):
    """A FIFO with no writer would block the read for ever: only regular files are read; and a
    FIFO as a CSV inlet file the same way."""
    import os

    fifo, folder = shared_tmp / "case.yaml", shared_tmp / "folder.yaml"
    if MPI.COMM_WORLD.rank == 0:
        os.mkfifo(fifo)
        folder.mkdir()
    MPI.COMM_WORLD.barrier()
    for path in (fifo, folder):
        assert_refused(*cli_error(capsys, "check", str(path)), str(path), "", "not a regular file")
    table = shared_tmp / "table.csv"
    if MPI.COMM_WORLD.rank == 0:
        os.mkfifo(table)
    MPI.COMM_WORLD.barrier()
    inlet = f"fluid.inlet={{kind: pressure_file, file: {table}, period: 0.01}}"
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", inlet),
        "--set",
        "fluid.inlet.file",
        "not a regular file",
    )


def test_a_file_over_1_mib_is_refused_unread(shared_tmp, capsys):
    path = write(shared_tmp / "big.yaml", "#" * reader.MAX_FILE_BYTES + "\n")
    assert_refused(*cli_error(capsys, "check", str(path)), str(path), "", "larger than 1048576")


@pytest.mark.parametrize(
    "text",
    [
        "[" * 100000,
        "[" * 100000 + "]" * 100000,
        "fluid: " + "{a: " * 5000 + "1" + "}" * 5000,
        "- " * 2000 + "x",
    ],
    ids=["open flow lists", "flow lists", "flow mappings", "block lists"],
)
def test_deeply_nested_yaml_exits_2_without_recursion_error(shared_tmp, capsys, text):
    path = write(shared_tmp / "deep.yaml", text)
    assert_refused(
        *cli_error(capsys, "check", str(path)),
        str(path),
        "",
        "YAML nested more than 32 levels deep (line 1",
    )


def test_duplicate_keys_are_refused_naming_key_and_both_lines(shared_tmp, capsys):
    path = write(
        shared_tmp / "case.yaml",
        "name: twice\nfluid:\n  density: 1000\n  supg: false\n"
        "  rheology: {model: newtonian}\n\n  density: 1060\n",
    )
    assert_refused(
        *cli_error(capsys, "check", str(path)),
        str(path),
        "fluid.density",
        "duplicate key (lines 3 and 7)",
    )
    path = write(
        shared_tmp / "case.yaml", "time:\n  schedule:\n    - {until: 0.8, dt: 0.01, dt: 0.02}\n"
    )
    assert_refused(
        *cli_error(capsys, "check", str(path)),
        str(path),
        "time.schedule[0].dt",
        "duplicate key (line 3, columns",
    )
    path = write(shared_tmp / "case.yaml", "name: a\nname: b\n")
    assert_refused(
        *cli_error(capsys, "check", str(path)), str(path), "name", "duplicate key (lines 1 and 2)"
    )


@pytest.mark.parametrize("key", ["name", "output.report_times", "fluid.solver.petsc_options"])
def test_an_alias_bomb_is_refused_quickly(shared_tmp, capsys, key):
    """Aliases share nodes: nine levels of ten are 10⁹ items if anything (the duplicate-key
    walk, the builder, the error message) expanded them."""
    levels = ["&a0 [x, x, x, x, x, x, x, x, x, x]"]
    levels += [f"&a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 10)]
    section, _, rest = key.partition(".")
    value = "[" + ", ".join(levels) + "]"
    text = f"{section}: {{{rest}: {value}}}" if rest else f"{section}: {value}"
    path = write(shared_tmp / "bomb.yaml", text)
    start = time.perf_counter()
    status, err = cli_error(capsys, "check", str(path))
    assert seconds_since(start) < QUICK
    assert_refused(status, err, str(path), key, "expected")


def test_unreadable_yaml_values_exit_2(shared_tmp, capsys):
    """PyYAML raises ValueError, not a YAML error, for these: still one line, exit 2."""
    for text in ["name: " + "1" * 5000, "name: 2024-13-45"]:
        path = write(shared_tmp / "case.yaml", text)
        assert_refused(
            *cli_error(capsys, "check", str(path)), str(path), "<file>", "a value cannot be read"
        )


# --------------------------------------------------------------------------------------------
# --set


def test_set_errors_name_set_for_list_elements_and_new_sections(capsys):
    status, err = cli_error(
        capsys, "check", str(CHANNEL), "--set", "time.schedule=[{until: 1, dt: -1}]"
    )
    assert_refused(status, err, "--set", "time.schedule[0].dt", "positive")
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "nosuch.key=1"),
        "--set",
        "nosuch",
        "one of the keys",
    )
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "fluid.nosuch.key=1"),
        "--set",
        "fluid.nosuch",
        "one of the keys",
    )
    # An error in the file is still the file's, beside an unrelated --set.
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "time.end=0.2"),
        str(CHANNEL),
        "time.schedule[0].until",
        "at least time.end",
    )


def test_set_values_have_the_file_limits(capsys):
    formula = "t+" * 500000 + "t"  # 1 MB
    assert_refused(
        *cli_error(
            capsys,
            "check",
            str(CHANNEL),
            "--set",
            f"fluid.inlet={{kind: pressure, formula: '{formula}'}}",
        ),
        "--set",
        "fluid.inlet.formula",
        "longer than 2000 characters",
        "(1000003 characters)",
    )
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "fluid={density: 1, density: 2}"),
        "--set",
        "fluid.density",
        "duplicate key",
    )
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "fluid=" + "[" * 1000),
        "--set",
        "fluid",
        "nested more than 32 levels",
    )
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "mesh.size=.inf"),
        "--set",
        "mesh.size",
        "a finite positive number",
    )


# --------------------------------------------------------------------------------------------
# Time steps


@pytest.mark.parametrize("path", sorted((ROOT / "configs").glob("**/*.yaml")), ids=lambda p: p.stem)
def test_step_count_is_that_of_the_schedule(path):
    time_ = config.load(path).time
    assert run_size.count_steps(time_) == sum(1 for _ in steps(time_))


@pytest.mark.parametrize(
    "end,schedule",
    [
        (0.8, [(0.4, 5e-3), (0.8, 1e-2)]),
        (0.8, [(0.1, 1 / 30), (0.45, 0.007), (0.8, 0.1)]),
        (0.25, [(0.1, 0.03), (0.3, 0.007)]),
        (0.3, [(0.1, 0.1), (0.3, 0.3)]),  # the second segment's dt is longer than the segment
        (1 / 3, [(1 / 3, 1 / 30)]),  # a leftover of round-off is merged, not a step of its own
    ],
)
def test_step_count_matches_odd_schedules(end, schedule):
    time_ = config.from_dict(
        {"time": {"end": end, "schedule": [{"until": until, "dt": dt} for until, dt in schedule]}}
    ).time
    assert run_size.count_steps(time_) == sum(1 for _ in steps(time_))


def test_too_many_steps_fail_at_once_with_the_count_and_how_to_raise_the_limit(capsys):
    start = time.perf_counter()
    status, err = cli_error(
        capsys, "check", str(CHANNEL), "--set", "time.schedule=[{until: 0.1, dt: 1.0e-12}]"
    )
    assert seconds_since(start) < QUICK
    assert_refused(
        status,
        err,
        "--set",
        "time.schedule",
        "100,000,000,000 steps",
        "time.max_steps = 1,000,000",
        "--set time.max_steps=100000000000",
    )
    status, err = cli_error(
        capsys, "check", str(CHANNEL), "--set", "time.schedule=[{until: 0.1, dt: 5.0e-324}]"
    )
    assert_refused(status, err, "--set", "time.schedule", "over 1e308 steps")
    # The limit is the user's: raised, the same schedule is valid (checked, never listed).
    assert (
        cli.main(
            [
                "check",
                str(CHANNEL),
                "--set",
                "time.schedule=[{until: 0.1, dt: 1.0e-12}]",
                "--set",
                "time.max_steps=100000000000",
            ]
        )
        == 0
    )
    # Exactly at the limit is allowed, one more is not.
    assert cli.main(["check", str(CHANNEL), "--set", "time.max_steps=100"]) == 0
    assert cli.main(["check", str(CHANNEL), "--set", "time.max_steps=99"]) == 2


# --------------------------------------------------------------------------------------------
# Cells


@pytest.mark.parametrize("path", [STENOSIS, TUREK_HRON], ids=lambda p: p.stem)
def test_cell_estimate_is_within_a_factor_3_of_gmsh(path):
    from fsi.physics import mesh

    case = config.load(path)
    built = mesh.build(case, MPI.COMM_WORLD).mesh.topology.index_map(2).size_global
    assert built / 3 < run_size.estimated_cells(case) < 3 * built, (
        run_size.estimated_cells(case),
        built,
    )


@pytest.mark.parametrize("path", [STENOSIS, TUREK_HRON, CHANNEL], ids=lambda p: p.stem)
def test_cell_estimate_grows_4_times_per_refinement(path):
    coarse, medium, fine, finest = (
        run_size.estimated_cells(config.load(path, [f"mesh.level={level}"]))
        for level in ("coarse", "medium", "fine", "finest")
    )
    assert medium == pytest.approx(4 * coarse, rel=1e-12)
    assert fine == pytest.approx(16 * coarse, rel=1e-12)
    assert finest == pytest.approx(64 * coarse, rel=1e-12)


def test_cell_estimate_follows_the_sizes():
    base = config.load(STENOSIS)
    halved = config.load(STENOSIS, ["mesh.size=3.0e-4", "mesh.local_size=1.1e-4"])
    assert run_size.estimated_cells(halved) == pytest.approx(4 * run_size.estimated_cells(base))
    channel = config.load(CHANNEL)
    assert run_size.estimated_cells(channel) == pytest.approx(
        0.02 * 0.007 / (math.sqrt(3) / 4 * 5e-4**2)
    )


def test_a_tiny_mesh_size_fails_at_once_with_the_estimate(shared_tmp, capsys):
    out = shared_tmp / "mesh"
    start = time.perf_counter()
    status, err = cli_error(
        capsys, "mesh", str(STENOSIS), "--out", str(out), "--set", "mesh.size=1.0e-6"
    )
    assert seconds_since(start) < QUICK
    assert_refused(
        status,
        err,
        "--set",
        "mesh",
        "triangles estimated",
        "mesh.size = 1e-06 m",
        "more than mesh.max_cells = 1,000,000",
        "GB",
        "raise mesh.max_cells",
    )
    assert not out.exists()
    # A fine level multiplies the estimate by 16: the coarse defaults times 16 is fine, but a
    # limit below it refuses the fine level while it accepts the coarse one.
    assert cli.main(["check", str(STENOSIS), "--set", "mesh.max_cells=10000"]) == 0
    assert_refused(
        *cli_error(
            capsys,
            "check",
            str(STENOSIS),
            "--set",
            "mesh.max_cells=10000",
            "--set",
            "mesh.level=fine",
        ),
        "--set",
        "mesh",
        "mesh.level = fine",
    )
    # Raised, the limit admits the mesh (validated only: nothing is meshed here).
    assert (
        cli.main(
            [
                "check",
                str(STENOSIS),
                "--set",
                "mesh.size=1.0e-6",
                "--set",
                "mesh.local_size=1.0e-6",
                "--set",
                "mesh.max_cells=1000000000000",
            ]
        )
        == 0
    )


# --------------------------------------------------------------------------------------------
# Formulas


@pytest.mark.parametrize(
    "formula,t,reason",
    [
        ("1/(t-0.001)", 0.001, "division by zero"),
        ("t % (t - 0.5)", 0.5, "division by zero"),
        ("log(0*t)", 0.2, "math domain error"),
        ("sqrt(-1-t)", 0.0, "math domain error"),
        ("9**9**9", 0.0, "overflow"),
        ("exp(1e6*t)", 0.01, "overflow"),
        ("(-1)**0.5", 0.0, "complex result"),
        ("(t - 1)**0.5", 0.5, "complex result"),
        ("1e308*10", 0.0, "the result is inf"),
        ("1e308*10 - 1e308*10", 0.0, "the result is nan"),
        ("max(t)", 0.0, "not iterable"),
    ],
)
def test_a_formula_failing_when_evaluated_raises_formula_error(formula, t, reason):
    pressure = boundary_data.time_function(formula)
    with pytest.raises(boundary_data.FormulaError) as error:
        pressure(t)
    assert reason in error.value.reason and error.value.t == t
    assert repr(formula) in str(error.value) and f"at t = {t:.6g} s" in str(error.value)
    assert isinstance(error.value, ValueError)


@pytest.mark.parametrize(
    "formula,reason",
    [
        ("import os", "not an expression"),
        ("x + 1", "unknown name 'x'"),
        ("t.real", "Attribute is not allowed"),
        ("t" + "+t" * 1000, "longer than 2000 characters"),
        ("-" * 1999 + "t", "not an expression|cannot be compiled|nested more than 100 levels"),
        ("t\0", "null bytes"),
        ("1" * 400, "too large"),
    ],
)
def test_a_formula_that_cannot_be_compiled_raises_formula_error(formula, reason):
    with pytest.raises(boundary_data.FormulaError, match=reason) as error:
        boundary_data.time_function(formula)
    assert error.value.t is None


def test_a_long_flat_sum_is_a_formula_evaluated_as_python_does():
    """A Fourier series of 100 terms (a flat sum, 100 levels deep as Python parses it) was
    refused as "nested more than 100 levels deep"; now any sum or product within the 2,000
    characters is accepted (1,000 terms), and its value is Python's, bit for bit: the same
    operations in the same order."""
    fourier = "+".join(f"{k % 7 - 3}*sin({k}*t)" for k in range(100))
    product = "*".join(["(1+t/50)"] * 200)
    mixed = "t" + "".join(f"{op}{k % 9 + 1}*t" for k, op in enumerate("+-*/" * 100))
    flat = "t" + "+t" * 999
    names = {"sin": math.sin, "pi": math.pi}
    for formula in (fourier, product, mixed, flat):
        assert len(formula) <= boundary_data.MAX_FORMULA_LENGTH
        value = boundary_data.time_function(formula)
        for t in (0.0, 0.0123, 0.5, 7.25):
            assert value(t) == eval(formula, {**names, "t": t}), (formula[:40], t)
    with pytest.raises(boundary_data.FormulaError, match="division by zero"):
        boundary_data.time_function("1/(" + "t-" * 40 + "t*40)")(0.0)
    with pytest.raises(boundary_data.FormulaError, match="nested more than 100 levels"):
        boundary_data.time_function("sin(" * 101 + "t" + ")" * 101)


def test_a_formula_is_checked_at_every_step_time_of_the_schedule(capsys):
    """The failing time is a late step of the schedule; a time after the end is not checked
    (nor one between steps: the run reports those if it gets there, e.g. in a retried step)."""
    schedule = "time.schedule=[{until: 0.1, dt: 1.0e-3}]"
    formula = "fluid.inlet={kind: pressure, formula: 'log(0.0965 - t)'}"
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", schedule, "--set", formula),
        "--set",
        "fluid.inlet.formula",
        "evaluation fails at t = 0.097 s (math domain error)",
    )
    after_the_end = "fluid.inlet={kind: pressure, formula: 'log(0.1005 - t)'}"
    assert cli.main(["check", str(CHANNEL), "--set", schedule, "--set", after_the_end]) == 0


# --------------------------------------------------------------------------------------------
# PETSc options


ALLOWED = {
    "ksp_type": "gmres",
    "ksp_rtol": 1e-10,
    "ksp_atol": 1e-12,
    "ksp_max_it": 500,
    "ksp_gmres_restart": 100,
    "ksp_pc_side": "right",
    "ksp_initial_guess_nonzero": "true",
    "pc_type": "hypre",
    "pc_hypre_type": "boomeramg",
    "pc_hypre_boomeramg_strong_threshold": 0.7,
    "pc_hypre_boomeramg_coarsen_type": "HMIS",
    "pc_hypre_boomeramg_P_max": 4,
    "pc_factor_mat_solver_type": "superlu_dist",
    "mat_mumps_icntl_14": 100,
    "mat_mumps_icntl_24": 1,
    "mat_mumps_cntl_1": 0.01,
    "pc_gamg_threshold": "0.01,0.005",
    "pc_gamg_agg_nsmooths": 1,
    "mg_levels_ksp_type": "chebyshev",
    "mg_levels_pc_type": "jacobi",
    "mg_levels_2_ksp_max_it": 3,
    "mg_coarse_pc_type": "lu",
    "pc_fieldsplit_type": "schur",
    "pc_fieldsplit_schur_fact_type": "full",
    "pc_fieldsplit_schur_precondition": "selfp",
    "fieldsplit_0_ksp_type": "preonly",
    "fieldsplit_u_pc_type": "gamg",
    "pc_fieldsplit_0_fields": "0,1",
    "sub_pc_type": "ilu",
    "sub_pc_factor_levels": 1,
    "ksp_divtol": 1e8,
    "ksp_chebyshev_eigenvalues": "0.1,1.1",
    "pc_hypre_boomeramg_relax_type_all": "symmetric-SOR/Jacobi",
}


def test_the_allowed_petsc_options_load_in_every_solver():
    for key in (
        "fluid.solver.petsc_options",
        "structure.solver.petsc_options",
        "mesh_motion.petsc_options",
    ):
        petsc_options.check_petsc_options(ALLOWED, key)
        section, *rest = key.split(".")
        data: dict = {}
        node = data.setdefault(section, {})
        for part in rest[:-1]:
            node = node.setdefault(part, {})
        node[rest[-1]] = ALLOWED
        case = config.from_dict(data)
        assert (
            case.mesh_motion.petsc_options
            if section == "mesh_motion"
            else getattr(case, section).solver.petsc_options
        ) == ALLOWED


def test_the_defaults_are_allowed_petsc_options():
    case = config.from_dict({})
    for key, options in [
        ("fluid", case.fluid.solver.petsc_options),
        ("structure", case.structure.solver.petsc_options),
        ("mesh_motion", case.mesh_motion.petsc_options),
    ]:
        petsc_options.check_petsc_options(options, key)


@pytest.mark.parametrize(
    "name,value,why",
    [
        ("ksp_view", "", "viewers"),
        ("ksp_view_mat", "binary:x.bin", "viewers"),
        ("pc_type", "python", "Python"),
        ("pc_python_type", "pkg.mod.Attr", "Python"),
        ("ksp_monitor_true_residual", "", "monitors"),
        ("options_file", "x.rc", "options files"),
        ("options_left", "", "options"),
        ("mat_mumps_icntl_4", 3, "printing"),
        ("fieldsplit_0_mat_mumps_icntl_2", 6, "output streams"),
        ("pc_hypre_boomeramg_print_statistics", 1, "printing"),
        ("log_view", "", "viewers"),
        ("draw_pause", 1, "drawing"),
        ("mat_mumps_icntl_99", 1, "not an allowed"),
        ("snes_type", "newtonls", "not an allowed"),
        ("ksp_type", "~/x", "no file paths"),
        ("ksp_type", "C:lu", "no file paths"),
        ("ksp_type", "", "a type name"),
        ("ksp_type", "x" * 65, "a type name"),
        ("x" * 101, 1, "not a PETSc option name"),
    ],
)
def test_refused_petsc_options_name_the_key_and_why(name, value, why):
    with pytest.raises(config.ConfigError, match=why) as error:
        petsc_options.check_petsc_options(
            {"ksp_type": "cg", name: value}, "structure.solver.petsc_options"
        )
    assert error.value.key.startswith("structure.solver.petsc_options." + name[:40])


def test_adaptive_steps_refuse_what_they_cannot_control(capsys):
    """time.step_control: adaptive estimates a second-order scheme's error (bdf2 only) and
    never makes a step shorter than time.adaptive.min_dt, which must allow the first step."""
    adaptive = ["--set", "time.step_control=adaptive"]
    status, err = cli_error(
        capsys, "check", str(CHANNEL), *adaptive, "--set", "time.scheme=backward_euler"
    )
    assert_refused(status, err, "--set", "time.step_control", "bdf2", "'backward_euler'")
    status, err = cli_error(
        capsys,
        "check",
        str(CHANNEL),
        *adaptive,
        "--set",
        "time.adaptive={first_dt: 1.0e-4, min_dt: 1.0e-3}",
    )
    assert_refused(status, err, "--set", "time.adaptive.min_dt", "at most", "first_dt")
    status, err = cli_error(
        capsys, "check", str(CHANNEL), *adaptive, "--set", "time.adaptive.tolerance=0"
    )
    assert_refused(status, err, "--set", "time.adaptive.tolerance", "positive")
    assert cli.main(["check", str(CHANNEL), *adaptive]) == 0


# --------------------------------------------------------------------------------------------
# A run's own config.yaml reloads to the same Case (issue #49)

AWKWARD_STRINGS = (
    *("1e-3", "2E+5", ".5", "5.", "-0", "+1", "1_000", "0x1F", "0o17", "017", "1:30", ".inf"),
    *(".nan", "true", "No", "on", "y", "null", "~", "", "2001-12-14", "<<", "'1'", "#1", "a: b"),
    *("*x", "é", "1\n2", "1e-3*t"),
)
"""Strings that YAML would read as something else were they written plain (numbers of YAML 1.1
or 1.2, base 60, bools, null, dates, indicators), and a few formulas."""

AWKWARD_NUMBERS = (1e-300, 0.1 + 0.2, 12)


def _values_of(tp):
    """What :func:`_round_trip_cases` tries at a key of type ``tp``: awkward strings for a string,
    awkward numbers for a number (None for another type)."""
    if tp is str:
        return AWKWARD_STRINGS
    if tp is float or tp is int:
        return [v for v in AWKWARD_NUMBERS if tp is float or isinstance(v, int)]
    return None


def _schema_keys(tp, key="", tags=()):
    """Every (key path, type, tags) of a scalar value of the schema below dataclass ``tp``:
    ``tags`` the (key, value) pairs that choose the union options on the way (``fluid.inlet
    .kind: flow_rate``); a ``dict[str, ...]`` (PETSc options) as the key path ``...*``."""
    for f in dataclasses.fields(tp):
        sub = f"{key}.{f.name}" if key else f.name
        hint = typing.get_type_hints(tp)[f.name]
        options = typing.get_args(hint) if typing.get_origin(hint) in (Union, UnionType) else ()
        if dataclasses.is_dataclass(hint):
            yield from _schema_keys(hint, sub, tags)
        elif options and all(dataclasses.is_dataclass(o) for o in options):
            for option in options:
                tag = dataclasses.fields(option)[0]
                yield from _schema_keys(option, sub, (*tags, (f"{sub}.{tag.name}", tag.default)))
        elif typing.get_origin(hint) is dict:
            for value_type in typing.get_args(typing.get_args(hint)[1]):
                yield f"{sub}.*", value_type, tags
        elif not options:
            yield sub, hint, tags


def _set(data: dict, key: str, value) -> None:
    *parents, name = key.split(".")
    for part in parents:
        data = data.setdefault(part, {})
    data[name] = value


def test_a_runs_own_config_yaml_reloads_to_the_same_case_whatever_it_holds():
    """Whatever a run accepts, its config.yaml (:func:`fsi.config.to_yaml`) reloads to the same
    Case: every string and number field of the schema, under every union option, set to values
    YAML would misread if written plain (``formula: 1e-3`` read back as the number 0.001 made
    ``fsi run --restart`` and ``fsi report`` refuse the run's own folder). A value the schema
    refuses is skipped; each string key (name, formulas, PETSc options) has values accepted.
    The values accepted are gathered into as few cases as the schema allows (YAML is slow to
    read: one round trip per value took 4 s), each written and read back."""
    base = reader.read_case_file(CHANNEL)
    # A string option whose value is any type name (ksp_type's must be one of the installed
    # PETSc's Krylov types: check_installed).
    petsc_names = {"int": "ksp_max_it", "float": "ksp_rtol", "str": "ksp_norm_type"}
    groups: dict[tuple, list[tuple[dict, set]]] = {}  # per union options: [(data, keys set)]
    accepted: dict[str, int] = {}

    def accepts(data: dict, key: str, value) -> dict | None:
        trial = copy.deepcopy(data)
        _set(trial, key, value)
        try:
            config.from_dict(trial)
        except config.ConfigError:
            return None
        return trial

    for key, tp, tags in _schema_keys(config.Case):
        values = _values_of(tp)
        if values is None or key.endswith((".kind", ".model", ".file")):
            continue  # a Literal or bool (YAML's own types); a file is written as its rows
        key = key.replace("*", petsc_names[tp.__name__])
        fresh = copy.deepcopy(base)
        for tag_key, tag in tags:
            _set(fresh, tag_key, tag)
        cases = groups.setdefault(tags, [])
        for value in values:
            alone = accepts(fresh, key, value)
            if alone is None:
                continue
            accepted[key] = accepted.get(key, 0) + 1
            for i, (data, keys) in enumerate(cases):
                trial = None if key in keys else accepts(data, key, value)
                if trial is not None:
                    cases[i] = (trial, keys | {key})
                    break
            else:
                cases.append((alone, {key}))
    for tags, cases in groups.items():
        for data, keys in cases:
            case = config.from_dict(data)
            text = config.to_yaml(case)
            again = config.from_dict(reader.parse_yaml(text), "config.yaml")
            assert again == case, (tags, sorted(keys), text)
    for key in ("name", "fluid.inlet.formula", "fluid.solver.petsc_options.ksp_norm_type"):
        assert accepted.get(key, 0) >= 5, (key, accepted.get(key))
    assert len(accepted) > 50, len(accepted)


def test_an_end_that_cuts_the_last_step_short_is_warned_of(capsys):
    """``tube_womersley.yaml --set time.end=0.002`` cut its one step from 0.5 s to 2 ms, and
    the coupling failed after 100 iterations without a word why: ``fsi check`` (and ``fsi
    run``) warn, naming the segment, the step and what to give; an end on the steps is not
    warned of."""
    tube = str(ROOT / "configs/axisymmetric/tube_womersley.yaml")
    capsys.readouterr()
    assert cli.main(["check", tube, "--set", "time.end=0.002"]) == 0
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert (
            "fsi: warning: time.end = 0.002 s cuts the last step of time.schedule[0] (dt = 0.5 s) "
            "to 0.002 s, 250 times shorter: a case set up for its dt may not converge" in err
        ), err
        assert "--set 'time.schedule=[{until: 0.002, dt: ...}]'" in err
    for end in ("1.0", "0.45", "100.0"):
        assert cli.main(["check", tube, "--set", f"time.end={end}"]) == 0
        assert "warning" not in capsys.readouterr().err, end


def test_base_60_is_not_a_number(capsys):
    """YAML 1.1 reads ``1:30`` as 90: ``--set time.end=1:30`` is refused, not run for 90 s."""
    assert_refused(
        *cli_error(capsys, "check", str(CHANNEL), "--set", "time.end=1:30"),
        "--set",
        "time.end",
        "got '1:30'",
    )
    assert reader.parse_yaml("a: 1:30") == {"a": "1:30"}
