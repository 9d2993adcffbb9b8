"""The pursuit core's curvature feed-forward (``pursuit_command`` with ``curvature_ff``), checked
against hand geometry: exact on an arc, no early turn-in on a straight before a bend, and the
osculating-circle cross-track error of the rollouts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import parametric_path
from companion.guidance.predictive import _nearest, _Window, pursuit_command
from companion.mission.segments import segments_path

V = 5.0


def one(win, x, y, course, look, ff, lead=0.0):
    a, *_ = pursuit_command(win, np.array([x]), np.array([y]), np.array([course]), np.array([V]),
                            np.array([look]), math.inf, ff, lead)
    return float(a[0])


def circle(radius_m):
    return parametric_path(lambda u: radius_m * np.cos(u), lambda u: radius_m * np.sin(u),
                           (0.0, 2.0 * math.pi), closed=True)


@pytest.mark.parametrize("ff", [0.0, 1.0])
def test_on_a_circle_both_forms_command_v2_over_r(ff):
    # On the circle with the tangent course, the pursuit's chord geometry gives exactly V^2/R
    # and the feed-forward replaces it by the same V^2 kappa: 25/20 = 1.25 m/s^2 (left).
    path = circle(20.0)
    win = _Window(path, 0.0, 60.0)
    assert one(win, 20.0, 0.0, math.pi / 2, 8.0, ff) == pytest.approx(1.25, rel=2e-3)


@pytest.mark.parametrize("look_m", [3.0, 8.0])
def test_on_a_circle_between_samples_the_command_is_still_v2_over_r(look_m):
    # The window samples the path every metre; a vehicle on a 30 m circle, tangent, anywhere
    # between two samples, still has V^2/R = 25/30 m/s^2 to fly (the chord geometry is exact on
    # the arc). With the nearest sample's tangent line taken for P's tangent and place, the
    # feed-forward term was off by 2 V^2 kappa along / L: 0.28 m/s^2 at 0.5 m along and L 3 m, a
    # sawtooth every sample passed (P on the tangent line alone, kappa along^2 / 2 off the arc: 0.015).
    path = circle(30.0)
    win = _Window(path, 0.0, 60.0)
    for s_m in np.linspace(0.0, 1.0, 11):
        u = s_m / 30.0
        cmd = one(win, 30.0 * math.cos(u), 30.0 * math.sin(u), u + math.pi / 2, look_m, 1.0)
        assert cmd == pytest.approx(V * V / 30.0, abs=1e-3), s_m


def test_feedforward_removes_the_early_turn_in_before_a_bend():
    # 40 m straight east, then a 20 m radius left arc (a 3 m curvature ramp around s = 40 m).
    path = segments_path((0.0, 0.0), 0.0, [("line", 40.0, 0.0), ("arc", 20.0, math.pi / 2)], 3.0,
                         closed=False)
    win = _Window(path, 25.0, 40.0)
    # On the straight at x = 30 m, on the line, course east, look-ahead 12 m: the goal lies on
    # the arc, so plain pursuit already turns left; with the feed-forward the command is
    # kappa(P) V^2 = 0.
    plain = one(win, 30.0, 0.0, 0.0, 12.0, 0.0)
    assert plain > 0.02
    assert one(win, 30.0, 0.0, 0.0, 12.0, 1.0) == pytest.approx(0.0, abs=1e-9)
    # Led by tau = 2 s (10 m at 5 m/s) the curvature is read at s = 40 m, inside the ramp:
    # positive and below the arc's 1/20 1/m.
    led = one(win, 30.0, 0.0, 0.0, 12.0, 1.0, lead=2.0)
    assert 0.0 < led < V * V / 20.0


def test_feedforward_leaves_the_feedback_on_a_straight_alone():
    # Far from any bend the path curvature and the implied one are both 0: same command.
    path = segments_path((0.0, 0.0), 0.0, [("line", 100.0, 0.0)], 3.0, closed=False)
    win = _Window(path, 10.0, 40.0)
    assert one(win, 12.0, 2.0, 0.1, 8.0, 1.0) == pytest.approx(one(win, 12.0, 2.0, 0.1, 8.0, 0.0), abs=1e-9)


def test_rollout_crosstrack_is_the_distance_to_the_circle_not_to_the_sample_tangent():
    # R = 30 m circle sampled every 1 m; a point on the circle half way between two samples has
    # tangent-line offset -R (1 - cos(0.5/R)) ~ -4.2 mm; the corrected error is ~0 (to 1e-5 m).
    r = 30.0
    path = circle(r)
    win = _Window(path, 10.0, 10.0)
    s = 10.0 + 0.5  # half way between window samples at s = 10 and 11 m
    x, y = r * math.cos(s / r), r * math.sin(s / r)
    _, d, _ = _nearest(win, np.array([x]), np.array([y]))
    assert r * (1 - math.cos(0.5 / r)) == pytest.approx(0.0042, abs=1e-4)
    assert abs(float(d[0])) < 1e-5
