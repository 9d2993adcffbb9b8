"""``sitl-mock --vehicle-model FILE`` and the copter personalities' identified defaults."""

from __future__ import annotations

import math

import pytest

from sitl_mock.cli import build_parser, config_from_args, main
from sitl_mock.personality import IDENTIFIED_COPTER_MODELS, Personality
from sitl_mock.posctl import PosControlParams


def config(*argv):
    return config_from_args(build_parser().parse_args(list(argv)))


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_copter_flies_the_model_identified_from_its_autopilot_by_default(autopilot):
    vp = config("--autopilot", autopilot).vehicle_params
    model = IDENTIFIED_COPTER_MODELS[autopilot]
    assert (vp.tau_vel_s, vp.a_max_m_s2, vp.delay_s, vp.speed_sag_s) == (
        model["lag_s"], model["a_max_m_s2"], model["delay_s"], model["speed_sag_s"])
    assert vp.yaw_rate_max_rad_s == pytest.approx(math.radians(model["yaw_rate_max_deg_s"]))
    assert (vp.vel_bias_m_s, vp.vel_bias_tc_s) == (model["vel_bias_m_s"], model["vel_bias_tc_s"])
    assert (vp.vel_bias_jerk_s2, vp.vel_bias_jerk_max_m_s3) == (model["vel_bias_jerk_s2"],
                                                                model["vel_bias_jerk_max_m_s3"])
    assert vp.pos_delay_s == model["pos_delay_s"]


def test_a_bias_given_on_the_command_line_is_one_level_throughout():
    assert IDENTIFIED_COPTER_MODELS["ardupilot"]["vel_bias_jerk_s2"] > 0.0
    vp = config("--autopilot", "ardupilot", "--vel-bias-m-s", "0.01").vehicle_params
    assert (vp.vel_bias_m_s, vp.vel_bias_jerk_s2) == (0.01, 0.0)


def test_the_ardupilot_copter_emulates_arducopters_position_controller_unless_a_model_is_given(tmp_path):
    assert config("--autopilot", "ardupilot").posctl == PosControlParams()
    assert config("--autopilot", "px4").posctl is None
    assert config("--autopilot", "ardupilot", "--vehicle", "rover").posctl is None
    f = tmp_path / "vehicle.yaml"
    f.write_text("vehicle:\n  a_max_m_s2: 2.5\n  lag_s: 0.4\n")
    for option in (("--no-posctl",), ("--vehicle-model", str(f)), ("--tau-vel-s", "0.3"), ("--a-max-m-s2", "5")):
        assert config("--autopilot", "ardupilot", *option).posctl is None, option


def test_a_rover_keeps_the_generic_model():
    vp = config("--vehicle", "rover").vehicle_params
    assert (vp.tau_vel_s, vp.a_max_m_s2, vp.delay_s) == (0.3, 3.0, 0.0)


def test_the_vehicle_model_file_sets_the_model_and_options_override_single_values(tmp_path):
    f = tmp_path / "vehicle.yaml"
    f.write_text("# from companion identify\nvehicle:\n  a_max_m_s2: 2.5\n  lag_s: 0.4\n  delay_s: 0.15\n"
                 "  speed_sag_s: 0.1\n  yaw_rate_max_deg_s: 60\n")
    vp = config("--vehicle-model", str(f)).vehicle_params
    assert (vp.a_max_m_s2, vp.tau_vel_s, vp.delay_s, vp.speed_sag_s, vp.accel_lag_s) == (2.5, 0.4, 0.15, 0.1, 0.0)
    assert vp.yaw_rate_max_rad_s == pytest.approx(math.radians(60.0))
    vp = config("--vehicle-model", str(f), "--a-max-m-s2", "4").vehicle_params
    assert (vp.a_max_m_s2, vp.tau_vel_s) == (4.0, 0.4)
    assert (vp.vel_bias_m_s, vp.vel_bias_tc_s) == (0.0, 3.0)  # the file has no bias: none
    f.write_text(f.read_text() + "  vel_bias_m_s: 0.2\n  vel_bias_tc_s: 5\n")
    vp = config("--vehicle-model", str(f)).vehicle_params
    assert (vp.vel_bias_m_s, vp.vel_bias_tc_s) == (0.2, 5.0)
    assert (vp.vel_bias_jerk_s2, vp.vel_bias_jerk_max_m_s3) == (0.0, 1.0)  # none in the file: one level
    f.write_text(f.read_text() + "  vel_bias_jerk_s2: 0.03\n  vel_bias_jerk_max_m_s3: 1.5\n")
    vp = config("--vehicle-model", str(f)).vehicle_params
    assert (vp.vel_bias_jerk_s2, vp.vel_bias_jerk_max_m_s3) == (0.03, 1.5)
    assert config("--vehicle-model", str(f), "--vel-bias-m-s", "0").vehicle_params.vel_bias_m_s == 0.0
    assert config("--vehicle-model", str(f)).vehicle_params.vel_offset_m_s == 0.0  # none in the file
    f.write_text(f.read_text() + "  vel_offset_m_s: 0.01\n")
    assert config("--vehicle-model", str(f)).vehicle_params.vel_offset_m_s == 0.01
    assert config("--vehicle-model", str(f), "--vel-offset-m-s", "0").vehicle_params.vel_offset_m_s == 0.0
    # without a file, the personality's: ArduCopter's offset, none for PX4
    assert config("--autopilot", "ardupilot").vehicle_params.vel_offset_m_s == IDENTIFIED_COPTER_MODELS[
        "ardupilot"]["vel_offset_m_s"] > 0.0
    assert config("--autopilot", "px4").vehicle_params.vel_offset_m_s == 0.0


@pytest.mark.parametrize("text, expected", [
    ("vehicle:\n  lag_s: 0.4\n", "vehicle.a_max_m_s2: missing"),
    ("vehicle:\n  a_max_m_s2: 2\n  lag_s: 0.4\n  lag: 1\n", "vehicle.lag: unknown key"),
    ("vehicle:\n  a_max_m_s2: fast\n  lag_s: 0.4\n", "vehicle.a_max_m_s2: expected a finite number"),
    ("name: x\n", "expected a mapping with a vehicle: block"),
    ("vehicle: [1\n", "not YAML"),
])
def test_a_bad_vehicle_model_file_is_one_line_and_exit_2(tmp_path, capsys, text, expected):
    f = tmp_path / "vehicle.yaml"
    f.write_text(text)
    assert main(["--vehicle-model", str(f), "--duration-s", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0], err


@pytest.mark.parametrize("a_max_m_s2, tilt_deg", [(3.86, 45.0), (12.0, math.degrees(math.atan(12.0 / 9.80665)))])
def test_the_px4_mock_publishes_the_firmware_tilt_limit_unless_its_vehicle_is_faster(a_max_m_s2, tilt_deg):
    # Real PX4 bounds OFFBOARD velocity control only by g tan(MPC_TILTMAX_AIR), 45 deg by default,
    # far above what its SIH quadrotor flies: the mock publishes the same, so that a companion
    # reads on the mock what it reads on the firmware.
    params = Personality("px4", "copter").default_params(1, 0.5, 3.0, a_max_m_s2, 90.0, 12.0, (15.0, 10.0, 25.0), 45.0)
    assert params["MPC_TILTMAX_AIR"].value == pytest.approx(tilt_deg)
    assert 9.80665 * math.tan(math.radians(params["MPC_TILTMAX_AIR"].value)) >= a_max_m_s2 - 1e-9
