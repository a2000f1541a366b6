"""Step schedules, BDF weights and the BDF history; the adaptive steps' error estimate, step
size control and step times."""

from mpi4py import MPI

import numpy as np
import pytest

from fsi import config
from fsi.numerics.timestepping import (
    AdaptiveSteps,
    BdfHistory,
    LocalError,
    StepSizeControl,
    bdf_weights,
    extrapolation_weights,
    fit_to_stop,
    steps,
)


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


# --------------------------------------------------------------------------------------------
# Adaptive steps: the local error estimate, the step size control, the steps' times


def test_extrapolation_weights_are_exact_for_quadratics_on_uneven_times():
    times, t = [0.1, 0.25, 0.3], 0.42
    w = extrapolation_weights(times, t)
    for degree in range(3):
        assert np.dot(w, np.array(times) ** degree) == pytest.approx(t**degree, rel=1e-13)


def test_local_error_scales_with_the_step_cubed_and_vanishes_for_quadratics():
    """x(t) = sin(ω t) e: the estimate ‖x(t) − P(t)‖∞ / ‖x‖max after three accepted levels h
    apart is h³ |x⁽³⁾| / max|x| to leading order (the Lagrange remainder h · 2h · 3h / 3! = h³,
    x⁽³⁾ between the levels; max|x| over the accepted levels), the relative difference O(h);
    a quadratic field gives 0; the floor replaces a smaller field size; a step that blows up
    is measured against the accepted levels, not against itself (which would make its error
    about 1 however large it grew)."""
    comm = MPI.COMM_WORLD
    e = np.array([1.0, -0.5, 0.25])
    omega, t0 = 3.0, 0.4

    def estimate(h, field, floor=0.0):
        error = LocalError(comm, len(e), floor)
        for k in range(3):
            error.accept(field(t0 + k * h), t0 + k * h)
        return error.estimate(field(t0 + 3 * h), t0 + 3 * h)

    def wave(t):
        return np.sin(omega * t) * e

    for h in (1e-2, 5e-3, 2.5e-3):
        size = max(abs(np.sin(omega * (t0 + k * h))) for k in range(3))  # ‖x‖max, e's 1
        exact = h**3 * omega**3 * abs(np.cos(omega * (t0 + 1.5 * h))) / size
        assert estimate(h, wave) == pytest.approx(exact, rel=10 * h)
    assert estimate(1e-2, lambda t: (1 + 2 * t - 3 * t * t) * e) < 1e-14
    size = max(abs(np.sin(omega * (t0 + k * 1e-2))) for k in range(3))
    floored = estimate(1e-2, wave, floor=10.0)
    assert floored == pytest.approx(estimate(1e-2, wave) * size / 10, rel=1e-12)
    blown_up = estimate(1e-2, lambda t: wave(t) * (1000.0 if t > t0 + 0.025 else 1.0))
    assert blown_up > 500  # (before: ~1, the step's own size in the scale)
    assert LocalError(comm, 3).estimate(e, 0.1) is None  # no levels yet


def test_local_error_state_round_trip():
    comm = MPI.COMM_WORLD
    error = LocalError(comm, 2, 0.5)
    for k, x in enumerate(([1.0, 2.0], [1.5, 2.5], [1.7, 2.4], [1.9, 2.0])):
        error.accept(np.array(x), 0.1 * k)
    again = LocalError(comm, 2, 0.5)
    again.load_state(error.state())
    x = np.array([2.0, 1.5])
    assert again.estimate(x, 0.45) == error.estimate(x, 0.45)
    assert again.state()["values"].shape == (2, 3) and again.scale == 2.5


def test_step_size_control():
    control = StepSizeControl(tolerance=1e-3, min_dt=1e-6)
    assert control.accepts(None) and control.accepts(1e-3) and not control.accepts(1.1e-3)
    # e = tol / 8: the step could double, less the safety factor 0.9.
    assert control.next_dt(0.1, 1e-3 / 8, 1.0) == pytest.approx(0.18)
    assert control.next_dt(0.1, 0.0, 1.0) == pytest.approx(0.2)  # growth capped at 2
    assert control.next_dt(0.1, 1.0, 1.0) == pytest.approx(0.02)  # shrink capped at 0.2
    assert control.next_dt(0.1, None, 1.0) == 0.1  # no estimate: the same step
    assert control.next_dt(0.1, 1e-6, 0.15) == 0.15  # the segment's dt bounds it
    # Growth below hold = 1.5 keeps the step (1.2 ×: e = tol (0.9/1.2)³); from 1.5 on it grows.
    assert control.next_dt(0.1, 1e-3 * (0.9 / 1.2) ** 3, 1.0) == 0.1
    assert control.next_dt(0.1, 1e-3 * (0.9 / 1.6) ** 3, 1.0) == pytest.approx(0.16)
    assert control.next_dt(0.1, 1e-3 * (0.9 / 0.95) ** 3, 1.0) == pytest.approx(0.095)
    assert control.next_dt(1e-6, 1.0, 1.0) == 1e-6  # never below min_dt


def test_fit_to_stop_leaves_no_sliver():
    assert fit_to_stop(0.0, 0.3, 1.0) == 0.3
    assert fit_to_stop(0.5, 0.3, 1.0) == pytest.approx(0.25)  # 0.5 left: two of 0.25
    assert fit_to_stop(0.8, 0.3, 1.0) == pytest.approx(0.2)
    assert fit_to_stop(0.7, 0.3, 1.0 + 1e-12) == pytest.approx(0.3 + 1e-12)


def test_adaptive_steps_end_on_segments_stops_and_end():
    """Steps the control lets double every step (no error) from 1 ms: they stay within each
    segment's dt, end exactly on every segment's until, on each report time and on the end, and
    a rejected step is retried from the same time, shorter."""
    time = config.Time(
        end=0.5,
        schedule=(config.TimeSegment(0.05, 0.01), config.TimeSegment(1.0, 0.1)),
        step_control="adaptive",
    )
    clock = AdaptiveSteps(time, StepSizeControl(1e-3, 1e-6), (0.123, 0.9), 0.0, 0, 1e-3)
    taken = []
    while (step := clock.next_step()) is not None:
        if step.index == 3 and not taken[-1].index == 3:
            retry = clock.retry(step, 1e-2)  # rejected: the error 10 x the tolerance
            assert retry.index == 3 and retry.t - retry.dt == pytest.approx(step.t - step.dt)
            assert retry.dt < step.dt
            taken.append(retry)
            clock.accept(retry, 1e-3)
            continue
        clock.accept(step, 0.0)
        taken.append(step)
    times = [s.t for s in taken]
    assert 0.05 in times and 0.123 in times and times[-1] == 0.5
    assert [s.index for s in taken] == list(range(1, len(taken) + 1))
    assert all(s.dt <= 0.01 * (1 + 1e-12) for s in taken if s.t <= 0.05)
    assert all(s.dt <= 0.1 * (1 + 1e-12) for s in taken)
    assert np.diff([0.0, *times]) == pytest.approx([s.dt for s in taken], rel=1e-12)
    assert max(s.dt for s in taken) == pytest.approx(0.1)
