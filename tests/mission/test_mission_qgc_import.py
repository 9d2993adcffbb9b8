"""QGroundControl imports: ``.plan`` JSON and ``QGC WPL 110``, written here with the field layouts
QGroundControl and Mission Planner save, round-tripped onto the mission path."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from companion.cli.main import main
from companion.geometry.geodetic import enu_from_geodetic
from companion.mission import load_mission

HOME = (47.3977419, 8.5455939, 488.1)  # PX4 SITL's default home (Zurich)
WAYPOINTS = [(47.3985, 8.5460), (47.3990, 8.5475), (47.39845, 8.5490), (47.3978, 8.5493)]


def simple_item(command, frame, params, jump_id, altitude=None):
    item = {"autoContinue": True, "command": command, "doJumpId": jump_id, "frame": frame,
            "params": params, "type": "SimpleItem"}
    if altitude is not None:
        item = {"AMSLAltAboveTerrain": None, "Altitude": altitude, "AltitudeMode": 1, **item}
    return item


def plan_text(items, home=HOME, vehicle_type=2):
    return json.dumps({
        "fileType": "Plan",
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "groundStation": "QGroundControl",
        "mission": {"cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1,
                    "hoverSpeed": 5, "items": items, "plannedHomePosition": list(home),
                    "vehicleType": vehicle_type, "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "version": 1,
    }, indent=4)


def survey_items(altitude=40.0):
    items = [simple_item(22, 3, [15, 0, 0, None, HOME[0], HOME[1], altitude], 1, altitude),
             simple_item(178, 2, [1, 7, -1, 0, 0, 0, 0], 2)]
    for i, (lat, lon) in enumerate(WAYPOINTS):
        items.append(simple_item(16, 3, [0, 0, 0, None, lat, lon, altitude], 3 + i, altitude))
    items.insert(4, simple_item(206, 2, [20, 0, 1, 0, 0, 0, 0], 9))  # camera trigger distance
    items.append(simple_item(20, 2, [0, 0, 0, 0, 0, 0, 0], 10))
    return items


def run_import(tmp_path, name, text, *extra):
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / "out.yaml"
    code = main(["mission", "import", str(src), "-o", str(out), *extra])
    return code, src, out


def assert_on_path(mission, lat_lon, height_m, origin):
    for lat, lon in lat_lon:
        e, n, _ = enu_from_geodetic(lat, lon, origin[2] + height_m, *origin)
        s = mission.path.project(float(e), float(n))
        px, py = mission.path.point(s)
        assert math.hypot(px - float(e), py - float(n)) < 0.01


def test_plan_round_trip_puts_every_waypoint_on_the_path(tmp_path, capsys):
    code, src, out = run_import(tmp_path, "survey.plan", plan_text(survey_items()))
    captured = capsys.readouterr()
    assert code == 0 and "Traceback" not in captured.err
    mission = load_mission(out)
    assert_on_path(mission, WAYPOINTS, 40.0, HOME)
    assert (mission.origin.lat_deg, mission.origin.lon_deg, mission.origin.alt_m) == HOME
    assert mission.frame == "geodetic" and mission.altitude_m == 40.0
    assert mission.speed_m_s == 7.0 and mission.on_finish == "rtl"
    assert mission.name == "survey"
    notes = captured.err.splitlines()
    assert f"{src}: note: mission.items[0]: skipped NAV_TAKEOFF (22): guidance starts airborne" in notes
    assert f"{src}: note: mission.items[4]: skipped DO_SET_CAM_TRIGG_DIST (206): not a navigation item" in notes
    assert any("NAV_RETURN_TO_LAUNCH (20) becomes on_finish: rtl" in n for n in notes)
    # The first waypoint, by hand: 0.0007581 deg north and 0.0004061 deg east of home.
    lat0 = math.radians(HOME[0])
    first = mission.path.start_xy_m
    assert first[1] == pytest.approx(math.radians(WAYPOINTS[0][0] - HOME[0]) * 6.3674e6, rel=2e-3)
    assert first[0] == pytest.approx(math.radians(WAYPOINTS[0][1] - HOME[1]) * 6.3888e6 * math.cos(lat0), rel=2e-3)


WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t-35.363262\t149.165237\t584.090000\t1
1\t0\t3\t22\t0.00000000\t0.00000000\t0.00000000\t0.00000000\t-35.36326200\t149.16523700\t25.000000\t1
2\t0\t3\t16\t0.00000000\t0.00000000\t0.00000000\t0.00000000\t-35.36200000\t149.16500000\t25.000000\t1
3\t0\t3\t16\t0.00000000\t0.00000000\t0.00000000\t0.00000000\t-35.36120000\t149.16620000\t25.000000\t1
4\t0\t0\t16\t0.00000000\t0.00000000\t0.00000000\t0.00000000\t-35.36150000\t149.16760000\t609.090000\t1
5\t0\t3\t183\t9.00000000\t1900.00000000\t0.00000000\t0.00000000\t0.00000000\t0.00000000\t0.000000\t1
6\t0\t3\t21\t0.00000000\t0.00000000\t0.00000000\t0.00000000\t-35.36240000\t149.16800000\t0.000000\t1
"""
WPL_POINTS = [(-35.362, 149.165), (-35.3612, 149.1662), (-35.3615, 149.1676), (-35.3624, 149.168)]


def test_wpl_round_trip_with_home_item_absolute_altitude_and_final_land(tmp_path, capsys):
    code, src, out = run_import(tmp_path, "route.waypoints", WPL)
    captured = capsys.readouterr()
    assert code == 0 and "Traceback" not in captured.err
    mission = load_mission(out)
    home = (-35.363262, 149.165237, 584.09)
    assert (mission.origin.lat_deg, mission.origin.lon_deg) == pytest.approx(home[:2], abs=1e-9)
    # Item 4 is AMSL (frame 0): 609.09 - 584.09 = 25 m above home, like the others.
    assert mission.altitude_m == pytest.approx(25.0, abs=1e-6)
    assert mission.on_finish == "land"
    assert_on_path(mission, WPL_POINTS, 25.0, home)
    assert mission.path.end_xy_m == pytest.approx(
        tuple(float(v) for v in enu_from_geodetic(-35.3624, 149.168, home[2] + 25, *home)[:2]), abs=1e-3)
    assert f"{src}: note: line 7 (item 5): skipped DO_SET_SERVO (183): not a navigation item" in captured.err


def test_imported_mission_simulation_starts_above_home_facing_the_first_waypoint(tmp_path):
    code, _, out = run_import(tmp_path, "survey.plan", plan_text(survey_items()))
    mission = load_mission(out)
    x, y = mission.path.start_xy_m
    assert (mission.start.x_m, mission.start.y_m) == (0.0, 0.0)
    assert mission.start.heading_rad == pytest.approx(math.atan2(y, x), abs=1e-4)


def refused(tmp_path, capsys, name, text, *extra):
    code, src, out = run_import(tmp_path, name, text, *extra)
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and not out.exists()
    return src, [line for line in err.splitlines()]


def test_do_jump_is_refused(tmp_path, capsys):
    items = survey_items()
    items.insert(5, simple_item(177, 2, [3, 2, 0, 0, 0, 0, 0], 11))
    src, lines = refused(tmp_path, capsys, "loop.plan", plan_text(items))
    assert lines == [f"companion: error: {src}: mission.items[5]: DO_JUMP (177): a DO_JUMP loop cannot "
                     "be represented (a mission path is flown once, or closed)"]


def test_rtl_in_the_middle_is_refused(tmp_path, capsys):
    items = survey_items()
    items.insert(3, simple_item(20, 2, [0, 0, 0, 0, 0, 0, 0], 12))
    src, lines = refused(tmp_path, capsys, "mid.plan", plan_text(items))
    assert lines == [f"companion: error: {src}: mission.items[3]: NAV_RETURN_TO_LAUNCH (20) in the middle "
                     "of the mission cannot be represented; expected it only as the last navigation item"]


def test_waypoint_altitudes_become_a_profile_without_flags_and_altitude_m_still_flattens(tmp_path, capsys):
    import yaml

    items = survey_items()
    items[3]["params"][6] = 60.0  # the second waypoint
    code, src, out = run_import(tmp_path, "alt.plan", plan_text(items))
    err = capsys.readouterr().err
    assert code == 0, err
    doc = yaml.safe_load(out.read_text())
    assert doc["altitude_m"] == [40.0, 60.0, 40.0, 40.0]
    assert f"{src}: note: waypoint altitudes from 40 m to 60 m above home: altitude_m is a profile along the path" in err
    mission = load_mission(out)
    # Each waypoint converted at its own height lies on the path.
    for (lat, lon), h in zip(WAYPOINTS, doc["altitude_m"]):
        assert_on_path(mission, [(lat, lon)], h, HOME)
    assert mission.profile is not None and mission.altitude_m == pytest.approx(40.0)
    code, _, out = run_import(tmp_path, "alt.plan", plan_text(items), "--altitude-m", "50", "--force")
    assert code == 0 and load_mission(out).altitude_m == 50.0 and load_mission(out).profile is None


def test_do_change_speed_items_apply_from_the_waypoint_before_them(tmp_path, capsys):
    import yaml

    items = survey_items()  # 7 m/s before the first waypoint
    items.insert(4, simple_item(178, 2, [1, 9.0, -1, 0, 0, 0, 0], 30))  # after waypoint 1
    items.insert(7, simple_item(178, 2, [1, 4.0, -1, 0, 0, 0, 0], 31))  # after waypoint 2
    items.insert(8, simple_item(178, 2, [2, 1.5, -1, 0, 0, 0, 0], 32))  # a climb speed: skipped
    code, src, out = run_import(tmp_path, "speeds.plan", plan_text(items))
    err = capsys.readouterr().err
    assert code == 0, err
    doc = yaml.safe_load(out.read_text())
    assert doc["speed_m_s"] == [7, 9, 4, 4]
    assert "mission.items[8]: skipped DO_CHANGE_SPEED of a climb speed" in err
    mission = load_mission(out)
    p = mission.profile
    s1 = mission.path.project(*_enu(WAYPOINTS[1]))
    s2 = mission.path.project(*_enu(WAYPOINTS[2]))
    # 7 -> 9 m/s from waypoint 1 at 1 m/s^2: (81 - 49) / 2 = 16 m; 9 -> 4 from waypoint 2: 32.5 m.
    assert p.speed_m_s(s1 - 1.0) == pytest.approx(7.0)
    assert p.speed_m_s(s1 + 8.0) == pytest.approx(math.sqrt(49.0 + 16.0), abs=0.01)
    assert p.speed_m_s(s1 + 16.5) == pytest.approx(9.0)
    assert p.speed_m_s(s2 - 1.0) == pytest.approx(9.0)
    assert p.speed_m_s(s2 + 20.0) == pytest.approx(math.sqrt(81.0 - 40.0), abs=0.01)
    assert p.speed_m_s(s2 + 33.0) == pytest.approx(4.0)


def _enu(lat_lon):
    e, n, _ = enu_from_geodetic(lat_lon[0], lat_lon[1], HOME[2] + 40.0, *HOME)
    return float(e), float(n)


def test_complex_survey_item_terrain_frame_and_zero_position_are_refused_together(tmp_path, capsys):
    items = survey_items()
    items.append({"complexItemType": "survey", "type": "ComplexItem", "version": 5})
    items[3]["frame"] = 10
    items[5]["params"][4] = 0.0
    items[5]["params"][5] = 0.0
    src, lines = refused(tmp_path, capsys, "complex.plan", plan_text(items))
    assert len(lines) == 3
    assert any("mission.items[8]: survey cannot be represented" in line for line in lines)
    assert any("mission.items[3]: terrain-relative altitude cannot be represented" in line for line in lines)
    assert any("mission.items[5]: NAV_WAYPOINT (16) expected a latitude and longitude, got none" in line
               for line in lines)


@pytest.mark.parametrize(
    "name, text, fragment",
    [
        ("bad.plan", "{\"fileType\": \"Plan\", ", "line 1, column 22: expected a QGroundControl .plan (JSON)"),
        ("fence.plan", json.dumps({"fileType": "GeoFence"}), "fileType: expected \"Plan\""),
        ("bad.waypoints", "QGC WPL 120\n", "line 1: expected the header 'QGC WPL 110', got 'QGC WPL 120'"),
        ("short.waypoints", "QGC WPL 110\n0\t1\t0\t16\n", "line 2: expected 12 tab-separated fields, got 4"),
        ("notes.md", "hello\n", "expected a QGroundControl .plan (JSON) or a 'QGC WPL 110' file"),
        ("one.plan", plan_text(survey_items()[:3]), "expected at least 2 waypoints with positions, got 1"),
    ],
)
def test_malformed_plans_give_one_line_errors(tmp_path, capsys, name, text, fragment):
    src, lines = refused(tmp_path, capsys, name, text)
    assert len(lines) == 1 and lines[0].startswith(f"companion: error: {src}") and fragment in lines[0]


def test_gallery_import_is_current(tmp_path):
    from pathlib import Path

    missions = Path(__file__).resolve().parents[2] / "missions"
    out = tmp_path / "qgc.yaml"
    code = main(["mission", "import", str(missions / "qgc_inspection.plan"), "-o", str(out),
                 "--name", "qgc-inspection"])
    assert code == 0
    committed = (missions / "qgc_inspection.yaml").read_text().splitlines()
    assert out.read_text().splitlines()[1:] == committed[1:]  # line 0 names the source path
    plan = json.loads((missions / "qgc_inspection.plan").read_text())
    points = [(it["params"][4], it["params"][5]) for it in plan["mission"]["items"] if it["command"] == 16]
    m = load_mission(missions / "qgc_inspection.yaml")
    assert_on_path(m, points, m.altitude_m, tuple(plan["mission"]["plannedHomePosition"]))
    assert np.isfinite(m.path.length_m)


def test_wpl_waypoints_keep_their_own_heights_in_frames_0_and_3(tmp_path, capsys):
    import yaml

    # Item 3 at 40 m above home (frame 3); item 4 at 599.09 m AMSL (frame 0): 599.09 - 584.09 = 15.
    text = WPL.replace("-35.36120000\t149.16620000\t25.000000", "-35.36120000\t149.16620000\t40.000000")
    text = text.replace("609.090000", "599.090000")
    # A DO_CHANGE_SPEED (ground speed 9 m/s) after item 3: the speed from that waypoint on.
    text = text.replace("5\t0\t3\t183", "5\t0\t3\t178\t1\t9\t-1\t0\t0\t0\t0\t1\n55\t0\t3\t183")
    code, src, out = run_import(tmp_path, "route.waypoints", text)
    err = capsys.readouterr().err
    assert code == 0, err
    doc = yaml.safe_load(out.read_text())
    # The landing point (item 6) is flown at the height of the waypoint before it.
    assert doc["altitude_m"] == [25.0, 40.0, 15.0, 15.0]
    assert doc["speed_m_s"] == [5, 5, 9, 9]  # no speed before it: 5 m/s
    mission = load_mission(out)
    home = (-35.363262, 149.165237, 584.09)
    for (lat, lon), h in zip(WPL_POINTS, doc["altitude_m"]):
        assert_on_path(mission, [(lat, lon)], h, home)


def test_terrain_relative_waypoints_are_refused_in_one_line(tmp_path, capsys):
    text = WPL.replace("2\t0\t3\t16", "2\t0\t10\t16")
    src, lines = refused(tmp_path, capsys, "terrain.waypoints", text)
    assert lines == [f"companion: error: {src}: line 4 (item 2): terrain-relative altitude cannot be represented; expected "
                     "frame 3 (relative to home) or 0 (AMSL)"]
