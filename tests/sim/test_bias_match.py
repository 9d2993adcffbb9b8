"""The velocity bias matched through the estimator (companion.sim.bias_match): on flights whose
drift is drawn from a known bias, it recovers that bias, where the direct fit of the same flights
comes out short of its correlation time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from companion.sim.bias_match import MATCH_LAGS_S, match_bias
from companion.sim.identify import Samples, pooled_across_track_bias

DT = 0.02


def circle_flight(rng: np.random.Generator, sigma: float, tau: float, duration_s: float = 90.0) -> Samples:
    """A 30 m circle at 5 m/s whose reported position drifts by the integral of a Gauss-Markov bias
    (``sigma`` m/s, ``tau`` s, each axis) away from the integral of its reported velocity."""
    t = np.arange(0.0, duration_s, DT)
    w = 5.0 / 30.0
    vel = np.column_stack([-5.0 * np.sin(w * t), 5.0 * np.cos(w * t)])
    phi = math.exp(-DT / tau)
    kicks = rng.standard_normal(vel.shape) * sigma * math.sqrt(1.0 - phi * phi)
    kicks[0] = rng.standard_normal(2) * sigma
    bias = lfilter([1.0], [1.0, -phi], kicks, axis=0)
    step = np.zeros_like(vel)
    step[1:] = 0.5 * (vel[1:] + vel[:-1]) * DT
    pos = np.cumsum(step, axis=0) + np.cumsum(bias, axis=0) * DT
    none = np.zeros(0)
    return Samples(t, vel, np.ones(t.size, bool), none, np.zeros((0, 2)), none, none, none, pos, None)


def test_a_known_slow_bias_is_recovered_where_the_direct_fit_is_short():
    rng = np.random.default_rng(7)
    flights = [circle_flight(rng, 0.25, 9.0) for _ in range(10)]
    direct_sigma, direct_tau, *_ = pooled_across_track_bias(flights)
    assert direct_tau < 0.6 * 9.0  # the premise: a minute and a half is too short for a direct fit
    m = match_bias(flights, taus_s=(2.0, 4.5, 9.0, 18.0), runs=40)
    assert m.tau_s == 9.0
    assert m.sigma_m_s == pytest.approx(0.25, rel=0.15)
    # its expected structure passes through the measured one, lag by lag
    assert len(m.measured_m) == len(m.expected_m) == len(MATCH_LAGS_S)
    assert np.allclose(m.expected_m, m.measured_m, rtol=0.08)
    assert min(m.misfit_by_tau, key=m.misfit_by_tau.__getitem__) == 9.0


def test_a_fast_bias_is_told_from_a_slow_one():
    rng = np.random.default_rng(3)
    flights = [circle_flight(rng, 0.25, 2.0) for _ in range(10)]
    m = match_bias(flights, taus_s=(2.0, 4.5, 9.0, 18.0), runs=40)
    assert m.tau_s == 2.0 and m.sigma_m_s == pytest.approx(0.25, rel=0.15)


def test_no_flights_or_no_positions_is_an_error():
    with pytest.raises(ValueError, match="at least one flight"):
        match_bias([])
    f = circle_flight(np.random.default_rng(0), 0.1, 3.0, 20.0)
    no_pos = Samples(f.t_s, f.vel_ne_m_s, f.valid, f.t_cmd_s, f.vel_cmd_raw_ne_m_s, f.yaw_rate_cmd_raw_rad_s,
                     f.t_yaw_s, f.yaw_rate_rad_s, None, None)
    with pytest.raises(ValueError, match="no positions"):
        match_bias([no_pos])
