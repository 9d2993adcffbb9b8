"""Mid-course phase: lemma 1's contact point, the case / sector selection, arrival at the start."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import function_path, waypoint_path
from companion.guidance.midcourse import (
    contact_approach,
    initiation_circles,
    plan_midcourse,
)
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState

V = 5.0


def brute_force_extrema(x, y, course, circle, n=200_000):
    """Park's command towards every point of the circle: the points of min and max command."""
    phi = np.linspace(-math.pi, math.pi, n, endpoint=False)
    ox, oy = circle.centre_xy_m
    px = ox + circle.radius_m * np.cos(phi)
    py = oy + circle.radius_m * np.sin(phi)
    dx, dy = px - x, py - y
    lat = math.cos(course) * dy - math.sin(course) * dx
    a = 2 * V * V * lat / (dx * dx + dy * dy)
    return (px[np.argmin(a)], py[np.argmin(a)], a.min()), (px[np.argmax(a)], py[np.argmax(a)], a.max())


@pytest.mark.parametrize("x, y, course_deg", [
    (0.0, -60.0, 90.0), (30.0, -50.0, 100.0), (-40.0, -30.0, 60.0), (50.0, 40.0, 200.0),
    (-70.0, 20.0, -20.0), (5.0, 70.0, 260.0),
])
def test_lemma_1_contact_points_are_the_extrema_of_the_command_over_the_circle(x, y, course_deg):
    course = math.radians(course_deg)
    for circle in initiation_circles((0.0, 0.0), math.pi / 2, 10.0):
        approach = contact_approach(x, y, course, V, circle, (0.0, 0.0))
        lo, hi = brute_force_extrema(x, y, course, circle)
        # The touch arriving in the circle's sense is one of the two extrema.
        target = hi if approach.a_cmd_m_s2 >= (lo[2] + hi[2]) / 2 else lo
        assert approach.contact_xy_m == pytest.approx(target[:2], abs=2e-3)
        assert approach.a_cmd_m_s2 == pytest.approx(target[2], rel=1e-6, abs=1e-9)
        # Lemma 1's W (primary) is the extremum with the smaller |a|.
        smaller = min(abs(lo[2]), abs(hi[2]))
        assert approach.primary == (abs(approach.a_cmd_m_s2) <= smaller + 1e-9)


def test_lemma_1_matches_the_papers_lambda_for_its_canonical_scene():
    # Paper frame: circle C centred at O = (0, 0), vehicle at P with heading pi; lambda is the
    # radius of the touching circle: lambda = (R^2 - X^2 - Y^2) / (2 (R - Y)).
    R, X, Y = 10.0, 40.0, 25.0
    lam = (R * R - X * X - Y * Y) / (2 * (R - Y))
    from companion.guidance.midcourse import InitiationCircle
    for sense in (+1, -1):
        circle = InitiationCircle("c", (0.0, 0.0), R, sense)
        a = contact_approach(X, Y, math.pi, V, circle, (R, 0.0))
        if abs(abs(1 / a.curvature_1_m) - lam) < 1e-9:
            break
    else:
        pytest.fail("no touching circle of radius lambda")
    # With the paper's cos(phi) = X / (R - lambda) the contact point is at angle phi.
    phi_cos = X / (R - lam)
    assert math.cos(math.atan2(a.contact_xy_m[1], a.contact_xy_m[0])) == pytest.approx(phi_cos, abs=1e-9)


def fly_midcourse(path, x, y, heading_deg, t_max_s=400.0, rate_hz=50.0, speed_of_t=lambda t: V, trace=None):
    params = GuidanceParams(method="fixed_l1", rate_hz=rate_hz)
    law = TwoPhaseGuidance(path, params)
    from companion.sim.simulator import unicycle_step

    dt = 1 / rate_hz
    psi = math.radians(heading_deg)
    t = 0.0
    while t < t_max_s:
        v = speed_of_t(t)
        out = law.step(t, VehicleState(x, y, psi, v))
        if trace is not None:
            trace.append((t, x, y, out.extra.get("stage")))
        if out.phase != "midcourse":
            return law, x, y, psi, out
        x, y, psi = unicycle_step(x, y, psi, v, out.a_cmd_m_s2, dt)
        t += dt
    raise AssertionError("the mid-course phase never ended")


STRAIGHT_NORTH = waypoint_path([(0.0, 0.0), (0.0, 100.0)])
SCENES = [  # (x, y, heading): the path starts at the origin heading north
    (0.0, -60.0, 90.0), (0.0, -60.0, 60.0), (0.0, -60.0, 120.0), (40.0, -40.0, 135.0),
    (-40.0, -40.0, 45.0), (-40.0, -40.0, 0.0), (40.0, -40.0, 180.0), (30.0, -80.0, 90.0),
    (60.0, 30.0, 180.0), (-60.0, 30.0, 0.0), (60.0, 30.0, 240.0), (-60.0, 30.0, -60.0),
    (10.0, 80.0, 270.0), (-10.0, 80.0, 270.0), (0.0, 50.0, 90.0), (20.0, 60.0, 90.0),
    (-25.0, 60.0, 90.0), (40.0, 10.0, 90.0), (-40.0, -10.0, 90.0), (0.0, -60.0, 270.0),
    (40.0, -40.0, 300.0), (-40.0, -40.0, 240.0),
]


@pytest.mark.parametrize("x, y, heading_deg", SCENES)
def test_every_case_arrives_at_the_path_start_within_1_m_and_5_deg(x, y, heading_deg):
    law, xe, ye, psi, out = fly_midcourse(STRAIGHT_NORTH, x, y, heading_deg)
    assert out.phase == "close_range"
    assert math.hypot(xe, ye) < 1.0
    heading_error = (psi - math.pi / 2 + math.pi) % (2 * math.pi) - math.pi
    assert abs(math.degrees(heading_error)) < 5.0


def test_the_scenes_cover_both_cases_every_rule_and_both_circles():
    seen = set()
    for x, y, h in SCENES:
        plan = plan_midcourse(x, y, math.radians(h), V, (0.0, 0.0), math.pi / 2, 10.0)
        seen.add((plan.case, plan.rule, plan.chosen.circle.name, plan.chosen.primary))
    cases = {s[0] for s in seen}
    assert cases == {1, 2}
    for case in (1, 2):
        # red and blue sectors: one circle reached through its primary W, on either side
        assert {(case, "only_primary", "left", True), (case, "only_primary", "right", True)} <= seen
    assert any(s[0] == 1 and s[1] == "lower_acceleration" and s[3] for s in seen)  # Case 1 green
    assert any(s[0] == 2 and s[1] == "lower_acceleration" and not s[3] for s in seen)  # Case 2 green: alternate


def test_mid_course_on_the_papers_sine_arrives_on_the_start():
    sine = function_path(lambda x: 10 * np.sin(0.078 * x) + 20 * np.cos(0.082 * x), (-15.0, 300.0))
    law, xe, ye, psi, out = fly_midcourse(sine, -70.0, -60.0, 0.0)
    sx, sy = sine.start_xy_m
    assert math.hypot(xe - sx, ye - sy) < 1.0
    heading_error = (psi - sine.start_heading_rad + math.pi) % (2 * math.pi) - math.pi
    assert abs(math.degrees(heading_error)) < 5.0


def test_a_vehicle_gathering_speed_still_flies_the_approach_arc_to_w():
    # A copter that has just taken off gathers speed during the approach (a real PX4 SIH: 3.4 m/s
    # at the plan, 4.5 m/s 12 s later). Held as a constant command, V^2 c at the plan's speed,
    # the arc flew straighter than planned and missed W; held as the curvature c, it reaches W.
    speed = lambda t: 3.4 + 1.6 * min(t / 12.0, 1.0)  # noqa: E731
    plan = plan_midcourse(-40.0, -10.0, math.radians(90.0), speed(0.0), (0.0, 0.0), math.pi / 2, 10.0)
    assert plan.chosen.arc_m > 50.0 and abs(plan.chosen.curvature_1_m) > 0.02  # a real arc to fly
    trace = []
    law, xe, ye, psi, out = fly_midcourse(STRAIGHT_NORTH, -40.0, -10.0, 90.0, speed_of_t=speed, trace=trace)
    at_w = next((x, y) for (_, x, y, stage), (_, _, _, nxt) in zip(trace, trace[1:])
                if stage == "approach" and nxt != "approach")
    wx, wy = law.midcourse_plan.chosen.contact_xy_m
    assert math.hypot(at_w[0] - wx, at_w[1] - wy) < 0.5
    assert math.hypot(xe, ye) < 1.0


def test_constant_command_during_the_approach_equals_parks_command_at_w():
    plan = plan_midcourse(-40.0, -40.0, math.radians(45.0), V, (0.0, 0.0), math.pi / 2, 10.0)
    wx, wy = plan.chosen.contact_xy_m
    dx, dy = wx + 40.0, wy + 40.0
    lat = math.cos(math.radians(45)) * dy - math.sin(math.radians(45)) * dx
    assert plan.chosen.a_cmd_m_s2 == pytest.approx(2 * V * V * lat / (dx * dx + dy * dy), rel=1e-9)


@pytest.mark.parametrize("trigger, expected", [("auto", True), ("paper", False), ("off", False)])
def test_trigger_on_a_nearly_straight_start(trigger, expected):
    # R0 at the start of a gentle arc is 1000 m: the paper's 2 R0 test never fires 80 m away.
    gentle = function_path(lambda x: x * x / 2000.0, (0.0, 200.0))
    params = GuidanceParams(midcourse_trigger=trigger, circle_radius_m=10.0)
    law = TwoPhaseGuidance(gentle, params)
    assert law.should_trigger_midcourse(VehicleState(0.0, -80.0, 0.0, V)) is expected
    # Close to the start (< 2 R = 20 m) auto leaves it to close-range guidance.
    assert not TwoPhaseGuidance(gentle, params).should_trigger_midcourse(VehicleState(0.0, -15.0, 0.0, V))


def test_paper_trigger_fires_beyond_twice_the_start_radius_of_curvature():
    arc = function_path(lambda x: 20.0 - np.sqrt(np.maximum(400.0 - x * x, 0.0)), (0.0, 15.0))  # R0 = 20 m
    law = TwoPhaseGuidance(arc, GuidanceParams(midcourse_trigger="paper"))
    assert law.should_trigger_midcourse(VehicleState(0.0, -41.0, 0.0, V))
    assert not law.should_trigger_midcourse(VehicleState(0.0, -39.0, 0.0, V))


def test_a_vehicle_inside_one_initiation_circle_flies_the_other_and_arrives():
    # Paper trigger on an arc of radius R0 = 6 m (fires 12 m away) with R = 10 m circles:
    # (-5, 14) is 14.9 m from S = (0, 0), inside the left circle (centre (0, 10)), outside the right.
    arc = function_path(lambda x: 6.0 - np.sqrt(np.maximum(36.0 - x * x, 0.0)), (0.0, 5.0))
    arc_start_heading = arc.start_heading_rad
    assert abs(arc_start_heading) < 1e-6
    plan = plan_midcourse(-5.0, 14.0, math.radians(-90.0), V, (0.0, 0.0), 0.0, 10.0)
    assert plan.rule == "only_outside" and plan.chosen.circle.name == "right" and plan.other is None
    law = TwoPhaseGuidance(arc, GuidanceParams(method="fixed_l1", midcourse_trigger="paper"))
    assert law.should_trigger_midcourse(VehicleState(-5.0, 14.0, math.radians(-90.0), V))
    from companion.sim.simulator import unicycle_step

    x, y, psi, t = -5.0, 14.0, math.radians(-90.0), 0.0
    while True:
        out = law.step(t, VehicleState(x, y, psi, V))
        if out.phase != "midcourse":
            break
        x, y, psi = unicycle_step(x, y, psi, V, out.a_cmd_m_s2, 0.02)
        t += 0.02
        assert t < 120.0
    assert math.hypot(x, y) < 1.0
    assert abs(math.degrees((psi + math.pi) % (2 * math.pi) - math.pi)) < 5.0


def test_an_arc_tighter_than_the_initiation_circle_is_replaced_by_a_turn_in():
    # 20.1 m from S, just outside the left circle (centre (-10, 0)), heading away from it:
    # lemma 1's touching circle has a radius of 2.7 m (3.7 V^2 / R); the vehicle turns in at
    # V^2 / R instead and never commands more than the circle's own command (plus the
    # closed-loop circle following's transients).
    plan = plan_midcourse(-20.1, 6.5, math.radians(-41.0), V, (0.0, 0.0), math.pi / 2, 10.0)
    assert abs(plan.chosen.curvature_1_m) * 10.0 > 3.0
    params = GuidanceParams(method="fixed_l1")
    law = TwoPhaseGuidance(STRAIGHT_NORTH, params)
    from companion.sim.simulator import unicycle_step

    x, y, psi, t, a_max = -20.1, 6.5, math.radians(-41.0), 0.0, 0.0
    stages = set()
    while True:
        out = law.step(t, VehicleState(x, y, psi, V))
        if out.phase != "midcourse":
            break
        stages.add(out.extra["stage"])
        a_max = max(a_max, abs(out.a_cmd_m_s2))
        x, y, psi = unicycle_step(x, y, psi, V, out.a_cmd_m_s2, 0.02)
        t += 0.02
        assert t < 200.0
    assert "turn_in" in stages
    assert a_max <= 1.05 * V * V / 10.0
    assert math.hypot(x, y) < 1.0
