"""Fixed-wing output end to end: SET_ATTITUDE_TARGET with the coordinated-turn bank on the mock plane."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink import mavutil

from companion.io.mock_process import MockProcess, free_udp_port
from companion.loop.runner import FlightRunner, FlyOptions, Status
from companion.mission import parse_mission

MISSION = """\
name: plane-sine
frame: local_enu
speed_m_s: 15.0
altitude_m: 50.0
path:
  type: function
  y_of_x: "30*sin(0.02*x)"
  x_range_m: [0, 500]
guidance: {l1_m: 40.0, method: corrector, rate_hz: 50}
midcourse: {circle_radius_m: 60.0, trigger: "off"}
on_finish: loiter
"""


@pytest.mark.parametrize("start_yaw_deg", [90, 270])
def test_plane_flies_the_path_with_bank_angle_setpoints(tmp_path, start_yaw_deg):
    """From 22 m before the path start, pointing along it (90) or away from it (270: the plane
    turns round at its tightest radius, 33 m, first moving that far beyond its closest approach;
    a plane that loitered while the companion started can begin so, and that is no runaway)."""
    m = parse_mission(MISSION, "plane.yaml")
    port = free_udp_port()
    mock = MockProcess(["--autopilot", "px4", "--vehicle", "plane", "--link", f"udpout:127.0.0.1:{port}",
                        "--speedup", "3", "--start-ned=-10,-20", "--start-alt-m", "50",
                        f"--start-yaw-deg={start_yaw_deg}",
                        "--start-airborne", "--quiet", "--offboard-loss-s", "5"])
    mock.start(timeout_s=60.0)
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot",
                      tlog_path=str(tmp_path / "p.tlog"), heartbeat_timeout_s=30.0, link_timeout_s=10.0,
                      max_duration_s=120.0, max_bank_deg=35.0)
    runner = FlightRunner(m, opts, Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    s = runner.summary
    assert s["vehicle"] == "plane" and s["exit"] == "finished"
    conn = mavutil.mavlink_connection(str(tmp_path / "p.tlog"))
    att, speed_cmds = [], []
    while (msg := conn.recv_match()) is not None:
        if msg.get_type() == "SET_ATTITUDE_TARGET":
            att.append(msg)
        elif msg.get_type() == "COMMAND_LONG" and msg.command == 178:
            speed_cmds.append(msg)
        assert msg.get_type() != "SET_POSITION_TARGET_LOCAL_NED"
    assert len(att) == runner.setpoints_sent
    assert speed_cmds and speed_cmds[0].param2 == 15.0  # DO_CHANGE_SPEED to the mission speed
    rolls = [math.atan2(2 * (a.q[0] * a.q[1] + a.q[2] * a.q[3]), 1 - 2 * (a.q[1] ** 2 + a.q[2] ** 2))
             for a in att]
    assert max(abs(r) for r in rolls) <= math.radians(35.0) + 1e-6
    # Once on the path (second half of the flight), it stays within a few metres of it.
    d = np.asarray(runner.record.crosstrack_m)
    tail = d[len(d) // 2:]
    assert float(np.sqrt(np.mean(tail ** 2))) < 3.0


PROFILE_MISSION = """\
name: plane-climb
frame: local_enu
speed_m_s: [15.0, 18.0, 18.0]
altitude_m: [50.0, 70.0, 70.0]
path:
  type: waypoints
  points_m: [[0, 0], [300, 0], [600, 0]]
guidance: {l1_m: 40.0, method: corrector, rate_hz: 50}
midcourse: {circle_radius_m: 60.0, trigger: "off"}
on_finish: loiter
"""


def test_an_ardupilot_plane_gets_the_profile_through_its_height_and_speed_commands(tmp_path):
    """ArduPlane in GUIDED holds the height given by GUIDED_CHANGE_ALTITUDE and the speed given
    by GUIDED_CHANGE_SPEED: the profile's climb (20 m over 300 m at 15 m/s, 1 m/s) and its speed
    change reach the plane through them."""
    m = parse_mission(PROFILE_MISSION, "plane-climb.yaml")
    port = free_udp_port()
    mock = MockProcess(["--autopilot", "ardupilot", "--vehicle", "plane", "--link", f"udpout:127.0.0.1:{port}",
                        "--speedup", "5", "--start-ned=0,-20", "--start-alt-m", "50", "--start-yaw-deg=90",
                        "--start-airborne", "--quiet", "--offboard-loss-s", "5"])
    mock.start(timeout_s=60.0)
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot",
                      tlog_path=str(tmp_path / "p.tlog"), heartbeat_timeout_s=30.0, link_timeout_s=10.0,
                      max_duration_s=120.0, max_bank_deg=35.0)
    runner = FlightRunner(m, opts, Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    assert runner.summary["exit"] == "finished", runner.events
    conn = mavutil.mavlink_connection(str(tmp_path / "p.tlog"))
    alts, speeds = [], []
    while (msg := conn.recv_match()) is not None:
        if msg.get_type() == "COMMAND_LONG" and msg.command == 43001:
            alts.append(msg.param7)
        elif msg.get_type() == "COMMAND_LONG" and msg.command == 43000:
            speeds.append(msg.param2)
    assert alts and min(alts) >= 50.0 - 1e-6 and max(alts) == pytest.approx(70.0, abs=0.5)
    assert speeds[0] == 15.0 and max(speeds) == pytest.approx(18.0, abs=0.2)
    # The plane followed: its height late in the flight is near 70 m (the mock's plane climbs
    # at up to its own limit toward the commanded height).
    assert runner.summary["h_rms_m"] < 5.0
    alt = [a for a in runner.record.alt_m if math.isfinite(a)]
    assert max(alt) == pytest.approx(70.0, abs=2.0)
