"""Step schedules and BDF weights."""

import numpy as np
import pytest

from fsi import config
from fsi.numerics.timestepping import bdf_weights, steps


def test_study_schedule():
    time = config.from_dict({}).time
    s = list(steps(time))
    assert len(s) == 80 + 40
    assert s[79].t == pytest.approx(0.4, abs=1e-15) and s[80].dt == pytest.approx(0.01)
    assert s[-1].t == 0.8 and [x.index for x in s] == list(range(1, 121))
    assert sum(x.dt for x in s) == pytest.approx(0.8, rel=1e-12)


def test_segments_end_exactly_and_runs_restart():
    time = config.Time(
        end=0.05, schedule=(config.TimeSegment(0.0101, 1e-3), config.TimeSegment(0.1, 7e-3))
    )
    s = list(steps(time))
    assert any(x.t == 0.0101 for x in s)
    assert s[-1].t == 0.05
    assert all(x.dt > 0 for x in s)
    # Restarting from step k gives the same remaining steps.
    k = 5
    assert [(x.index, x.t) for x in steps(time, s[k].t, s[k].index)] == [
        (x.index, x.t) for x in s[k + 1 :]
    ]


@pytest.mark.parametrize("order", [1, 2])
def test_bdf_weights_differentiate_polynomials_exactly(order):
    dt, dt_prev = 0.3, 0.2
    times = np.array([1.0, 1.0 - dt, 1.0 - dt - dt_prev])
    w = bdf_weights(order, dt, dt_prev)
    for degree in range(order + 1):  # exact for polynomials up to the order
        values = times[: len(w)] ** degree
        assert np.dot(w, values) == pytest.approx(degree * 1.0 ** max(degree - 1, 0), abs=1e-12)
