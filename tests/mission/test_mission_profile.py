"""Missions with altitude and speed along the path: loading, knots at the right arc lengths."""

from __future__ import annotations

import math

import pytest

from companion.errors import MissionError
from companion.mission import parse_mission


def test_a_flat_constant_speed_mission_has_no_profile():
    m = parse_mission("name: flat\nspeed_m_s: 5\naltitude_m: 12\n"
                      "path: {type: waypoints, points_m: [[0, 0], [100, 0]]}\n")
    assert m.profile is None and m.altitude_m == 12.0 and m.speed_m_s == 5.0


def test_waypoint_heights_are_reached_on_a_straight_line_at_their_arc_lengths():
    # Collinear waypoints: the spline is the straight line, waypoint i at s = 100 i.
    # Slopes 0.05 then 0.1 (0.25 and 0.5 m/s at 5 m/s): w = 25 * 0.05 / 1 = 1.25 m, so the
    # corner at s = 100 moves by dg w / 8 = 0.0078 m; the far ends are exact.
    m = parse_mission("name: ramp\nspeed_m_s: 5\naltitude_m: [10, 15, 25]\n"
                      "path: {type: waypoints, points_m: [[0, 0], [100, 0], [200, 0]]}\n")
    p = m.profile
    assert m.altitude_m == pytest.approx(10.0)
    assert p.altitude_m(0.0) == pytest.approx(10.0)
    assert p.altitude_m(50.0) == pytest.approx(12.5, abs=1e-6)
    assert p.altitude_m(100.0) == pytest.approx(15.0, abs=0.01)
    assert p.altitude_m(150.0) == pytest.approx(20.0, abs=1e-6)
    assert p.altitude_m(200.0) == pytest.approx(25.0)
    assert p.climb_m_s(50.0) == pytest.approx(5.0 * 0.05, abs=1e-6)   # V dh/ds
    assert p.climb_m_s(150.0) == pytest.approx(5.0 * 0.10, abs=1e-6)
    assert not m.warnings


def test_speeds_per_waypoint_change_where_the_waypoint_is():
    m = parse_mission("name: fast\nspeed_m_s: [4, 6, 6]\n"
                      "path: {type: waypoints, points_m: [[0, 0], [100, 0], [200, 0]]}\n")
    p = m.profile
    assert m.speed_m_s == 4.0 and m.guidance.speed_m_s == 4.0
    assert p.speed_m_s(99.0) == pytest.approx(4.0)
    # 1 m/s^2 from s = 100: V^2 = 16 + 2 d, reaching 36 after 10 m.
    assert p.speed_m_s(105.0) == pytest.approx(math.sqrt(26.0), abs=1e-3)
    assert p.speed_m_s(111.0) == pytest.approx(6.0)


def test_segment_ends_carry_the_heights_and_segments_their_speeds():
    text = """\
name: seg
speed_m_s: [5, 3]
altitude_m: [10, 12, 20]
path:
  type: segments
  start_m: [0, 0]
  start_heading_deg: 0
  segments:
    - {type: line, length_m: 100}
    - {type: arc, radius_m: 50, turn_deg: 90}
"""
    m = parse_mission(text)
    p = m.profile
    arc = 50 * math.pi / 2
    assert m.path.length_m == pytest.approx(100 + arc, abs=1e-5)
    assert p.altitude_m(50.0) == pytest.approx(11.0, abs=1e-6)
    assert p.altitude_m(100.0 + arc / 2) == pytest.approx(16.0, abs=1e-3)
    assert p.end_altitude_m == pytest.approx(20.0)
    assert p.speed_m_s(90.0) == pytest.approx(5.0)
    assert p.speed_m_s(100.0 + 8.5) == pytest.approx(3.0)  # (25 - 9) / 2 = 8 m to slow down


def test_an_expression_of_arc_length_for_a_function_path():
    m = parse_mission('name: f\nspeed_m_s: "4 + s/100"\naltitude_m: "10 + 0.02*s"\n'
                      'path: {type: function, y_of_x: "0*x", x_range_m: [0, 200]}\n')
    p = m.profile
    assert p.altitude_m(100.0) == pytest.approx(12.0, abs=1e-6)
    # The speed rises by 0.01 m/s per metre: V dV/ds <= 6 * 0.01 < 1 m/s^2, followed exactly
    # (one grid node late at most).
    assert p.speed_m_s(100.0) == pytest.approx(5.0, abs=1e-3)


def test_a_climb_the_limits_cannot_fly_is_warned_about_at_its_waypoint():
    m = parse_mission("name: steep\nspeed_m_s: 10\naltitude_m: [10, 60, 60]\n"
                      "path: {type: waypoints, points_m: [[0, 0], [50, 0], [100, 0]]}\n")
    assert any("path.points_m[1]: warning: the altitude profile passes at" in w for w in m.warnings)
    assert m.profile.climb_table_m_s().max() <= 2.0


def test_problems_are_one_line_each_and_all_reported():
    text = ("name: bad\nspeed_m_s: [5, 6]\naltitude_m: [10, 20]\nvertical: {sink_max_m_s: -1}\n"
            "path: {type: waypoints, points_m: [[0, 0], [50, 0], [100, 0]]}\n")
    with pytest.raises(MissionError) as err:
        parse_mission(text, "m.yaml")
    lines = str(err.value).splitlines()
    assert "m.yaml: vertical.sink_max_m_s: expected a finite number > 0 and <= 50, got -1" in lines
    assert len(lines) == 1  # the list lengths are checked once the limits are usable


def test_closed_waypoint_loops_wrap_their_heights():
    m = parse_mission("name: loop\nspeed_m_s: 5\naltitude_m: [10, 20, 20, 10]\n"
                      "path: {type: waypoints, closed: true, points_m: [[0, 0], [100, 0], [100, 100], [0, 100]]}\n")
    p = m.profile
    assert p.altitude_m(0.0) == pytest.approx(p.altitude_m(p.length_m))
    assert p.climb_table_m_s().max() <= 2.0
