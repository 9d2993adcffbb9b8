"""``method: predictive`` through TwoPhaseGuidance: delegation, limits, internals, phases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import function_path, waypoint_path
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate


def sine():
    return function_path(lambda x: 6.0 * np.sin(x / 12.0), (0.0, 110.0))


def test_close_range_is_exactly_the_predictive_law_with_the_params_it_is_given():
    path = sine()
    params = GuidanceParams(method="predictive", midcourse_trigger="off", lambda_s4=0.1,
                            rollout_tau_s=0.3, a_max_m_s2=4.0)
    wired = TwoPhaseGuidance(path, params)
    alone = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.1, lag_s=0.3, a_max_m_s2=4.0))
    state = VehicleState(1.0, 2.0, 0.3, 5.0)
    for n in range(30):
        t = n / 50.0
        a, b = wired.step(t, state), alone.step(t, state)
        assert a.a_cmd_m_s2 == b.a_cmd_m_s2 and a.reoptimised == b.reoptimised
        # advance the state by hand along a straight course (the law does not see the difference)
        state = VehicleState(state.x_m + 0.1 * math.cos(0.3), state.y_m + 0.1 * math.sin(0.3), 0.3, 5.0)


def test_predictive_outputs_have_no_corrector_weights_and_report_their_lookahead():
    path = sine()
    g = TwoPhaseGuidance(path, GuidanceParams(method="predictive", midcourse_trigger="off"))
    out = g.step(0.0, VehicleState(0.0, 1.0, 0.0, 5.0))
    assert out.phase == "close_range"
    assert math.isnan(out.k1) and math.isnan(out.k2)
    assert 3.0 <= out.extra["lookahead_m"] <= 30.0
    assert out.reoptimised  # the first tick plans


def test_every_command_stays_within_the_vehicle_limit_under_lag():
    # A 6 m radius bend needs 25/6 = 4.2 m/s^2; a 2 m/s^2 limit must saturate, never exceed.
    path = waypoint_path([(0, 0), (30, 0), (36, 6), (36, 40)])
    params = GuidanceParams(method="predictive", midcourse_trigger="off", rollout_tau_s=0.3,
                            a_max_m_s2=2.0)
    res = simulate(path, TwoPhaseGuidance(path, params), VehicleState(0.0, 3.0, 0.0, 5.0), params,
                   model=LagModel(tau_s=0.3, a_max_m_s2=2.0), t_max_s=20.0)
    assert np.max(np.abs(res.a_cmd_m_s2)) <= 2.0 + 1e-12
    assert np.max(np.abs(res.a_cmd_m_s2)) == pytest.approx(2.0)  # it did saturate


def test_open_path_finishes_with_a_zero_command_at_its_end():
    path = function_path(lambda x: 0.0 * x, (0.0, 40.0))  # straight line east, 40 m
    params = GuidanceParams(method="predictive", midcourse_trigger="off")
    g = TwoPhaseGuidance(path, params)
    res = simulate(path, g, VehicleState(0.0, 0.0, 0.0, 5.0), params, t_max_s=20.0)
    assert res.finished
    # Flown along the line at 5 m/s, the projection reaches x = 40 m after 8 s (one tick's slack).
    assert res.t_s[-1] == pytest.approx(8.0, abs=0.05)
    assert g.step(res.t_s[-1] + 0.02, VehicleState(41.0, 0.0, 0.0, 5.0)).a_cmd_m_s2 == 0.0


def test_far_start_flies_the_midcourse_phase_first_then_the_predictive_law():
    path = sine()
    params = GuidanceParams(method="predictive")  # trigger auto: 2 R = 20 m from the start
    g = TwoPhaseGuidance(path, params)
    res = simulate(path, g, VehicleState(-40.0, -30.0, math.pi / 2, 5.0), params, t_max_s=60.0)
    phases = list(res.phase)
    assert phases[0] == "midcourse"
    first_close = phases.index("close_range")
    assert "midcourse" not in phases[first_close:]
    # Once on the path (|d| < 1 m) it stays close: a 6 m amplitude sine at 5 m/s is easy.
    on = np.flatnonzero(np.abs(res.crosstrack_m[first_close:]) < 1.0)
    assert on.size and np.max(np.abs(res.crosstrack_m[first_close + on[0]:])) < 1.0


@pytest.mark.parametrize("field, value", [("lambda_s4", -1.0), ("lambda_s4", math.inf),
                                          ("a_max_m_s2", 0.0), ("a_max_m_s2", math.nan),
                                          ("wind_x_m_s", math.inf), ("rollout_tau_s", -0.1),
                                          ("method", "mpc")])
def test_guidance_params_refuse_bad_predictive_values(field, value):
    with pytest.raises(ValueError, match=field):
        GuidanceParams(**{field: value})
