"""With the damped wall (docs/wall-damping.md), the study's reported quantities must not depend on
the time step: halving every step of the schedule changes them by less than 2 % (issue 9).

The moving-wall Newtonian case on the coarse mesh (the most sensitive: the wall rings after the
pulse), run over the pulse and the ring, t <= 0.05 s, once with its schedule and once with every
dt of it halved. Compared at the study's reported times inside that window (0.01, 0.02, 0.05 s):
peak velocity, peak pressure, peak displacement, max SSS and peak wall displacement.

**The measure**: |q_half(t) - q(t)| / max_s q(s), the change at t relative to the quantity's
peak over the run (reached during the pulse, 2.5-5.5 ms). Not |Δq| / q(t): after the pulse these
quantities follow the wall's decaying ring (|η| falls to zero every 6.6 ms, and the peak pressure
to ~0 Pa whenever the wall draws blood in), so a sample can sit near a zero crossing, where the
relative change is meaningless (peak pressure at 0.01 s is 0.15 Pa against the pulse's 1200 Pa).
A time step error of an oscillation is a phase error: it shifts a sample by about
(amplitude x phase error) wherever the sample falls, and the pulse's peak is the quantity's scale.

Measured (docs/wall-damping.md, "Sensitivity to the time step and rho_inf"), 1 and 2 ranks alike:

The shipped schedule resolves the ring (0.25 ms steps to 50 ms): at most 0.80 % (displacement
at 0.01 s, from the pulse's 0.25 ms steps). With 1 ms steps from 10 ms on (the schedule before
this test) it failed at 0.02 s: 5.0 % of the displacement's peak, the ring's phase error.
"""

import math

import pytest

from fsi import cli, config
from fsi.output import metrics_csv
from fsi.performance import comparison

CASE = "configs/stenosis_moving_newtonian.yaml"
WINDOW = 0.05  # s: the pulse and the ring, up to where it has decayed to ~3 % of the peak
TIMES = (0.01, 0.02, 0.05)  # the study's reported times inside the window
QUANTITIES = (
    "peak_velocity",
    "peak_pressure",
    "peak_displacement",
    "max_sss",
    "peak_wall_displacement",
)
CRITERION = 0.02


def schedule_text(schedule) -> str:
    return "[" + ", ".join(f"{{until: {u!r}, dt: {dt!r}}}" for u, dt in schedule) + "]"


def run(out, schedule, case: str = CASE) -> list[dict]:
    code = cli.main(
        [
            "run",
            case,
            "--out",
            str(out),
            "--set",
            f"time.end={WINDOW!r}",
            "--set",
            f"time.schedule={schedule_text(schedule)}",
        ]
    )
    assert code == 0
    return metrics_csv.read_metrics(out / "metrics.csv")


def at(rows: list[dict], t: float) -> dict:
    row = min(rows, key=lambda r: abs(r["t"] - t))
    assert row["t"] == pytest.approx(t, abs=1e-9), (t, row["t"])
    return row


def changes(rows: list[dict], halved: list[dict]) -> dict[tuple[str, float], tuple[float, float]]:
    """{(quantity, t): (change / peak over the run, change / value at t)}."""
    out = {}
    for q in QUANTITIES:
        peak = max(r[q] for r in rows)
        assert peak > 0 and math.isfinite(peak), q
        for t in TIMES:
            a, b = at(rows, t)[q], at(halved, t)[q]
            out[q, t] = ((b - a) / peak, (b - a) / a)
    return out


@pytest.mark.slow
def test_reported_quantities_change_by_less_than_two_percent_when_dt_is_halved(shared_tmp):
    schedule = [(s.until, s.dt) for s in config.load(CASE).time.schedule]
    rows = run(shared_tmp / "dt", schedule)
    halved = run(shared_tmp / "dt_half", [(u, dt / 2) for u, dt in schedule])
    found = changes(rows, halved)
    table = "\n".join(
        f"{q:24s} t={t:<5} {100 * p:+7.2f} % of peak  ({100 * r:+7.2f} % of value)"
        for (q, t), (p, r) in found.items()
    )
    print(f"\ndt halved\n{table}")
    worst = max(found, key=lambda k: abs(found[k][0]))
    assert abs(found[worst][0]) < CRITERION, f"{worst}: {100 * found[worst][0]:+.2f} %\n{table}"


BETWEEN_REPORT_TIMES = {
    "mean_outlet_pressure": 0.10,
    "min_wss": 0.05,
    "max_sss": 0.03,
    "max_principal_cap": 0.03,
}
"""The bounds of the moving Carreau case's headline columns at every step of the pulse window
with its steps halved (measured 7.1 %, 3.4 %, 1.2 %, 2.0 % of the columns' peaks over the
window; docs/wall-damping.md §7 gives the mean outlet pressure's as 6.7 % of its peak over the
heartbeat); every other headline column 1.5 % (measured ≤ 0.97 %)."""


@pytest.mark.slow
def test_the_headline_columns_between_the_report_times_change_as_documented(shared_tmp):
    """The moving-wall Carreau case (coarse) through the pulse window (t <= 0.05 s) with its
    0.25 ms steps and with 0.125 ms, every headline column of metrics.csv compared at every
    common step (fsi/performance/comparison.py: the largest difference over the steps relative to
    the column's peak): the study's reported quantities hold 2 % at its report times (the test
    above), but between them the stress maxima move by up to 2 %, the smallest WSS by 3.4 % (it
    crosses zero at 1.4 Pa/ms near 10.7 ms) and the mean outlet pressure, a discretisation error
    at the stress-free outlet (docs/boundary-conditions.md §4), by 7 %. Asserted with the
    bounds of :data:`BETWEEN_REPORT_TIMES` so that a change that makes them worse is seen."""
    case = "configs/stenosis_moving_carreau.yaml"
    schedule = [(s.until, s.dt) for s in config.load(case).time.schedule]
    rows = run(shared_tmp / "carreau_dt", schedule, case)
    halved = run(shared_tmp / "carreau_dt_half", [(u, dt / 2) for u, dt in schedule], case)
    common = {round(r["t"], 9): r for r in halved}
    found = comparison.largest_differences(rows, [common[round(r["t"], 9)] for r in rows])
    print(f"\ndt halved, every step: {found}")
    for column, change in found.items():
        assert change < BETWEEN_REPORT_TIMES.get(column, 0.015), (column, change)
