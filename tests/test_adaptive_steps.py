"""Adaptive time stepping (``time.step_control: adaptive``; fsi.numerics.timestepping's
LocalError, StepSizeControl and AdaptiveSteps, driven by fsi.run.simulation.march).

Verified on the channel flow started from rest by a constant pressure difference (Newtonian,
rigid wall, the study's open boundaries): its flow rate per unit depth has the exact series

    Q(t) = Q∞ [1 − Σ_{n odd} 96/(n⁴ π⁴) exp(−n² π² ν t / H²)],   Q∞ = G H³ / (12 μ)

(the start-up of plane Poiseuille flow; the open ends keep the flow parallel, test_open_boundaries).
From rest the solution changes on time scales from the first step's to H²/(π² ν) = 1.4 s, so
the steps must grow by orders of magnitude.
"""

import csv
import math
from pathlib import Path

from mpi4py import MPI

import pytest

from fsi import cli

G, L, H, MU, RHO = 100.0, 0.02, 0.007, 0.0035, 1060.0  # Pa/m, m, m, Pa s, kg/m³
Q_INF = G * H**3 / (12 * MU)
NU = MU / RHO
REPORT = (0.02, 0.1, 0.3, 1.0, 2.0)


def exact_flow_rate(t: float) -> float:
    series = sum(
        96 / (n**4 * math.pi**4) * math.exp(-(n**2) * math.pi**2 * NU * t / H**2)
        for n in range(1, 200, 2)
    )
    return Q_INF * (1 - series)


def channel_case(out: Path, tolerance: float, *extra: str, restart: Path | None = None) -> int:
    """The channel (0.5 mm cells) from rest to 2 s under G, adaptive steps of at most 0.5 s
    from 1 ms, the error relative to the peak velocity G H² / (8 μ)."""
    settings = [
        "geometry={kind: channel}",
        "structure.mode=rigid",
        "mesh={size: 5.0e-4, local_size: 5.0e-4}",
        f"fluid.rheology={{model: newtonian, viscosity: {MU}}}",
        f"fluid.inlet={{kind: pressure, formula: '{G * L!r}'}}",
        "fluid.open_boundary=do_nothing",
        "fluid.normal_flow=true",
        "fluid.inflow_stabilization=0.0",
        "time.end=2.0",
        "time.schedule=[{until: 2.0, dt: 0.5}]",
        "time.step_control=adaptive",
        f"time.adaptive={{tolerance: {tolerance}, first_dt: 1.0e-3, "
        f"velocity_scale: {G * H**2 / (8 * MU)!r}}}",
        f"output.report_times=[{', '.join(map(str, REPORT))}]",
        "output.fields_every=100000",
        *extra,
    ]
    args = ["run", "configs/channel_poiseuille.yaml", "--out", str(out)]
    args += sum((["--set", s] for s in settings), [])
    return cli.main(args + ([] if restart is None else ["--restart", str(restart)]))


def rows(out: Path) -> list[dict]:
    with open(out / "metrics.csv") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The channel at tolerances 1e-2 and 1e-3 (the same folder on every rank)."""
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("adaptive"))))
    found = {}
    for tolerance in (1e-2, 1e-3):
        out = folder / f"tol{tolerance:g}"
        assert channel_case(out, tolerance) == 0
        found[tolerance] = rows(out)
    return found


def test_adaptive_steps_follow_the_start_up_flow(runs):
    """The flow rate at the report times (each a step's end) against the exact series, the
    worst error over them relative to Q∞. Measured (`time_error` ≤ tolerance on every step):

        tolerance   steps   worst error   largest step
        1e-2        22      2.8e-3        0.38 s
        1e-3        35      5.8e-4        0.13 s
        1e-4        65      1.4e-4        0.07 s

    (fixed steps for comparison: 100 of 0.02 s 3.0e-4, 30 of 0.067 s 5.5e-4 at 1 s and none
    ending on the report times before). The error follows the tolerance, falling about as a
    second-order scheme's global error does when its local error is held to the tolerance
    (tol^(2/3): 4.6 × for 10 ×; measured 4.9 ×), while the steps grow from 1 ms by two orders
    of magnitude."""
    errors = {}
    for tolerance, found in runs.items():
        at = {round(float(r["t"]), 12): r for r in found}
        assert all(t in at for t in REPORT), sorted(at)[:5]
        errors[tolerance] = max(
            abs(float(at[t]["outlet_flow_rate"]) - exact_flow_rate(t)) / Q_INF for t in REPORT
        )
        dts = [float(r["dt"]) for r in found]
        assert dts[0] == 1e-3 and max(dts) > 100 * dts[0], dts
        assert all(float(r["time_error"]) <= tolerance for r in found if r["time_error"])
    assert errors[1e-2] < 5e-3, errors
    assert errors[1e-3] < 1e-3, errors
    assert errors[1e-2] / errors[1e-3] > 3, errors
    steps = {tolerance: len(found) for tolerance, found in runs.items()}
    assert steps[1e-2] < steps[1e-3] < 40, steps


def test_an_adaptive_run_restarts_exactly(tmp_path_factory, runs):
    """Stopped at t = 0.3 s (a report time, so both runs end a step there) and restarted, the
    run takes the same steps as the uninterrupted one (the checkpoint holds the error
    estimate's levels and the next step's size) and gives the same rows: equal on one rank; on
    two, SCOTCH's partition changes round-off (test_restart.py), so to 1e-9."""
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("adaptive_restart"))))
    out = folder / "restarted"
    assert channel_case(out, 1e-2, "time.end=0.3") == 0
    assert channel_case(out, 1e-2, restart=out) == 0
    restarted, straight = rows(out), runs[1e-2]
    assert [(r["step"], r["t"], r["dt"]) for r in restarted] == [
        (r["step"], r["t"], r["dt"]) for r in straight
    ] or MPI.COMM_WORLD.size > 1
    assert len(restarted) == len(straight)
    for a, b in zip(restarted, straight):
        for key in ("t", "outlet_flow_rate", "peak_velocity", "time_error"):
            if a[key] != b[key]:
                assert float(a[key]) == pytest.approx(float(b[key]), rel=1e-9), (key, a, b)


def test_a_step_still_too_inaccurate_at_min_dt_fails_the_run(tmp_path_factory, fsi_log):
    """A tolerance no step can meet: the third step (the first with an estimate) is rejected
    down to time.adaptive.min_dt and then fails the run (exit 3), with the state after step 2
    checkpointed and the reason named."""
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("adaptive_fail"))))
    out = folder / "failed"
    assert channel_case(out, 1e-14, "time.adaptive.min_dt=2.0e-4") == 3
    assert len(rows(out)) == 2
    text = MPI.COMM_WORLD.bcast(fsi_log.text)
    assert "time.adaptive.tolerance = 1e-14 at time.adaptive.min_dt = 0.0002 s" in text
    # ... and what a run from rest usually lacks: the fields' scales.
    assert (
        f"time.adaptive.velocity_scale = {G * H**2 / (8 * MU):g} m/s and displacement_scale = 0 m"
        in text
    )
    assert f"checkpointed in {out / 'checkpoint'}" in text


def test_adaptive_steps_run_a_shipped_study_case_through_the_pulse(shared_tmp):
    """``--set time.step_control=adaptive`` on the moving-wall study case, as shipped otherwise
    (its ``time.adaptive`` scales: 0.3 m/s, 0.1 mm): the 5 ms pulse runs (before the scales it
    failed at step 3, its error measured against fields still at rest), and the peaks at
    5 ms agree with the scheduled run's (0.25 ms steps) within 2 %."""
    end = ["--set", "time.end=0.005"]
    adaptive, scheduled = shared_tmp / "adaptive", shared_tmp / "scheduled"
    case = "configs/stenosis_moving_newtonian.yaml"
    assert cli.main(["run", case, "--out", str(adaptive), *end,
                     "--set", "time.step_control=adaptive"]) == 0  # fmt: skip
    assert cli.main(["run", case, "--out", str(scheduled), *end]) == 0
    a, s = rows(adaptive)[-1], rows(scheduled)[-1]
    assert float(a["t"]) == pytest.approx(0.005) and a["time_error"] != ""
    for key in ("peak_velocity", "peak_displacement"):
        assert float(a[key]) == pytest.approx(float(s[key]), rel=2e-2), key
