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
  z = 1, 1.5, … 4 cm (linear in time between stored fields and along the axis between nodes);
- and the run's size and cost from its summary.json: ``cells``, ``dofs_fluid``,
  ``dofs_solid``, ``seconds_per_step``, ``ranks``.

``--case pulse3d``: the same pulse in the tube as tetrahedra, its quarter between the
symmetry planes y = 0 and z = 0 (``configs/3d/tube_pulse.yaml``, docs/3d.md; point A on +y,
the axis the x axis).

``--case womersley``: Womersley flow in a deformable tube
(``configs/axisymmetric/tube_womersley.yaml``), run here rather than by ``fsi run``: the exact
linear solution (fsi/benchmarks/womersley_tube.py) is imposed at both ends (the fluid's velocity
at the inlet and the outlet, the wall's displacement at its ends: ends that do not reflect the
wave) and is the initial state (fluid velocity and pressure, the wall's displacement, velocity,
acceleration and load, the mesh). Over the last period the script takes the complex amplitude
at the frequency of the pressure on the axis and of the wall's radial displacement at every node
(a discrete Fourier coefficient), fits log a(z) = c − i k z over the middle 60 % of the tube and
gives ``wave_speed`` = ω/Re k (m/s), ``amplitude_ratio_per_wavelength`` = exp(2π Im k/Re k) and
``wall_radial_per_pressure`` = |w_r|/|p| at mid-length (m/Pa), beside the exact values.

It prints a report, the references (:data:`REFERENCES`; the thick-wall estimate of the wave
speed, :func:`thick_wall_wave_speed`; the exact deformable-tube solution) and, as the last line
of its standard output, one JSON object of the case's values. The report is also written to
``DIR/benchmark.txt``.

Usage::

    .venv/bin/python scripts/benchmark_tube.py --case pulse --out results/tube_pulse
        [--set mesh.size=1.25e-4] [--set 'time.schedule=[{until: 0.01, dt: 1.25e-5}]']
    .venv/bin/python scripts/benchmark_tube.py --case pulse --analyse-only results/tube_pulse
    .venv/bin/python scripts/benchmark_tube.py --case womersley --out results/tube_womersley
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

from fsi import cli, config
from fsi.benchmarks.womersley_tube import TubeParameters, WomersleyTube
from fsi.coupled import coupling, partitioned
from fsi.geometry.tags import Boundary
from fsi.numerics.timestepping import steps
from fsi.output import field_files
from fsi.physics import fluid_boundaries, solid_boundaries

ROOT = Path(__file__).resolve().parents[2]

CONFIGS = {
    "pulse": ROOT / "configs" / "axisymmetric" / "tube_pulse.yaml",
    "pulse3d": ROOT / "configs" / "3d" / "tube_pulse.yaml",
    "womersley": ROOT / "configs" / "axisymmetric" / "tube_womersley.yaml",
}

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
    """z (sorted) and p of the pressure nodes on the axis (y = 0; y = z = 0 in 3D) at the
    stored time ``t``."""
    snapshot = field_files.read_field(run, "pressure", t, warp=0.0)
    xy, p = snapshot.reference, snapshot.values
    on_axis = np.all(np.abs(xy[:, 1:]) < 1e-12, axis=1)
    z, values = xy[on_axis, 0], p[on_axis]
    order = np.argsort(z)
    return z[order], values[order]


def front_arrivals(run: Path, level: float, stations: np.ndarray) -> np.ndarray:
    """The first time (s) the axis pressure reaches ``level`` at each station (linear in time
    between stored fields, along the axis between nodes); NaN where it never does."""
    times = field_files.stored_times(run, "pressure")
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


# --------------------------------------------------------------------------------------------
# Womersley flow in a deformable tube


def exact_solution(case: config.Case) -> WomersleyTube:
    """The exact linear solution for the case's tube, fluid and wall (1 Pa on the axis at the
    inlet; the frequency of the config's inlet formula is the script's: 0.02 Hz)."""
    g, wall, fluid = case.geometry, case.structure.wall, case.fluid
    return WomersleyTube(
        TubeParameters(
            a=g.radius,
            h=g.wall_thickness,
            young=wall.young_modulus,
            poisson=wall.poisson_ratio,
            rho_solid=wall.density,
            rho_fluid=fluid.density,
            mu=fluid.rheology.viscosity,
        )
    )


def _vector(pair) -> np.ndarray:
    return np.vstack([np.asarray(pair[0]), np.asarray(pair[1])])


def outlet_traction(exact: WomersleyTube, x: np.ndarray, t: float) -> np.ndarray:
    """σ n of the exact fluid on a cross-section with the normal +e_z (the outlet):
    (σ_zz, σ_rz) with σ_zz = −p + 2 μ ∂u_z/∂z and ∂/∂z = −ik (Pa)."""
    amplitude = exact.fluid_amplitudes(x[1])
    wave = np.exp(1j * (exact.params.omega * t - exact.k * x[0]))
    mu = exact.params.mu
    zz = -amplitude["p"] + 2 * mu * (-1j * exact.k) * amplitude["u_z"]
    return np.vstack([(zz * wave).real, (amplitude["s_rz"] * wave).real])


def womersley_problem(case: config.Case, exact: WomersleyTube) -> partitioned.CoupledProblem:
    """The coupled tube with the exact solution at its ends and as its initial state."""
    velocity = lambda x, t: _vector(exact.fluid_velocity(x[1], x[0], t))  # noqa: E731
    displacement = lambda x, t: _vector(exact.wall_displacement(x[1], x[0], t))  # noqa: E731
    fluid_conditions = (
        fluid_boundaries.PrescribedVelocity(Boundary.INLET, velocity),
        fluid_boundaries.PrescribedTraction(
            Boundary.OUTLET, lambda x, t: outlet_traction(exact, x, t)
        ),
        fluid_boundaries.Velocity(Boundary.INTERFACE),
        fluid_boundaries.Axis(Boundary.AXIS),
    )
    solid_conditions = solid_boundaries.SolidBoundaryConditions(
        dirichlet=(solid_boundaries.PrescribedDisplacement(displacement, (Boundary.CLAMPED,)),)
    )
    problem = partitioned.build_coupled(
        case, fluid_conditions=fluid_conditions, solid_conditions=solid_conditions
    )
    start_exactly(problem, case, exact)
    return problem


def start_exactly(problem: partitioned.CoupledProblem, case, exact: WomersleyTube) -> None:
    """The exact state at t = 0: the wall's η, η̇, η̈ and its load from the blood (the traction
    −σ e_r of the exact fluid at r = a, which the first step's load at t_n uses), the mesh at
    the extension of the wall's displacement, the fluid's velocity and pressure; the
    predictor's history restarted from it."""
    wall = problem.solid
    radius = case.geometry.radius
    for field, values in (
        (wall.eta, exact.wall_displacement),
        (wall.eta_n, exact.wall_displacement),
        (wall.v_n, exact.wall_velocity),
        (wall.a_n, exact.wall_acceleration),
    ):
        field.interpolate(lambda x, values=values: _vector(values(x[1], x[0], 0.0)))
        field.x.scatter_forward()

    def load(x):
        amplitude = exact.fluid_amplitudes(np.full(x.shape[1], radius))
        phase = np.exp(-1j * exact.k * x[0])
        return np.vstack([(-amplitude["s_rz"] * phase).real, (-amplitude["s_rr"] * phase).real])

    wall.traction_n.interpolate(load)
    x0 = wall.interface_displacement().ravel()
    problem.fluid_side.start_from(x0)
    problem.fluid.set_initial_state(
        lambda x: _vector(exact.fluid_velocity(x[1], x[0], 0.0)),
        lambda x: exact.pressure(x[1], x[0], 0.0),
    )
    problem.predictor = coupling.predictor_from_config(case.coupling)
    problem.predictor.record(problem.unknown.stack(x0), 0.0)


def _gathered(points: np.ndarray, values: np.ndarray, comm) -> tuple[np.ndarray, np.ndarray]:
    """Rows gathered from every rank, sorted by z, duplicates (shared nodes) dropped."""
    points = np.concatenate(comm.allgather(points))
    values = np.concatenate(comm.allgather(values))
    z, index = np.unique(np.round(points[:, 0], 12), return_index=True)
    return z, values[index]


def womersley_samples(problem, case) -> tuple[np.ndarray, ...]:
    """March the case; over its last period: the times, the axis pressure's z and values
    (times × nodes), the wall's z and radial displacement (times × nodes)."""
    comm = problem.fluid.comm
    owned = problem.fluid.Q.dofmap.index_map.size_local
    xp = problem.fluid.Q.tabulate_dof_coordinates()[:owned]
    axis = np.abs(xp[:, 1]) < 1e-12 * case.geometry.radius
    wall_points = problem.solid.interface_points
    period = 1.0 / 0.02
    times, pressure, radial = [], [], []
    for step in steps(case.time):
        result = problem.step(step.index, step.t, step.dt)  # raises CouplingNotConverged
        if comm.rank == 0 and step.index % 10 == 0:
            print(f"step {step.index}  t = {step.t:g} s  coupling {result.iterations}", flush=True)
        if step.t > case.time.end - period + 1e-9 * period:
            z_p, p = _gathered(xp[axis], problem.fluid.p.x.array[:owned][axis], comm)
            w = problem.solid.interface_displacement()
            z_w, w_r = _gathered(wall_points, w[:, 1], comm)
            times.append(step.t)
            pressure.append(p)
            radial.append(w_r)
    return np.array(times), z_p, np.array(pressure), z_w, np.array(radial)


def amplitudes(times: np.ndarray, values: np.ndarray, omega: float) -> np.ndarray:
    """The complex amplitude a of each column, values ≈ Re(a e^{iωt}) over whole periods."""
    return 2 / len(times) * np.exp(-1j * omega * times) @ values


def fitted_wave_number(z: np.ndarray, a: np.ndarray, window: tuple[float, float]) -> complex:
    """k of a(z) ∝ e^{−ikz}: the slopes of the unwrapped phase (−Re k) and of log |a| (Im k)
    fitted over ``window`` (m)."""
    inside = (z >= window[0]) & (z <= window[1])
    phase = np.unwrap(np.angle(a[inside]))
    re = -np.polyfit(z[inside], phase, 1)[0]
    im = np.polyfit(z[inside], np.log(np.abs(a[inside])), 1)[0]
    return complex(re, im)


def womersley_values(samples, case: config.Case, exact: WomersleyTube) -> dict[str, float]:
    times, z_p, pressure, z_w, radial = samples
    omega = exact.params.omega
    length = case.geometry.length
    window = (0.2 * length, 0.8 * length)
    a_p, a_w = amplitudes(times, pressure, omega), amplitudes(times, radial, omega)
    k_p, k_w = fitted_wave_number(z_p, a_p, window), fitted_wave_number(z_w, a_w, window)
    middle = length / 2
    at_p = np.interp(middle, z_p, a_p.real) + 1j * np.interp(middle, z_p, a_p.imag)
    at_w = np.interp(middle, z_w, a_w.real) + 1j * np.interp(middle, z_w, a_w.imag)
    return {
        "wave_speed": omega / k_p.real,
        "amplitude_ratio_per_wavelength": math.exp(2 * math.pi * k_p.imag / k_p.real),
        "wall_radial_per_pressure": abs(at_w) / abs(at_p),
        "wall_wave_speed": omega / k_w.real,
        "wall_amplitude_ratio_per_wavelength": math.exp(2 * math.pi * k_w.imag / k_w.real),
    }


def womersley_report(values: dict, exact: WomersleyTube, run: Path, seconds: float) -> str:
    reference = {
        "wave_speed": exact.wave_speed,
        "amplitude_ratio_per_wavelength": exact.amplitude_ratio_per_wavelength,
        "wall_radial_per_pressure": exact.wall_radial_per_pressure,
        "wall_wave_speed": exact.wave_speed,
        "wall_amplitude_ratio_per_wavelength": exact.amplitude_ratio_per_wavelength,
    }
    lines = [f"Womersley flow in a deformable tube: {run}", "  (from the axis pressure; wall_*:"]
    lines[-1] += " from the wall's radial displacement)"
    for key, ours in values.items():
        lines.append(
            f"  {key:36s} {ours:12.6g}  exact {reference[key]:12.6g}"
            f"  ({100 * (ours / reference[key] - 1):+.2f} %)"
        )
    lines.append(f"  wall time {seconds:.0f} s on {MPI.COMM_WORLD.size} rank(s)")
    return "\n".join(lines)


def run_womersley(out: Path, overrides: list[str]) -> tuple[dict, str]:
    case = config.load(CONFIGS["womersley"], overrides)
    exact = exact_solution(case)
    if MPI.COMM_WORLD.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        (out / "config.yaml").write_text(config.to_yaml(case))
    start = time.perf_counter()
    problem = womersley_problem(case, exact)
    values = womersley_values(womersley_samples(problem, case), case, exact)
    text = womersley_report(values, exact, out, time.perf_counter() - start)
    return values, text


# --------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", choices=sorted(CONFIGS), required=True)
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--out", type=Path, help="run the case into this folder")
    where.add_argument("--analyse-only", type=Path, help="analyse an existing run folder")
    parser.add_argument("--set", action="append", default=[], help="a config override")
    args = parser.parse_args(argv)

    if args.case == "womersley":
        if args.out is None:
            parser.error("--case womersley runs the case itself: give --out")
        values, text = run_womersley(args.out, args.set)
        if MPI.COMM_WORLD.rank == 0:
            (args.out / "benchmark.txt").write_text(text + "\n")
            print(text)
            keys = ("wave_speed", "amplitude_ratio_per_wavelength", "wall_radial_per_pressure")
            print(json.dumps({k: values[k] for k in keys}))
        return 0
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
        keys = ("ur_max_A", "t_ur_max_A", "uz_min_A", "wave_speed")
        print(json.dumps({**{k: values[k] for k in keys}, **run_size(run)}))
    return 0


def run_size(run: Path) -> dict:
    """``cells``, ``dofs_fluid``, ``dofs_solid``, ``seconds_per_step`` and ``ranks`` of the run
    in ``run`` (its summary.json)."""
    summary = json.loads((run / "summary.json").read_text())
    return {
        "cells": summary["cells"]["total"],
        "dofs_fluid": summary["fluid_dofs"],
        "dofs_solid": summary["solid_dofs"],
        "seconds_per_step": summary["mean_step_time_s"],
        "ranks": summary["ranks"],
    }
