"""The capture reference of the predictive law's rollout cost (``capture_reference``,
``PredictiveParams.capture_tc_scale``): its closed form checked by hand, and what it is for, a
capture onto a line that flattens out instead of diving at the path and overshooting."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.guidance.capture import SIDE_MIN_OFFSET_M
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams, capture_reference, weigh_overshoot
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from bench_scenes import CirclePath, LinePath  # noqa: E402

V = 5.0
# The law as it was when the reference's and the overshoot weight's flights below were measured:
# the look-ahead search over 8 distances from 3 m, one Gauss-Newton step a re-optimisation. Each
# test isolates its own mechanism; the search's lower bound (1.5 m by default) and the second
# Gauss-Newton step have their own tests (test_predictive_lookahead.py, test_predictive_refine.py).
SEARCH_FROM_3_M = {"l_min_m": 3.0, "n_candidates": 8, "refine_iterations": 1}


def test_reference_from_rest_is_the_critically_damped_decay():
    # d0 = 2 m, no rate, T = 0.5 s: r(t) = 2 (1 + t/T) exp(-t/T); at t = T: 4/e = 1.4715 m.
    t = np.array([0.0, 0.5, 1.0])
    r = capture_reference(2.0, 0.0, 0.5, t)
    assert r == pytest.approx([2.0, 4.0 / math.e, 6.0 / math.e**2], rel=1e-12)


def test_reference_keeps_a_rate_towards_the_path():
    # d0 = 3 m (left), d0' = -2 m/s (closing), T = 1 s: r(t) = (3 + (-2 + 3) t) exp(-t).
    t = np.linspace(0.0, 3.0, 7)
    r = capture_reference(3.0, -2.0, 1.0, t)
    assert r == pytest.approx((3.0 + t) * np.exp(-t), rel=1e-12)
    # r'(0) = d0' (forward difference over 1 us).
    slope = (capture_reference(3.0, -2.0, 1.0, np.array([1e-6]))[0] - 3.0) / 1e-6
    assert slope == pytest.approx(-2.0, abs=1e-4)
    # d0' = -d0/T: the plain exponential.
    assert capture_reference(3.0, -3.0, 1.0, t) == pytest.approx(3.0 * np.exp(-t), rel=1e-12)


def test_reference_ignores_a_rate_away_from_the_path_and_never_crosses_it():
    # Right of the path (d0 < 0) and drifting further right (d0' < 0): taken as from rest.
    t = np.linspace(0.0, 5.0, 51)
    r = capture_reference(-1.5, -4.0, 0.4, t)
    assert r == pytest.approx(capture_reference(-1.5, 0.0, 0.4, t), rel=1e-12)
    assert np.all(r <= 0.0) and np.all(np.diff(r) >= 0.0)  # monotone back towards the path


def test_no_reference_when_disabled():
    t = np.linspace(0.0, 5.0, 26)
    assert np.array_equal(capture_reference(2.0, -1.0, 0.0, t), np.zeros(26))
    assert PredictiveParams(lambda_s4=0.0625, capture_tc_scale=0.6).capture_tc_s() == pytest.approx(0.3)
    assert PredictiveParams(lambda_s4=0.0).capture_tc_s() == 0.0
    with pytest.raises(ValueError, match="capture_tc_scale"):
        PredictiveParams(capture_tc_scale=-0.1)


def _capture(scale: float, y0_m: float, heading_rad: float):
    path = LinePath(x0=-50.0, length_m=600.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=5.0,
                                                    capture_tc_scale=scale))
    res = simulate(path, law, VehicleState(0.0, y0_m, heading_rad, V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 5.0), t_max_s=12.0)
    d = res.y_m  # the line is the x axis: the cross-track error is y (left positive)
    i0 = int(np.flatnonzero(np.abs(d) <= 1.0)[0])
    return {
        "overshoot": float(np.max(d)),  # started on the right: any d > 0 is a crossing
        "reach_s": float(res.t_s[i0]),
        "d_rms": float(np.sqrt(np.mean(d[i0:] ** 2))),
        "a_rms": float(np.sqrt(np.mean(res.a_cmd_m_s2[i0:] ** 2))),
        "a_max": float(np.max(np.abs(res.a_cmd_m_s2))),
        "settled": float(np.max(np.abs(d[-100:]))),
    }


@pytest.mark.parametrize("heading_deg", [90.0, 45.0])
def test_capture_under_lag_flattens_out_instead_of_overshooting(heading_deg):
    # 10 m right of a line, flying at it, 0.3 s lag, 5 m/s^2: penalising d itself, the plan dives
    # at the line (the metres of the approach outweigh an overshoot of decimetres) and crosses it
    # by about 0.27 m; with the reference the approach flattens out in time. Both reach the 1 m
    # band at about the same time, and from there the reference flies with less error AND less
    # acceleration.
    plain = _capture(0.0, -10.0, math.radians(heading_deg))
    ref = _capture(0.6, -10.0, math.radians(heading_deg))
    assert plain["overshoot"] > 0.2
    assert ref["overshoot"] < 0.7 * plain["overshoot"]
    assert ref["d_rms"] < plain["d_rms"]
    assert ref["a_rms"] < 0.9 * plain["a_rms"]
    assert abs(ref["reach_s"] - plain["reach_s"]) < 0.2
    assert ref["a_max"] <= 5.0 + 1e-12
    assert ref["settled"] < 0.01


def test_on_the_path_the_reference_changes_little():
    # Starting on a 30 m circle along it (the vehicle starts with no lateral acceleration, so the
    # lag drifts it out by about 7 cm before it settles): the error and its rate stay centimetres,
    # so does the reference, and the flight with it differs from the one without by a fraction
    # of the error itself; both settle to a few millimetres.
    path = CirclePath(30.0)
    runs = []
    for scale in (0.0, 0.6):
        # The reference alone is compared: the cost to go at the horizon (its own tests,
        # test_predictive_terminal.py) moves this steady state by a few millimetres.
        law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=5.0,
                                                        capture_tc_scale=scale, terminal_cost=False,
                                                        **SEARCH_FROM_3_M))
        res = simulate(path, law, VehicleState(30.0, 0.0, math.pi / 2, V), GuidanceParams(speed_m_s=V),
                       model=LagModel(0.3, 5.0), t_max_s=8.0)
        runs.append(np.hypot(res.x_m, res.y_m) - 30.0)
    plain, ref = runs
    assert np.max(np.abs(ref - plain)) < 0.1 * np.max(np.abs(plain))
    assert np.max(np.abs(ref)) == pytest.approx(np.max(np.abs(plain)), abs=1e-3)
    assert np.max(np.abs(ref[-100:])) < 0.005 and np.max(np.abs(plain[-100:])) < 0.005


def test_an_overshoot_is_weighed_only_beyond_the_path_and_only_off_it():
    # Two rollouts of three steps (dt 0.25 s, sqrt 0.5), three residuals to go. Reference from
    # d0 = 2 m: (2, 1, 0.5); the rows fly d = (2, 0.5, -0.5) and (2, 1.5, 1).
    sq = 0.5
    ref = np.array([2.0, 1.0, 0.5])
    d = np.array([[2.0, 0.5, -0.5], [2.0, 1.5, 1.0]])
    res = np.zeros((2, 9))
    res[:, 0:-3:2] = (d - ref) * sq
    res[:, 1:-3:2] = 0.3  # the acceleration residuals: never weighed
    res[:, -3:] = [0.1, 0.2, 0.3]  # the cost to go: never weighed
    out = weigh_overshoot(res, ref, sq, 3.0)
    # Only the first row's last step lies across the path from d0 = 2: (-0.5 - 0.5) * 0.5 * 3.
    expected = res.copy()
    expected[0, 4] = -1.5
    assert out == pytest.approx(expected, abs=1e-15)
    assert res[0, 4] == pytest.approx(-0.5)  # the input is left as it was
    # The squared cost grows by (3^2 - 1) times that step's square: 8 * 0.25.
    assert np.sum(out[0] ** 2) - np.sum(res[0] ** 2) == pytest.approx(8 * 0.25)
    # Weight 1, no reference, or a vehicle within SIDE_MIN_OFFSET_M of the path: unchanged.
    assert np.array_equal(weigh_overshoot(res, ref, sq, 1.0), res)
    assert np.array_equal(weigh_overshoot(res, None, sq, 3.0), res)
    near = ref * (0.9 * SIDE_MIN_OFFSET_M / 2.0)
    assert np.array_equal(weigh_overshoot(res, near, sq, 3.0), res)
    with pytest.raises(ValueError, match="overshoot_weight"):
        PredictiveParams(overshoot_weight=0.5)


def _join(lambda_s4: float, heading_deg: float, weight: float):
    path = LinePath(x0=-50.0, length_m=600.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=lambda_s4, lag_s=0.3, a_max_m_s2=5.0,
                                                    overshoot_weight=weight, **SEARCH_FROM_3_M))
    res = simulate(path, law, VehicleState(0.0, -10.0, math.radians(heading_deg), V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 5.0), t_max_s=14.0)
    d = res.y_m  # started 10 m right of the x axis: any d > 0 is a crossing
    i0 = int(np.flatnonzero(np.abs(d) <= 1.0)[0])
    return (float(np.max(d)), float(res.t_s[i0]), float(np.sqrt(np.mean(d[i0:] ** 2))),
            float(np.sqrt(np.mean(res.a_achieved_m_s2[i0:] ** 2))))


@pytest.mark.parametrize("lambda_s4, heading_deg", [(0.03, 90.0), (0.3, 45.0), (1.0, 90.0)])
def test_weighing_the_overshoot_lands_the_join_without_arriving_later(lambda_s4, heading_deg):
    # From 10 m right of a line, flying at it (0.3 s lag, 5 m/s^2). Weighed like the approach, the
    # plan crosses the line by 0.15-0.46 m to touch the 1 m band a little sooner; weighed 4 times
    # (from more than SIDE_MIN_OFFSET_M off), it crosses by a quarter to a half less (26 % at
    # lambda 0.03, where it was 38 % while a dropped plan waited a period before its refinement:
    # docs/benchmarks.md, "A plan that alternated far off the path"), touches the band no later
    # than 0.1 s after, and from there flies less acceleration for at most 5 % more error.
    over1, touch1, d1, a1 = _join(lambda_s4, heading_deg, 1.0)
    over4, touch4, d4, a4 = _join(lambda_s4, heading_deg, 4.0)
    assert over1 > 0.15
    assert over4 < 0.8 * over1
    assert touch4 <= touch1 + 0.1
    assert d4 <= 1.05 * d1
    assert a4 < a1


def test_the_overshoot_weight_fades_out_over_the_decade_below_its_full_lambda():
    # Full from OVERSHOOT_FULL_LAMBDA_S4 = 0.03 up, 1 a decade below, linear in log10 lambda
    # between: half a decade below, half the way from 4 to 1 (2.5); a quarter decade, 3.25.
    def w(lam: float, weight: float = 4.0) -> float:
        return PredictiveParams(lambda_s4=lam, overshoot_weight=weight).overshoot_weight_in_use()

    assert w(0.03) == 4.0 and w(1.0) == 4.0
    assert w(0.003) == 1.0 and w(0.001) == 1.0 and w(0.0) == 1.0
    assert w(0.03 * 10 ** -0.5) == pytest.approx(2.5, abs=1e-12)
    assert w(0.03 * 10 ** -0.25) == pytest.approx(3.25, abs=1e-12)
    assert w(0.03 * 10 ** -0.5, weight=2.0) == pytest.approx(1.5, abs=1e-12)


@pytest.mark.parametrize("lambda_s4, same", [(0.003, True), (0.03, False)])
def test_a_decade_below_the_full_lambda_the_join_flies_as_without_the_weight(lambda_s4, same):
    # The flights of _join with the weight 4 and 1: the same to the bit a decade below 0.03,
    # where the weight in use is 1; apart at 0.03, where it is 4 (the test above it).
    over4, touch4, d4, a4 = _join(lambda_s4, 90.0, 4.0)
    over1, touch1, d1, a1 = _join(lambda_s4, 90.0, 1.0)
    assert ((over4, touch4, d4, a4) == (over1, touch1, d1, a1)) is same


def _away_from_a_line(lambda_s4: float):
    """A held-out bench case (random scenario 1121, reduced to a line): 25.3 m to the left of a
    line heading 147.7 deg, 116 m along it, pointing 58 deg away from it (course -88.4 deg), at
    10.4 m/s with a 0.222 s lag, a 5 m/s^2 limit and a 2.5 m/s wind."""
    h = math.atan2(0.534, -0.845)
    path = LinePath(0.0, 0.0, h, 500.0)
    px, py = 116.0 * math.cos(h), 116.0 * math.sin(h)
    x0, y0 = px - 25.3 * math.sin(h), py + 25.3 * math.cos(h)  # 25.3 m to the left
    v = 10.378
    wind = (-2.448, -0.569)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=lambda_s4, lag_s=0.222, a_max_m_s2=5.0,
                                                    wind_x_m_s=wind[0], wind_y_m_s=wind[1]))
    res = simulate(path, law, VehicleState(x0, y0, -1.54213, v), GuidanceParams(speed_m_s=v, rate_hz=50.0),
                   model=LagModel(0.222, 5.0, wind_enu_m_s=wind), t_max_s=40.0, keep_outputs=True)
    # distance to the line (the vehicle stays beside it: 116 m from its start, 384 m from its end)
    d = np.abs(-(res.x_m - 0.0) * math.sin(h) + (res.y_m - 0.0) * math.cos(h))
    return res, d, v


@pytest.mark.parametrize("lambda_s4", [0.03, 0.3])
def test_pointing_away_the_law_turns_round_and_joins_the_path(lambda_s4):
    # Behind the beam the pursuit's goal gives a small command (sin(eta) near 0 at eta near 180
    # deg) and a 5 s plan cannot see the end of a turn round, so without the capture turn the
    # vehicle flew straight away at lambda 0.03 (2.3 km off after 240 s). With it, it turns at
    # the limit (radius V^2 / a_max = 21.5 m) and returns: at most the start distance plus the
    # turn's diameter (plus the lag's V tau), and on the path within 1 m by 20 s.
    res, d, v = _away_from_a_line(lambda_s4)
    assert d[0] == pytest.approx(25.3, abs=1e-6)
    assert np.max(d) <= 25.3 + 2.0 * v * v / 5.0 + v * 0.222
    assert np.min(d[res.t_s <= 20.0]) < 1.0
    assert np.max(np.abs(res.a_cmd_m_s2)) <= 5.0 + 1e-9
    # The turn round is at the limit, on one side, and costs no re-optimisation after the first
    # tick's (which found it).
    turning = [o for o in res.outputs if o.extra.get("capture_side")]
    assert len(turning) >= 50  # at least a second of it
    assert {o.extra["capture_side"] for o in turning} in ({1}, {-1})
    assert all(abs(o.a_cmd_m_s2) == pytest.approx(5.0) for o in turning)
    assert not any(o.reoptimised for o in turning[1:])


@pytest.mark.parametrize("offset_m", [0.01, -0.01, 0.0])
def test_started_on_the_path_facing_across_it_the_law_turns_the_short_way(offset_m):
    # A copter on the ground at the path start, facing 97 deg from the path's direction (an
    # eastward line, the copter pointing north-north-west): its goal lies ahead along the line,
    # behind the beam on the right; so the short turn is right (97 deg, not 263). A real
    # ArduCopter, a centimetre to the left of the line, turned left and went 15 m off.
    path = LinePath(-10.0, 0.0, 0.0, 500.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=2.5))
    res = simulate(path, law, VehicleState(0.0, offset_m, math.radians(97.0), V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 2.5), t_max_s=15.0, keep_outputs=True)
    assert res.a_cmd_m_s2[0] < 0.0  # right
    # a right turn of radius V^2 / a_max = 10 m from a 97 deg heading strays r (1 - cos 97 deg)
    # = 11.2 m beside the line, plus V tau = 1.5 m of lag; the long way round would be 2 r = 20 m
    assert np.max(np.abs(res.y_m)) < 11.2 + 1.5 + 0.5
    assert abs(res.y_m[-1]) < 0.5


@pytest.mark.parametrize("y0_m, heading_deg", [(-60.0, 0.0), (-60.0, 30.0), (-30.0, 0.0)])
def test_far_from_a_line_the_plan_turns_in_about_as_fast_as_the_limit_allows(y0_m, heading_deg):
    # Far from the path the pursuit aims sqrt(2) |d| ahead and its command 2 V^2 sin(eta) / L_eff
    # is a gentle turn; the plan has to turn the vehicle in. From 60 m its residuals are tens of
    # metres and a few centimetres of each correction, so the Gauss-Newton step was hundreds of
    # m/s^2: clipped to the limit element by element it pointed anywhere, no fraction of it lowered
    # the cost, and no plan was ever kept (reach 22.3 s here, from 60 m heading along the line).
    # The step is now scaled into the limit as a whole (its direction kept).
    # No law reaches the 1 m band sooner than a turn at the limit (radius R = V^2 / a_max) to
    # head straight at the line and the straight flight in: (pi/2 - h0) V / a_max + (|y0| - 1 -
    # R cos h0) / V (the turn from h0 to 90 deg gains R cos h0 towards the line); the lag (0.3 s)
    # adds a fraction of a second to it.
    path = LinePath(x0=-50.0, length_m=1000.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=5.0))
    h0 = math.radians(heading_deg)
    res = simulate(path, law, VehicleState(0.0, y0_m, h0, V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 5.0), t_max_s=30.0)
    r = V * V / 5.0
    fastest = (math.pi / 2 - h0) * V / 5.0 + (abs(y0_m) - 1.0 - r * math.cos(h0)) / V
    reach = float(res.t_s[np.flatnonzero(np.abs(res.y_m) <= 1.0)[0]])
    assert fastest < reach < fastest + 0.8
    assert np.max(res.y_m) < 0.3  # and it does not dive through the line
    assert np.max(np.abs(res.a_cmd_m_s2)) <= 5.0 + 1e-9


def test_a_gauss_newton_step_is_kept_far_from_the_path():
    # The first re-optimisation 60 m from a line, heading along it: the refined plan lowers the
    # rollout cost below the pursuit's own (no plan), and stays within the limit.
    path = LinePath(x0=-50.0, length_m=1000.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=5.0))
    state = VehicleState(0.0, -60.0, 0.0, V)
    law.step(0.0, state)
    assert np.any(law._plan != 0.0)
    assert np.max(np.abs(law._plan)) <= 5.0
    looks = np.array([law._look_m])
    with_plan = law.rollout(state, looks, law._plan[None, :], law._reference(state))
    without = law.rollout(state, looks, np.zeros((1, law._plan.size)), law._reference(state))
    assert np.sum(with_plan**2) < 0.98 * np.sum(without**2)


@pytest.mark.parametrize("speed_m_s", [0.5, 2.0])
def test_near_hover_facing_away_the_turn_round_is_the_pursuits_bound_at_a_3_m_look_ahead(speed_m_s):
    # A real PX4 copter at the start of its path, on it, just off hover: its velocity points
    # anywhere (here back along the path), so the goal is behind the beam. The turn round was at
    # the limit read from the autopilot (9.8 m/s^2, its tilt limit) whatever the speed: a second of
    # it at the start of a figure-eight doubled the flight's a_rms. It is now no sharper than the
    # pursuit's own bound at a 3 m look-ahead (HOVER_TURN_LOOK_M), 2 V^2 / 3 m, by hand: 0.17 and
    # 2.67 m/s^2. The look-ahead search itself goes down to 1.5 m; the turn does not follow it.
    path = LinePath(-10.0, 0.0, 0.0, 500.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.35, a_max_m_s2=9.8))
    out = law.step(0.0, VehicleState(0.0, 0.0, math.radians(175.0), speed_m_s))
    assert out.extra["capture_side"] != 0
    assert abs(out.a_cmd_m_s2) == pytest.approx(2.0 * speed_m_s**2 / 3.0, rel=1e-12)
    # at cruise speed the same turn is at the limit: 2 V^2 / 3 m = 64 m/s^2 at 9.8 m/s is above it
    fast = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.35, a_max_m_s2=9.8))
    assert abs(fast.step(0.0, VehicleState(0.0, 0.0, math.radians(175.0), 9.8)).a_cmd_m_s2) == pytest.approx(9.8)


def test_pointing_away_within_two_turn_radii_it_turns_onto_the_paths_direction():
    # 3 m right of an eastward line, pointing away from it and 10 deg back against its direction
    # (course -100 deg), 10 m/s, 5 m/s^2, 0.05 s lag: R = V^2 / a_max = 20 m. The closest point
    # lies behind on the right, but within 2 R the turn is the short way onto the path's
    # direction: left, 100 deg (to the right it is 260 deg, and a circle begun 3 m off, towards
    # the line, sweeps across it and runs east 20 m beyond). Turning left from -100 deg, the
    # vehicle comes round heading east at its farthest, y = -3 - R (1 + sin 10 deg), plus the
    # V tau sin 80 deg it flies before the lagged turn bites: -26.96 m. From there the approach
    # joins the line going east.
    path = LinePath(x0=-200.0, length_m=1000.0)
    v, tau, a_max = 10.0, 0.05, 5.0
    h = math.radians(-100.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=tau, a_max_m_s2=a_max))
    res = simulate(path, law, VehicleState(0.0, -3.0, h, v), GuidanceParams(speed_m_s=v, rate_hz=50.0),
                   model=LagModel(tau, a_max), t_max_s=25.0, keep_outputs=True)
    r = v * v / a_max
    y_far = -3.0 - r * (1.0 + math.sin(math.radians(10.0))) - v * tau * math.sin(math.radians(80.0))
    assert res.outputs[0].extra["capture_side"] == 1 and res.a_cmd_m_s2[0] == pytest.approx(a_max)  # left, at once
    farthest = int(np.argmin(res.y_m))
    assert res.y_m[farthest] == pytest.approx(y_far, abs=0.1)
    assert abs(math.sin(res.course_rad[farthest])) < 0.01 and math.cos(res.course_rad[farthest]) > 0.99  # east
    assert np.max(res.y_m) < 0.3  # it never crosses the line by more than the approach's join
    assert abs(res.y_m[-1]) < 0.05 and math.cos(res.course_rad[-1]) > 0.99  # on it, going east


@pytest.mark.parametrize("y0_m, radius_m, expected", [(-5.0, 3.0, 1), (-5.0, 2.4, -1), (-5.0, 0.0, -1)])
def test_within_two_turn_radii_a_new_capture_turns_the_short_way_onto_the_paths_direction(y0_m, radius_m, expected):
    # 5 m right of an eastward line, course -100 deg: the closest point (0, 0) lies behind on the
    # right (eta = 90 - (-100) = 190 deg, sin < 0), the pursuit's goal (10, 0) behind as well. The
    # path's direction, east, is 100 deg to the left and 260 deg to the right: left within
    # 2 R = 6 m, the closest point's side (right) beyond (2 R = 4.8 m) or with no radius given.
    from companion.guidance.capture import join_side, pursuit_capture_side
    from companion.guidance.path_frame import path_frame

    path = LinePath(x0=-50.0, length_m=500.0)
    state = VehicleState(0.0, y0_m, math.radians(-100.0), 5.0)
    frame = path_frame(path, state.x_m, state.y_m, None)
    assert frame.crosstrack_m == pytest.approx(y0_m)
    assert pursuit_capture_side(state, frame, 10.0, 0.0, 0, radius_m) == expected
    assert pursuit_capture_side(state, frame, 10.0, 0.0, -expected, radius_m) == -expected  # a side is kept
    assert join_side(math.radians(-100.0), 1.0, 0.0) == 1
    assert join_side(math.radians(-80.0), -1.0, 0.0) == -1  # the path going west: right, 100 deg


def test_near_the_path_at_hover_the_capture_turns_round_at_once():
    # A copter starting from hover on the path (20 cm right of it), its velocity noise pointing
    # away from it and 10 deg back against it at 0.5 m/s (the goal behind the beam: a capture):
    # "away" is noise there, so the turn round begins at once (at 2 V^2 / 3 m, 0.17 m/s^2)
    # instead of flying on along the noise. 1.2 m off (within two of that turn's 1.5 m radii) it
    # begins at once too, the short way onto the path's direction (left), which runs beside the
    # path instead of across it.
    path = LinePath(x0=-50.0, length_m=500.0)
    off_law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=2.5))
    off = off_law.step(0.0, VehicleState(0.0, -1.2, math.radians(-100.0), 0.5))
    assert off.extra["capture_side"] == 1
    assert off.a_cmd_m_s2 == pytest.approx(2.0 * 0.5 ** 2 / 3.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.03, lag_s=0.3, a_max_m_s2=2.5))
    out = law.step(0.0, VehicleState(0.0, -0.2, math.radians(-100.0), 0.5))
    assert out.extra["capture_side"] != 0
    assert abs(out.a_cmd_m_s2) == pytest.approx(2.0 * 0.5 ** 2 / 3.0)
