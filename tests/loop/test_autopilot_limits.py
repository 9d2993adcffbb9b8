"""The acceleration limit read from the autopilot at start-up (companion.loop.limits): which
parameter gives which limit, when the mission's own word wins, and a flight on the mock that
reads the mock's WPNAV_ACCEL, says so, flies within it and replays within tolerance."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink import mavutil

from companion.cli.main import main
from companion.guidance.types import VehicleModel
from companion.io.mock_process import free_udp_port
from companion.loop.limits import AutopilotLimit, limit_from_params, mission_with_limit
from companion.mission import load_mission

ROOT = Path(__file__).resolve().parents[2]


def test_wpnav_accel_is_in_centimetres_and_zero_means_the_firmware_default():
    assert limit_from_params({"WPNAV_ACCEL": 243.0}).a_max_m_s2 == pytest.approx(2.43)
    assert limit_from_params({"WPNAV_ACCEL": 0.0}).a_max_m_s2 == pytest.approx(2.5)


def test_px4_tilt_limit_bounds_the_acceleration_by_g_tan_tilt():
    # 30 deg: g tan(30 deg) = 9.80665 / sqrt(3)
    assert limit_from_params({"MPC_TILTMAX_AIR": 30.0}).a_max_m_s2 == pytest.approx(9.80665 / math.sqrt(3.0))
    assert limit_from_params({"MPC_TILTMAX_AIR": 95.0}) is None
    assert limit_from_params({"OTHER": 1.0}) is None


def test_the_mission_says_otherwise_with_a_vehicle_block_or_a_lower_guidance_limit():
    m = load_mission(str(ROOT / "missions" / "racetrack.yaml"))
    limit = AutopilotLimit(2.5, "WPNAV_ACCEL 250 cm/s^2")
    assert m.vehicle is None and math.isinf(m.guidance.a_max_m_s2)
    used, line = mission_with_limit(m, limit)
    assert used.guidance.a_max_m_s2 == 2.5 and "from the autopilot's WPNAV_ACCEL" in line
    lower = dataclasses.replace(m, guidance=dataclasses.replace(m.guidance, a_max_m_s2=2.0))
    used, line = mission_with_limit(lower, limit)
    assert used.guidance.a_max_m_s2 == 2.0 and "guidance.a_max_m_s2" in line
    with_vehicle = dataclasses.replace(m, vehicle=VehicleModel(a_max_m_s2=4.0, lag_s=0.3))
    used, line = mission_with_limit(with_vehicle, limit)
    assert used is with_vehicle and "vehicle: block" in line and "not used" in line


@pytest.mark.parametrize("mission_limit, read", [(math.inf, 2.5), (2.0, 2.5), (math.inf, None)])
def test_with_a_limit_read_and_no_vehicle_block_the_model_monitor_is_on_and_the_log_says_so(mission_limit, read):
    # Nothing describes how the autopilot flies the commands: predictive must learn it in flight.
    # With no limit read (no PARAM_VALUE in the log for replay to see) the mission is flown as it is.
    m = load_mission(str(ROOT / "missions" / "racetrack.yaml"))
    m = dataclasses.replace(m, guidance=dataclasses.replace(m.guidance, method="predictive", a_max_m_s2=mission_limit))
    assert not m.guidance.adapt_model
    used, line = mission_with_limit(m, None if read is None else AutopilotLimit(read, "WPNAV_ACCEL 250 cm/s^2"))
    if read is None:
        assert used is m and "model monitor" not in line
    else:
        assert used.guidance.adapt_model and "model monitor" in line
        assert used.guidance.a_max_m_s2 == min(mission_limit, read)


def _messages(tlog: Path) -> list:
    conn = mavutil.mavlink_connection(str(tlog))
    out = []
    while (m := conn.recv_match()) is not None:
        out.append(m)
    return out


def test_a_flight_on_the_mock_reads_wpnav_accel_flies_within_it_and_replays(tmp_path, capsys):
    mission = tmp_path / "tight.yaml"
    # A 6 m circle at 5 m/s needs V^2/R = 4.2 m/s^2, more than the mock ArduCopter's WPNAV_ACCEL
    # (the firmware's default 250 cm/s^2, which its emulated position controller keeps to).
    mission.write_text("name: tight\nframe: local_enu\nspeed_m_s: 5.0\naltitude_m: 10.0\n"
                       "path: {type: parametric, x_of_s: '6*cos(s)', y_of_s: '6*sin(s)', "
                       "s_range: [0, 6.283185307179586], closed: true}\n"
                       "guidance: {method: predictive, accel_feedforward: true}\n")
    tlog = tmp_path / "flight.tlog"
    port = free_udp_port()
    mock = subprocess.Popen(
        [sys.executable, "-m", "sitl_mock", "--autopilot", "ardupilot", "--vehicle", "copter",
         "--link", f"udpout:127.0.0.1:{port}", "--start-airborne", "--start-alt-m", "10",
         "--quiet", "--duration-s", "60", "--start-ned=0,6"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        fly = subprocess.run(
            [sys.executable, "-m", "companion", "fly", str(mission), "--connect", f"udpin:127.0.0.1:{port}",
             "--tlog", str(tlog), "--max-duration-s", "4", "--json"],
            cwd=ROOT, capture_output=True, text=True, timeout=120)
    finally:
        mock.terminate()
        mock.wait(timeout=10)
    assert fly.returncode == 0, fly.stderr
    assert "acceleration limit 2.5 m/s^2 from the autopilot's WPNAV_ACCEL 250 cm/s^2" in fly.stderr
    # and it slows for the circle: V = sqrt(0.8 * 2.5 * 6) on the whole of it
    assert f"slower in the path's turns: down to {math.sqrt(12.0):.2f} m/s over 100 % of the path" in fly.stderr
    assert json.loads(fly.stdout)["a_max_m_s2"] <= 2.5 + 1e-9
    # Asked for by the mission (the log names the key): the command also goes as the acceleration
    # target, within the same limit, and the replay below finds that from the log.
    assert "acceleration feed-forward: the setpoints carry the command up to 2.5 m/s^2 (guidance.accel_feedforward)" in fly.stderr
    sent = [m for m in _messages(tlog) if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED" and m.type_mask == 1031]
    assert len(sent) > 100
    # flown at sqrt(12) m/s the circle asks 0.8 x 2.5 = 2 m/s^2: about that, never beyond the limit
    assert 1.5 < max(math.hypot(m.afx, m.afy) for m in sent) <= 2.5 + 1e-6
    assert main(["replay", str(tlog), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["within_tolerance"] is True
