"""Reference paths checked against closed-form geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import function_path, parametric_path, waypoint_path


def sine_y(x):
    return 10 * np.sin(0.078 * x) + 20 * np.cos(0.082 * x)


def sine_dy(x):
    return 10 * 0.078 * np.cos(0.078 * x) - 20 * 0.082 * np.sin(0.082 * x)


def sine_ddy(x):
    return -10 * 0.078**2 * np.sin(0.078 * x) - 20 * 0.082**2 * np.cos(0.082 * x)


@pytest.fixture(scope="module")
def sine():
    return function_path(sine_y, (-15.0, 300.0))


@pytest.fixture(scope="module")
def circle():
    return parametric_path(lambda u: 20 * np.cos(u), lambda u: 20 * np.sin(u), (0.0, 2 * np.pi), closed=True)


def test_sine_curvature_matches_the_closed_form_of_a_graph(sine):
    for x in np.linspace(-15, 300, 37):
        s = sine.project(float(x), float(sine_y(x)))
        k_closed = sine_ddy(x) / (1 + sine_dy(x) ** 2) ** 1.5
        assert sine.curvature(s) == pytest.approx(k_closed, abs=1e-5)
        assert sine.heading_rad(s) == pytest.approx(math.atan(sine_dy(x)), abs=1e-7)


def test_sine_length_matches_quadrature_of_the_arc_length_integral(sine):
    x = np.linspace(-15, 300, 2_000_001)
    integrand = np.sqrt(1 + sine_dy(x) ** 2)
    length = float(np.sum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(x)))
    assert sine.length_m == pytest.approx(length, rel=1e-8)
    assert sine.start_xy_m == pytest.approx((-15.0, float(sine_y(-15.0))), abs=1e-9)


def test_arc_length_parameter_has_unit_speed(sine):
    s = np.linspace(0, sine.length_m, 5001)
    x, y = sine.point_array(s)
    chord = np.hypot(np.diff(x), np.diff(y))
    # A chord across an arc ds of curvature k is shorter than ds by the factor 1 - k^2 ds^2 / 24.
    ds = np.diff(s)
    k_mid = sine.curvature_array(0.5 * (s[1:] + s[:-1]))
    assert np.allclose(chord / ds, 1 - k_mid**2 * ds**2 / 24, rtol=0, atol=2e-8)


def test_circle_is_a_circle_anticlockwise_with_curvature_one_over_radius(circle):
    assert circle.length_m == pytest.approx(40 * math.pi, rel=1e-9)
    for s in np.linspace(0, 300, 41):  # beyond one lap: wraps
        angle = s / 20.0
        assert circle.point(s) == pytest.approx((20 * math.cos(angle), 20 * math.sin(angle)), abs=1e-7)
        assert circle.curvature(s) == pytest.approx(0.05, abs=1e-7)
        tx, ty = circle.tangent(s)
        assert (tx, ty) == pytest.approx((-math.sin(angle), math.cos(angle)), abs=1e-7)


def test_clockwise_circle_has_negative_curvature():
    cw = parametric_path(lambda u: 15 * np.cos(-u), lambda u: 15 * np.sin(-u), (0.0, 2 * np.pi), closed=True)
    assert cw.curvature(3.0) == pytest.approx(-1 / 15, abs=1e-7)


def test_lookahead_on_a_circle_is_the_chord_of_length_l1_from_the_centre_offset(circle):
    # Vehicle on the circle at angle 0: the look-ahead point at chord L1 subtends 2 asin(L1 / 2R).
    s = circle.lookahead(20.0, 0.0, 10.0, 0.0)
    assert s == pytest.approx(20 * 2 * math.asin(10 / 40), abs=1e-6)
    # Vehicle at the centre: every point is at distance 20 > L1, so no look-ahead point exists.
    assert circle.lookahead(0.0, 0.0, 10.0, 0.0) is None
    # A look-ahead past the seam of the loop continues onto the next lap.
    s_seam = circle.lookahead(20.0, -1e-9, 10.0, circle.length_m - 1e-9)
    x, y = circle.point(s_seam)
    assert math.hypot(x - 20.0, y) == pytest.approx(10.0, abs=1e-6)
    assert y > 0


def test_lookahead_on_a_line_is_pythagoras():
    line = waypoint_path([(0.0, 0.0), (100.0, 0.0)])
    # Vehicle 6 m left of the line at x = 30: the L1 = 10 circle cuts it 8 m ahead.
    s = line.lookahead(30.0, 6.0, 10.0, line.project(30.0, 6.0))
    assert s == pytest.approx(38.0, abs=1e-6)
    # Near the end the path leaves the circle nowhere: None.
    assert line.lookahead(95.0, 0.0, 10.0, 95.0) is None
    # Too far from the line: the circle never reaches it.
    assert line.lookahead(30.0, 11.0, 10.0, 30.0) is None


def test_projection_is_the_foot_of_the_perpendicular_and_crosstrack_is_signed_left_positive():
    line = waypoint_path([(0.0, 0.0), (10.0, 10.0)])
    s = line.project(2.0, 6.0)
    assert s == pytest.approx(4 * math.sqrt(2), abs=1e-7)
    assert line.crosstrack_m(2.0, 6.0, s) == pytest.approx(2 * math.sqrt(2), abs=1e-7)
    s = line.project(6.0, 2.0)
    assert line.crosstrack_m(6.0, 2.0, s) == pytest.approx(-2 * math.sqrt(2), abs=1e-7)


def test_projection_with_a_hint_stays_on_its_branch_of_a_hairpin():
    # Two parallel legs 4 m apart joined by a half circle: a point between the legs, nearer the
    # return leg, projects onto the outbound leg when the hint says we are on it.
    pts = [(x, 0.0) for x in np.linspace(0, 40, 9)] + [(42.0, 2.0)] + [(x, 4.0) for x in np.linspace(40, 0, 9)]
    hairpin = waypoint_path(pts)
    s_out = hairpin.project(20.0, 0.0)
    assert hairpin.point(s_out)[1] == pytest.approx(0.0, abs=0.05)
    s_hinted = hairpin.project(20.0, 2.3, s_hint=s_out)
    assert hairpin.point(s_hinted)[1] == pytest.approx(0.0, abs=0.05)
    # Without a hint an open path is followed from its start: the first leg, although the
    # return leg is nearer (1.7 m against 2.3 m).
    s_first = hairpin.project(20.0, 2.3)
    assert hairpin.point(s_first) == pytest.approx((20.0, 0.0), abs=0.05)


def test_first_projection_of_an_open_path_is_the_first_local_minimum_from_its_start():
    # A U: out along y = 0 to x = 100, a half circle of radius 5, back along y = 10. Without a
    # hint the distance from s = 0 falls to the foot on the first leg, then rises: that foot,
    # when it is within 2 d_min + 2 m of the nearest point's distance d_min.
    out = [(x, 0.0) for x in np.linspace(0.0, 100.0, 21)]
    turn = [(100.0 + 5.0 * math.sin(a), 5.0 - 5.0 * math.cos(a)) for a in np.linspace(0.2, math.pi - 0.2, 7)]
    back = [(x, 10.0) for x in np.linspace(100.0, 0.0, 21)]
    u = waypoint_path(out + turn + back)
    s = u.project(50.0, 6.0)  # 6 m from the first leg, 4 m from the return leg: 6 <= 2 * 4 + 2
    assert s == pytest.approx(50.0, abs=1e-6)
    assert u.point(s) == pytest.approx((50.0, 0.0), abs=1e-6)
    # 8.5 m from the first leg, 1.5 m from the return leg: 8.5 > 2 * 1.5 + 2, the return leg.
    assert u.point(u.project(50.0, 8.5)) == pytest.approx((50.0, 10.0), abs=1e-6)
    # Behind the start, the distance only rises: s = 0.
    assert u.project(-20.0, 3.0) == 0.0
    # With a hint on the return leg, the return leg.
    assert u.point(u.project(50.0, 6.0, s_hint=u.length_m - 50.0))[1] == pytest.approx(10.0, abs=1e-6)
    # A closed path keeps the global search: the same U closed by its left end.
    loop = waypoint_path(out[:-1] + turn + back[:-1] + [(-5.0 * math.sin(a), 5.0 + 5.0 * math.cos(a))
                                                          for a in np.linspace(0.2, math.pi - 0.2, 7)],
                         closed=True)
    assert loop.point(loop.project(50.0, 6.0))[1] == pytest.approx(10.0, abs=0.05)


def test_waypoint_spline_passes_through_its_points_and_is_c2():
    pts = [(0, 0), (10, 0), (20, 10), (30, 10), (40, 0)]
    path = waypoint_path(pts)
    for x, y in pts:
        s = path.project(float(x), float(y))
        assert math.hypot(*(np.subtract(path.point(s), (x, y)))) < 1e-4
    s = np.linspace(0, path.length_m, 20001)
    k = path.curvature_array(s)
    assert np.max(np.abs(np.diff(k))) < 1e-3  # no curvature jumps


def test_closed_waypoint_loop_wraps_with_continuous_heading():
    loop = waypoint_path([(0, 0), (30, 0), (30, 20), (0, 20)], closed=True)
    assert loop.closed
    before = loop.tangent(loop.length_m - 1e-4)
    after = loop.tangent(1e-4)
    assert before == pytest.approx(after, abs=1e-3)
    assert loop.point(loop.length_m + 3.0) == pytest.approx(loop.point(3.0), abs=1e-9)


def test_bad_inputs_raise_value_errors_naming_the_field():
    with pytest.raises(ValueError, match="x_range_m"):
        function_path(np.sin, (5.0, 1.0))
    with pytest.raises(ValueError, match="y_of_x: the curve is not finite"):
        function_path(lambda x: np.where(x > 0.5, np.inf, x), (-1.0, 1.0))
    with pytest.raises(ValueError, match="coincide"):
        waypoint_path([(0, 0), (0, 0), (1, 1)])
    with pytest.raises(ValueError, match="closed"):
        parametric_path(np.cos, np.sin, (0.0, 3.0), closed=True)


def test_largest_curvature_over_an_interval_sees_the_arc_and_wraps_on_a_closed_racetrack():
    from companion.mission import parse_mission
    from companion.replay.synthetic import RACETRACK_MISSION

    # Two 120 m straights and two R = 40 m half circles, joined by 5 m curvature blends; the
    # path starts at the start of the first straight, in the blend from the last arc.
    track = parse_mission(RACETRACK_MISSION, "<racetrack>").path
    assert track.max_abs_curvature(20.0, 100.0) < 1e-9  # inside the first straight
    assert track.max_abs_curvature(20.0, 140.0) == pytest.approx(1 / 40.0, rel=1e-3)  # into the arc
    assert track.max_abs_curvature(140.0, 20.0) == pytest.approx(1 / 40.0, rel=1e-3)  # either order
    across = track.max_abs_curvature(track.length_m - 5.0, track.length_m + 20.0)  # across s = 0
    assert 1e-3 < across <= 1 / 40.0 + 1e-6
    assert track.max_abs_curvature(0.0, 3.0 * track.length_m) == pytest.approx(1 / 40.0, rel=1e-3)


def test_largest_curvature_on_a_circle_of_radius_20_is_one_twentieth(circle):
    assert circle.max_abs_curvature(0.5, 2.0) == pytest.approx(1.0 / 20.0, rel=1e-6)
    assert circle.max_abs_curvature(-10.0, 1e6) == pytest.approx(1.0 / 20.0, rel=1e-6)  # a whole lap
    line = waypoint_path([(0.0, 0.0), (100.0, 0.0)])
    assert line.max_abs_curvature(-5.0, 200.0) < 1e-9  # open path: clamped to its ends
