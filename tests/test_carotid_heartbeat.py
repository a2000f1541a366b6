"""The shipped carotid heartbeat (configs/carotid_heartbeat.yaml, docs/carotid.md): a flow-rate
waveform in, a three-element Windkessel out, Carreau blood, the vessel wall held.

By default its systole (0.2 s) runs; the three heartbeats and the periodic-state checks are
behind ``-m slow`` (about 6 minutes on 1 rank).
"""

import json

import numpy as np
import pytest
import support_run

from fsi import config
from fsi.config.boundary_data import read_waveform

CONFIG = "configs/carotid_heartbeat.yaml"
MMHG = 133.322  # Pa


def carotid(out, overrides: list[str]) -> list[dict]:
    status, rows = support_run.fsi_run(CONFIG, out, overrides)
    assert status == 0
    return rows


def file_flow_rate(t: np.ndarray) -> np.ndarray:
    """Q(t) of configs/waveforms/carotid_flow.csv (m²/s), periodic, linear between rows."""
    rows = np.array(read_waveform("configs/waveforms/carotid_flow.csv", "Q"))
    period = config.load(CONFIG).fluid.inlet.period
    return np.interp(np.mod(t, period), rows[:, 0], rows[:, 1])


def test_the_carotid_systole_follows_the_waveform_at_arterial_pressure(shared_tmp):
    """Through the systolic peak (0.2 s; the ramp from rest ends at 0.1 s): from 0.1 s the inlet
    carries the file's flow rate (a velocity inlet: to 1e-3), what enters leaves within 2 %
    (the plaque moves a little), and the outlet's pressure stays in the arterial range
    (80–140 mmHg; measured 84–134 over the first beat) while the jet through the throat is
    over 1.5 m/s at the peak (measured 2.1 m/s)."""
    case = config.load(CONFIG)
    Rp = case.fluid.outlet.proximal_resistance
    rows = carotid(shared_tmp / "systole", ["time.cycles=0", "time.end=0.2"])
    assert len(rows) == 100
    late = [r for r in rows if r["t"] >= 0.1 - 1e-9]
    t = np.array([r["t"] for r in late])
    q_in = np.array([r["inlet_flow_rate"] for r in late])
    # the P2 interpolant of the Womersley profiles on the coarse inlet carries their flux to
    # its interpolation error (measured 2.7e-4 of the peak)
    assert np.abs(q_in - file_flow_rate(t)).max() < 1e-3 * np.abs(file_flow_rate(t)).max()
    for r in late:
        assert r["outlet_flow_rate"] == pytest.approx(r["inlet_flow_rate"], rel=2e-2)
        assert r["outlet_pressure"] == pytest.approx(
            r["windkessel_pressure"] + Rp * r["outlet_flow_rate"], rel=1e-9
        )
        assert 80 * MMHG < r["outlet_pressure"] < 140 * MMHG, r
    assert max(r["peak_velocity"] for r in rows) > 1.5


@pytest.mark.slow
def test_three_carotid_heartbeats_reach_a_periodic_state(shared_tmp):
    """The shipped run, 3 heartbeats on the coarse mesh: beat 3 against beat 2 changes every
    headline value by at most 2 % (``max_change``); over beat 3 the mean inlet flow rate is the
    file's within 0.5 %, the outlet's mean equals the inlet's within 0.5 %, and the mean outlet
    pressure is (R_p + R_d) × mean Q within 2 % (a Windkessel's periodic state)."""
    out = shared_tmp / "beats"
    rows = carotid(out, [])
    case = config.load(CONFIG)
    outlet, period = case.fluid.outlet, case.fluid.inlet.period
    summary = json.loads((out / "summary.json").read_text())
    beats = summary["cycles"]
    assert [b["complete"] for b in beats] == [True, True, True]
    assert beats[2]["max_change"] <= 0.02, beats[2]["change"]
    beat = [r for r in rows if r["cycle"] == 3]
    dt = np.array([r["dt"] for r in beat])

    def mean(column: str) -> float:
        return float(np.sum(dt * np.array([r[column] for r in beat])) / dt.sum())

    file_mean = file_flow_rate(np.arange(20000) * period / 20000).mean()  # periodic: uniform mean
    assert mean("inlet_flow_rate") == pytest.approx(file_mean, rel=5e-3)
    assert mean("outlet_flow_rate") == pytest.approx(mean("inlet_flow_rate"), rel=5e-3)
    resistance = outlet.proximal_resistance + outlet.distal_resistance
    assert mean("outlet_pressure") == pytest.approx(resistance * mean("outlet_flow_rate"), rel=2e-2)
