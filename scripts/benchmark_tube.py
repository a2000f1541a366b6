"""Elastic-tube benchmarks of the axisymmetric model (docs/axisymmetric.md).

``--case pulse``: the pressure pulse in an elastic tube (Formaggia et al. 2001; Tuković et al.
2018, Section 4.4; solids4foam's 3dTube), ``configs/axisymmetric/tube_pulse.yaml``, run through
the command line's own code path (:func:`fsi.cli.main`) into ``--out`` (or, with
``--analyse-only DIR``, an existing run folder analysed). From the run:

- ``ur_max_A`` (m), ``t_ur_max_A`` (s): the largest radial displacement of the inner wall at
  mid-length (point A, ``ur_A`` in metrics.csv) and when (a parabola through the largest sample
  and its neighbours);
- ``uz_min_A`` (m): the smallest (most negative) axial displacement there;
- ``wave_speed`` (m/s): the pressure front's speed along the axis, the least-squares slope of
  z against the time the axis pressure first reaches half the inlet's peak at the stations
  z = 1, 1.5, … 4 cm (linear in time between stored fields and along the axis between nodes).

It prints a report, the references (:data:`REFERENCES`; the thick-wall estimate of the wave
speed, :func:`thick_wall_wave_speed`) and, as the last line of its standard output, one JSON
object of the four values. The report is also written to ``DIR/benchmark.txt``.

Usage::

    .venv/bin/python scripts/benchmark_tube.py --case pulse --out results/tube_pulse
        [--set mesh.size=1.25e-4] [--set 'time.schedule=[{until: 0.01, dt: 1.25e-5}]']
    .venv/bin/python scripts/benchmark_tube.py --case pulse --analyse-only results/tube_pulse
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fsi import cli, config  # noqa: E402
from fsi.output import plot  # noqa: E402

CONFIGS = {"pulse": ROOT / "configs" / "axisymmetric" / "tube_pulse.yaml"}

REFERENCES = {
    "pulse": {
        # Tuković et al. 2018 (3D, St. Venant–Kirchhoff, backward Euler 2nd order, dt 2.5e-5 s),
        # their Fig. 25, as read by solids4foam's 3dTube verification; and solids4foam's own
        # benchmark data (solids4foam-tutorials-benchmark-data @ 6917f43, 3dTube v2012
        # solidPointDisplacement, backward, dt 5e-5 s): 0.1573 mm at 7.30 ms, uz -0.0899 mm.
        "ur_max_A": 1.5694e-4,
        "t_ur_max_A": 7.23e-3,
        "uz_min_A": -8.99e-5,
        "wave_speed": 4.54,  # Tuković et al. 2018, Section 4.4 (their simulation)
    }
}
"""The published values (SI) the benchmark is set beside (docs/axisymmetric.md, sources)."""

STATIONS = np.arange(0.01, 0.0401, 0.005)
"""z (m) of the stations where the pressure front's arrival is timed."""


def thick_wall_wave_speed(young: float, poisson: float, rho_fluid: float, a: float, b: float):
    """The pulse wave speed c = 1/sqrt(ρ D) (Bramwell & Hill 1922) of a tube whose
    distensibility D = (1/A) dA/dp = 2 u_r(a)/(a p) is Lamé's for a thick cylinder of inner
    and outer radii a, b with free ends (σ_zz = 0): u_r(a)/a = p/E ((b² + a²)/(b² − a²) + ν), so

        c = sqrt(E / (2 ρ ((b² + a²)/(b² − a²) + ν))).

    For a thin wall (b − a = h ≪ a) it tends to Moens–Korteweg's sqrt(E h/(2 ρ a))."""
    ratio = (b * b + a * a) / (b * b - a * a)
    return math.sqrt(young / (2 * rho_fluid * (ratio + poisson)))


def read_rows(run: Path) -> list[dict[str, float]]:
    with open(run / "metrics.csv") as f:
        return [
            {k: float(v) if v not in ("", None) else math.nan for k, v in row.items()}
            for row in csv.DictReader(f)
        ]


def peak_time(t: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """The largest value and its time, refined by the parabola through the largest sample
    and its neighbours (the sample itself at either end)."""
    i = int(np.argmax(values))
    if i == 0 or i == len(values) - 1:
        return float(values[i]), float(t[i])
    (t0, t1, t2), (v0, v1, v2) = t[i - 1 : i + 2], values[i - 1 : i + 2]
    coefficients = np.polyfit([t0 - t1, 0.0, t2 - t1], [v0, v1, v2], 2)
    if coefficients[0] >= 0:
        return float(v1), float(t1)
    s = -coefficients[1] / (2 * coefficients[0])
    return float(np.polyval(coefficients, s)), float(t1 + s)


def axis_pressure(run: Path, t: float) -> tuple[np.ndarray, np.ndarray]:
    """z (sorted) and p of the pressure nodes on the axis (y = 0) at the stored time ``t``."""
    snapshot = plot.read_field(run, "pressure", t, warp=0.0)
    xy, p = snapshot.reference, snapshot.values
    on_axis = np.abs(xy[:, 1]) < 1e-12
    z, values = xy[on_axis, 0], p[on_axis]
    order = np.argsort(z)
    return z[order], values[order]


def front_arrivals(run: Path, level: float, stations: np.ndarray) -> np.ndarray:
    """The first time (s) the axis pressure reaches ``level`` at each station (linear in time
    between stored fields, along the axis between nodes); NaN where it never does."""
    times = plot.stored_times(run, "pressure")
    arrival = np.full(len(stations), np.nan)
    previous = None
    for t in times:
        z, p = axis_pressure(run, t)
        now = np.interp(stations, z, p)
        if previous is not None:
            t0, p0 = previous
            crossing = np.isnan(arrival) & (p0 < level) & (now >= level)
            fraction = (level - p0[crossing]) / (now[crossing] - p0[crossing])
            arrival[crossing] = t0 + fraction * (t - t0)
        previous = (t, now)
    return arrival


def pulse_values(run: Path, case: config.Case) -> dict[str, float]:
    """ur_max_A, t_ur_max_A, uz_min_A and wave_speed of a pulse run (the module docstring)."""
    rows = read_rows(run)
    t = np.array([r["t"] for r in rows])
    ur, uz = np.array([r["ur_A"] for r in rows]), np.array([r["uz_A"] for r in rows])
    ur_max, t_max = peak_time(t, ur)
    peak_inlet = 1333.2  # the config's pulse (Pa)
    arrivals = front_arrivals(run, peak_inlet / 2, STATIONS)
    known = ~np.isnan(arrivals)
    speed = math.nan
    if known.sum() >= 2:
        speed = float(np.polyfit(arrivals[known], STATIONS[known], 1)[0])
    return {
        "ur_max_A": ur_max,
        "t_ur_max_A": t_max,
        "uz_min_A": float(uz.min()),
        "wave_speed": speed,
        "arrivals": [None if math.isnan(a) else float(a) for a in arrivals],
    }


def report(values: dict, case: config.Case, run: Path, seconds: float | None) -> str:
    g, wall, fluid = case.geometry, case.structure.wall, case.fluid
    estimate = thick_wall_wave_speed(
        wall.young_modulus, wall.poisson_ratio, fluid.density, g.radius, g.radius + g.wall_thickness
    )
    moens = math.sqrt(wall.young_modulus * g.wall_thickness / (2 * fluid.density * g.radius))
    reference = REFERENCES["pulse"]
    lines = [f"Elastic-tube pressure pulse: {run}"]
    for key, unit, scale in (
        ("ur_max_A", "mm", 1e3),
        ("t_ur_max_A", "ms", 1e3),
        ("uz_min_A", "mm", 1e3),
        ("wave_speed", "m/s", 1.0),
    ):
        ours, ref = values[key], reference[key]
        lines.append(
            f"  {key:11s} {ours * scale:10.5g} {unit:4s} reference {ref * scale:10.5g}"
            f"  ({100 * (ours / ref - 1):+.1f} %)"
        )
    lines.append(
        f"  wave speed: thick-wall estimate (Bramwell–Hill, Lamé) {estimate:.4g} m/s "
        f"({100 * (values['wave_speed'] / estimate - 1):+.1f} %), Moens–Korteweg {moens:.4g} m/s"
    )
    arrivals = ", ".join("–" if a is None else f"{1e3 * a:.3f}" for a in values["arrivals"])
    lines.append(f"  front arrivals (ms) at z = {', '.join(f'{1e2 * z:g}' for z in STATIONS)} cm:")
    lines.append(f"    {arrivals}")
    if seconds is not None:
        lines.append(f"  wall time {seconds:.0f} s on {MPI.COMM_WORLD.size} rank(s)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", choices=sorted(CONFIGS), required=True)
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--out", type=Path, help="run the case into this folder")
    where.add_argument("--analyse-only", type=Path, help="analyse an existing run folder")
    parser.add_argument("--set", action="append", default=[], help="a config override")
    args = parser.parse_args(argv)

    seconds = None
    run = args.analyse_only or args.out
    if args.out is not None:
        command = ["run", str(CONFIGS[args.case]), "--out", str(args.out), "--overwrite"]
        for override in args.set:
            command += ["--set", override]
        start = time.perf_counter()
        status = cli.main(command)
        seconds = time.perf_counter() - start
        if status != 0:
            return status
    case = config.load(run / "config.yaml")
    values = pulse_values(run, case)
    if MPI.COMM_WORLD.rank == 0:
        text = report(values, case, run, seconds)
        (run / "benchmark.txt").write_text(text + "\n")
        print(text)
        print(
            json.dumps({k: values[k] for k in ("ur_max_A", "t_ur_max_A", "uz_min_A", "wave_speed")})
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
