"""Fixed-wing output end to end: SET_ATTITUDE_TARGET with the coordinated-turn bank on the mock plane."""

from __future__ import annotations

import math

import numpy as np
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


def test_plane_flies_the_path_with_bank_angle_setpoints(tmp_path):
    m = parse_mission(MISSION, "plane.yaml")
    port = free_udp_port()
    mock = MockProcess(["--autopilot", "px4", "--vehicle", "plane", "--link", f"udpout:127.0.0.1:{port}",
                        "--speedup", "5", "--start-ned=-10,-20", "--start-alt-m", "50", "--start-yaw-deg=90",
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
