"""How far a vessel's wall moves per kPa of blood pressure, from a run's field files.

At the inner wall point nearest (``--z``, R) (R the lumen's radius, or height, from the run's
config.yaml) it reads, at every stored time from ``--from`` on, the wall's radial displacement
(``eta`` in solid.xdmf, y component) and the blood pressure (``pressure`` in fields.xdmf, at the
fluid node nearest the same point), and prints

- ``slope``: the least-squares du_r/dp over those times (m/Pa; also in µm/kPa), the wall's
  dynamic compliance over the pressures the run swept;
- ``ratio``: u_r/p at the largest pressure (m/Pa), the static ratio (the wall's reference state
  is unloaded, p = 0);
- the thin tube's ΔR/ΔP = R²/(E h) and Lamé's thick cylinder in plane strain (the clamped ends
  hold the length), u_r(a)/p = a (1 + ν)/E ((1 − 2ν) a² + b²)/(b² − a²), b = a + h, with the
  wall's E, ν; and each relative difference.

The last line of its standard output is one JSON object of these values. For an axisymmetric
run (docs/axisymmetric.md); a plane run's strip gets the same numbers, which the tube formulas
do not describe.

Usage::

    .venv/bin/python scripts/wall_compliance.py results/heartbeat --z 0.0275 --from 1.834
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fsi import config
from fsi.output import field_files

ROOT = Path(__file__).resolve().parents[2]


def lumen_radius(case: config.Case) -> float:
    g = case.geometry
    return g.radius if isinstance(g, config.TubeGeometry) else g.height


def nearest(points: np.ndarray, target: tuple[float, float]) -> int:
    return int(np.argmin(np.linalg.norm(points[:, :2] - np.asarray(target), axis=1)))


def samples(run: Path, z: float, radius: float, start: float) -> tuple[np.ndarray, ...]:
    """Times, the wall's radial displacement (m) and the pressure (Pa) at (z, radius)."""
    times = [t for t in field_files.stored_times(run, "eta") if t >= start - 1e-12]
    wall, blood, where = [], [], None
    for t in times:
        eta = field_files.read_field(run, "eta", t, warp=0.0)
        p = field_files.read_field(run, "pressure", t, warp=0.0)
        if where is None:
            where = (nearest(eta.reference, (z, radius)), nearest(p.reference, (z, radius)))
        wall.append(eta.values[where[0], 1])
        blood.append(p.values[where[1]])
    return np.array(times), np.array(wall), np.array(blood)


def estimates(case: config.Case, radius: float) -> dict[str, float]:
    """The thin tube's R²/(E h) and Lamé's plane-strain u_r(a)/p (m/Pa) of the vessel wall."""
    wall = case.structure.wall
    E, nu, h = wall.young_modulus, wall.poisson_ratio, case.geometry.wall_thickness
    a, b = radius, radius + h
    lame = a * (1 + nu) / E * ((1 - 2 * nu) * a * a + b * b) / (b * b - a * a)
    return {"thin_tube": radius**2 / (E * h), "lame": lame}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--z", type=float, required=True, help="axial position (m)")
    parser.add_argument("--from", dest="start", type=float, default=0.0, help="first time (s)")
    args = parser.parse_args(argv)
    case = config.load(args.run / "config.yaml")
    radius = lumen_radius(case)
    t, u, p = samples(args.run, args.z, radius, args.start)
    slope = float(np.polyfit(p, u, 1)[0])
    top = int(np.argmax(p))
    values = {"slope": slope, "ratio": float(u[top] / p[top]), **estimates(case, radius)}
    where = f"z = {1e3 * args.z:g} mm, r = {1e3 * radius:g} mm"
    print(f"{args.run}: the wall at {where}, {len(t)} times")
    span = f"u_r {1e6 * u.min():.4g} to {1e6 * u.max():.4g} µm"
    print(f"  pressure {p.min():.4g} to {p.max():.4g} Pa, {span}")
    for key in ("slope", "ratio", "thin_tube", "lame"):
        print(f"  {key:9s} {1e9 * values[key]:.4g} µm/kPa")
    for key in ("slope", "ratio"):
        for reference in ("thin_tube", "lame"):
            change = 100 * (values[key] / values[reference] - 1)
            print(f"  {key} against {reference}: {change:+.1f} %")
    print(json.dumps(values))
    return 0
