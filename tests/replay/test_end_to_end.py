"""End to end over loopback UDP: fly against sitl_mock, then replay and summarise the real tlog;
and a tlog written by MAVProxy (not by the companion) connected to the mock, summarised."""

from __future__ import annotations

import json
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from companion.cli.main import main
from companion.io.mock_process import free_udp_port
from replay_tlogtools import iter_frames, refresh_crc

ROOT = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.executable).parent

MISSION = """\
name: e2e-sine
frame: local_enu
speed_m_s: 5.0
altitude_m: 10.0
path:
  type: parametric
  x_of_s: "6*sin(0.06*s)"
  y_of_s: "s"
  s_range: [0, 200]
guidance: {l1_m: 10.0, method: corrector, rate_hz: 50}
"""
FLIGHT_S = 5.0
SPT_YAW_RATE_OFFSET = 10 + 4 + 10 * 4  # header, time_boot_ms, x .. yaw
DFA_DATA_OFFSET = 10 + 8 + 2 + 10  # header, time_usec, array_id, name (data is an extension field)



def start_mock(port: int, autopilot: str, *extra: str, duration_s: float = 60.0) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "sitl_mock", "--autopilot", autopilot, "--vehicle", "copter",
         "--link", f"udpout:127.0.0.1:{port}", "--start-airborne", "--start-alt-m", "10",
         "--quiet", "--duration-s", str(duration_s), *extra],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def stop(proc: subprocess.Popen, sig=signal.SIGTERM) -> None:
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@pytest.fixture(scope="module")
def mock_flight(tmp_path_factory):
    """A real flight: `companion fly` against sitl_mock (PX4 copter) for 8 s; its tlog and summary."""
    tmp = tmp_path_factory.mktemp("e2e")
    mission = tmp / "sine.yaml"
    mission.write_text(MISSION)
    tlog = tmp / "flight.tlog"
    port = free_udp_port()
    mock = start_mock(port, "px4", "--start-ned=-12,6")
    try:
        out = subprocess.run(
            [sys.executable, "-m", "companion", "fly", str(mission), "--connect", f"udpin:127.0.0.1:{port}",
             "--tlog", str(tlog), "--max-duration-s", str(FLIGHT_S), "--quiet", "--json"],
            cwd=ROOT, capture_output=True, text=True, timeout=120)
    finally:
        stop(mock)
    assert out.returncode == 0, out.stderr
    return tlog, json.loads(out.stdout)


def test_flight_against_the_mock_replays_within_tolerance(mock_flight, capsys):
    tlog, fly = mock_flight
    assert main(["replay", str(tlog), "--json"]) == 0
    j = json.loads(capsys.readouterr().out)
    assert j["kind"] == "companion"
    assert j["within_tolerance"] is True
    # Every guidance result is a recorded row; a result that arrived after its tick had coasted
    # (a slow re-optimisation) has no setpoint of its own, and there is at most one per coast
    # (plus, on a very busy machine, a rare row whose setpoint left more than 0.45 period later).
    assert j["ticks"] == fly["ticks"] > 0.8 * FLIGHT_S * 50
    assert fly["ticks"] - fly["coast_ticks"] - 2 <= j["steps_compared"] <= fly["ticks"]
    # the flight's own figures are the ones the flight reported
    assert j["d_rms_m"] == pytest.approx(fly["d_rms_m"], rel=1e-5)
    assert j["a_max_m_s2"] == pytest.approx(fly["a_max_m_s2"], rel=1e-5)


def test_flight_with_one_altered_setpoint_is_caught_at_that_tick(mock_flight, tmp_path, capsys):
    tlog, fly = mock_flight
    tampered = tmp_path / "tampered.tlog"
    shutil.copy(tlog, tampered)
    shutil.copy(str(tlog) + ".mission.yaml", str(tampered) + ".mission.yaml")
    data = bytearray(tampered.read_bytes())
    # The setpoints the companion sent in the loop: each comes right after its tick's guidance row.
    frames = list(iter_frames(bytes(data)))
    loop_setpoints = []  # (tick recorded in the row, packet offset, packet length)
    for (_, row_us, row), (off, pkt_us, pkt) in zip(frames, frames[1:]):
        row_id = row[7] | row[8] << 8 | row[9] << 16
        msg_id = pkt[7] | pkt[8] << 8 | pkt[9] << 16
        if pkt[6] == 191 and msg_id == 84 and row_id == 350 and pkt_us - row_us < 2000:
            (tick,) = struct.unpack_from("<f", row, DFA_DATA_OFFSET)
            loop_setpoints.append((int(tick), off + 8, len(pkt)))
    victim, at, length = loop_setpoints[len(loop_setpoints) // 2]
    packet = bytearray(data[at:at + length])
    (old,) = struct.unpack_from("<f", packet, SPT_YAW_RATE_OFFSET)
    struct.pack_into("<f", packet, SPT_YAW_RATE_OFFSET, old + 0.02)
    refresh_crc(packet)
    data[at:at + length] = packet
    tampered.write_bytes(bytes(data))

    assert main(["replay", str(tampered), "--json"]) == 1
    fd = json.loads(capsys.readouterr().out)["first_divergence"]
    assert fd["tick"] == victim
    assert fd["reasons"] == ["yaw_rate"]
    assert fd["logged"]["yaw_rate_rad_s"] - fd["replayed"]["yaw_rate_rad_s"] == pytest.approx(0.02, abs=1e-5)


def test_flight_tlog_summary_shows_both_sides_and_offboard(mock_flight, capsys):
    tlog, fly = mock_flight
    assert main(["log", "summary", str(tlog), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    systems = {(x["system"], x["component"]): (x["type"], x["autopilot"]) for x in s["systems"]}
    assert systems[(1, 1)] == ("MAV_TYPE_QUADROTOR", "MAV_AUTOPILOT_PX4")
    assert systems[(1, 191)] == ("MAV_TYPE_ONBOARD_CONTROLLER", "MAV_AUTOPILOT_INVALID")
    assert "OFFBOARD" in [m["mode"] for m in s["modes"]]
    counts = {(m["component"], m["type"]): m["count"] for m in s["messages"] if m["system"] == 1}
    assert counts[(191, "DEBUG_FLOAT_ARRAY")] == fly["ticks"]
    assert s["warnings"] == []


@pytest.mark.interop
def test_mavproxy_tlog_of_the_mock_is_read_and_summarised(tmp_path):
    mavproxy = VENV_BIN / "mavproxy.py"
    if not mavproxy.exists():
        pytest.fail(f"MAVProxy is part of the interop extra but {mavproxy} is missing")
    port = free_udp_port()
    tlog = tmp_path / "mavproxy.tlog"
    mock = start_mock(port, "px4", duration_s=30.0)
    proxy = subprocess.Popen(
        [sys.executable, str(mavproxy), f"--master=udpin:127.0.0.1:{port}", f"--logfile={tlog}",
         "--non-interactive"],
        cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # stopped with SIGINT below
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and (not tlog.exists() or tlog.stat().st_size < 8_000):
            time.sleep(0.2)
    finally:
        stop(proxy, signal.SIGINT)
        stop(mock)
    from companion.replay.summary import summarise_log

    s = summarise_log(tlog)
    assert s["warnings"] == []
    systems = {(x["system"], x["component"]): (x["type"], x["autopilot"]) for x in s["systems"]}
    assert systems[(1, 1)] == ("MAV_TYPE_QUADROTOR", "MAV_AUTOPILOT_PX4")
    gcs = [k for k, v in systems.items() if v[0] == "MAV_TYPE_GCS"]
    assert gcs, f"MAVProxy's own heartbeat is in its tlog: {systems}"
    kinds = {m["type"] for m in s["messages"] if (m["system"], m["component"]) == (1, 1)}
    assert {"HEARTBEAT", "LOCAL_POSITION_NED"} <= kinds
    assert s["modes"] and s["modes"][0]["armed"] is True  # the mock starts airborne
