"""Lines and arcs blended to C^2, and waypoints with rounded corners, against hand geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.errors import MissionError
from companion.mission import parse_mission
from companion.mission.segments import filleted_waypoint_path, segments_path

R, L, B = 30.0, 100.0, 5.0
RACETRACK = [("line", L / 2, 0.0), ("arc", R, math.pi), ("line", L, 0.0), ("arc", R, math.pi),
             ("line", L / 2, 0.0)]


def racetrack(blend=B):
    return segments_path((0.0, 0.0), 0.0, RACETRACK, blend, closed=True)


def test_racetrack_length_is_two_straights_and_a_circle():
    assert racetrack().length_m == pytest.approx(2 * L + 2 * math.pi * R, abs=1e-3)


def test_racetrack_follows_its_lines_and_arcs_away_from_the_ramps():
    p = racetrack()
    # Middle of the first arc: centre (50, 30), so the point (80, 30) heading north, curvature 1/R.
    s = L / 2 + math.pi * R / 2
    shift = B * B / (24 * R)  # the lateral shift a curvature ramp causes
    assert p.point(s) == pytest.approx((L / 2 + R, R), abs=2 * shift)
    assert p.heading_rad(s) == pytest.approx(math.pi / 2, abs=1e-3)
    assert p.curvature(s) == pytest.approx(1 / R, rel=1e-3)
    # Middle of the northern straight: y = 2R, heading west, straight.
    s = L / 2 + math.pi * R + L / 2
    assert p.point(s)[1] == pytest.approx(2 * R, abs=2 * shift)
    assert p.curvature(s) == pytest.approx(0.0, abs=1e-4)
    assert abs(math.remainder(p.heading_rad(s) - math.pi, 2 * math.pi)) < 1e-3


def test_curvature_ramps_linearly_over_the_blend_instead_of_jumping():
    p = racetrack()
    joint = L / 2  # line -> arc
    ks = [p.curvature(joint + d) for d in (-B / 2 - 0.5, -B / 4, 0.0, B / 4, B / 2 + 0.5)]
    assert ks == pytest.approx([0.0, 0.25 / R, 0.5 / R, 0.75 / R, 1 / R], abs=2e-4)
    # C^2: the curvature table has no step bigger than its ramp slope allows.
    k = p.k_table_1_m
    h = p.length_m / (k.size - 1)
    assert np.max(np.abs(np.diff(k))) <= 2.0 * h / (R * B)  # ramp slope 1/(R B), kinks smoothed


def test_without_blend_steps_the_curvature_jumps():
    p = segments_path((0.0, 0.0), 0.0, RACETRACK, 0.0, closed=True)
    k = np.asarray(p.k_table_1_m)
    assert np.max(np.abs(np.diff(k))) > 0.5 / R


def test_open_segments_end_where_lines_and_arcs_say():
    # Line 40 east, quarter circle left R 20 (centre (40, 20)), then 30 north: ends at (60, 50).
    p = segments_path((0.0, 0.0), 0.0, [("line", 40, 0), ("arc", 20, math.pi / 2), ("line", 30, 0)],
                      2.0, closed=False)
    assert p.end_xy_m == pytest.approx((60.0, 50.0), abs=2 * 4 / (24 * 20))
    assert p.end_heading_rad == pytest.approx(math.pi / 2, abs=1e-6)


def test_a_loop_that_does_not_close_is_refused():
    with pytest.raises(ValueError, match="gap of"):
        segments_path((0, 0), 0.0, [("line", 50, 0), ("arc", 20, math.pi), ("line", 40, 0),
                                    ("arc", 20, math.pi)], 2.0, closed=True)


def test_square_with_rounded_corners_cuts_each_corner_by_r_sqrt2_minus_1():
    r = 10.0
    p = filleted_waypoint_path([[0, 0], [60, 0], [60, 60], [0, 60]], r, closed=True)
    # Straight parts 60 - 2 r each, four quarter circles: 4 (60 - 2r) + 2 pi r.
    assert p.length_m == pytest.approx(4 * (60 - 2 * r) + 2 * math.pi * r, abs=1e-3)
    s, x, y = p.sample(20000)
    for cx, cy in [(0, 0), (60, 0), (60, 60), (0, 60)]:
        dist = np.min(np.hypot(x - cx, y - cy))
        assert dist == pytest.approx(r * (math.sqrt(2) - 1), abs=0.1)


def test_open_filleted_path_starts_and_ends_on_its_end_waypoints():
    pts = [[0, 0], [100, 0], [100, 40], [0, 40], [0, 80]]
    p = filleted_waypoint_path(pts, 12.0, closed=False)
    assert p.start_xy_m == pytest.approx((0.0, 0.0), abs=1e-9)
    assert p.end_xy_m == pytest.approx((0.0, 80.0), abs=1e-6)
    # Mid-leg points stay on the straight legs.
    s = p.project(50.0, 0.2)
    assert p.point(s)[1] == pytest.approx(0.0, abs=0.1)


def test_segments_mission_in_ned_turns_clockwise_positive():
    text = """\
name: ned-hook
frame: local_ned
speed_m_s: 4
path:
  type: segments
  start_heading_deg: 0      # north
  blend_m: 1
  segments:
    - {type: line, length_m: 30}
    - {type: arc, radius_m: 20, turn_deg: 90}   # clockwise in NED: a right turn, to the east
    - {type: line, length_m: 10}
"""
    m = parse_mission(text, "hook.yaml")
    # ENU: north 30, right turn to the east about (20, 30): ends at (20 + 10, 50).
    assert m.path.end_xy_m == pytest.approx((30.0, 50.0), abs=0.05)
    assert m.path.end_heading_rad == pytest.approx(0.0, abs=1e-6)
    assert m.path.curvature(40.0) < 0  # a right turn has negative ENU curvature


def test_reversal_corner_is_refused():
    text = """\
name: reversal
speed_m_s: 4
path: {type: waypoints, corner_radius_m: 5, points_m: [[0, 0], [50, 0], [10, 0]]}
"""
    with pytest.raises(MissionError, match=r"path.points_m\[1\]: expected a corner of less than 180 deg"):
        parse_mission(text, "rev.yaml")
