"""End to end: a QGroundControl plan that climbs from 10 to 40 m and changes speed twice is
imported without flags, flown on the mock over loopback UDP, and replayed.

The plan's five waypoints lie 80 m apart eastwards (a gentle zig-zag north and south), at 10, 20,
40, 30 and 15 m above home. It starts at the plan's hover speed (5 m/s), a DO_CHANGE_SPEED after
the second waypoint sets 7 m/s and one after the fourth 4 m/s. The steepest leg climbs 20 m in
about 81 m at 7 m/s: 1.7 m/s, within the default climb limit (2 m/s), so the smoothed profile
reaches every height and the copter's vz (feed-forward V dh/ds plus 1/s times the altitude error)
keeps it within half a metre of the profile.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.cli.demo import MockProcess, free_udp_port
from companion.cli.main import main
from companion.loop.runner import FlightRunner, FlyOptions, Status
from companion.mission import load_mission

HOME = (47.397742, 8.545594, 488.0)
SPEEDUP = 5.0
# (east_m, north_m, altitude above home m)
WAYPOINTS_ENU = [(0.0, 20.0, 10.0), (80.0, 35.0, 20.0), (160.0, 20.0, 40.0), (240.0, 35.0, 30.0),
                 (320.0, 20.0, 15.0)]
A_M = 6378137.0
E2 = (1.0 / 298.257223563) * (2.0 - 1.0 / 298.257223563)


def lat_lon(east_m: float, north_m: float) -> tuple[float, float]:
    """Local radii of curvature at home (exact to well below a millimetre over 300 m)."""
    phi = math.radians(HOME[0])
    w = math.sqrt(1.0 - E2 * math.sin(phi) ** 2)
    m = A_M * (1.0 - E2) / w ** 3 + HOME[2]
    n = A_M / w + HOME[2]
    return HOME[0] + math.degrees(north_m / m), HOME[1] + math.degrees(east_m / (n * math.cos(phi)))


def plan_text() -> str:
    import json

    def item(command, frame, params, jump_id):
        return {"autoContinue": True, "command": command, "doJumpId": jump_id, "frame": frame,
                "params": params, "type": "SimpleItem"}

    items = [item(22, 3, [0, 0, 0, None, HOME[0], HOME[1], 10.0], 1)]
    for i, (e, n, alt) in enumerate(WAYPOINTS_ENU):
        lat, lon = lat_lon(e, n)
        items.append(item(16, 3, [0, 0, 0, None, lat, lon, alt], 2 + i))
        if i == 1:
            items.append(item(178, 2, [1, 7.0, -1, 0, 0, 0, 0], 20))
        if i == 3:
            items.append(item(178, 2, [1, 4.0, -1, 0, 0, 0, 0], 21))
    return json.dumps({"fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
                       "geoFence": {"circles": [], "polygons": [], "version": 2},
                       "rallyPoints": {"points": [], "version": 2},
                       "mission": {"cruiseSpeed": 15, "firmwareType": 12, "hoverSpeed": 5,
                                   "items": items, "plannedHomePosition": list(HOME),
                                   "vehicleType": 2, "version": 2}})


@pytest.fixture(scope="module")
def profile_flight(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("profile")
    src = tmp / "climb.plan"
    src.write_text(plan_text())
    out = tmp / "climb.yaml"
    assert main(["mission", "import", str(src), "-o", str(out)]) == 0  # no flags
    mission = load_mission(out)
    port = free_udp_port()
    mock = MockProcess([
        "--autopilot", "px4", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
        "--speedup", f"{SPEEDUP:g}", "--start-ned=20,-2", "--start-alt-m", "10",
        "--start-yaw-deg=90", "--start-airborne", "--origin", f"{HOME[0]},{HOME[1]},{HOME[2]}",
        "--quiet", "--offboard-loss-s", str(SPEEDUP), "--pace-lead-s", "0.04",
    ])
    mock.start(timeout_s=60.0)
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot",
                      tlog_path=str(tmp / "flight.tlog"), heartbeat_timeout_s=30.0,
                      link_timeout_s=10.0, max_duration_s=200.0)
    runner = FlightRunner(mission, opts, Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    return mission, runner, tmp / "flight.tlog"


def test_the_imported_plan_keeps_every_height_and_speed_change(profile_flight):
    mission, _, _ = profile_flight
    p = mission.profile
    assert p is not None and mission.altitude_m == pytest.approx(10.0, abs=1e-9)
    assert p.end_altitude_m == pytest.approx(15.0, abs=1e-9)
    # The vertical-acceleration limit rounds the 40 m crest: by at most dg w / 8 with the slope
    # change dg = 20/81 + 10/81 and the window w = V^2 (g_max - g_min) / a = 49 * 0.43 / 1 m.
    dg = 30.0 / 81.0
    assert 40.0 - dg * 49 * (20 / 81 + 15 / 81) / 8 - 0.1 <= float(p.alt_m.max()) <= 40.0
    assert sorted(set(np.round(p.speed_m_s_table[[0, -1]], 9))) == [4.0, 5.0]
    assert float(p.speed_m_s_table.max()) == pytest.approx(7.0)


def test_the_profile_is_flown_within_half_a_metre_and_the_climb_limit(profile_flight):
    mission, runner, _ = profile_flight
    s = runner.summary
    assert s["exit"] == "finished", runner.events
    assert s["h_rms_m"] <= 0.5, s["h_rms_m"]
    assert s["h_max_m"] < 1.5
    assert math.isfinite(s["v_err_rms_m_s"])
    vz = np.array([v for v in runner.record.vz_cmd_ned_m_s if math.isfinite(v)])
    limits = mission.profile.limits
    assert vz.size > 1000
    assert -vz.min() <= limits.climb_max_m_s + 1e-9  # up is -vz
    assert vz.max() <= limits.sink_max_m_s + 1e-9
    # It really climbed: some ticks command at least 1 m/s up.
    assert -vz.min() > 1.0
    # The flown heights cover 10..40 m.
    alt = np.array([a for a in runner.record.alt_m if math.isfinite(a)])
    assert alt.max() == pytest.approx(40.0, abs=1.0) and alt.min() == pytest.approx(10.0, abs=1.0)


def test_the_profile_flight_replays_within_tolerance(profile_flight):
    from companion.replay.replay import replay_log

    _, _, tlog = profile_flight
    result = replay_log(tlog, progress=False)
    assert result.within_tolerance, result.first_divergence
    assert result.steps_compared > 1000


def test_replay_compares_vz_a_different_altitude_profile_diverges(profile_flight):
    """The same flight replayed against the mission with its heights lowered by 3 m: the
    horizontal setpoints are unchanged, only vz differs (the correction 1/s * 3 m, clamped at the
    1.5 m/s sink limit, against the logged climb), and the replay must report it."""
    import yaml

    from companion.mission import parse_mission
    from companion.replay.replay import replay_log

    mission, _, tlog = profile_flight
    doc = yaml.safe_load(mission.source_text)
    doc["altitude_m"] = [h - 3.0 for h in doc["altitude_m"]]
    lowered = parse_mission(yaml.safe_dump(doc), "lowered.yaml")
    result = replay_log(tlog, lowered, progress=False)
    assert not result.within_tolerance
    fd = result.first_divergence
    assert fd["tick"] <= 2 and any("vel" in r for r in fd["reasons"]), fd
    logged, replayed = fd["logged"], fd["replayed"]
    assert abs(logged["vx_m_s"] - replayed["vx_m_s"]) < 1e-6
    assert replayed["vz_m_s"] == pytest.approx(1.5, abs=1e-6)  # down at the sink limit
    assert replayed["vz_m_s"] - logged["vz_m_s"] > 1.0
