"""A hovering copter turns to face its path before the path starts, on the mock over loopback UDP.

A copter's velocity loop flies any direction, but every law reads a hovering copter's course
from its nose: started facing north on a path going east, a law sees a vehicle already doing
5 m/s north and turns it round, and the copter swings out by metres (1.4 m d_rms on the
racetrack with ArduCopter's 2.5 m/s^2). The companion first turns the nose to the start course
(:func:`companion.guidance.capture.start_course_rad`), holding its position.

Both autopilots' personalities start facing north (yaw 0) on the ground beside a line going
east. Checked from the flight's own log: the event, the yaw when the first guidance tick ran
(within the facing tolerance of east, 90 deg NED; it was 0 without the turn), the position
held meanwhile, and the first seconds of the path flown without a swing (cross-track within
0.3 m; a copter flying off north at 5 m/s and turned round at 5 m/s^2 is 2.5 m off after 1 s).
"""

from __future__ import annotations

import math

import pytest

from companion.io.mock_process import MockProcess, free_udp_port
from companion.loop.runner import FlightRunner, FlyOptions, Status
from companion.loop.session import FACE_TOLERANCE_RAD
from companion.mission import parse_mission
from companion.replay.flightlog import read_flight

LINE = """\
name: e2e-face-path
frame: local_enu
speed_m_s: 5.0
altitude_m: 10.0
path: {type: waypoints, points_m: [[0, 0], [150, 0]]}
guidance: {l1_m: 10.0, method: METHOD, rate_hz: 50}
"""
SPEEDUP = 4.0


@pytest.mark.parametrize("autopilot, method", [("px4", "corrector"), ("ardupilot", "pure_pursuit")])
def test_a_copter_facing_north_turns_to_the_path_going_east_before_it_starts(tmp_path, autopilot, method):
    port = free_udp_port()
    mock = MockProcess(["--autopilot", autopilot, "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                        "--speedup", f"{SPEEDUP:g}", "--start-yaw-deg", "0", "--vel-bias-m-s", "0",
                        "--vel-offset-m-s", "0", "--offboard-loss-s", str(SPEEDUP), "--quiet"])
    mock.start(timeout_s=60.0)
    tlog = tmp_path / "f.tlog"
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot", arm=True,
                      tlog_path=str(tlog), heartbeat_timeout_s=30.0, link_timeout_s=10.0, max_duration_s=3.0)
    runner = FlightRunner(parse_mission(LINE.replace("METHOD", method), "line.yaml"), opts, Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    assert any(e.startswith("facing the path: yaw ") for e in runner.events), runner.events

    ticks = [tk for tk in read_flight(str(tlog), progress=False).ticks if tk.sample is not None]
    first = ticks[0]
    assert first.yaw_ned_rad is not None
    assert abs(math.degrees(first.yaw_ned_rad) - 90.0) <= math.degrees(FACE_TOLERANCE_RAD) + 1.0, first.yaw_ned_rad
    assert math.hypot(first.sample.x_ned_m, first.sample.y_ned_m) <= 0.5  # held over the take-off point
    assert len(ticks) > 100  # 2 s and more of the path
    assert max(abs(tk.debug_value("crosstrack_m")) for tk in ticks) <= 0.3
