"""The bench's baselines (ap_l1, npfg, pure_pursuit) as mission methods: the factory builds them,
their first command on a straight line matches each law's closed form, each flies the gallery in
``companion sim`` and converges, and a baseline flight on the mock replays within tolerance."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.cli.main import main
from companion.geometry.paths import waypoint_path
from companion.guidance.factory import make_law
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import BASELINE_METHODS, METHODS, GuidanceParams, VehicleState
from companion.io.mock_process import free_udp_port
from companion.mission import load_mission
from companion.sim.simulator import simulate

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = ROOT / "missions"
V_M_S = 5.0
LINE = waypoint_path([(0.0, 0.0), (400.0, 0.0)])  # due east


def first_command(method: str, offset_m: float, **tuning: float) -> float:
    """The first command with the vehicle ``offset_m`` left (+) or right (-) of the line, flying east."""
    law = make_law(LINE, GuidanceParams(method=method, **tuning), 50.0, V_M_S)
    return law.step(0.0, VehicleState(100.0, offset_m, 0.0, V_M_S)).a_cmd_m_s2


def test_every_method_is_a_mission_method_and_the_two_phase_object_refuses_a_baseline():
    assert set(BASELINE_METHODS) <= set(METHODS)
    with pytest.raises(ValueError, match="make_law"):
        TwoPhaseGuidance(LINE, GuidanceParams(method="npfg"))


@pytest.mark.parametrize("offset_m", [2.0, -2.0])
def test_ap_l1_on_a_line_two_metres_off_commands_k_v2_d_over_l1_squared(offset_m):
    # ArduPilot defaults T = 17 s, zeta = 0.75: L1 = zeta T V / pi, K = 4 zeta^2, Nu2 = 0,
    # sin(Nu1) = d / L1 towards the line (the integrator has had no time step yet).
    l1 = 0.75 * 17.0 * V_M_S / math.pi
    expected = -4 * 0.75**2 * V_M_S**2 * offset_m / l1**2
    assert first_command("ap_l1", offset_m) == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("offset_m", [2.0, -2.0])
def test_npfg_on_a_line_commands_kp_v_cos_of_its_look_ahead_angle(offset_m):
    # PX4 defaults T = 10 s, zeta = 0.7: e_b = V T zeta, th = pi/2 (1 - |e|/e_b)^2, bearing
    # between "straight at the line" and "along it"; no wind, no curvature: a = k_p V cos(th).
    e_b = V_M_S * 10.0 * 0.7
    theta = 0.5 * math.pi * (1.0 - abs(offset_m) / e_b) ** 2
    expected = -math.copysign(4 * math.pi * 0.7 / 10.0 * V_M_S * math.cos(theta), offset_m)
    assert first_command("npfg", offset_m) == pytest.approx(expected, rel=1e-9)
    period = first_command("npfg", offset_m, period_s=5.0)  # the mission's period_s is used
    theta = 0.5 * math.pi * (1.0 - abs(offset_m) / (V_M_S * 5.0 * 0.7)) ** 2
    assert period == pytest.approx(-math.copysign(4 * math.pi * 0.7 / 5.0 * V_M_S * math.cos(theta), offset_m))


@pytest.mark.parametrize("offset_m", [2.0, -2.0])
def test_pure_pursuit_on_a_line_commands_two_v2_d_over_ld_squared(offset_m):
    # Goal point L_d away on the line: sin(alpha) = d / L_d, a = 2 V^2 sin(alpha) / L_d.
    assert first_command("pure_pursuit", offset_m) == pytest.approx(-2 * V_M_S**2 * offset_m / 10.0**2, rel=1e-9)
    assert first_command("pure_pursuit", offset_m, lookahead_m=5.0) == pytest.approx(
        -2 * V_M_S**2 * offset_m / 5.0**2, rel=1e-9)


def test_the_mission_keys_reach_the_law(tmp_path):
    mission_file = tmp_path / "m.yaml"
    doc = _mission_with_guidance("{method: ap_l1, period_s: 6.0, lookahead_m: 7.0}")
    mission_file.write_text(doc)
    m = load_mission(str(mission_file))
    assert (m.guidance.method, m.guidance.period_s, m.guidance.lookahead_m) == ("ap_l1", 6.0, 7.0)
    law = make_law(m.path, m.guidance, 50.0, m.speed_m_s)
    assert law.params.period_s == 6.0
    mission_file.write_text(_mission_with_guidance("{method: npfg, period_s: 0}"))
    assert main(["mission", "check", str(mission_file)]) == 2


def _mission_with_guidance(guidance: str) -> str:
    return ("name: line\nframe: local_enu\nspeed_m_s: 5.0\naltitude_m: 10.0\n"
            "path: {type: waypoints, points_m: [[0, 0], [200, 0]]}\n"
            f"guidance: {guidance}\n")


@pytest.mark.parametrize("method", BASELINE_METHODS)
def test_each_baseline_joins_the_racetrack_from_its_far_start_and_stays_on_it(method):
    m = load_mission(str(MISSIONS / "racetrack.yaml"))
    assert m.start is not None
    params = dataclasses.replace(m.guidance, method=method)
    start = VehicleState(m.start.x_m, m.start.y_m, m.start.heading_rad, m.speed_m_s)
    res = simulate(m.path, make_law(m.path, params, params.rate_hz, m.speed_m_s), start, params)
    d = np.abs(res.crosstrack_m)
    assert d[0] > 40.0  # a far start: the law has to join the path by itself
    tail = d[2 * d.size // 3:]
    assert tail.max() < 2.0  # converged, and stays on the loop (ap_l1's 20 m L1 is the loosest)
    assert set(res.phase) == {"close_range"}  # no mid-course phase for a baseline


@pytest.mark.parametrize("method", METHODS)
def test_companion_sim_flies_the_paper_sine_with_every_method(method, capsys):
    assert main(["sim", str(MISSIONS / "paper_sine.yaml"), "--method", method, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == method and out["finished"] is True
    assert out["d_rms_m"] < 4.0 and out["a_max_m_s2"] < 6.0


def test_a_baseline_flight_on_the_mock_replays_within_tolerance(tmp_path, capsys):
    mission = tmp_path / "npfg.yaml"
    mission.write_text("name: npfg-sine\nframe: local_enu\nspeed_m_s: 5.0\naltitude_m: 10.0\n"
                       "path: {type: parametric, x_of_s: '6*sin(0.06*s)', y_of_s: s, s_range: [0, 200]}\n"
                       "guidance: {method: npfg, period_s: 4.0, rate_hz: 50}\n")
    tlog = tmp_path / "flight.tlog"
    port = free_udp_port()
    mock = subprocess.Popen(
        [sys.executable, "-m", "sitl_mock", "--autopilot", "px4", "--vehicle", "copter",
         "--link", f"udpout:127.0.0.1:{port}", "--start-airborne", "--start-alt-m", "10",
         "--quiet", "--duration-s", "60", "--start-ned=-12,6"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        fly = subprocess.run(
            [sys.executable, "-m", "companion", "fly", str(mission), "--connect", f"udpin:127.0.0.1:{port}",
             "--tlog", str(tlog), "--max-duration-s", "5", "--quiet", "--json"],
            cwd=ROOT, capture_output=True, text=True, timeout=120)
    finally:
        mock.terminate()
        mock.wait(timeout=10)
    assert fly.returncode == 0, fly.stderr
    assert main(["replay", str(tlog), "--json"]) == 0
    j = json.loads(capsys.readouterr().out)
    assert j["within_tolerance"] is True and j["steps_compared"] > 100
    assert j["d_rms_m"] == pytest.approx(json.loads(fly.stdout)["d_rms_m"], rel=1e-5)
