"""Interoperability with clients nobody on this project wrote: MAVSDK 4.x and MAVProxy.

Both run as real clients against the mock over loopback UDP. MAVSDK 4.x (``pip install mavsdk``) is
the native binding: a blocking Python API over the bundled C++ library, no separate server.
MAVProxy runs ``--non-interactive`` (it then reads no stdin), driven by ``--cmd``: a ``repeat``
timer (misc module) runs staged ``script`` files so each step waits for the previous one, the
way an operator would type them.
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import threading
import time

import pytest
from pymavlink import mavutil
from sitl_mock_helpers import ROOT, MockProcess, free_udp_port

from sitl_mock.personality import Personality

M = mavutil.mavlink
pytestmark = pytest.mark.interop


def wait_until(predicate, timeout_s: float, period_s: float = 0.05):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(period_s)
    return predicate()


def test_mavsdk_connects_reads_position_arms_and_flies_offboard_velocity(first_order_vehicle):
    from mavsdk import ComponentType, Configuration, ConnectionResult, Mavsdk
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.offboard import Offboard, VelocityNedYaw
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    port = free_udp_port()
    mock = MockProcess("--autopilot", "px4", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                       "--speedup", "4", "--origin", "47.397742,8.545594,488", *first_order_vehicle)
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        assert sdk.add_any_connection(f"udpin://127.0.0.1:{port}") == ConnectionResult.SUCCESS
        system = sdk.first_autopilot(15.0)
        assert system is not None
        telemetry, action, offboard = Telemetry(system), Action(system), Offboard(system)
        def known_position():
            p = telemetry.position()
            return p if math.isfinite(p.latitude_deg) else None

        position = wait_until(known_position, 10.0)
        assert position.latitude_deg == pytest.approx(47.397742, abs=1e-6)
        assert position.longitude_deg == pytest.approx(8.545594, abs=1e-6)
        assert position.absolute_altitude_m == pytest.approx(488.0, abs=0.01)
        assert wait_until(lambda: telemetry.flight_mode() == FlightMode.HOLD, 10.0)
        action.arm()
        assert wait_until(telemetry.armed, 10.0)
        # Offboard: climb, then fly north-east at (2, 1) m/s.
        offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, -2.0, 0.0))
        offboard.start()
        assert wait_until(lambda: telemetry.flight_mode() == FlightMode.OFFBOARD, 10.0)
        assert wait_until(lambda: telemetry.position_velocity_ned().position.down_m < -3.0, 15.0)
        offboard.set_velocity_ned(VelocityNedYaw(2.0, 1.0, 0.0, 0.0))
        start = telemetry.position_velocity_ned().position
        moved = wait_until(lambda: (p := telemetry.position_velocity_ned()).position.north_m - start.north_m > 10.0
                           and p, 20.0)
        assert moved, "the vehicle did not move north as commanded"
        assert moved.velocity.north_m_s == pytest.approx(2.0, abs=0.1)
        assert moved.velocity.east_m_s == pytest.approx(1.0, abs=0.1)
        # The track points where the velocity asked: east / north = 1 / 2 (the lag settles fast).
        d_north = moved.position.north_m - start.north_m
        d_east = moved.position.east_m - start.east_m
        assert math.degrees(math.atan2(d_east, d_north)) == pytest.approx(math.degrees(math.atan2(1, 2)), abs=3.0)
        offboard.stop()
        assert wait_until(lambda: telemetry.flight_mode() == FlightMode.HOLD, 10.0)
    finally:
        sdk.destroy()
        mock.stop()
    assert mock.proc.returncode == 0
    assert int(mock.summary()["rx_dropped"]) == 0


def test_mavsdk_flies_the_ardupilot_personality_after_asking_for_streams():
    """ArduPilot sends nothing until asked: MAVSDK's set_rate_* calls are what start the telemetry."""
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.offboard import Offboard, VelocityNedYaw
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    port = free_udp_port()
    mock = MockProcess("--autopilot", "ardupilot", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                       "--speedup", "4")
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = sdk.first_autopilot(15.0)
        assert system is not None
        telemetry, action, offboard = Telemetry(system), Action(system), Offboard(system)
        time.sleep(0.5)
        assert math.isnan(telemetry.position_velocity_ned().position.north_m)  # nothing streamed yet
        telemetry.set_rate_position_velocity_ned(20.0)
        assert wait_until(lambda: telemetry.position_velocity_ned().position.down_m == 0.0, 10.0)
        action.set_takeoff_altitude(5.0)
        action.arm()
        action.takeoff()  # MAVSDK switches to GUIDED, then MAV_CMD_NAV_TAKEOFF
        assert wait_until(lambda: abs(telemetry.position_velocity_ned().position.down_m + 5.0) < 0.2, 15.0)
        offboard.set_velocity_ned(VelocityNedYaw(2.0, 1.0, 0.0, 0.0))
        offboard.start()
        moved = wait_until(lambda: (p := telemetry.position_velocity_ned()).position.north_m > 10.0 and p, 20.0)
        assert moved and moved.velocity.east_m_s == pytest.approx(1.0, abs=0.1)
        offboard.stop()  # ArduCopter: BRAKE, which MAVSDK shows as Hold
        assert wait_until(lambda: telemetry.flight_mode() == FlightMode.HOLD, 10.0)
    finally:
        sdk.destroy()
        mock.stop()
    assert mock.proc.returncode == 0


def _tlog_has_heartbeat_mode(path, custom_mode: int) -> bool:
    """Whether a tlog being written holds an autopilot HEARTBEAT with this custom_mode."""
    if not path.exists():
        return False
    log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega", robust_parsing=True)
    try:
        while (msg := log.recv_match(type="HEARTBEAT")) is not None:
            if msg.autopilot == 3 and msg.custom_mode == custom_mode:
                return True
        return False
    finally:
        log.close()


def _mavproxy_scripts(folder) -> str:
    """Staged MAVProxy scripts; each clears the timer, does one step and schedules the next."""
    stages = [
        ["mode GUIDED", "arm throttle"],
        ["takeoff 10"],
        ["mode LOITER"],
        ["mode RTL"],
    ]
    for index, commands in enumerate(stages):
        lines = ["repeat clean", *commands]
        if index + 1 < len(stages):
            lines.append(f"repeat add 1.5 script {folder / f'stage{index + 1}.scr'}")
        (folder / f"stage{index}.scr").write_text("\n".join(lines) + "\n")
    return f"repeat add 3 script {folder / 'stage0.scr'}"


def test_mavproxy_downloads_parameters_shows_and_switches_modes_arms_and_logs(tmp_path):
    port = free_udp_port()
    mock_tlog = tmp_path / "mock.tlog"
    gcs_tlog = tmp_path / "gcs.tlog"
    mock = MockProcess("--autopilot", "ardupilot", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                       "--speedup", "4", "--tlog", str(mock_tlog))
    proxy = subprocess.Popen(
        [sys.executable, str(ROOT / ".venv/bin/mavproxy.py"), f"--master=udpin:127.0.0.1:{port}", "--non-interactive",
         f"--state-basedir={tmp_path}", f"--logfile={gcs_tlog}",
         "--default-modules=log,signing,wp,ftp,param,arm,mode,misc,cmdlong",
         f"--cmd={_mavproxy_scripts(tmp_path)}"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # stopped with SIGINT below
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proxy.stdout.readline, "")), daemon=True)
    reader.start()
    try:
        assert wait_until(lambda: any("Mode RTL" in ln for ln in lines), 45.0), "".join(lines)
        assert wait_until(lambda: any("Received" in ln and "parameters" in ln for ln in lines), 30.0), "".join(lines)
        # MAVProxy writes its tlog from a queue in a thread of its own, which a loaded machine
        # delays: wait until the file holds the mock's RTL heartbeat (the last mode) rather than
        # a fixed time, and only then stop MAVProxy.
        assert wait_until(lambda: _tlog_has_heartbeat_mode(gcs_tlog, 6), 30.0), "RTL heartbeat never reached gcs.tlog"
    finally:
        proxy.send_signal(signal.SIGINT)
        try:
            proxy.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proxy.kill()
        mock.stop()
    out = "".join(lines)
    # Parameters downloaded: the count and values are the mock's.
    served = Personality("ardupilot", "copter").default_params(1, 0.5, 3.0, 5.0, 90.0, 12.0, (15.0, 10.0, 25.0), 45.0)
    assert f"Received {len(served)} parameters" in out
    saved = (tmp_path / "mav.parm").read_text()
    assert "GUID_TIMEOUT" in saved and "SYSID_THISMAV" in saved
    # Modes shown as ArduCopter names, in the order commanded; armed; every command accepted.
    shown = [name for name in ("Mode STABILIZE", "Mode GUIDED", "Mode LOITER", "Mode RTL") if name in out]
    assert shown == ["Mode STABILIZE", "Mode GUIDED", "Mode LOITER", "Mode RTL"]
    assert out.index("Mode GUIDED") < out.index("Mode LOITER") < out.index("Mode RTL")
    assert "ARMED" in out
    assert "COMPONENT_ARM_DISARM: ACCEPTED" in out and "NAV_TAKEOFF: ACCEPTED" in out
    assert "DO_SET_MODE: ACCEPTED" in out
    # MAVProxy's own tlog reads back with mavlogdump.py.
    dump = subprocess.run([sys.executable, str(ROOT / ".venv/bin/mavlogdump.py"), "--types", "HEARTBEAT,COMMAND_ACK",
                           str(gcs_tlog)], capture_output=True, text=True, timeout=60)
    assert dump.returncode == 0
    heartbeats = [ln for ln in dump.stdout.splitlines() if "HEARTBEAT" in ln and "autopilot : 3" in ln]
    assert any("custom_mode : 4," in ln for ln in heartbeats)  # GUIDED
    assert any("custom_mode : 6," in ln for ln in heartbeats)  # RTL
    assert any("COMMAND_ACK" in ln and "command : 400" in ln and "result : 0" in ln for ln in dump.stdout.splitlines())
    # And so does the mock's.
    log = mavutil.mavlink_connection(str(mock_tlog), dialect="ardupilotmega")
    types = set()
    while (msg := log.recv_match()) is not None:
        types.add(msg.get_type())
    assert {"PARAM_REQUEST_LIST", "PARAM_VALUE", "COMMAND_LONG", "COMMAND_ACK", "HEARTBEAT"} <= types
