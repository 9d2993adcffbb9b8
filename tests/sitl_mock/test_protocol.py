"""The mock on the wire, driven by a pymavlink client over loopback UDP."""

from __future__ import annotations

import math
import signal
import socket
import statistics
import subprocess
import sys
import time

import pytest
from pymavlink import mavutil

from sitl_mock.cli import main
from sitl_mock.personality import px4_custom_mode

from sitl_mock_helpers import NAN, ROOT, Client, free_udp_port

M = mavutil.mavlink
VEL_ONLY = 0b0000_1111_1100_0111
OFFBOARD = px4_custom_mode(6)
HOLD = px4_custom_mode(4, 3)


def stream_setpoints(client: Client, seconds: float, vn: float, ve: float, hz: float = 20.0) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        client.mav.set_position_target_local_ned_send(0, 1, 1, M.MAV_FRAME_LOCAL_NED, VEL_ONLY, 0, 0, 0, vn, ve, 0,
                                                      0, 0, 0, 0, 0)
        time.sleep(1.0 / hz)


def test_px4_identity_in_ready_line_and_heartbeat(mock_factory):
    mock, client = mock_factory("--autopilot", "px4", "--vehicle", "plane", "--sysid", "7", "--speedup", "5")
    assert mock.ready_line == "sitl_mock ready sysid=7 autopilot=px4 vehicle=plane"
    hb = client.wait("HEARTBEAT")
    assert hb.get_srcSystem() == 7 and hb.get_srcComponent() == 1
    assert (hb.autopilot, hb.type) == (M.MAV_AUTOPILOT_PX4, M.MAV_TYPE_FIXED_WING)
    assert hb.custom_mode == (4 << 16) | (3 << 24)  # AUTO.LOITER (Hold)
    assert hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.get_header().mlen is not None and hb.get_msgbuf()[0] == 0xFD  # MAVLink 2


def test_ardupilot_streams_nothing_until_asked_then_position_at_200_hz_of_simulated_time(mock_factory):
    _, client = mock_factory("--autopilot", "ardupilot", "--speedup", "4")
    hb = client.wait("HEARTBEAT")
    assert (hb.autopilot, hb.custom_mode) == (M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0)  # STABILIZE
    seen = set()
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        msg = client.conn.recv_match(blocking=True, timeout=0.1)
        if msg is not None:
            seen.add(msg.get_type())
    # GPS_GLOBAL_ORIGIN is no stream: it is announced once, when the estimator sets its origin
    # (right after the first heartbeat here), and may fall in this window.
    assert seen <= {"HEARTBEAT", "GPS_GLOBAL_ORIGIN"} and "HEARTBEAT" in seen
    assert client.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 5000) == M.MAV_RESULT_ACCEPTED
    stamps = []
    while len(stamps) < 200:
        msg = client.wait("LOCAL_POSITION_NED", 5.0)
        assert msg is not None
        stamps.append(msg.time_boot_ms)
    assert statistics.median(b - a for a, b in zip(stamps, stamps[1:])) == 5
    assert client.command(M.MAV_CMD_GET_MESSAGE_INTERVAL, 32) == M.MAV_RESULT_ACCEPTED
    assert client.wait("MESSAGE_INTERVAL").interval_us == 5000
    assert client.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, -1) == M.MAV_RESULT_ACCEPTED
    client.command(M.MAV_CMD_GET_MESSAGE_INTERVAL, 32)
    assert client.wait("MESSAGE_INTERVAL").interval_us == -1  # off


def test_request_data_stream_starts_the_ardupilot_position_group(mock_factory):
    _, client = mock_factory("--autopilot", "ardupilot", "--speedup", "4")
    client.wait("HEARTBEAT")
    client.mav.request_data_stream_send(1, 1, M.MAV_DATA_STREAM_POSITION, 10, 1)
    assert client.wait("GLOBAL_POSITION_INT", 5.0) is not None
    assert client.wait("LOCAL_POSITION_NED", 5.0) is not None


def test_unknown_command_with_nan_params_gets_unsupported(mock_factory):
    _, client = mock_factory("--speedup", "5")
    client.wait("HEARTBEAT")
    assert client.command(31010, NAN, NAN) == M.MAV_RESULT_UNSUPPORTED
    assert client.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 9999, 1000) == M.MAV_RESULT_DENIED
    assert client.command(M.MAV_CMD_COMPONENT_ARM_DISARM, NAN) == M.MAV_RESULT_DENIED


def test_commands_for_another_system_are_ignored_and_command_int_works(mock_factory):
    _, client = mock_factory("--speedup", "5")
    client.wait("HEARTBEAT")
    assert client.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, target=(2, 1), timeout_s=1.0) is None
    client.mav.command_int_send(1, 1, 0, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 1, NAN, NAN, NAN, 0, 0, NAN)
    ack = client.wait("COMMAND_ACK", predicate=lambda m: m.command == M.MAV_CMD_COMPONENT_ARM_DISARM)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    assert (ack.target_system, ack.target_component) == (255, 190)
    assert client.wait("HEARTBEAT", predicate=lambda m: m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED) is not None


def test_px4_offboard_refused_without_stream_then_flies_the_velocity_then_fails_safe_to_hold(
        mock_factory, tmp_path, first_order_vehicle):
    tlog = tmp_path / "mock.tlog"
    mock, client = mock_factory("--start-airborne", "--start-alt-m", "10", "--speedup", "4",
                                "--offboard-loss-s", "0.5", "--tlog", str(tlog), *first_order_vehicle)
    client.wait("HEARTBEAT")
    assert client.command(M.MAV_CMD_DO_SET_MODE, 1, 6) == M.MAV_RESULT_TEMPORARILY_REJECTED
    refusal = client.wait("STATUSTEXT", predicate=lambda m: "Offboard" in m.text)
    assert refusal is not None and refusal.severity <= M.MAV_SEVERITY_WARNING
    stream_setpoints(client, 0.3, 2.0, -1.0)
    client.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 6, 0, 0, 0, 0, 0)
    stream_setpoints(client, 1.5, 2.0, -1.0)
    client.drain()
    pos = client.wait("LOCAL_POSITION_NED")
    assert (pos.vx, pos.vy) == (pytest.approx(2.0, abs=0.05), pytest.approx(-1.0, abs=0.05))
    assert pos.z == pytest.approx(-10.0, abs=0.05)
    # Stop the setpoints: PX4 falls back to Hold after COM_OF_LOSS_T.
    assert client.wait("HEARTBEAT", 10.0, lambda m: m.custom_mode == HOLD) is not None
    mock.stop()
    log = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    last_setpoint_s = fallback_s = None
    in_offboard = False
    while (msg := log.recv_match()) is not None:
        if msg.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
            last_setpoint_s = msg._timestamp
        if msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1:
            in_offboard = in_offboard or msg.custom_mode == OFFBOARD
            if in_offboard and msg.custom_mode == HOLD:
                fallback_s = msg._timestamp
                break
    # tlog times are simulated time: the fallback comes 0.5 s after the last setpoint, to a physics step.
    assert 0.5 < fallback_s - last_setpoint_s < 0.5 + 0.01


def test_param_list_read_and_set(mock_factory):
    _, client = mock_factory("--sysid", "3", "--speedup", "5")
    client.wait("HEARTBEAT")
    client.mav.param_request_list_send(3, 1)
    values = {}
    while True:
        msg = client.wait("PARAM_VALUE", 3.0)
        if msg is None:
            break
        values[msg.param_index] = msg
        if len(values) == msg.param_count:
            break
    count = next(iter(values.values())).param_count
    assert sorted(values) == list(range(count))
    by_name = {m.param_id: m for m in values.values()}
    sysid = by_name["MAV_SYS_ID"]
    assert sysid.param_type == M.MAV_PARAM_TYPE_INT32
    # PX4 sends integers bytewise: the float's bytes are the int32.
    import struct
    assert struct.unpack("<i", struct.pack("<f", sysid.param_value))[0] == 3
    assert by_name["COM_OF_LOSS_T"].param_value == pytest.approx(0.5)
    client.mav.param_set_send(3, 1, b"COM_OF_LOSS_T", 1.5, M.MAV_PARAM_TYPE_REAL32)
    echo = client.wait("PARAM_VALUE", predicate=lambda m: m.param_id == "COM_OF_LOSS_T")
    assert echo.param_value == pytest.approx(1.5)
    client.mav.param_request_read_send(3, 1, b"COM_OF_LOSS_T", -1)
    assert client.wait("PARAM_VALUE", predicate=lambda m: m.param_id == "COM_OF_LOSS_T").param_value == 1.5


def test_timesync_autopilot_version_home_and_counters_on_request(mock_factory):
    _, client = mock_factory("--speedup", "5", "--origin", "10.0,20.0,100.0", "--start-ned", "111.32,0")
    client.wait("HEARTBEAT")
    client.mav.timesync_send(0, 123456789)
    sync = client.wait("TIMESYNC", predicate=lambda m: m.ts1 == 123456789)
    assert sync is not None and sync.tc1 > 0
    assert client.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == M.MAV_RESULT_ACCEPTED
    version = client.wait("AUTOPILOT_VERSION")
    assert version.capabilities & M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert version.capabilities & M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    assert client.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_HOME_POSITION) == M.MAV_RESULT_ACCEPTED
    home = client.wait("HOME_POSITION")
    # 111.32 m north of the origin is 111.32 / 6378137 rad = 0.00100000 deg of latitude.
    assert home.latitude == round((10.0 + math.degrees(111.32 / 6378137.0)) * 1e7)
    assert (home.longitude, home.altitude) == (200000000, 100000)
    assert client.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_STATUSTEXT) == M.MAV_RESULT_ACCEPTED
    assert client.wait("STATUSTEXT", predicate=lambda m: m.text.startswith("rx datagrams=")) is not None


def test_two_links_both_get_the_streams(mock_factory):
    udpin_port = free_udp_port()
    _, client = mock_factory("--link", f"udpin:127.0.0.1:{udpin_port}", "--speedup", "5")
    gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{udpin_port}", source_system=250, dialect="ardupilotmega")
    try:
        gcs.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        assert gcs.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=5) is not None
        assert client.wait("LOCAL_POSITION_NED") is not None
    finally:
        gcs.close()


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGINT])
def test_tlog_holds_both_directions_and_mavlogdump_reads_it(mock_factory, tmp_path, stop_signal):
    tlog = tmp_path / "both.tlog"
    mock, client = mock_factory("--speedup", "5", "--tlog", str(tlog))
    client.wait("HEARTBEAT")
    assert client.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    mock.proc.send_signal(stop_signal)
    mock.stop()
    assert mock.proc.returncode == 0
    assert "tlog_records=" in mock.stderr
    dump = subprocess.run([sys.executable, str(ROOT / ".venv/bin/mavlogdump.py"), "--types",
                           "COMMAND_LONG,COMMAND_ACK", str(tlog)], capture_output=True, text=True, timeout=60)
    assert dump.returncode == 0
    lines = dump.stdout.splitlines()
    assert any("COMMAND_LONG" in ln and "command : 400" in ln for ln in lines)
    assert any("COMMAND_ACK" in ln and "result : 0" in ln for ln in lines)


@pytest.mark.parametrize("argv, expected", [
    (["--link", "tcp:1.2.3.4:5"], "--link 'tcp:1.2.3.4:5'"),
    (["--link", "udpout:127.0.0.1:0"], "port out of range"),
    (["--tlog", "/nonexistent-dir/x.tlog", "--link", "udpin:127.0.0.1:0"], "--tlog /nonexistent-dir/x.tlog"),
    (["--origin", "95,0,0", "--link", "udpin:127.0.0.1:0"], "--origin"),
    (["--start-airborne", "--link", "udpin:127.0.0.1:0"], "--start-alt-m"),
])
def test_bad_options_exit_2_with_one_line(argv, expected, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sitl-mock: error: ") and expected in err[0]


def test_a_busy_udpin_port_is_reported_before_the_ready_line(capsys):
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as busy:
        busy.bind(("127.0.0.1", 0))
        port = busy.getsockname()[1]
        assert main(["--link", "udpout:127.0.0.1:14540", "--link", f"udpin:127.0.0.1:{port}"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith(f"sitl-mock: error: --link udpin:127.0.0.1:{port}: cannot open it")


def test_duration_runs_in_simulated_time_and_speedup_shortens_the_wall_time(capsys):
    start = time.monotonic()
    assert main(["--link", "udpin:127.0.0.1:0", "--speedup", "20", "--duration-s", "10", "--quiet"]) == 0
    wall_s = time.monotonic() - start
    assert wall_s < 5.0  # 10 s of flight at 20x is 0.5 s of wall time, plus start-up
    out, err = capsys.readouterr()
    assert out.strip() == "sitl_mock ready sysid=1 autopilot=px4 vehicle=copter"
    assert "sim_s=10.00" in err


def test_px4_do_reposition_as_command_int_goes_to_hold_at_the_geodetic_point(mock_factory):
    # 0.0003 deg of latitude north of the origin is 0.0003 * pi/180 * 6378137 = 33.40 m.
    _, client = mock_factory("--start-airborne", "--start-alt-m", "10", "--speedup", "8",
                             "--origin", "47.0,8.0,400.0", "--vel-bias-m-s", "0",
                             "--vel-offset-m-s", "0")  # holds exactly
    client.wait("HEARTBEAT")
    client.drain()
    client.mav.command_int_send(1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_CMD_DO_REPOSITION, 0, 0,
                                -1, 1, 0, NAN, int(47.0003e7), int(8.0e7), 15.0)
    ack = client.wait("COMMAND_ACK", predicate=lambda m: m.command == M.MAV_CMD_DO_REPOSITION)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    north_m = math.radians(0.0003) * 6378137.0
    pos = client.wait("LOCAL_POSITION_NED", 20.0, lambda m: abs(m.x - north_m) < 0.2 and abs(m.z + 15.0) < 0.2)
    assert pos is not None and abs(pos.y) < 0.2
    assert client.wait("HEARTBEAT").custom_mode == HOLD
    # A latitude no planet has is refused.
    assert client.command(M.MAV_CMD_DO_REPOSITION, -1, 1, 0, NAN, 1000.0, 8.0, 415.0) == M.MAV_RESULT_DENIED


def test_ardupilot_global_int_target_is_flown_in_guided(mock_factory):
    _, client = mock_factory("--autopilot", "ardupilot", "--start-airborne", "--start-alt-m", "10",
                             "--speedup", "8", "--origin=-35.0,149.0,500.0")
    client.wait("HEARTBEAT")
    assert client.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == M.MAV_RESULT_ACCEPTED
    assert client.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 20000) == M.MAV_RESULT_ACCEPTED
    # 0.0002 deg of longitude at 35 deg S is 0.0002 * pi/180 * 6378137 * cos(35 deg) = 18.24 m east.
    east_m = math.radians(0.0002) * 6378137.0 * math.cos(math.radians(-35.0))
    client.mav.set_position_target_global_int_send(0, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                                   0b0000_1111_1111_1000, int(-35.0e7), int(149.0002e7), 12.0,
                                                   0, 0, 0, 0, 0, 0, 0, 0)
    pos = client.wait("LOCAL_POSITION_NED", 20.0, lambda m: abs(m.y - east_m) < 0.2 and abs(m.z + 12.0) < 0.2)
    assert pos is not None and abs(pos.x) < 0.2


def test_udpout_answers_a_second_client_where_its_datagrams_come_from(mock_factory):
    _, client = mock_factory("--speedup", "5")
    client.wait("HEARTBEAT")
    (address,) = client.conn.clients
    other = mavutil.mavlink_connection(f"udpout:{address[0]}:{address[1]}", source_system=254,
                                       source_component=190, dialect="ardupilotmega")
    try:
        other.mav.command_long_send(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                    NAN, NAN, NAN, NAN, NAN, NAN)
        ack = other.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
        assert ack is not None and (ack.command, ack.target_system) == (M.MAV_CMD_REQUEST_MESSAGE, 254)
        # It is now a peer of that link: the streams reach it too.
        assert other.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=5) is not None
    finally:
        other.close()


def test_a_mavlink_1_command_is_accepted_and_answered_in_mavlink_2(mock_factory):
    from pymavlink.dialects.v10 import ardupilotmega as v1

    _, client = mock_factory("--speedup", "5")
    client.wait("HEARTBEAT")
    (address,) = client.conn.clients
    packer = v1.MAVLink(None, srcSystem=255, srcComponent=190)
    frame = bytes(packer.command_long_encode(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
                  .pack(packer))
    assert frame[0] == 0xFE
    client.drain()
    client.conn.port.sendto(frame, address)
    ack = client.wait("COMMAND_ACK", predicate=lambda m: m.command == M.MAV_CMD_COMPONENT_ARM_DISARM)
    assert ack.result == M.MAV_RESULT_ACCEPTED and ack.get_msgbuf()[0] == 0xFD


def _recorded_positions(tmp_path, seed: int, name: str) -> list[tuple[float, float, float]]:
    tlog = tmp_path / name
    # The port the mock sends to stays bound here for the whole run: a port only probed free
    # could be handed to the mock as its own ephemeral port, and the mock would then receive
    # (and record) its own messages twice.
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", 0))
        argv = ["--link", f"udpout:127.0.0.1:{sink.getsockname()[1]}", "--speedup", "20", "--duration-s", "5",
                "--quiet", "--start-airborne", "--start-alt-m", "10", "--pos-noise-m", "0.5", "--seed", str(seed),
                "--tlog", str(tlog)]
        proc = subprocess.run([sys.executable, "-m", "sitl_mock", *argv], cwd=ROOT, capture_output=True, text=True,
                              timeout=60)
    assert proc.returncode == 0, proc.stderr
    log = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    out = []
    while (msg := log.recv_match(type="LOCAL_POSITION_NED")) is not None:
        out.append((msg.time_boot_ms, msg.x, msg.y, msg.z))
    return out


def test_same_seed_same_reported_track_across_runs(tmp_path):
    first = _recorded_positions(tmp_path, 3, "a.tlog")
    assert len(first) == 151  # due at 0, 1/30, ..., 150/30 = 5 s: PX4 default 30 Hz
    assert first == _recorded_positions(tmp_path, 3, "b.tlog")
    assert first != _recorded_positions(tmp_path, 4, "c.tlog")


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_gps_global_origin_is_the_origin_on_request(mock_factory, autopilot):
    """REQUEST_MESSAGE 49 answers GPS_GLOBAL_ORIGIN = --origin (degE7, altitude AMSL in mm)."""
    _, client = mock_factory("--autopilot", autopilot, "--speedup", "4", "--origin=-35.3632621,149.1652374,584.25")
    assert client.wait("HEARTBEAT") is not None
    assert client.command(M.MAV_CMD_REQUEST_MESSAGE, 49) == M.MAV_RESULT_ACCEPTED
    msg = client.wait("GPS_GLOBAL_ORIGIN", 5.0)
    assert msg is not None
    assert (msg.latitude, msg.longitude, msg.altitude) == (-353632621, 1491652374, 584250)


def test_without_an_ekf_origin_a_request_is_accepted_and_nothing_follows(mock_factory):
    _, client = mock_factory("--autopilot", "ardupilot", "--speedup", "4", "--no-ekf-origin")
    assert client.wait("HEARTBEAT") is not None
    assert client.command(M.MAV_CMD_REQUEST_MESSAGE, 49) == M.MAV_RESULT_ACCEPTED
    assert client.wait("GPS_GLOBAL_ORIGIN", 1.5) is None


def test_every_sitl_mock_option_has_help_text():
    from sitl_mock.cli import build_parser

    missing = [a.option_strings[0] for a in build_parser()._actions
               if a.option_strings and not (a.help or "").strip()]
    assert missing == []


def test_a_second_signal_inside_the_stop_handler_cannot_deadlock_the_mock():
    # Two signals in quick succession (SIGINT, then the SIGTERM of a supervisor) run the handler inside
    # itself. A handler that takes a lock (Event.set) then waits for the lock its own interrupted call
    # holds, forever. Here the interrupted call is played by this thread holding the event's lock.
    import threading

    from sitl_mock.autopilot import MockAutopilot
    from sitl_mock.cli import build_parser, config_from_args

    mock = MockAutopilot(config_from_args(build_parser().parse_args(["--link", "udpin:127.0.0.1:0", "--quiet"])))
    try:
        with mock.stop_event._cond:
            second = threading.Thread(target=mock.request_stop, args=(signal.SIGTERM, None), daemon=True)
            second.start()
            second.join(timeout=5.0)
            assert not second.is_alive(), "the stop handler blocked on a lock"
        started = time.monotonic()
        assert mock.run() == 0  # stop already requested: returns at once
        assert time.monotonic() - started < 5.0
    finally:
        mock.close()


def _paced_client(client: Client, seconds: float, newest_ms: int) -> int:
    """A well-behaved paced client for ``seconds`` of wall time: a setpoint every 20 ms stamped
    with the newest time_boot_ms heard so far; returns that newest time."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        client.mav.set_position_target_local_ned_send(newest_ms, 1, 1, M.MAV_FRAME_LOCAL_NED, VEL_ONLY,
                                                      0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)
        until = time.monotonic() + 0.02
        while (left := until - time.monotonic()) > 0:
            msg = client.conn.recv_match(blocking=True, timeout=left)
            if msg is not None:
                newest_ms = max(newest_ms, getattr(msg, "time_boot_ms", 0) or 0)
    return newest_ms


def test_a_paced_client_that_lost_the_newest_telemetry_is_told_the_time_and_the_clock_goes_on(mock_factory):
    # --pace-lead-s holds the simulated clock while a setpoint client is more than 0.04 s behind.
    # A client that lost the newest datagrams (a full socket buffer drops the latest ones) stamps
    # its setpoints with a time older than the last one sent, and would wait for telemetry the
    # held clock never produces: both sides waiting for ever (seen once in a loaded full run: the
    # mock silent for 10 s after the mode change). While it waits, the mock sends SYSTEM_TIME.
    _, client = mock_factory("--autopilot", "px4", "--speedup", "5", "--pace-lead-s", "0.04",
                             "--start-airborne", "--start-alt-m", "10", "--quiet")
    client.wait("HEARTBEAT")
    first = client.wait("LOCAL_POSITION_NED").time_boot_ms
    # A client stuck at that first time: the clock is held near it, and the client hears the
    # held time at least every 0.1 s (old mock: nothing at all after the hold began).
    told = []
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        client.mav.set_position_target_local_ned_send(first, 1, 1, M.MAV_FRAME_LOCAL_NED, VEL_ONLY,
                                                      0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)
        msg = client.conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=0.02)
        if msg is not None:
            told.append((time.monotonic(), msg.time_boot_ms))
    late = [tb for t, tb in told if t > end - 1.0]  # after the hold has set in
    assert len(late) >= 5, told
    held = max(tb for _, tb in told)
    assert held - first < 1000  # the clock was held: 1.5 s of wall time at 5x would be 7.5 s
    # Stamping with the time it hears, the client lets the clock go on (at most 0.04 s ahead of
    # it per 20 ms setpoint: 2x at least, of the 5x asked).
    assert _paced_client(client, 1.0, held) - held > 1000
