"""The velocity bias that wanders more while the vehicle manoeuvres (companion.sim.wander)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.io.idlog import read_identification_samples
from companion.sim.identify import pooled_jerk_wander
from companion.sim.wander import JERK_MAX_GRID_M_S3, JERK_TC_S, fit_jerk_wander, manoeuvre_jerk_m_s3, window_variance
from sitl_mock import vehicle as mock_vehicle
from sitl_mock.personality import IDENTIFIED_COPTER_MODELS

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


@pytest.mark.parametrize("window_s", [0.5, 1.0, 2.0, 4.0])
def test_a_steady_level_changes_the_drift_as_the_gauss_markov_closed_form(window_s):
    # D^2(T) = 2 sigma^2 tau^2 (T / tau - 1 + exp(-T / tau)), the continuous process's; the
    # discrete sum at 50 Hz is within 0.1 % of it.
    dt, tau, sigma = 0.02, 1.63, 0.01
    var = window_variance(np.full(2000, sigma * sigma), dt, tau, int(round(window_s / dt)))
    closed = 2.0 * sigma ** 2 * tau ** 2 * (window_s / tau - 1.0 + math.exp(-window_s / tau))
    assert var == pytest.approx(np.full(var.size, closed), rel=1e-3)


def test_each_kick_counts_once_with_the_weight_its_impulse_response_gives():
    # Brute force: the drift's change over each window is linear in the kicks; simulate the
    # recursion b[i+1] = phi b[i] + level_i sqrt(1 - phi^2) w[i] for each kick alone (the past
    # before the first sample at the first level, 600 steps of it) and sum the squared responses.
    rng = np.random.default_rng(4)
    dt, tau, k, n = 0.1, 0.7, 5, 30
    level2 = rng.uniform(0.1, 2.0, n)
    phi = math.exp(-dt / tau)
    past = 600
    levels = np.concatenate([np.full(past, level2[0]), level2])
    expected = np.zeros(n - k)
    for i in range(past + n):
        b = np.zeros(past + n + 1)
        b[i + 1] = math.sqrt(levels[i] * (1.0 - phi * phi))
        for m in range(i + 2, past + n + 1):
            b[m] = phi * b[m - 1]
        e = np.concatenate([[0.0], np.cumsum(b[past:past + n]) * dt])  # e[j] = dt * sum(b[:j])
        expected += (e[k:n] - e[:n - k]) ** 2
    assert window_variance(level2, dt, tau, k) == pytest.approx(expected, rel=1e-9)


def _manoeuvres(duration_s: float, dt: float) -> np.ndarray:
    """A flight's jerk: ten seconds of a 1.5 m/s^2 sine (5 s period) in every twenty, straight between."""
    t = np.arange(0.0, duration_s, dt)
    acc = np.zeros((t.size, 2))
    weave = (t % 20.0) < 10.0
    acc[weave, 0] = 1.5 * np.sin(2.0 * np.pi * (t[weave] % 20.0) / 5.0)
    return manoeuvre_jerk_m_s3(acc, dt)


def _drifts(jerk: np.ndarray, dt: float, tau: float, sigma: float, gain: float, jerk_max: float,
            flights: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Drifts drawn step by step from the model (both axes), one per flight over the same jerk."""
    rng = np.random.default_rng(seed)
    phi = math.exp(-dt / tau)
    level = np.sqrt(sigma ** 2 + (gain * np.minimum(jerk, jerk_max)) ** 2)
    out = []
    for _ in range(flights):
        b = np.zeros((jerk.size, 2))
        b[0] = rng.standard_normal(2) * level[0]
        for i in range(jerk.size - 1):
            b[i + 1] = phi * b[i] + level[i] * math.sqrt(1.0 - phi * phi) * rng.standard_normal(2)
        e = np.vstack([[0.0, 0.0], np.cumsum(b * dt, axis=0)[:-1]])
        out.append((e, np.ones(jerk.size, bool), jerk))
    return out


def test_the_fit_recovers_a_wander_drawn_from_the_model():
    dt, tau = 0.02, 1.63
    jerk = _manoeuvres(300.0, dt)
    fit = fit_jerk_wander(_drifts(jerk, dt, tau, 0.0075, 0.02, 1.2, flights=3, seed=1), dt, tau)
    assert fit is not None
    assert abs(fit.sigma_m_s - 0.0075) <= 3.0 * fit.se_sigma_m_s and fit.se_sigma_m_s < 0.2 * 0.0075
    assert abs(fit.jerk_gain_s2 - 0.02) <= 3.0 * fit.se_jerk_gain_s2 and fit.se_jerk_gain_s2 < 0.2 * 0.02
    grid = list(JERK_MAX_GRID_M_S3)
    assert abs(grid.index(fit.jerk_max_m_s3) - grid.index(1.2)) <= 1


def test_a_bias_of_one_level_shows_no_share_of_the_jerk():
    dt, tau = 0.02, 1.63
    jerk = _manoeuvres(300.0, dt)
    fit = fit_jerk_wander(_drifts(jerk, dt, tau, 0.015, 0.0, 1.0, flights=3, seed=2), dt, tau)
    assert fit is not None
    assert fit.jerk_gain_s2 < 3.0 * fit.se_jerk_gain_s2
    assert abs(fit.sigma_m_s - 0.015) <= 3.0 * fit.se_sigma_m_s


def test_the_mock_measures_the_jerk_as_identify_does():
    # A velocity of constant jerk j (v = j t^2 / 2 along one axis: a = j t, |d a / dt| = j): the log's
    # measure and the mock's (the same low-pass; the same 50 Hz samples, smoothed over 0.3 s)
    # both settle on j.
    assert mock_vehicle.JERK_TC_S == JERK_TC_S
    j, dt = 0.7, 0.02
    t = np.arange(0.0, 8.0, dt)
    vel = np.column_stack([j * t ** 2 / 2.0, np.zeros_like(t)])
    acc = np.diff(vel, axis=0) / dt
    assert manoeuvre_jerk_m_s3(acc, dt)[-1] == pytest.approx(j, rel=1e-3)
    mock = mock_vehicle.ManoeuvreJerk()
    for tk in np.arange(0.0, 8.0, 0.0025):
        value = mock.update(0.0025, j * tk ** 2 / 2.0, 0.0)
    assert value == pytest.approx(j, rel=1e-3)


def test_arducopters_shared_mission_flights_wander_with_the_jerk_as_its_tune_set_does():
    # The two shared ArduCopter SITL mission flights (recorded apart from the tune set that set
    # the mock's ArduCopter, at the bias's 1.63 s, past each flight's offset and 19 ms position
    # delay): the jerk's share stands clear of zero and agrees with the tune set's within 3 of its
    # standard errors.
    flights = [read_identification_samples(REAL / f"ardupilot-copter-{name}.tlog")
               for name in ("figure-eight-corrector", "racetrack-predictive")]
    model = IDENTIFIED_COPTER_MODELS["ardupilot"]
    fit = pooled_jerk_wander(flights, model["vel_bias_tc_s"], pos_delay_s=model["pos_delay_s"])
    assert fit is not None
    assert fit.jerk_gain_s2 > 4.0 * fit.se_jerk_gain_s2
    assert abs(fit.jerk_gain_s2 - model["vel_bias_jerk_s2"]) <= 3.0 * fit.se_jerk_gain_s2
