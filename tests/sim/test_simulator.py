"""The simulator's kinematics and inner-loop model against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import waypoint_path
from companion.guidance.types import GuidanceOutput, GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate, unicycle_step


class ConstantLaw:
    """A guidance law that always commands the same lateral acceleration."""

    def __init__(self, a_m_s2: float):
        self.a = a_m_s2

    def step(self, t_s, state):
        return GuidanceOutput(a_cmd_m_s2=self.a, phase="close_range", crosstrack_m=0.0, s_proj_m=0.0)


LINE = waypoint_path([(0.0, 0.0), (100.0, 0.0)])
PARAMS = GuidanceParams(rate_hz=50.0)


def test_unicycle_step_draws_the_exact_arc():
    # a = V^2 / R with R = 10: a quarter turn takes (pi/2) R / V seconds and ends at (R, R).
    x, y, psi = unicycle_step(0.0, 0.0, 0.0, 5.0, 2.5, math.pi / 2 * 10 / 5)
    assert (x, y, psi) == pytest.approx((10.0, 10.0, math.pi / 2))
    assert unicycle_step(1.0, 2.0, 0.3, 5.0, 0.0, 2.0) == pytest.approx((1 + 10 * math.cos(0.3), 2 + 10 * math.sin(0.3), 0.3))


def test_constant_command_flies_a_closed_circle_in_one_period():
    # V = 5, a = 2.5: R = 10 m, period 2 pi R / V = 4 pi s.
    result = simulate(LINE, ConstantLaw(2.5), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS, t_max_s=4 * math.pi)
    radius = np.hypot(result.x_m - 0.0, result.y_m - 10.0)
    assert np.allclose(radius, 10.0, atol=1e-9)
    assert result.t_s[-1] == pytest.approx(4 * math.pi, abs=0.02)
    assert not result.finished


def _step_response_tick_mean(t_s: np.ndarray, a_m_s2: float, tau_s: float, dt_s: float) -> np.ndarray:
    """Mean over [t, t + dt] of the first-order step response a (1 - exp(-t / tau)), t >= 0:
    a (1 - tau / dt exp(-t / tau) (1 - exp(-dt / tau)))."""
    return a_m_s2 * (1.0 - tau_s / dt_s * np.exp(-t_s / tau_s) * (1.0 - math.exp(-dt_s / tau_s)))


def test_lag_model_follows_a_step_with_the_first_order_response():
    tau, dt = 0.5, 1.0 / PARAMS.rate_hz
    result = simulate(LINE, ConstantLaw(2.0), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS,
                      model=LagModel(tau_s=tau), t_max_s=3.0)
    # The flown acceleration of a tick is the response's mean over that tick.
    expected = _step_response_tick_mean(result.t_s, 2.0, tau, dt)
    assert np.allclose(result.a_achieved_m_s2, expected, atol=1e-9)
    # Its time integral is the course change: psi(t) = (1/V) int_0^t a.
    assert result.course_rad[-1] == pytest.approx(np.sum(result.a_achieved_m_s2[:-1]) * dt / 5.0, abs=1e-12)


def test_lag_model_saturates_the_command():
    result = simulate(LINE, ConstantLaw(9.0), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS,
                      model=LagModel(tau_s=0.0, a_max_m_s2=2.5), t_max_s=2.0)
    # Turning at 2.5 m/s^2 (not 9): the course changes at 0.5 rad/s.
    assert result.course_rad[-1] == pytest.approx(0.5 * result.t_s[-1], abs=1e-9)
    # The raw command is kept; the saturated command and what was flown are 2.5; the metrics
    # charge what was flown.
    assert np.all(result.a_cmd_m_s2 == 9.0)
    assert np.all(result.a_sat_m_s2 == 2.5) and np.all(result.a_achieved_m_s2 == 2.5)
    assert result.metrics["a_rms_m_s2"] == pytest.approx(2.5) and result.metrics["a_max_m_s2"] == pytest.approx(2.5)


def test_ideal_model_flies_the_command_exactly_on_the_tick_it_is_issued():
    class Ramp:
        def step(self, t_s, state):
            return GuidanceOutput(a_cmd_m_s2=0.5 * t_s, phase="close_range", crosstrack_m=0.0, s_proj_m=0.0)

    result = simulate(LINE, Ramp(), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS, t_max_s=1.0)
    assert np.array_equal(result.a_achieved_m_s2, result.a_cmd_m_s2)
    assert np.array_equal(result.a_sat_m_s2, result.a_cmd_m_s2)
    # Course after the run: sum of a_i dt / V over the flown ticks (all but the last).
    dt = 1.0 / PARAMS.rate_hz
    assert result.course_rad[-1] == pytest.approx(sum(0.5 * i * dt for i in range(50)) * dt / 5.0, abs=1e-12)


def test_wind_drifts_the_vehicle_and_the_law_sees_the_ground_course():
    result = simulate(LINE, ConstantLaw(0.0), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS,
                      model=LagModel(wind_enu_m_s=(0.0, 2.0)), t_max_s=10.0)
    assert result.y_m[-1] == pytest.approx(2.0 * result.t_s[-1])
    assert result.x_m[-1] == pytest.approx(5.0 * result.t_s[-1])
    assert result.course_rad[-1] == pytest.approx(math.atan2(2.0, 5.0))


def test_lag_model_rejects_bad_values():
    with pytest.raises(ValueError, match="tau_s"):
        LagModel(tau_s=-1.0)
    with pytest.raises(ValueError, match="a_max_m_s2"):
        LagModel(a_max_m_s2=0.0)


def test_metrics_come_from_the_shared_definition():
    result = simulate(LINE, ConstantLaw(1.0), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS, t_max_s=1.0)
    assert result.metrics["a_rms_m_s2"] == pytest.approx(1.0)
    assert result.metrics["samples"] == 51
    assert result.metrics["phases"]["close_range"]["duration_s"] == pytest.approx(1.0)


def test_lag_model_with_a_dead_time_is_the_step_response_shifted_by_it():
    tau, delay = 0.5, 0.2  # 10 ticks at 50 Hz
    result = simulate(LINE, ConstantLaw(2.0), VehicleState(0.0, 0.0, 0.0, 5.0), PARAMS,
                      model=LagModel(tau_s=tau, delay_s=delay), t_max_s=3.0)
    t = result.t_s
    expected = np.where(t >= delay - 1e-9, _step_response_tick_mean(t - delay, 2.0, tau, 1.0 / PARAMS.rate_hz), 0.0)
    assert np.allclose(result.a_achieved_m_s2, expected, atol=1e-9)


def test_lag_model_from_a_vehicle_block_takes_its_lag_limit_and_dead_time():
    from companion.guidance.types import VehicleModel

    model = LagModel.from_vehicle(VehicleModel(a_max_m_s2=2.4, delay_s=0.17, lag_s=0.46, accel_lag_s=0.04))
    assert (model.tau_s, model.a_max_m_s2, model.delay_s) == pytest.approx((0.5, 2.4, 0.17))
