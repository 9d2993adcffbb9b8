"""End to end over loopback UDP: the companion flies the mock autopilot (PX4 and ArduPilot).

The mission is a shortened paper sine path with a far start (mid-course then close range). The
flight ticks on the autopilot's clock while the mock runs faster than real time.

Tolerance on d_rms against the offline simulator (same mission, same guidance, LagModel with the
mock's velocity time constant and acceleration limit): the two vehicle models differ in ways
that are not errors of the companion:

* the mock lags the *velocity vector* (tau = 0.3 s) where LagModel lags the lateral acceleration:
  in a turn at omega = a/V the flown course trails the command by about omega tau (here up to
  ~0.2 rad at the sine's crests), shifting the track by a fraction of a metre;
* the mock starts hovering (speed 0, yaw along the start heading), the companion first turns it
  to face its start course (docs/flying.md, "Facing the path"), and it accelerates to V within
  V / a_max = 0.5 s; the simulator starts on that course at speed V;
* the flown loop sees one tick of transport delay (the setpoint acts on the next physics step)
  and the occasional coasted tick while a re-optimisation runs.

The mid-course phase dominates the overall d_rms (about 20 m of distance to the path while the
vehicle flies in from the far start). Starting from a hover costs up to V * (V / a_max + tau)
~ 4 m of along-track offset early in that phase, which moves its d_rms by a few per cent: the
overall figure must agree within 10 %. The close-range figure (sub-metre) must agree within
0.35 m absolute, about the track shift one velocity-loop time constant of course lag produces on
this path (V * tau * sin(0.2 rad) ~ 0.3 m).

Pacing: at 5x the companion must run 250 ticks per wall second. On a loaded machine (the CI's 2
cores shared with other jobs) it is sometimes descheduled for tens of milliseconds, which at 5x
is several ticks of simulated flight without a new setpoint, plus coasted re-optimisations: the
track then reflects the machine, not the guidance (a 1.2 m close-range d_rms was measured under
two busy loops, against 0.46 m idle; 0.93 m still with a 0.1 s lead). The mock is therefore run
with ``--pace-lead-s 0.04``: it holds simulated time while the newest autopilot time stamped on
the companion's setpoints lags by more than 0.04 s (two ticks), as a machine fast enough for the
run would (under two busy loops: 50.0 Hz achieved, 0-1 skipped ticks, close-range d_rms
0.43-0.44 m against 0.47 m offline). The tolerances are unchanged; the loop-rate and
stale-sample checks still use the autopilot's clock.
"""

from __future__ import annotations

import math

import pytest
from pymavlink import mavutil

from companion.io.mock_process import MockProcess, free_udp_port
from companion.errors import FlightAborted
from companion.geometry import frames
from companion.guidance.capture import start_course_rad
from companion.guidance.types import VehicleState
from companion.loop.runner import FlightRunner, FlyOptions, Status, make_guidance
from companion.mission import parse_mission
from companion.sim.simulator import LagModel, simulate

TAU_VEL_S = 0.3
A_MAX_M_S2 = 10.0
SPEEDUP = 5.0
#: The mock holds its simulated time while the companion's setpoints lag it by more than this.
PACE_LEAD_S = 0.04

MISSION = """\
name: e2e-short-sine
frame: local_enu
speed_m_s: 5.0
altitude_m: 10.0
path:
  type: function
  y_of_x: "10*sin(0.078*x) + 20*cos(0.082*x)"
  x_range_m: [-15, 110]
guidance: {l1_m: 10.0, method: corrector, rate_hz: 50}
midcourse: {circle_radius_m: 10.0, trigger: auto}
start: {x_m: -45.0, y_m: -30.0, heading_deg: 0.0}
"""


def mission():
    return parse_mission(MISSION, "e2e.yaml")


def start_mock(m, autopilot, port, vehicle_model_file, extra=()):
    """The mock flying the offline simulator's vehicle: a first-order lag and a limit, no dead
    time, slow tail or speed sag (the personalities' identified defaults have those)."""
    vehicle_model_file.write_text(f"vehicle: {{lag_s: {TAU_VEL_S}, a_max_m_s2: {A_MAX_M_S2}}}\n")
    yaw_deg = math.degrees(frames.yaw_ned_from_enu(m.start.heading_rad))
    mock = MockProcess([
        "--autopilot", autopilot, "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
        "--speedup", f"{SPEEDUP:g}", f"--start-ned={m.start.y_m},{m.start.x_m}",
        "--start-alt-m", "10", f"--start-yaw-deg={yaw_deg}", "--start-airborne",
        "--vehicle-model", str(vehicle_model_file), "--quiet",
        "--offboard-loss-s", str(SPEEDUP), "--guided-timeout-s", str(3 * SPEEDUP),
        "--pace-lead-s", str(PACE_LEAD_S), *extra,
    ])
    mock.start(timeout_s=60.0)
    return mock


def fly(m, autopilot, tmp_path, extra_mock=(), **kw):
    port = free_udp_port()
    mock = start_mock(m, autopilot, port, tmp_path / "vehicle.yaml", extra_mock)
    opts = dict(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot",
                tlog_path=str(tmp_path / "flight.tlog"), heartbeat_timeout_s=30.0,
                link_timeout_s=10.0, max_duration_s=200.0)
    opts.update(kw)
    runner = FlightRunner(m, FlyOptions(**opts), Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    return runner


def offline(m):
    g = make_guidance(m, 50.0)
    course = start_course_rad(m.path, m.start.x_m, m.start.y_m, m.guidance.l1_m)  # what the copter faces
    start = VehicleState(m.start.x_m, m.start.y_m, course, m.speed_m_s)
    return simulate(m.path, g, start, g.params if hasattr(g, "params") else m.guidance,
                    model=LagModel(TAU_VEL_S, A_MAX_M_S2)).metrics


def tlog_types(path):
    conn = mavutil.mavlink_connection(str(path))
    out = []
    while (msg := conn.recv_match()) is not None:
        out.append(msg)
    return out


@pytest.fixture(scope="module")
def offline_metrics():
    return offline(mission())


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_flown_track_matches_the_offline_simulator(autopilot, tmp_path, offline_metrics):
    m = mission()
    runner = fly(m, autopilot, tmp_path)
    s = runner.summary
    assert s["exit"] == "finished", runner.events
    assert s["autopilot"] == autopilot
    off = offline_metrics
    assert set(s["phases"]) >= {"midcourse", "close_range"}
    assert s["d_rms_m"] == pytest.approx(off["d_rms_m"], rel=0.10)
    assert abs(s["phases"]["close_range"]["d_rms_m"] - off["phases"]["close_range"]["d_rms_m"]) <= 0.35
    # The loop kept its rate (on the autopilot's clock) and never held.
    assert s["rate_hz_achieved"] > 45.0
    assert s["hold_ticks"] == 0
    # Never a setpoint from a position older than the stale limit.
    assert max(runner.record.sample_age_s) <= 0.3
    # Every setpoint sent is in the tlog, one guidance record per guidance tick.
    msgs = tlog_types(tmp_path / "flight.tlog")
    sent = [x for x in msgs if x.get_type() == "SET_POSITION_TARGET_LOCAL_NED" and x.get_srcComponent() == 191]
    assert len(sent) == runner.setpoints_sent
    assert sum(1 for x in msgs if x.get_type() == "DEBUG_FLOAT_ARRAY") == s["ticks"]


def test_pilot_mode_change_stops_the_companion(tmp_path):
    """A second ground station selects LOITER mid-flight: no setpoint after the vehicle reports it."""
    import socket
    import threading
    import time

    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    m = mission()
    gcs_port = free_udp_port()

    class Out:
        def __init__(self, sock):
            self.sock = sock

        def write(self, buf):
            self.sock.sendto(bytes(buf), ("127.0.0.1", gcs_port))

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs = mavlink2.MAVLink(Out(sock), srcSystem=255, srcComponent=190)

    def pilot():
        time.sleep(4.0)  # well into the flight (about 20 s simulated)
        for _ in range(3):
            gcs.command_long_send(1, 1, 176, 0, 1, 5, 0, 0, 0, 0, 0)  # ArduCopter LOITER
            time.sleep(0.05)

    th = threading.Thread(target=pilot, daemon=True)
    th.start()
    with pytest.raises(FlightAborted, match="pilot override"):
        fly(m, "ardupilot", tmp_path, extra_mock=("--link", f"udpin:127.0.0.1:{gcs_port}"))
    th.join(5.0)
    sock.close()
    msgs = tlog_types(tmp_path / "flight.tlog")
    hb = [(i, x.custom_mode) for i, x in enumerate(msgs)
          if x.get_type() == "HEARTBEAT" and x.get_srcComponent() == 1]
    first_guided = next(i for i, mode in hb if mode == 4)
    first_loiter = next(i for i, mode in hb if mode == 5 and i > first_guided)
    after = [x for x in msgs[first_loiter:] if x.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    assert after == []
    guided_requests = [i for i, x in enumerate(msgs) if x.get_type() == "COMMAND_LONG" and x.command == 176
                       and int(x.param2) == 4]
    # Asked for GUIDED before the flight (more than once only if an ACK came late: a retry on a
    # loaded machine), never after the pilot's LOITER: no switching back.
    assert guided_requests and max(guided_requests) < first_loiter
    assert any(x.get_type() == "SET_POSITION_TARGET_LOCAL_NED" for x in msgs[first_guided:first_loiter])
