"""Constant-L1 guidance (Park 2007) against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import parametric_path, waypoint_path
from companion.guidance.l1 import l1_bound_m_s2, l1_command
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import simulate


def circle_path(radius_m: float):
    return parametric_path(lambda u: radius_m * np.cos(u), lambda u: radius_m * np.sin(u),
                           (0.0, 2 * np.pi), closed=True)


@pytest.mark.parametrize("radius_m, l1_m", [(20.0, 10.0), (20.0, 39.0), (8.0, 10.0), (50.0, 5.0)])
def test_on_a_circle_with_l1_up_to_its_diameter_the_command_is_v2_over_r(radius_m, l1_m):
    path = circle_path(radius_m)
    params = GuidanceParams(method="fixed_l1", l1_m=l1_m, speed_m_s=5.0, midcourse_trigger="off")
    law = TwoPhaseGuidance(path, params)
    for angle in (0.0, 1.0, 4.0):
        # On the circle, flying its tangent anticlockwise.
        state = VehicleState(radius_m * math.cos(angle), radius_m * math.sin(angle), angle + math.pi / 2, 5.0)
        out = law.step(0.0, state)
        assert out.a_cmd_m_s2 == pytest.approx(25.0 / radius_m, rel=1e-6)


def test_steady_state_on_a_circle_after_a_flight_is_v2_over_r():
    path = circle_path(20.0)
    params = GuidanceParams(method="fixed_l1", l1_m=10.0, midcourse_trigger="off")
    start = VehicleState(24.0, 0.0, math.pi / 2 + 0.3, 5.0)  # 4 m outside, 17 deg off
    result = simulate(path, TwoPhaseGuidance(path, params), start, params, t_max_s=60.0)
    tail = result.a_cmd_m_s2[-200:]
    assert np.allclose(tail, 25.0 / 20.0, rtol=1e-4)
    assert np.max(np.abs(result.crosstrack_m[-200:])) < 1e-3


def test_converges_onto_a_straight_line_from_an_offset():
    line = waypoint_path([(0.0, 0.0), (400.0, 0.0)])
    params = GuidanceParams(method="fixed_l1", l1_m=10.0, midcourse_trigger="off")
    start = VehicleState(0.0, 8.0, 0.0, 5.0)  # 8 m left of the line, parallel to it
    result = simulate(line, TwoPhaseGuidance(line, params), start, params)
    assert result.finished
    d = np.abs(result.crosstrack_m)
    assert d[0] == pytest.approx(8.0)
    # Park: on a line the error decays like a damped second-order system (zeta = 0.707,
    # omega = sqrt(2) V / L1 = 0.71 rad/s): within 10 s it is down to centimetres, and stays.
    assert np.max(d[result.t_s > 15.0]) < 0.01
    # |d| never grows past its start (no overshoot beyond 5 % for zeta = 0.707).
    assert np.max(d) <= 8.0 + 1e-9
    assert np.min(result.crosstrack_m) > -0.05 * 8.0


def test_command_is_twice_v2_sin_eta_over_distance_from_hand_geometry():
    # Vehicle at the origin heading east, target 10 m away at 30 deg left: a = 2 V^2 sin30 / 10.
    a, eta, dist = l1_command(0.0, 0.0, 0.0, 5.0, 10 * math.cos(math.pi / 6), 10 * math.sin(math.pi / 6))
    assert a == pytest.approx(2 * 25 * 0.5 / 10)
    assert eta == pytest.approx(math.pi / 6)
    assert dist == pytest.approx(10.0)
    a, eta, _ = l1_command(0.0, 0.0, 0.0, 5.0, 0.0, -10.0)  # straight right: -2 V^2 / L
    assert a == pytest.approx(-5.0)
    assert eta == pytest.approx(-math.pi / 2)


def test_fixed_l1_never_exceeds_two_v2_over_l1_even_from_bad_starts():
    path = waypoint_path([(0, 0), (30, 10), (60, -10), (90, 20), (120, 0)])
    params = GuidanceParams(method="fixed_l1", l1_m=10.0, midcourse_trigger="off")
    bound = l1_bound_m_s2(5.0, 10.0)
    assert bound == pytest.approx(5.0)
    for heading_deg in range(0, 360, 45):
        start = VehicleState(0.0, 3.0, math.radians(heading_deg), 5.0)
        result = simulate(path, TwoPhaseGuidance(path, params), start, params, t_max_s=60.0)
        assert np.max(np.abs(result.a_cmd_m_s2)) <= bound + 1e-9
