"""Loading the mission shapes of the guidance issue and the shared SITL data."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from companion.errors import MissionError
from companion.mission import load_mission, parse_mission

SHARED_SINE = Path("/work/shared/data/ardupilot-copter-sitl-sine.yaml")

PAPER_SINE = """\
name: paper-sine
frame: local_enu
speed_m_s: 5.0
path:
  type: function
  y_of_x: "10*sin(0.078*x) + 20*cos(0.082*x)"
  x_range_m: [-15, 300]
guidance: {l1_m: 10.0, method: corrector, rate_hz: 50}
midcourse: {circle_radius_m: 10.0}
start: {x_m: -15.0, y_m: 0.0, heading_deg: 39.118}
"""


def test_paper_sine_loads_with_its_start_and_guidance():
    m = parse_mission(PAPER_SINE, "paper.yaml")
    assert m.name == "paper-sine"
    assert m.speed_m_s == 5.0 and m.guidance.speed_m_s == 5.0
    assert m.guidance.l1_m == 10.0 and m.guidance.method == "corrector" and m.guidance.rate_hz == 50
    assert m.guidance.circle_radius_m == 10.0
    assert m.start.x_m == -15.0 and m.start.y_m == 0.0
    assert math.isclose(m.start.heading_rad, math.radians(39.118))
    assert m.on_finish == "hold" and m.source_text == PAPER_SINE
    # The path starts at (-15, f(-15)) with heading atan(f'(-15)), by hand.
    x0 = -15.0
    f = 10 * math.sin(0.078 * x0) + 20 * math.cos(0.082 * x0)
    df = 10 * 0.078 * math.cos(0.078 * x0) - 20 * 0.082 * math.sin(0.082 * x0)
    assert m.path.start_xy_m == pytest.approx((x0, f), abs=1e-9)
    assert m.path.start_heading_rad == pytest.approx(math.atan(df), abs=1e-6)


# A copy of /work/shared/data/ardupilot-copter-sitl-sine.yaml, so the check runs on any machine.
SITL_SINE = """\
name: ardupilot-copter-sitl-sine
frame: local_enu
speed_m_s: 4.0
altitude_m: 10.0
path:
  type: parametric
  x_of_s: "8*sin(0.08*s)"
  y_of_s: "s"
  s_range: [0, 110]
guidance: {l1_m: 10.0, method: fixed_l1, rate_hz: 50}
"""


@pytest.mark.parametrize("source", ["inline", "shared"])
def test_shared_sitl_parametric_mission_loads(source):
    if source == "shared":
        if not SHARED_SINE.exists():
            pytest.skip("shared SITL data not on this machine (the inline copy is checked)")
        m = load_mission(SHARED_SINE)
    else:
        m = parse_mission(SITL_SINE, "sitl.yaml")
    assert m.guidance.method == "fixed_l1" and m.speed_m_s == 4.0 and m.altitude_m == 10.0
    # x = 8 sin(0.08 y), y in [0, 110]: starts at the origin heading atan2(1, 0.64).
    assert m.path.start_xy_m == pytest.approx((0.0, 0.0), abs=1e-9)
    assert m.path.start_heading_rad == pytest.approx(math.atan2(1.0, 8 * 0.08), abs=1e-6)
    assert m.path.end_xy_m == pytest.approx((8 * math.sin(8.8), 110.0), abs=1e-6)


def test_waypoints_lie_on_the_loaded_path():
    text = """\
name: wp
speed_m_s: 3
path: {type: waypoints, points_m: [[0, 0], [20, 5], [40, 0], [60, 10]]}
"""
    m = parse_mission(text, "wp.yaml")
    for x, y in [(0, 0), (20, 5), (40, 0), (60, 10)]:
        s = m.path.project(x, y)
        px, py = m.path.point(s)
        assert math.hypot(px - x, py - y) < 1e-3


def test_local_ned_waypoints_swap_axes_into_enu():
    text = """\
name: ned
frame: local_ned
speed_m_s: 3
path: {type: waypoints, points_m: [[0, 0], [30, 0]]}
start: {x_m: 0, y_m: 5, heading_deg: 90}
"""
    m = parse_mission(text, "ned.yaml")
    # 30 m north is ENU (0, 30); NED yaw 90 deg (east) is ENU heading 0.
    assert m.path.end_xy_m == pytest.approx((0.0, 30.0), abs=1e-9)
    assert m.path.start_heading_rad == pytest.approx(math.pi / 2, abs=1e-9)
    assert (m.start.x_m, m.start.y_m) == (5.0, 0.0)
    assert m.start.heading_rad == pytest.approx(0.0, abs=1e-12)


def test_every_problem_is_reported_at_once():
    text = """\
name: many
speed_m_s: -1
path: {type: function, y_of_x: "foo(x)", x_range_m: [5, 1]}
guidance: {l1: 10}
"""
    with pytest.raises(MissionError) as info:
        parse_mission(text, "many.yaml")
    lines = str(info.value).splitlines()
    assert any(line.startswith("many.yaml: speed_m_s: expected") for line in lines)
    assert any(line.startswith("many.yaml: path.y_of_x: expected a function") for line in lines)
    assert any(line.startswith("many.yaml: path.x_range_m: expected") for line in lines)
    assert any(line.startswith("many.yaml: guidance.l1: unknown key") for line in lines)
    assert len(lines) == 4


def test_local_ned_function_gives_east_as_a_function_of_north():
    text = """\
name: ned-line
frame: local_ned
speed_m_s: 3
path: {type: function, y_of_x: "0.5*x", x_range_m: [0, 40]}
"""
    m = parse_mission(text, "ned.yaml")
    # east = 0.5 north: in ENU the line x = 0.5 y, from (0, 0) to (20, 40), heading atan2(1, 0.5).
    assert m.path.end_xy_m == pytest.approx((20.0, 40.0), abs=1e-9)
    assert m.path.start_heading_rad == pytest.approx(math.atan2(1.0, 0.5), abs=1e-9)
    assert m.path.length_m == pytest.approx(math.hypot(20.0, 40.0), abs=1e-6)


def test_geodetic_waypoints_in_degrees_match_points_in_metres():
    from companion.geometry.geodetic import enu_from_geodetic

    origin = (47.3977419, 8.5455939, 488.0)
    deg = [(47.3980, 8.5460), (47.3990, 8.5470), (47.3995, 8.5490)]
    text = f"""\
name: geo
frame: geodetic
origin: {{lat_deg: {origin[0]}, lon_deg: {origin[1]}, alt_m: {origin[2]}}}
speed_m_s: 5
altitude_m: 30
path: {{type: waypoints, points_deg: {[list(p) for p in deg]}}}
"""
    m = parse_mission(text, "geo.yaml")
    assert (m.origin.lat_deg, m.origin.lon_deg, m.origin.alt_m) == origin
    for lat, lon in deg:
        e, n, _ = enu_from_geodetic(lat, lon, origin[2] + 30.0, *origin)
        px, py = m.path.point(m.path.project(float(e), float(n)))
        assert math.hypot(px - float(e), py - float(n)) < 1e-3
