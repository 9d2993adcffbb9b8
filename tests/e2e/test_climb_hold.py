"""A PX4 copter climbing in OFFBOARD holds its take-off position, on the mock over loopback UDP.

PX4's velocity loop holds its velocity *estimate* at the setpoint; when the estimate is off by a
bias ``b`` the vehicle drifts by it. Climbing on zero-velocity setpoints, the real PX4 SIH left
the path's start up to 2 m from where it took off. The companion's climb hold closes a
proportional loop on the reported position instead (gain ``k`` 1/s, at most 1 m/s), so a
constant bias leaves it ``b / k`` from the take-off point, however long the climb lasts.

The mock's bias starts at 0 at its boot and wanders (here 1 m/s over 20 s: slowly, so over
the climb it is nearly constant). Without the hold the reported velocity stays near zero during
the climb and the position walks ``b T`` away (T the climb's duration); with it the reported
velocity settles at ``-b``. The bias is measured in the same flight's tlog, as what the
position did beyond the integral of the reported velocity (``b = dp/dt - v`` over the climb),
and the position where the path starts must lie within ``max |b| / k`` (plus transients) of
the take-off point.
"""

from __future__ import annotations

import math

from pymavlink import mavutil

from companion.io.mock_process import MockProcess, free_udp_port
from companion.io.setpoints import POSITION_HOLD_GAIN_1_S, POSITION_HOLD_MAX_M_S
from companion.loop.runner import FlightRunner, FlyOptions, Status
from companion.mission import parse_mission

LINE = """\
name: e2e-climb-hold
frame: local_enu
speed_m_s: 5.0
altitude_m: 12.0
path: {type: waypoints, points_m: [[0, 0], [150, 0]]}
guidance: {l1_m: 10.0, method: corrector, rate_hz: 50}
"""
BIAS_M_S, BIAS_TC_S = 1.0, 20.0  # one sigma per axis, started at 0 at boot: seed 8 reaches 0.81 m/s in the climb
SPEEDUP = 4.0


def drift_beyond_velocity_m(samples):
    """(north, east) change of the position over ``samples`` (t, n, e, d, vn, ve) beyond the
    trapezoidal integral of the reported velocity: what the velocity estimate's bias moved."""
    pairs = list(zip(samples, samples[1:]))
    return tuple(samples[-1][i] - samples[0][i] - sum((b[0] - a[0]) * 0.5 * (a[i + 3] + b[i + 3]) for a, b in pairs)
                 for i in (1, 2))


def test_a_px4_copter_climbs_over_its_take_off_point_despite_a_drifting_velocity_estimate(tmp_path):
    model = tmp_path / "vehicle.yaml"
    model.write_text(f"vehicle: {{lag_s: 0.3, a_max_m_s2: 5.0, vel_bias_m_s: {BIAS_M_S}, vel_bias_tc_s: {BIAS_TC_S:g}}}\n")
    port = free_udp_port()
    mock = MockProcess(["--autopilot", "px4", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                        "--speedup", f"{SPEEDUP:g}", "--vehicle-model", str(model), "--seed", "8",
                        "--offboard-loss-s", str(SPEEDUP), "--quiet"])
    mock.start(timeout_s=60.0)
    tlog = tmp_path / "f.tlog"
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot", arm=True,
                      tlog_path=str(tlog), heartbeat_timeout_s=30.0, link_timeout_s=10.0, max_duration_s=2.0)
    runner = FlightRunner(parse_mission(LINE, "line.yaml"), opts, Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    assert any("holding the position N" in e for e in runner.events), runner.events

    # from the tlog: the autopilot's positions and velocities up to the companion's "flying" event
    conn = mavutil.mavlink_connection(str(tlog))
    samples, started = [], False
    while (msg := conn.recv_match()) is not None:
        kind = msg.get_type()
        if kind == "STATUSTEXT" and msg.get_srcComponent() == 191 and msg.text.startswith("flying "):
            started = True
            break
        if kind == "LOCAL_POSITION_NED":
            samples.append((msg.time_boot_ms / 1000.0, msg.x, msg.y, msg.z, msg.vx, msg.vy))
    assert started and len(samples) > 50
    t0, n0, e0 = samples[0][0], samples[0][1], samples[0][2]
    climb = [s for s in samples if -s[3] > 0.3]  # airborne
    climb_s = climb[-1][0] - climb[0][0]
    assert climb_s >= 4.0 and t0 < climb[0][0]
    # the bias over each 25 samples (0.5 s at 50 Hz) of the climb
    biases = [math.hypot(*drift_beyond_velocity_m(climb[k:k + 26])) / (climb[k + 25][0] - climb[k][0])
              for k in range(len(climb) - 25)]
    b_max = max(biases)
    # the result: where the path starts lies within b / k (+ 0.25 m of transients) of the
    # take-off point; unheld, the vehicle walks about b T away (2.4 m here)
    n1, e1 = samples[-1][1], samples[-1][2]
    assert math.hypot(n1 - n0, e1 - e0) <= b_max / POSITION_HOLD_GAIN_1_S + 0.25, (n1 - n0, e1 - e0, b_max)
    # the premise: unheld, the bias would have carried the vehicle at least 1.5 m over the climb
    # (the position's change beyond the reported velocity's, end to end), and it stayed within
    # the hold's speed limit
    unheld_m = math.hypot(*drift_beyond_velocity_m(climb))
    assert unheld_m >= 1.5 and b_max <= POSITION_HOLD_MAX_M_S, (unheld_m, b_max)
