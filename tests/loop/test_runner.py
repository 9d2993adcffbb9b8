"""The flight runner against a small in-test autopilot over loopback UDP (wall clock).

A stub guidance on a straight path keeps these tests about the runner: modes, failsafes,
recording. The real guidance and the mock autopilot are exercised in tests/e2e.
"""

import math
from dataclasses import replace

import pytest
from pymavlink import mavutil

from companion.errors import FlightAborted, LinkError
from companion.geometry.paths import waypoint_path
from companion.guidance.types import GuidanceOutput
from companion.io.setpoints import FACE_MAX_RATE_RAD_S
from companion.loop.runner import FlightRunner, FlyOptions, Status
from companion.loop.session import FACE_TOLERANCE_RAD
from companion.mission import Mission
from kinematic_peer import KinematicAutopilot


class StraightLineGuidance:
    """Pull back to the x axis; finished at x >= finish_x. Records the states it was given."""

    def __init__(self, finish_x_m=1e9):
        self.finish_x_m = finish_x_m
        self.calls = []

    def step(self, t_s, state):
        self.calls.append((t_s, state))
        phase = "finished" if state.x_m >= self.finish_x_m else "close_range"
        return GuidanceOutput(a_cmd_m_s2=-0.5 * state.y_m, phase=phase, crosstrack_m=state.y_m,
                              s_proj_m=state.x_m)


def line_mission():
    path = waypoint_path([(0.0, 0.0), (100.0, 0.0), (200.0, 0.0)])
    return Mission(name="line", path=path, speed_m_s=5.0, altitude_m=10.0, source_text="name: line\n")


def fly(port, tmp_path, peer, guidance, status=None, **kw):
    opts = dict(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, tlog_path=str(tmp_path / "f.tlog"),
                heartbeat_timeout_s=5.0)
    opts.update(kw)
    peer.start()
    runner = FlightRunner(line_mission(), FlyOptions(**opts), status or Status(quiet=True), guidance=guidance)
    try:
        runner.run()
    finally:
        peer.stop()
    return runner


def tlog_messages(path):
    conn = mavutil.mavlink_connection(str(path))
    out = []
    while True:
        m = conn.recv_match()
        if m is None:
            return out
        out.append(m)


def test_px4_flight_streams_a_second_before_offboard_and_records_every_setpoint(free_udp_port, tmp_path):
    # 1 m north of the path (NED x = north), flying east at 5 m/s
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", x=1.0, y=0.0, ve=5.0)
    g = StraightLineGuidance(finish_x_m=8.0)
    runner = fly(free_udp_port, tmp_path, peer, g)
    s = runner.summary
    assert s["exit"] == "finished"
    mode_cmds = [(t, m) for t, m in peer.commands if m.command == 176]
    t_offboard = next(t for t, m in mode_cmds if int(m.param2) == 6)
    first_sp = peer.setpoints[0][0]
    assert t_offboard - first_sp >= 0.95  # PX4 needs the stream flowing first (1 s, clock jitter)
    # On finish: hold = AUTO.LOITER (main 4, sub 3)
    assert any(int(m.param2) == 4 and int(m.param3) == 3 for _, m in mode_cmds)
    # Every setpoint sent is in the tlog, and one DEBUG_FLOAT_ARRAY per tick.
    msgs = tlog_messages(tmp_path / "f.tlog")
    sent = [m for m in msgs if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    debug = [m for m in msgs if m.get_type() == "DEBUG_FLOAT_ARRAY"]
    assert len(sent) == runner.setpoints_sent == len(peer.setpoints)
    assert len(debug) == s["ticks"] and [int(d.array_id) for d in debug] == list(range(s["ticks"]))
    # PX4: velocity + yaw rate, no acceleration target unless the mission asks for one.
    assert all(m.type_mask == 1479 and m.coordinate_frame == 1 for m in sent)
    assert (tmp_path / "f.tlog.mission.yaml").read_text() == "name: line\n"
    # The guidance was given ENU: 1 m north is y = +1 (left of the eastbound path). The vehicle
    # hovered (zero velocity) until OFFBOARD, so the course falls back to its yaw, which it turned
    # to face the path's L1 point 1 m to its right and 9.95 m ahead (ENU -5.7 deg) from east (the
    # peer's start, ENU 0), to within the facing tolerance.
    first = g.calls[0][1]
    assert first.y_m == pytest.approx(1.0, abs=1e-6)
    assert abs(first.course_rad + math.asin(0.1)) <= FACE_TOLERANCE_RAD + 0.02 and first.speed_m_s == 5.0
    assert s["d_rms_m"] >= 0 and s["samples"] > 0
    # The end-of-path tick is not a phase: the names and phases are the simulator's.
    assert "finished" not in s["phases"]


def test_dropped_position_stream_holds_within_one_tick_of_the_stale_limit(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", ve=5.0, drop_positions_at_s=0.5)
    g = StraightLineGuidance()
    runner = fly(free_udp_port, tmp_path, peer, g, stale_s=0.3, max_duration_s=1.5)
    r = runner.record
    holds = [i for i, h in enumerate(r.hold) if h]
    assert holds, "no hold after the position stream stopped"
    first = holds[0]
    # The hold starts on the very first tick past the limit: the tick before it was still fresh.
    # (On an idle machine the first hold age is 0.30-0.32 s; the bound allows scheduling delay
    # on a loaded one.)
    assert r.sample_age_s[first - 1] <= 0.3 < r.sample_age_s[first] <= 0.3 + 0.25
    # Never a setpoint computed from a position older than the stale limit.
    assert all(age <= 0.3 for age, h in zip(r.sample_age_s, r.hold) if not h)
    # The hold setpoints on the wire are zero velocity and zero yaw rate.
    last = peer.setpoints[-1][1]
    assert (last.vx, last.vy, last.yaw_rate) == (0.0, 0.0, 0.0)


def test_pilot_mode_change_stops_commanding_and_never_switches_back(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", ve=5.0, mode_change_at_s=0.5)
    with pytest.raises(FlightAborted, match="pilot override"):
        fly(free_udp_port, tmp_path, peer, StraightLineGuidance())
    t_change = peer.offboard_entered_s + 0.5
    late = [t for t, _ in peer.setpoints if t > t_change + 0.25]  # heartbeat period 0.2 s + a tick
    assert late == []
    offboard_requests = [t for t, m in peer.commands if m.command == 176 and int(m.param2) == 6]
    assert len(offboard_requests) == 1  # never asked for OFFBOARD again


def test_ardupilot_guided_then_arm_retries_with_reason_then_takeoff(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "ardupilot", ve=0.0, alt=0.0, armed=False,
                              arm_refusals=2)
    runner = fly(free_udp_port, tmp_path, peer, StraightLineGuidance(finish_x_m=3.0), arm=True,
                 arm_timeout_s=20.0, max_duration_s=5.0)
    order = [int(m.command) for _, m in peer.commands if m.command in (176, 400, 22)]
    assert order.index(176) < order.index(400) < order.index(22)
    assert order.count(400) == 3  # two refusals, then accepted
    assert any("PreArm: EKF not ready" in e for e in runner.events)
    assert any(m.command == 176 and int(m.param2) == 4 for _, m in peer.commands)  # GUIDED = 4


def test_refuses_to_start_far_from_the_path(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", x=0.0, y=1000.0)  # 1 km north
    with pytest.raises(FlightAborted, match="max-start-distance"):
        fly(free_udp_port, tmp_path, peer, StraightLineGuidance())
    assert peer.setpoints == []


def test_no_heartbeat_is_a_clear_link_error_and_leaves_no_file(free_udp_port, tmp_path):
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{free_udp_port}", rate_hz=50.0,
                      tlog_path=str(tmp_path / "logs" / "f.tlog"), heartbeat_timeout_s=0.5)
    with pytest.raises(LinkError, match="no HEARTBEAT"):
        FlightRunner(line_mission(), opts, Status(quiet=True), guidance=StraightLineGuidance()).run()
    assert list(tmp_path.rglob("*")) == []  # no empty tlog, no mission copy, not even logs/


def test_heartbeat_loss_stops_and_leaves_a_readable_tlog(free_udp_port, tmp_path):
    import threading

    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", ve=5.0)
    timer = threading.Timer(2.0, peer.stop_flag.set)  # the autopilot goes silent after 2 s
    timer.start()
    with pytest.raises(LinkError, match="heartbeat lost"):
        fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), link_timeout_s=0.5)
    timer.cancel()
    msgs = tlog_messages(tmp_path / "f.tlog")
    assert any(m.get_type() == "DEBUG_FLOAT_ARRAY" for m in msgs)
    assert any(m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 191 for m in msgs)


def test_resume_waits_for_the_pilot_to_hand_back_control_then_continues(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", ve=5.0, mode_change_at_s=0.5,
                              mode_return_at_s=1.5)
    runner = fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), resume=True, max_duration_s=2.5)
    assert runner.summary["exit"] == "max duration"
    t_off = peer.offboard_entered_s + 0.5
    t_back = peer.offboard_entered_s + 1.5
    during = [t for t, _ in peer.setpoints if t_off + 0.25 < t < t_back]
    after = [t for t, _ in peer.setpoints if t > t_back]
    assert during == [] and len(after) > 10
    assert sum(1 for _, m in peer.commands if m.command == 176 and int(m.param2) == 6) == 1
    assert any("resuming" in e for e in runner.events)


class SlowEveryN(StraightLineGuidance):
    """Every 50th step takes 150 ms (a re-optimisation) and commands a left turn.

    ``slow_windows`` holds the (start, end) of each slow step on ``time.monotonic``, the clock
    the runner's wall-clock loop ticks on.
    """

    SLOW_S = 0.15

    def __init__(self):
        super().__init__()
        self.slow_windows = []

    def step(self, t_s, state):
        import time as _time

        out = super().step(t_s, state)
        if len(self.calls) % 50 == 0:
            t0 = _time.monotonic()
            _time.sleep(self.SLOW_S)
            self.slow_windows.append((t0, _time.monotonic()))
        return GuidanceOutput(a_cmd_m_s2=1.0, phase=out.phase, crosstrack_m=out.crosstrack_m,
                              s_proj_m=out.s_proj_m)


def test_a_slow_guidance_step_coasts_instead_of_freezing_the_setpoint_stream(free_udp_port, tmp_path,
                                                                            monkeypatch):
    """While a 150 ms step runs in the worker, the loop keeps sending (coasted) setpoints.

    Measured on the sender's side with the loop's own clock (``time.monotonic``), not by when
    the test's peer thread got round to reading the datagrams: a loaded machine delays the
    reader, which says nothing about the loop. A frozen stream sends nothing during a slow step;
    a coasting loop sends one setpoint per 20 ms tick, about 7 in 150 ms. At least 3 are
    required: the loop thread then needs under half of a core, which a loaded 2-core machine
    still gives it, while a freeze gives 0.
    """
    import time as _time

    from companion.io.link import MavLink

    sent_at = []
    original = MavLink.send_setpoint

    def recording_send(self, sp):
        sent_at.append(_time.monotonic())
        original(self, sp)

    monkeypatch.setattr(MavLink, "send_setpoint", recording_send)
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", ve=5.0)
    g = SlowEveryN()
    runner = fly(free_udp_port, tmp_path, peer, g, max_duration_s=2.0)
    assert g.slow_windows, "no slow step ran"
    for t0, t1 in g.slow_windows:
        during = [t for t in sent_at if t0 < t < t1]
        assert len(during) >= 3, f"{len(during)} setpoints sent during a {t1 - t0:.3f} s step"
    assert runner.coast_ticks >= 3 * len(g.slow_windows)
    # Late results are recorded, flagged as not sent; a late result only follows a coasted tick.
    debug = [m for m in tlog_messages(tmp_path / "f.tlog") if m.get_type() == "DEBUG_FLOAT_ARRAY"]
    sent_flags = [m.data[26] for m in debug]
    assert 0.0 in sent_flags and 1.0 in sent_flags
    assert sent_flags.count(0.0) <= runner.coast_ticks


def test_px4_ground_start_offboard_then_arm_then_climb_before_the_path(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", alt=0.0, armed=False)
    g = StraightLineGuidance()
    runner = fly(free_udp_port, tmp_path, peer, g, arm=True, max_duration_s=0.5)
    t_offboard = next(t for t, m in peer.commands if m.command == 176 and int(m.param2) == 6)
    t_arm = next(t for t, m in peer.commands if m.command == 400)
    assert peer.setpoints[0][0] + 0.95 <= t_offboard < t_arm
    # the setpoint stream never paused while arming and climbing: PX4 keeps OFFBOARD only while
    # setpoints flow at more than 2 Hz (no gap of 0.5 s); the loop sends them at 50 Hz
    times = [t for t, _ in peer.setpoints if t_offboard <= t]
    assert max(b - a for a, b in zip(times, times[1:])) < 0.5
    # the path starts only at 90 % of the mission altitude (10 m), reached by climbing with vz
    assert any(m.vz < 0 for _, m in peer.setpoints)
    debug = [m for m in tlog_messages(tmp_path / "f.tlog") if m.get_type() == "DEBUG_FLOAT_ARRAY"]
    assert debug[0].data[21] >= 9.0  # alt_m of the first guidance tick
    assert runner.summary["exit"] == "max duration" and g.calls


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_a_disarmed_vehicle_without_arm_is_refused_before_any_mode_change(free_udp_port, tmp_path, autopilot):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), autopilot, alt=0.0, armed=False)
    with pytest.raises(FlightAborted, match="disarmed") as info:
        fly(free_udp_port, tmp_path, peer, StraightLineGuidance())
    assert "\n" not in str(info.value)
    assert [m for _, m in peer.commands if m.command == 176] == []  # no DO_SET_MODE
    assert peer.setpoints == []  # not even PX4's pre-stream
    assert peer.custom_mode == peer.hold_mode


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_an_arming_refusal_puts_back_the_mode_the_vehicle_was_in(free_udp_port, tmp_path, autopilot):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), autopilot, alt=0.0, armed=False, arm_refusals=1000)
    with pytest.raises(FlightAborted, match="could not arm within 1 s: PreArm: EKF not ready; mode set back to"):
        fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), arm=True, arm_timeout_s=1.0)
    modes = [int(m.param2) for _, m in peer.commands if m.command == 176]
    flight_main = 6 if autopilot == "px4" else 4  # OFFBOARD main mode, GUIDED
    hold_main = 4 if autopilot == "px4" else 5  # AUTO (Loiter sub-mode), LOITER: what it was in
    assert modes == [flight_main, hold_main]
    assert peer.custom_mode == peer.hold_mode


def test_px4_arm_acknowledged_before_its_heartbeat_shows_it_is_not_a_refusal(free_udp_port, tmp_path):
    # PX4 ACKs ACCEPTED at once; its HEARTBEAT carries the armed flag later (here 1 s).
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", alt=0.0, armed=False, arm_delay_s=1.0)
    runner = fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), arm=True, max_duration_s=0.3)
    assert not any("arming refused" in e for e in runner.events), runner.events
    assert sum(1 for _, m in peer.commands if m.command == 400) == 1
    assert "armed" in runner.events


def test_an_airborne_ardupilot_copter_with_arm_flies_without_a_takeoff(free_udp_port, tmp_path):
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "ardupilot", x=1.0, alt=10.0, armed=True, ve=5.0)
    runner = fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), arm=True, max_duration_s=0.5)
    assert not any(m.command == 22 for _, m in peer.commands)  # no NAV_TAKEOFF
    assert any(e.startswith("already airborne at 10.0 m") for e in runner.events)
    assert runner.summary["exit"] == "max duration"
    # ArduPilot: the guidance's setpoints carry the command as the acceleration target (1031), a / V
    # being the yaw rate, at right angles to the velocity bar what the drift compensation takes from
    # it (no limit was read from this peer, so only g bounds it). The peer stands still until GUIDED
    # and then flies each setpoint's 5 m/s at once: the first ticks see a hovering copter and send
    # the target times its speed over V (none), the rest the whole command.
    sent = [m for m in tlog_messages(tmp_path / "f.tlog") if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    guided = [m for m in sent if m.type_mask == 1031]
    assert guided and all(m.type_mask in (1479, 1031) for m in sent)
    assert max(math.hypot(m.afx, m.afy) for m in guided) > 0.1  # 1 m left of the path: it turns right
    full = 0
    for m in guided:
        af, whole = math.hypot(m.afx, m.afy), abs(m.yaw_rate) * 5.0
        assert af == pytest.approx(whole, rel=1e-4, abs=1e-6) or (af < 1e-6 < whole)
        full += whole > 1e-6 and af == pytest.approx(whole, rel=1e-4)
        assert m.afx * m.vx + m.afy * m.vy == pytest.approx(0.0, abs=2e-3)
    assert full >= len(guided) - 3


def test_an_ardupilot_rover_gets_no_acceleration_target_even_when_the_mission_asks(free_udp_port, tmp_path):
    # ArduPilot Rover ignores a SET_POSITION_TARGET_LOCAL_NED that carries one ("set ACC_IGNORE in mask").
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "ardupilot", x=1.0, alt=0.0, armed=True, ve=5.0,
                              rover=True)
    mission = replace(line_mission(), accel_feedforward=True)
    peer.start()
    opts = FlyOptions(connect=f"udpin:127.0.0.1:{free_udp_port}", rate_hz=50.0, tlog_path=str(tmp_path / "f.tlog"),
                      heartbeat_timeout_s=5.0, max_duration_s=0.5)
    runner = FlightRunner(mission, opts, Status(quiet=True), guidance=StraightLineGuidance())
    try:
        runner.run()
    finally:
        peer.stop()
    sent = [m for m in tlog_messages(tmp_path / "f.tlog") if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    assert sent and all(m.type_mask == 1479 for m in sent)
    assert any(e.startswith("guidance.accel_feedforward not used: only a copter") for e in runner.events)


def test_the_position_wait_shows_the_autopilots_reasons_and_ends_in_one_line(free_udp_port, tmp_path):
    import io
    import re

    assert FlyOptions(connect="udpin:0.0.0.0:14540", rate_hz=50.0).position_timeout_s == 90.0
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "ardupilot", positions_from_s=math.inf)
    stream = io.StringIO()
    with pytest.raises(LinkError) as info:
        fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), status=Status(stream), position_timeout_s=1.5)
    msg = str(info.value)
    assert "\n" not in msg and "no valid LOCAL_POSITION_NED within --position-timeout-s 1.5" in msg
    assert "EKF lacks relative position, absolute position" in msg and "PreArm: Need Position Estimate" in msg
    out = stream.getvalue()
    assert re.search(r"waiting for the position estimate \(LOCAL_POSITION_NED\): \d s of 1.5 s; EKF lacks", out)
    assert out.count("companion: autopilot: PreArm: Need Position Estimate") == 1  # repeats not shown
    assert peer.setpoints == [] and not [m for _, m in peer.commands if m.command == 176]


def test_the_status_line_shows_mode_armed_altitude_ground_speed_and_path_share(free_udp_port, tmp_path):
    import io
    import re

    # A real PX4 sends ~25 messages a second whose ids the dialect does not know.
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", alt=10.0, ve=5.0, unknown_ids_hz=25.0)
    stream = io.StringIO()
    runner = fly(free_udp_port, tmp_path, peer, StraightLineGuidance(), status=Status(stream), max_duration_s=2.5)
    lines = [ln for ln in stream.getvalue().splitlines() if ln.startswith("t ")]
    assert len(lines) >= 2 and "nan" not in stream.getvalue()
    last = lines[-1]
    assert "OFFBOARD armed  alt 10.0 m  gs 5.0 m/s" in last, last
    share = float(re.search(r"path +(\d+) %", last).group(1))
    t_line = float(re.search(r"^t +([\d.]+) s", last).group(1))
    r = runner.record
    i = min(range(len(r.t_s)), key=lambda k: abs(r.t_s[k] - t_line))
    assert share == pytest.approx(100.0 * r.x_m[i] / 200.0, abs=1.0)  # s = x east on a 200 m path
    assert "rejected 0" in last and "ignored" in last
    link = runner.summary["link"]
    assert link["rejected_total"] == 0 and link["ignored_unknown_id"] >= 25


def test_the_setpoint_stream_does_not_pause_after_offboard_while_the_interpreter_is_set_up(
        free_udp_port, tmp_path, monkeypatch):
    # The full collection before the loop can take most of a second in a big process on a busy
    # machine; PX4 leaves OFFBOARD after COM_OF_LOSS_T without a setpoint. Here it takes 0.6 s.
    import gc
    import time as _time

    real_collect = gc.collect

    def slow_collect(*args):
        _time.sleep(0.6)
        return real_collect(*args)

    monkeypatch.setattr(gc, "collect", slow_collect)
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", x=1.0, y=0.0, ve=5.0)
    runner = fly(free_udp_port, tmp_path, peer, StraightLineGuidance(finish_x_m=8.0))
    assert runner.summary["exit"] == "finished"
    t_offboard = next(t for t, m in peer.commands if m.command == 176 and int(m.param2) == 6)
    times = [t for t, _ in peer.setpoints if t >= t_offboard]
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert len(times) > 10 and max(gaps) < 0.2, max(gaps)


@pytest.mark.parametrize("x_m, yaw_deg, turns", [(1.0, 0.0, True), (0.0, 90.0, False), (1.0, -100.0, True)])
def test_a_hovering_copter_faces_the_path_before_the_first_tick(free_udp_port, tmp_path, x_m, yaw_deg, turns):
    # hovering x_m north of the line going east, its nose at yaw_deg (NED): the first tick's
    # course (the yaw, the copter being at rest) faces the path's L1 point (10 m away: 1 m to
    # the right, so ENU -asin(0.1); on the line, east), within the facing tolerance
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", x=x_m, yaw=math.radians(yaw_deg))
    g = StraightLineGuidance(finish_x_m=0.5)
    runner = fly(free_udp_port, tmp_path, peer, g, max_duration_s=1.0)
    want = -math.asin(x_m / 10.0)
    assert abs(g.calls[0][1].course_rad - want) <= FACE_TOLERANCE_RAD + 0.02
    assert any(e.startswith("facing the path") for e in runner.events) is turns
    if turns:  # the short way round (0 -> 84: clockwise; -100 -> 84: 176 deg anticlockwise), capped
        sign = 1.0 if yaw_deg == 0.0 else -1.0
        assert max(sign * m.yaw_rate for _, m in peer.setpoints) == pytest.approx(FACE_MAX_RATE_RAD_S, rel=1e-6)


def test_a_yaw_that_does_not_turn_starts_the_path_after_the_facing_timeout_with_a_warning(
        free_udp_port, tmp_path, monkeypatch):
    import companion.loop.session as session

    monkeypatch.setattr(session, "FACE_TIMEOUT_S", 0.5)
    peer = KinematicAutopilot(("127.0.0.1", free_udp_port), "px4", yaw=0.0, yaw_turns=False)
    g = StraightLineGuidance(finish_x_m=0.5)
    runner = fly(free_udp_port, tmp_path, peer, g, max_duration_s=1.0)
    assert any(e.startswith("did not face the path within 0.5 s (yaw 0 deg)") for e in runner.events), runner.events
    assert g.calls and g.calls[0][1].course_rad == pytest.approx(math.pi / 2, abs=1e-6)  # still its yaw, north
