"""The velocity estimate's drift from position and velocity reports: closed forms and invariants."""

import math
import random

import pytest

from companion.guidance.drift import MAX_DRIFT_M_S, DriftEstimator


def feed_circle(est, t_end_s, dt_s=0.02, radius_m=15.0, speed_m_s=5.0, drift=(0.0, 0.0)):
    """A vehicle on a circle whose reports are exact, its position moving by ``drift`` besides."""
    omega = speed_m_s / radius_m
    out = None
    for k in range(int(round(t_end_s / dt_s)) + 1):
        t = k * dt_s
        x = radius_m * math.sin(omega * t) + drift[0] * t
        y = radius_m * (1.0 - math.cos(omega * t)) + drift[1] * t
        vx, vy = speed_m_s * math.cos(omega * t), speed_m_s * math.sin(omega * t)
        out = est.update(t, x, y, vx, vy)
    return out


def test_a_constant_drift_is_recovered_as_a_first_order_response():
    # In a 1.7 m/s^2 turn, with 0.15 m/s north and -0.1 m/s east of drift: after t seconds the
    # estimate is drift * (1 - exp(-t / tc)) (the low pass of a constant), to the trapezoid's error.
    for t_end in (0.5, 1.0, 3.0, 8.0):
        est = DriftEstimator(tc_s=1.0)
        bx, by = feed_circle(est, t_end, drift=(0.15, -0.1))
        gain = 1.0 - math.exp(-t_end / 1.0)
        assert bx == pytest.approx(0.15 * gain, abs=2e-4)
        assert by == pytest.approx(-0.1 * gain, abs=2e-4)


def test_a_turn_with_exact_reports_shows_no_drift():
    # The trapezoid is what keeps a turn from looking like a drift: the plain difference of the
    # positions against the newest velocity is off by a dt / 2 = 0.017 m/s across a 1.7 m/s^2 turn.
    est = DriftEstimator(tc_s=0.5)
    bx, by = feed_circle(est, 20.0)
    assert math.hypot(bx, by) < 1e-3


def test_a_repeated_report_changes_nothing_and_a_gap_restarts_without_a_jump():
    est = DriftEstimator(tc_s=1.0)
    before = feed_circle(est, 4.0, drift=(0.2, 0.0))
    t_last = est._last[0]
    assert est.update(t_last, 100.0, 100.0, 0.0, 0.0) == before  # the same sample again
    # A 2 s gap, after which the vehicle is 10 m elsewhere: not a drift of 5 m/s.
    assert est.update(t_last + 2.0, 50.0, 50.0, 5.0, 0.0) == before
    after = est.update(t_last + 2.02, 50.0 + 0.1, 50.0, 5.0, 0.0)  # exactly on the reports again
    assert after[0] == pytest.approx(before[0] * math.exp(-0.02), abs=1e-9)


def test_the_estimate_is_bounded_and_ignores_non_finite_reports():
    est = DriftEstimator(tc_s=0.2)
    b = feed_circle(est, 5.0, drift=(4.0, 3.0))
    assert math.hypot(*b) == pytest.approx(MAX_DRIFT_M_S)
    assert b[0] / b[1] == pytest.approx(4.0 / 3.0, rel=1e-4)
    assert est.update(est._last[0] + 0.02, math.nan, 0.0, 0.0, 0.0) == b
    with pytest.raises(ValueError, match="tc_s"):
        DriftEstimator(tc_s=0.0)


def test_a_wandering_bias_is_followed_to_the_low_pass_closed_form():
    # A first-order Gauss-Markov bias (sigma, correlation time tau), as PX4 SIH's estimate flies:
    # the error of a first-order low pass (time constant T) of it has the variance
    # sigma^2 T / (T + tau) (the filter's output and its covariance with the input are both
    # sigma^2 tau / (tau + T)). 4000 s at 10 Hz: about 800 independent samples.
    sigma, tau, tc, dt = 0.2, 4.0, 1.0, 0.1
    rng = random.Random(7)
    est = DriftEstimator(tc_s=tc)
    phi = math.exp(-dt / tau)
    b = [0.0, 0.0]
    b_mid = [0.0, 0.0]  # the bias's mean over the last interval (its trapezoid)
    x = [0.0, 0.0]
    err2, n = 0.0, 0
    for k in range(40000):
        t = k * dt
        est_b = est.update(t, x[0], x[1], 0.0, 0.0)
        if k > 200:
            # the estimate is the low pass of the bias's means over the intervals: compare it
            # with the bias at the middle of the last one
            err2 += sum((est_b[i] - b_mid[i]) ** 2 for i in range(2))
            n += 2
        b_old = list(b)
        b = [phi * b[i] + sigma * math.sqrt(1 - phi * phi) * rng.gauss(0.0, 1.0) for i in range(2)]
        x = [x[i] + 0.5 * (b_old[i] + b[i]) * dt for i in range(2)]
        b_mid = [0.5 * (b_old[i] + b[i]) for i in range(2)]
    rms = math.sqrt(err2 / n)
    expected = sigma * math.sqrt(tc / (tc + tau))
    assert rms == pytest.approx(expected, rel=0.15)
    assert rms < 0.5 * sigma  # followed: without the estimate the error is sigma
