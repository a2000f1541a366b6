"""The elastic-tube benchmarks through scripts/benchmark_tube.py (issue #28;
docs/axisymmetric.md): the pressure pulse's point A and wave speed against the published values
and the thick-wall estimate; Womersley flow in a deformable tube against the exact linear
solution (fsi/benchmarks/womersley_tube.py).

The shipped pulse (0.25 mm cells, 25 µs steps, 400 steps) takes ~2.5 minutes serially, its 3D
quarter (configs/3d/tube_pulse.yaml) ~11 minutes and the shipped Womersley case (two periods of 100
steps) ~7: all three are ``slow``. The default selection runs the pulse on 0.5 mm cells and
50 µs steps (~8× less work), held to the same tolerances, and Womersley over one period of 50
steps (its attenuation to 10 %: see its test); measured in docs/axisymmetric.md.
"""

import json
import math
from pathlib import Path

import pytest

from fsi import config  # noqa: E402
from fsi.benchmarks import elastic_tube as benchmark_tube

COARSER = [
    "--set",
    "mesh.size=5.0e-4",
    "--set",
    "mesh.local_size=5.0e-4",
    "--set",
    "time.schedule=[{until: 0.01, dt: 5.0e-5}]",
    "--set",
    "output.fields_every=2",
]


def pulse(out: Path, options: list[str], capsys, case: str = "pulse") -> dict:
    """Run the pulse benchmark into ``out``; the JSON object of its last line (on every rank)."""
    from mpi4py import MPI

    assert benchmark_tube.main(["--case", case, "--out", str(out), *options]) == 0
    text = capsys.readouterr().out
    line = text.strip().splitlines()[-1] if MPI.COMM_WORLD.rank == 0 else None
    return json.loads(MPI.COMM_WORLD.bcast(line))


def check(values: dict, out: Path) -> None:
    """Point A's peak radial displacement within 5 % of the published converged value
    (Tuković et al. 2018: 0.15694 mm), the wave speed within 10 % of the thick-wall estimate
    (:func:`benchmark_tube.thick_wall_wave_speed`, 5.07 m/s), both as issue #28 asks; the
    peak's time within 5 % of the published 7.23 ms and the axial trough within 10 % of
    solids4foam's −0.0899 mm (looser: read from a figure, platform-dependent by 1.5–3 %)."""
    reference = benchmark_tube.REFERENCES["pulse"]
    case = config.load(out / "config.yaml")
    g, wall = case.geometry, case.structure.wall
    estimate = benchmark_tube.thick_wall_wave_speed(
        wall.young_modulus,
        wall.poisson_ratio,
        case.fluid.density,
        g.radius,
        g.radius + g.wall_thickness,
    )
    assert values["ur_max_A"] == pytest.approx(reference["ur_max_A"], rel=0.05), values
    assert values["t_ur_max_A"] == pytest.approx(reference["t_ur_max_A"], rel=0.05), values
    assert values["uz_min_A"] == pytest.approx(reference["uz_min_A"], rel=0.10), values
    assert math.isfinite(values["wave_speed"])
    assert values["wave_speed"] == pytest.approx(estimate, rel=0.10), (values, estimate)


def test_the_pressure_pulse_on_a_coarser_mesh(shared_tmp, capsys):
    out = shared_tmp / "pulse_coarser"
    check(pulse(out, COARSER, capsys), out)


def test_the_3d_pulse_benchmark_reports_its_values_and_its_size(shared_tmp, capsys):
    """``--case pulse3d`` (configs/3d/tube_pulse.yaml, the quarter tube) on 2 mm tetrahedra for
    2 steps: its last line is the JSON object of point A's values and the run's size and cost
    (the shipped case's published values need its 400 steps: docs/3d.md says what is
    measured)."""
    from mpi4py import MPI

    short = ["mesh.size=2.0e-3", "mesh.local_size=2.0e-3", "time.end=1.0e-4"]
    short.append("time.schedule=[{until: 1.0e-4, dt: 5.0e-5}]")
    values = pulse(
        shared_tmp / "pulse3d", sum((["--set", s] for s in short), []), capsys, "pulse3d"
    )
    keys = {"ur_max_A", "t_ur_max_A", "uz_min_A", "wave_speed", "cells", "dofs_fluid"}
    assert keys | {"dofs_solid", "seconds_per_step", "ranks"} == set(values)
    assert values["ranks"] == MPI.COMM_WORLD.size and values["cells"] > 1500  # 1,775
    assert values["dofs_fluid"] > 2000 and values["dofs_solid"] > 2000
    assert values["t_ur_max_A"] == pytest.approx(1e-4) and values["seconds_per_step"] > 0


@pytest.mark.slow
def test_the_shipped_pressure_pulse(shared_tmp, capsys):
    out = shared_tmp / "pulse"
    check(pulse(out, [], capsys), out)


@pytest.mark.slow
def test_the_shipped_3d_pressure_pulse(shared_tmp, capsys):
    """configs/3d/tube_pulse.yaml: the quarter tube (1 mm tetrahedra, 400 steps of 25 µs; ~11 min
    serially) held to the axisymmetric pulse's tolerances (docs/3d.md has its values beside the
    axisymmetric model's)."""
    out = shared_tmp / "pulse3d_shipped"
    check(pulse(out, [], capsys, "pulse3d"), out)


WOMERSLEY_SHORTER = ["--set", "time.end=50.0", "--set", "time.schedule=[{until: 50.0, dt: 1.0}]"]


def womersley(out: Path, options: list[str], capsys) -> dict:
    from mpi4py import MPI

    assert benchmark_tube.main(["--case", "womersley", "--out", str(out), *options]) == 0
    text = capsys.readouterr().out
    line = text.strip().splitlines()[-1] if MPI.COMM_WORLD.rank == 0 else None
    return json.loads(MPI.COMM_WORLD.bcast(line))


def check_womersley(values: dict, out: Path, attenuation: float = 0.03) -> None:
    """The issue's tolerances against the exact thick-wall solution: the wave speed within 1 %,
    the amplitude ratio per wavelength within ``attenuation`` (the issue's 3 %), the wall's
    radial displacement per pascal of axis pressure at mid-length within 2 %."""
    exact = benchmark_tube.exact_solution(config.load(out / "config.yaml"))
    assert values["wave_speed"] == pytest.approx(exact.wave_speed, rel=0.01), values
    assert values["amplitude_ratio_per_wavelength"] == pytest.approx(
        exact.amplitude_ratio_per_wavelength, rel=attenuation
    ), values
    assert values["wall_radial_per_pressure"] == pytest.approx(
        exact.wall_radial_per_pressure, rel=0.02
    ), values


def test_womersley_flow_in_a_deformable_tube_over_one_period(shared_tmp, capsys):
    """One period of 50 steps (the shipped case: two of 100): the wave speed and the wall's
    displacement per pascal at the issue's tolerances (measured −0.20 %, −0.04 %); the
    attenuation, the small imaginary part of k, within 10 % only (measured +6.8 %: the 1 s
    step's error, +2.1 % with the shipped 0.5 s steps, which the slow test holds to 3 %)."""
    out = shared_tmp / "womersley_shorter"
    check_womersley(womersley(out, WOMERSLEY_SHORTER, capsys), out, attenuation=0.10)


@pytest.mark.slow
def test_the_shipped_womersley_tube(shared_tmp, capsys):
    out = shared_tmp / "womersley"
    check_womersley(womersley(out, [], capsys), out)
