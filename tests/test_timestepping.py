"""Step schedules, BDF weights and the BDF history."""

import numpy as np
import pytest

from fsi import config
from fsi.numerics.timestepping import BdfHistory, bdf_weights, steps


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


def test_bdf_history_advances_differentiates_and_restores():
    """x(t) = 1 + 2t (a vector) at steps 0.3, then 0.2: the history's backward Euler and
    variable-step BDF2 derivatives are 2 (both exact on a linear field), summed as
    a₀ x + a₁ x^n + a₂ x^{n−1}; advance shifts the levels in the arrays it was given (as the
    fluid's u_n, u_nm1 Functions' value arrays), and restore brings back a save."""
    x, x_n, x_nm1 = np.zeros(3), np.zeros(3), np.zeros(3)
    history = BdfHistory(x, x_n, x_nm1)

    def field(t):
        return 1 + 2 * t * np.array([1.0, 0.5, -1.0])

    x[:] = field(0.0)
    history.start()
    assert np.array_equal(x_n, field(0.0)) and np.array_equal(x_nm1, field(0.0))
    x[:] = field(0.3)
    be = bdf_weights(1, 0.3)
    assert np.array_equal(history.derivative(be), be[0] * x + be[1] * x_n)
    assert history.derivative(be) == pytest.approx(2 * np.array([1.0, 0.5, -1.0]), rel=1e-12)
    history.advance()
    saved = history.save()
    x[:] = field(0.5)
    bdf2 = bdf_weights(2, 0.2, 0.3)
    assert np.array_equal(history.derivative(bdf2), bdf2[0] * x + bdf2[1] * x_n + bdf2[2] * x_nm1)
    assert history.derivative(bdf2) == pytest.approx(2 * np.array([1.0, 0.5, -1.0]), rel=1e-12)
    history.advance()
    assert np.array_equal(x_n, field(0.5)) and np.array_equal(x_nm1, field(0.3))
    history.restore(*saved)
    assert np.array_equal(x_n, field(0.3)) and np.array_equal(x_nm1, field(0.0))
    assert history.x_n is x_n and history.x_nm1 is x_nm1  # written in place, never rebound
