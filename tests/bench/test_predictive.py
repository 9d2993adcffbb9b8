"""The predictive law: its pursuit core against Park's closed form, sign conventions, the
acceleration limit, the effect of its one knob, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench_scenes import CirclePath, LinePath, fly, mirror_path, mirror_state
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams, _Window, pursuit_command
from companion.guidance.types import GuidanceParams, VehicleState

V = 5.0


def test_parameters_are_validated():
    with pytest.raises(ValueError, match="lambda_s4"):
        PredictiveParams(lambda_s4=-1.0)
    with pytest.raises(ValueError, match="l_max_m"):
        PredictiveParams(l_min_m=10.0, l_max_m=5.0)
    with pytest.raises(ValueError, match="a_max_m_s2"):
        PredictiveParams(a_max_m_s2=0.0)
    with pytest.raises(ValueError, match="plan_segments"):
        PredictiveParams(plan_segments=0)


def test_pursuit_core_on_a_circle_is_parks_chord_command():
    # On the circle, along it: the point at chord L is at eta = asin(L / 2R), so
    # 2 V^2 sin(eta) / L = V^2 / R whatever L (Park 2007).
    r = 30.0
    win = _Window(CirclePath(r), 0.0, 60.0)
    look = np.array([6.0, 12.0, 20.0])
    a, l_eff, gx, gy, d = pursuit_command(win, np.full(3, r), np.zeros(3), np.full(3, math.pi / 2),
                                          np.full(3, V), look, math.inf)
    assert np.allclose(l_eff, look)
    assert np.allclose(np.hypot(gx - r, gy), look, atol=1e-2)  # goal on the L circle
    assert np.allclose(a, V**2 / r, rtol=2e-3)
    assert np.allclose(d, 0.0, atol=1e-3)


def test_pursuit_core_far_from_a_line_uses_a_45_degree_capture():
    # 20 m left of a line, flying along it: L_eff = sqrt(2) 20, the goal 20 m ahead on the line,
    # eta = -45 deg, a = 2 V^2 sin(-45 deg) / (20 sqrt(2)) = -V^2 / 20.
    win = _Window(LinePath(x0=-50.0), 50.0, 80.0)
    a, l_eff, gx, gy, d = pursuit_command(win, np.array([0.0]), np.array([20.0]), np.array([0.0]),
                                          np.array([V]), np.array([5.0]), math.inf)
    assert l_eff[0] == pytest.approx(20.0 * math.sqrt(2.0), rel=1e-6)
    assert (gx[0], gy[0]) == pytest.approx((20.0, 0.0), abs=1e-3)
    assert a[0] == pytest.approx(-V**2 / 20.0, rel=1e-4)
    assert d[0] == pytest.approx(20.0)


@pytest.mark.parametrize("lag_s", [0.0, 0.3])
def test_mirroring_the_scene_flips_the_command(lag_s):
    params = PredictiveParams(lag_s=lag_s, a_max_m_s2=5.0)
    path = CirclePath(25.0, cx=3.0, cy=-2.0, phi0_rad=0.4)
    state = VehicleState(26.0, 9.0, 2.3, V)
    a = PredictiveGuidance(path, params).step(0.0, state)
    b = PredictiveGuidance(mirror_path(path), params).step(0.0, mirror_state(state))
    assert abs(a.a_cmd_m_s2) > 1e-3
    # Equal and opposite up to the rounding of the plan's least-squares solve.
    assert b.a_cmd_m_s2 == pytest.approx(-a.a_cmd_m_s2, rel=1e-4)


def test_same_inputs_same_outputs():
    path = CirclePath(20.0)
    runs = [fly(PredictiveGuidance(path, PredictiveParams(lag_s=0.3)), VehicleState(23.0, 0.0, 1.4, V), 4.0)
            for _ in range(2)]
    assert np.array_equal(runs[0], runs[1])


def test_converges_onto_a_line_under_lag():
    from companion.sim.simulator import LagModel, simulate

    path = LinePath(x0=-20.0, length_m=400.0)
    law = PredictiveGuidance(path, PredictiveParams(lag_s=0.3, a_max_m_s2=5.0))
    res = simulate(path, law, VehicleState(0.0, 8.0, 0.0, V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 5.0), t_max_s=25.0)
    assert abs(res.crosstrack_m[0]) == pytest.approx(8.0)
    assert np.max(np.abs(res.crosstrack_m[-250:])) < 0.05
    assert np.max(np.abs(res.a_cmd_m_s2)) <= 5.0 + 1e-12


def test_acceleration_limit_is_respected_when_the_path_asks_for_more():
    # A 6 m circle at 5 m/s needs 4.2 m/s^2; with a 2 m/s^2 limit every command stays within it.
    from companion.sim.simulator import LagModel, simulate

    path = CirclePath(6.0)
    law = PredictiveGuidance(path, PredictiveParams(lag_s=0.3, a_max_m_s2=2.0))
    res = simulate(path, law, VehicleState(6.0, 0.0, math.pi / 2, V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 2.0), t_max_s=6.0)
    assert np.max(np.abs(res.a_cmd_m_s2)) <= 2.0 + 1e-12
    assert np.max(np.abs(res.a_cmd_m_s2)) == pytest.approx(2.0)  # it does saturate


def test_a_larger_lambda_flies_smoother_and_looser():
    from companion.sim.simulator import LagModel, simulate

    path = CirclePath(30.0)
    out = []
    for lam in (0.003, 3.0):
        law = PredictiveGuidance(path, PredictiveParams(lambda_s4=lam, lag_s=0.3, a_max_m_s2=5.0))
        res = simulate(path, law, VehicleState(36.0, 0.0, math.pi / 2, V), GuidanceParams(speed_m_s=V),
                       model=LagModel(0.3, 5.0), t_max_s=12.0)
        out.append((np.sqrt(np.mean(res.a_cmd_m_s2**2)), np.sqrt(np.mean(res.crosstrack_m**2))))
    (a_tight, d_tight), (a_smooth, d_smooth) = out
    assert a_smooth < a_tight
    assert d_smooth > d_tight


def test_far_start_heading_away_under_lag_captures_without_circling():
    # 40 m right of a line and flying away from it: the law must turn back and capture (a plan
    # that saturates the turn must not get stuck circling).
    from companion.sim.simulator import LagModel, simulate

    path = LinePath(x0=-50.0, length_m=600.0)
    law = PredictiveGuidance(path, PredictiveParams(lag_s=0.3, a_max_m_s2=5.0))
    res = simulate(path, law, VehicleState(0.0, -40.0, -math.pi / 2, V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 5.0), t_max_s=40.0)
    d = np.abs(res.crosstrack_m)
    reached = np.flatnonzero(d <= 1.0)
    assert reached.size and res.t_s[reached[0]] < 25.0
    assert np.max(d[-250:]) < 0.1
    assert res.x_m[-1] > 80.0  # it went along the line, not round in circles
