"""TwoPhaseGuidance as a whole: symmetry, invariance, determinism, phases, end of path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import function_path, parametric_path, waypoint_path
from companion.guidance.optimiser import GainOptimiser, gains_from_ratio, ratio_from_gains
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import simulate


def wavy(transform):
    """The same wavy path, with every point mapped by ``transform``."""
    x = np.linspace(0.0, 120.0, 25)
    pts = [transform(xi, 8.0 * math.sin(xi / 15.0)) for xi in x]
    return waypoint_path(pts)


def fly(path, x, y, heading, method, t_max_s=12.0):
    params = GuidanceParams(method=method, midcourse_trigger="off")
    return simulate(path, TwoPhaseGuidance(path, params), VehicleState(x, y, heading, 5.0), params,
                    t_max_s=t_max_s)


@pytest.mark.parametrize("method", ["fixed_l1", "corrector"])
def test_mirroring_the_scene_flips_the_sign_of_the_command(method):
    plain = fly(wavy(lambda x, y: (x, y)), 0.0, 3.0, 0.4, method)
    mirrored = fly(wavy(lambda x, y: (x, -y)), 0.0, -3.0, -0.4, method)
    assert np.max(np.abs(plain.a_cmd_m_s2)) > 0.5
    assert np.allclose(mirrored.a_cmd_m_s2, -plain.a_cmd_m_s2, atol=1e-6)
    assert np.allclose(mirrored.crosstrack_m, -plain.crosstrack_m, atol=1e-6)


@pytest.mark.parametrize("method", ["fixed_l1", "corrector"])
def test_rotating_the_scene_leaves_the_command_unchanged(method):
    ang = 2.1
    c, s = math.cos(ang), math.sin(ang)
    rot = lambda x, y: (c * x - s * y + 7.0, s * x + c * y - 4.0)  # noqa: E731
    plain = fly(wavy(lambda x, y: (x, y)), 0.0, 3.0, 0.4, method)
    x0, y0 = rot(0.0, 3.0)
    rotated = fly(wavy(rot), x0, y0, 0.4 + ang, method)
    assert np.allclose(rotated.a_cmd_m_s2, plain.a_cmd_m_s2, atol=1e-6)
    assert np.allclose(rotated.k2, plain.k2, rtol=1e-6)


def test_same_inputs_same_outputs():
    path = wavy(lambda x, y: (x, y))
    a = fly(path, 0.0, 3.0, 0.4, "corrector")
    b = fly(path, 0.0, 3.0, 0.4, "corrector")
    assert np.array_equal(a.a_cmd_m_s2, b.a_cmd_m_s2)
    assert np.array_equal(a.k1, b.k1) and np.array_equal(a.k2, b.k2)


def test_run_finishes_when_the_path_end_is_within_l1():
    line = waypoint_path([(0.0, 0.0), (50.0, 0.0)])
    result = fly(line, 0.0, 0.0, 0.0, "fixed_l1", t_max_s=60.0)
    assert result.finished
    # Flying the line at 5 m/s, the end comes within L1 = 10 m after 40 m: t = 8 s.
    assert result.t_s[-1] == pytest.approx(8.0, abs=0.021)


def test_closed_paths_never_finish():
    loop = waypoint_path([(0, 0), (40, 0), (40, 30), (0, 30)], closed=True)
    result = fly(loop, 0.0, 0.0, 0.0, "corrector", t_max_s=70.0)
    assert not result.finished
    assert result.t_s[-1] == pytest.approx(70.0)
    assert np.max(np.abs(result.crosstrack_m[result.t_s > 20])) < 2.0


def test_more_than_l1_from_the_path_steers_at_the_projection():
    line = waypoint_path([(0.0, 0.0), (200.0, 0.0)])
    law = TwoPhaseGuidance(line, GuidanceParams(method="corrector", midcourse_trigger="off"))
    out = law.step(0.0, VehicleState(50.0, 15.0, 0.0, 5.0))  # 15 m left, flying east
    # Target (50, 0): straight right, eta = -90 deg: a = -2 V^2 / 15.
    assert out.lookahead_xy_m == pytest.approx((50.0, 0.0))
    assert out.a_cmd_m_s2 == pytest.approx(-2 * 25 / 15)
    assert out.crosstrack_m == pytest.approx(15.0)


def test_gains_map_ratios_to_bounded_pairs_with_both_pure_ends():
    assert gains_from_ratio(0.0, 1.0, 1e4) == (1.0, 0.0)
    assert gains_from_ratio(math.inf, 1.0, 1e4) == (0.0, 1e4)
    assert gains_from_ratio(50.0, 1.0, 1e4) == (1.0, 50.0)
    k1, k2 = gains_from_ratio(1e6, 1.0, 1e4)
    assert (k1, k2) == (pytest.approx(1e-2), 1e4)
    assert ratio_from_gains(*gains_from_ratio(1e6, 1.0, 1e4)) == pytest.approx(1e6)


def test_window_is_min_of_two_l1_and_the_radius_over_v():
    arc = function_path(lambda x: 15.0 - np.sqrt(np.maximum(225.0 - x * x, 0.0)), (0.0, 10.0))  # R = 15
    line = waypoint_path([(0.0, 0.0), (100.0, 0.0)])
    params = GuidanceParams(l1_m=10.0)
    assert GainOptimiser(arc, params).window_s(1.0, 5.0) == pytest.approx(15.0 / 5.0, rel=1e-4)
    assert GainOptimiser(line, params).window_s(1.0, 5.0) == pytest.approx(20.0 / 5.0)


def test_optimiser_prefers_the_corrector_on_a_tight_curve_and_improves_the_rollout_cost():
    sine = function_path(lambda x: 10 * np.sin(0.078 * x) + 20 * np.cos(0.082 * x), (-15.0, 150.0))
    params = GuidanceParams()
    opt = GainOptimiser(sine, params)
    s = sine.project(40.0, float(10 * np.sin(0.078 * 40) + 20 * np.cos(0.082 * 40)))
    x, y = sine.point(s)
    heading = sine.heading_rad(s)
    s_look = sine.lookahead(x, y, 10.0, s)
    k1, k2, window = opt.optimise(x, y, heading, 5.0, s, s_look)
    assert 0.0 <= k1 <= params.k1_max and 0.0 <= k2 <= params.k2_max
    rhos = np.array([0.0, ratio_from_gains(k1, k2)])
    cost = opt._rollout_cost(rhos, x, y, heading, 5.0, s, s_look, window)
    assert cost[1] <= cost[0]


def test_inner_loop_estimate_follows_the_first_order_step_response():
    params = GuidanceParams(rollout_tau_s=0.4)
    law = TwoPhaseGuidance(waypoint_path([(0.0, 0.0), (100.0, 0.0)]), params)
    law._remember_command(0.0, 2.0)  # command 2 m/s^2 from t = 0, from rest
    for t in (0.1, 0.4, 1.2):
        assert law._a_achieved_estimate(t) == pytest.approx(2.0 * (1 - math.exp(-t / 0.4)))
    law._remember_command(1.2, -1.0)  # then -1 from t = 1.2
    a12 = 2.0 * (1 - math.exp(-1.2 / 0.4))
    assert law._a_achieved_estimate(1.5) == pytest.approx(-1.0 + (a12 + 1.0) * math.exp(-0.3 / 0.4))


def test_rollout_tau_must_be_non_negative():
    with pytest.raises(ValueError, match="rollout_tau_s"):
        GuidanceParams(rollout_tau_s=-0.1)


def test_no_reoptimisation_while_hovering():
    line = waypoint_path([(0.0, 0.0), (100.0, 0.0)])
    law = TwoPhaseGuidance(line, GuidanceParams(method="corrector", midcourse_trigger="off"))
    out = law.step(0.0, VehicleState(0.0, 1.0, 0.0, 0.0))
    assert not out.reoptimised and math.isfinite(out.a_cmd_m_s2)
    out = law.step(0.02, VehicleState(0.0, 1.0, 0.0, 5.0))
    assert out.reoptimised


def test_search_is_skipped_on_a_straight_reach_and_says_constant_l1(monkeypatch):
    line = waypoint_path([(0.0, 0.0), (400.0, 0.0)])
    params = GuidanceParams(l1_m=10.0)
    opt = GainOptimiser(line, params)

    def no_rollouts(*args, **kwargs):
        raise AssertionError("the search rolled out candidates on a straight line")

    monkeypatch.setattr(opt, "_rollout_cost", no_rollouts)
    k1, k2, window = opt.optimise(50.0, 1.0, 0.1, 5.0, 50.0, 60.0, warm_ratio=3.0)
    assert (k1, k2, window) == (params.k1_max, 0.0, pytest.approx(2 * 10.0 / 5.0))


def test_search_runs_where_the_rollouts_can_reach_a_bend(monkeypatch):
    # 100 m straight then a bend: from s = 50 a 4 s window reaches past s = 100.
    bend = waypoint_path([(0.0, 0.0), (100.0, 0.0), (130.0, 30.0), (130.0, 100.0)])
    opt = GainOptimiser(bend, GuidanceParams(l1_m=10.0))
    called = []
    real = opt._rollout_cost
    monkeypatch.setattr(opt, "_rollout_cost", lambda *a, **k: (called.append(1), real(*a, **k))[1])
    opt.optimise(50.0, 0.0, 0.0, 5.0, 50.0, 60.0)
    assert called


def test_frozen_maker_builds_the_same_object_as_the_constructor_and_refuses_validated_classes():
    from dataclasses import FrozenInstanceError

    from companion.guidance.types import GuidanceOutput, frozen_maker

    make = frozen_maker(GuidanceOutput)
    fast = make(1.5, "close_range", -0.2, 12.0, 1.0, 3.0, (1.0, 2.0), None, True, {"w1": 0.5})
    slow = GuidanceOutput(a_cmd_m_s2=1.5, phase="close_range", crosstrack_m=-0.2, s_proj_m=12.0,
                          k1=1.0, k2=3.0, lookahead_xy_m=(1.0, 2.0), corrector_xy_m=None,
                          reoptimised=True, extra={"w1": 0.5})
    assert fast == slow and type(fast) is GuidanceOutput
    with pytest.raises(FrozenInstanceError):
        fast.k1 = 2.0
    with pytest.raises(TypeError):
        make(1.5, "close_range")  # every field, in order
    with pytest.raises(TypeError):
        frozen_maker(GuidanceParams)  # validates in __post_init__


def _circle(closed: bool):
    """A circle of radius 50 m about (0, 50), anticlockwise from (0, 0) going east; open, it is
    the same circle short of its last 10 degrees."""
    end = 2.0 * math.pi if closed else 2.0 * math.pi * 35.0 / 36.0
    return parametric_path(lambda u: 50.0 * np.sin(u), lambda u: 50.0 - 50.0 * np.cos(u), (0.0, end),
                           closed=closed)


@pytest.mark.parametrize("closed, beside_m, expected", [
    (True, 5.0, False),    # 5 m above the top of the closed circle, 105 m from its start: joins it there
    (True, 25.0, True),    # 25 m off it: more than 2 R from every point of it, flies to its start
    (False, 5.0, True),    # the same 5 m beside an open path: the paper's test, 100 m from its start
])
def test_the_midcourse_trigger_measures_a_closed_path_from_its_closest_point(closed, beside_m, expected):
    path = _circle(closed)
    g = TwoPhaseGuidance(path, GuidanceParams(method="corrector", circle_radius_m=10.0))
    state = VehicleState(x_m=0.0, y_m=100.0 + beside_m, course_rad=math.pi, speed_m_s=5.0)
    assert 100.0 + beside_m > 2 * 10.0  # far from the start either way
    assert g.should_trigger_midcourse(state) is expected
    assert (g.step(0.0, state).phase == "midcourse") is expected
