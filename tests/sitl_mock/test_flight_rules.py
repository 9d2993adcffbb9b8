"""PX4 and ArduPilot rules of the mock's flight logic, driven in simulated time without sockets."""

from __future__ import annotations

import math

import pytest

from sitl_mock import flight as fl
from sitl_mock.flight import FlightLogic
from sitl_mock.personality import Personality, px4_custom_mode
from sitl_mock.vehicle import VehicleModel, VehicleParams

DT_S = 1.0 / 400.0
VEL_ONLY = 0b0000_1111_1100_0111  # position, acceleration, yaw ignored; velocity and yaw rate used
NAN = math.nan


def make(autopilot: str, vehicle: str = "copter", airborne: bool = True, loss_s: float = 0.5, timeout_s: float = 3.0,
         yaw_deg: float = 0.0, posctl=None, **vehicle_kw) -> FlightLogic:
    pers = Personality(autopilot, vehicle)
    vp = VehicleParams(kind=vehicle, **vehicle_kw)
    model = VehicleModel(vp, (0.0, 0.0, -10.0 if airborne else 0.0), math.radians(yaw_deg), airborne)
    params = pers.default_params(1, loss_s, timeout_s, vp.a_max_m_s2, 90.0, vp.v_max_m_s, (15.0, 10.0, 25.0), 45.0)
    return FlightLogic(pers, model, params, airborne, (0.0, 0.0, 0.0), posctl)


def advance(f: FlightLogic, seconds: float, setpoint=None, every_s: float = 0.05) -> None:
    """Step the logic; with ``setpoint`` (args of set_position_target) send it every ``every_s``."""
    steps_between = max(1, round(every_s / DT_S))
    for i in range(round(seconds / DT_S)):
        if setpoint is not None and i % steps_between == 0:
            assert f.set_position_target(*setpoint) is None
        f.step(DT_S)


def vel_setpoint(vn: float, ve: float, vd: float = 0.0, frame: int = fl.MAV_FRAME_LOCAL_NED, yaw_rate: float = 0.0):
    return (frame, VEL_ONLY, (0.0, 0.0, 0.0), (vn, ve, vd), (0.0, 0.0, 0.0), 0.0, yaw_rate)


def test_px4_refuses_offboard_before_setpoints_stream_and_accepts_after():
    f = make("px4")
    offboard = f.pers.mode_named("OFFBOARD")
    assert f.set_mode(offboard) == fl.MAV_RESULT_TEMPORARILY_REJECTED
    assert f.mode.name == "AUTO.LOITER"
    assert any("Offboard refused" in text for _, text in f.events)
    # PX4 checks that the newest setpoint is younger than COM_OF_LOSS_T (0.5 s here).
    f.set_position_target(*vel_setpoint(1.0, 0.0))
    advance(f, 0.6)
    assert f.set_mode(offboard) == fl.MAV_RESULT_TEMPORARILY_REJECTED  # a stale setpoint is not a stream
    advance(f, 0.5, vel_setpoint(1.0, 0.0))
    assert f.set_mode(offboard) == fl.MAV_RESULT_ACCEPTED
    assert f.mode.custom_mode == px4_custom_mode(6)


@pytest.mark.parametrize("loss_s", [0.5, 1.0])
def test_px4_falls_back_to_hold_when_setpoints_stop_for_the_loss_time(loss_s):
    f = make("px4", loss_s=loss_s)
    advance(f, 0.5, vel_setpoint(2.0, 0.0))
    assert f.set_mode(f.pers.mode_named("OFFBOARD")) == fl.MAV_RESULT_ACCEPTED
    advance(f, 2.0, vel_setpoint(2.0, 0.0))
    last = f.t_s - (f.t_s % 0.05)  # the last setpoint went out on a 50 ms tick
    t_fallback = None
    while t_fallback is None and f.t_s < last + 5.0:
        f.step(DT_S)
        if f.mode.name != "OFFBOARD":
            t_fallback = f.t_s
    assert f.mode.name == "AUTO.LOITER"
    assert loss_s < t_fallback - last <= loss_s + 0.05 + DT_S
    # Hold brakes the vehicle to a stop.
    advance(f, 6.0)
    assert math.hypot(*f.model.state.vel_ned_m_s[:2]) < 0.05


def test_ardupilot_guided_velocity_times_out_and_the_vehicle_brakes_staying_in_guided():
    f = make("ardupilot", timeout_s=3.0)
    assert f.set_mode(f.pers.mode_named("GUIDED")) == fl.MAV_RESULT_ACCEPTED
    assert f.set_position_target(*vel_setpoint(3.0, 0.0)) is None
    advance(f, 2.9)
    assert f.model.state.vel_ned_m_s[0] == pytest.approx(3.0, abs=0.01)  # still obeyed before the timeout
    advance(f, 0.2)
    advance(f, 3.0)
    assert f.mode.name == "GUIDED"
    assert math.hypot(*f.model.state.vel_ned_m_s) < 0.01


def test_ardupilot_position_targets_do_not_time_out():
    f = make("ardupilot", timeout_s=1.0)
    f.set_mode(f.pers.mode_named("GUIDED"))
    f.set_position_target(fl.MAV_FRAME_LOCAL_NED, 0b0000_1111_1111_1000, (20.0, 0.0, -10.0), (0, 0, 0), (0, 0, 0),
                          0.0, 0.0)
    advance(f, 15.0)
    assert f.model.state.pos_ned_m[0] == pytest.approx(20.0, abs=0.1)


def test_arducopter_ignores_a_group_when_any_of_its_bits_is_set_and_brakes_on_nothing_left():
    # x and y used, z marked ignored: ArduCopter master ignores the whole position group
    # (`bool pos_ignore = type_mask & MASK_POS_IGNORE`); with velocity and acceleration ignored as
    # well nothing is left, and GUIDED re-initialises: it brakes to a stop where it is.
    f = make("ardupilot")
    f.set_mode(f.pers.mode_named("GUIDED"))
    advance(f, 1.0, vel_setpoint(2.0, 0.0))
    mask_xy_only = 0b0000_1111_1111_1100
    assert f.set_position_target(fl.MAV_FRAME_LOCAL_NED, mask_xy_only, (30.0, 0.0, 0.0), (0, 0, 0), (0, 0, 0),
                                 0.0, 0.0) == "unsupported_type_mask"
    x0 = f.model.state.pos_ned_m[0]
    advance(f, 12.0)
    s = f.model.state
    assert math.hypot(*s.vel_ned_m_s[:2]) < 0.05  # stopped, short of x = 30 and not sent to 0
    assert x0 < s.pos_ned_m[0] < x0 + 3.0
    assert s.pos_ned_m[2] == pytest.approx(-10.0, abs=0.1)  # altitude kept, not z = 0


def test_arducopter_ignores_the_whole_acceleration_group_when_one_of_its_bits_is_set():
    f = make("ardupilot")
    f.set_mode(f.pers.mode_named("GUIDED"))
    vel_accel_but_az = 0b0000_0101_0000_0111  # position, az and yaw ignored
    assert f.set_position_target(fl.MAV_FRAME_LOCAL_NED, vel_accel_but_az, (0, 0, 0), (1.0, 0.0, 0.0),
                                 (0.0, 2.0, 0.0), 0.0, 0.0) is None
    assert f.setpoint.acc_ned_m_s2 == (None, None, None)
    assert f.setpoint.vel_ned_m_s == (1.0, 0.0, 0.0)
    assert f.set_position_target(fl.MAV_FRAME_LOCAL_NED, 0x0407, (0, 0, 0), (1.0, 0.0, 0.0), (0.0, 2.0, 0.0),
                                 0.0, 0.0) is None
    assert f.setpoint.acc_ned_m_s2 == (0.0, 2.0, 0.0)


def test_ardupilot_rover_ignores_a_target_whose_acceleration_is_not_ignored():
    f = make("ardupilot", vehicle="rover", airborne=False)
    f.set_mode(f.pers.mode_named("GUIDED"))
    before = f.setpoint
    assert f.set_position_target(fl.MAV_FRAME_LOCAL_NED, 0x0407, (0, 0, 0), (1.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                                 0.0, 0.0) == "acc_not_ignored"
    assert f.setpoint is before
    assert f.events[-1] == (fl.SEVERITY_INFO, "Ignoring SET_POSITION_TARGET_LOCAL_NED; set ACC_IGNORE in mask"[:50])
    assert f.set_position_target(*vel_setpoint(1.0, 0.0)) is None


def test_px4_reads_each_axis_of_type_mask_so_an_ignored_z_holds_altitude():
    f = make("px4")
    mask_xy_only = 0b0000_1111_1111_1100
    sp = (fl.MAV_FRAME_LOCAL_NED, mask_xy_only, (5.0, 0.0, 0.0), (0, 0, 0), (0, 0, 0), 0.0, 0.0)
    advance(f, 0.5, sp)
    assert f.set_mode(f.pers.mode_named("OFFBOARD")) == fl.MAV_RESULT_ACCEPTED
    advance(f, 12.0, sp)
    assert f.model.state.pos_ned_m[0] == pytest.approx(5.0, abs=0.05)
    assert f.model.state.pos_ned_m[2] == pytest.approx(-10.0, abs=0.05)


def test_body_frame_velocity_is_rotated_by_the_heading():
    f = make("ardupilot", yaw_deg=90.0)  # facing east
    f.set_mode(f.pers.mode_named("GUIDED"))
    assert f.set_position_target(*vel_setpoint(2.0, 0.0, frame=fl.MAV_FRAME_BODY_NED)) is None
    vn, ve, _ = f.setpoint.vel_ned_m_s
    assert vn == pytest.approx(0.0, abs=1e-12)
    assert ve == pytest.approx(2.0)


def test_body_offset_position_is_relative_to_the_vehicle():
    f = make("ardupilot", yaw_deg=180.0)  # facing south, at (0, 0, -10)
    f.set_mode(f.pers.mode_named("GUIDED"))
    f.set_position_target(fl.MAV_FRAME_BODY_OFFSET_NED, 0b0000_1111_1111_1000, (3.0, 0.0, -2.0), (0, 0, 0),
                          (0, 0, 0), 0.0, 0.0)
    assert f.setpoint.pos_ned_m == pytest.approx((-3.0, 0.0, -12.0))


@pytest.mark.parametrize("bad", [NAN, math.inf])
def test_a_non_finite_value_in_a_used_field_is_dropped_and_moves_nothing(bad):
    f = make("ardupilot")
    f.set_mode(f.pers.mode_named("GUIDED"))
    assert f.set_position_target(*vel_setpoint(bad, 0.0)) == "bad_value"
    assert f.setpoint is None
    advance(f, 1.0)
    assert f.model.state.pos_ned_m == pytest.approx([0.0, 0.0, -10.0], abs=1e-9)


def test_nan_in_an_unused_field_is_fine():
    f = make("ardupilot")
    f.set_mode(f.pers.mode_named("GUIDED"))
    assert f.set_position_target(fl.MAV_FRAME_LOCAL_NED, VEL_ONLY, (NAN, NAN, NAN), (1.0, 0.0, 0.0),
                                 (NAN, NAN, NAN), NAN, 0.0) is None


def test_arducopter_takeoff_needs_guided_and_armed_then_climbs_and_hovers():
    f = make("ardupilot", airborne=False)
    assert f.takeoff(10.0, 0.0) == fl.MAV_RESULT_FAILED  # STABILIZE
    f.set_mode(f.pers.mode_named("GUIDED"))
    assert f.takeoff(10.0, 0.0) == fl.MAV_RESULT_FAILED  # disarmed
    assert f.arm(True) == fl.MAV_RESULT_ACCEPTED
    # On the ground in GUIDED, ArduCopter ignores velocity targets until it has taken off.
    advance(f, 1.0, vel_setpoint(0.0, 0.0, -2.0))
    assert f.model.state.on_ground
    assert f.takeoff(10.0, 0.0) == fl.MAV_RESULT_ACCEPTED
    advance(f, 10.0)
    assert -f.model.state.pos_ned_m[2] == pytest.approx(10.0, abs=0.15)
    assert f.mode.name == "GUIDED"


def test_a_velocity_target_during_an_arducopter_guided_takeoff_ends_it_at_once():
    # ArduCopter's GUIDED switches from its TakeOff sub-mode to velocity control on the first
    # target (the real SITL, companion started at 90 % of the take-off height, was moving at
    # 1.5 m/s 1 s later); the mock used to finish the climb first, 1.3 s without moving.
    f = make("ardupilot", airborne=False)
    f.set_mode(f.pers.mode_named("GUIDED"))
    assert f.arm(True) == fl.MAV_RESULT_ACCEPTED
    assert f.takeoff(30.0, 0.0) == fl.MAV_RESULT_ACCEPTED
    advance(f, 6.0)
    alt = -f.model.state.pos_ned_m[2]
    assert 5.0 < alt < 25.0  # climbing
    advance(f, 1.5, vel_setpoint(5.0, 0.0, 0.0))
    s = f.model.state
    # this vehicle's default 0.3 s lag: 5 (1 - exp(-1.5 / 0.3)) = 4.97 m/s if the target is flown at once
    assert s.vel_ned_m_s[0] > 2.0
    assert abs(s.vel_ned_m_s[2]) < 0.5  # the climb is over: vz follows the target's 0
    assert -s.pos_ned_m[2] < 30.0 - 1.0  # and it never reached the take-off height
    assert f.mode.name == "GUIDED"


def test_px4_takeoff_altitude_is_amsl_and_ends_in_hold():
    f = make("px4", airborne=False)
    assert f.arm(True) == fl.MAV_RESULT_ACCEPTED
    assert f.takeoff(488.0 + 7.0, 488.0) == fl.MAV_RESULT_ACCEPTED
    assert f.mode.name == "AUTO.TAKEOFF"
    advance(f, 8.0)
    assert f.mode.name == "AUTO.LOITER"
    assert -f.model.state.pos_ned_m[2] == pytest.approx(7.0, abs=0.15)


def test_disarm_in_the_air_is_refused_unless_forced():
    for autopilot, refusal in (("px4", fl.MAV_RESULT_DENIED), ("ardupilot", fl.MAV_RESULT_FAILED)):
        f = make(autopilot)
        assert f.arm(False) == refusal
        assert f.armed
        assert f.arm(False, force=True) == fl.MAV_RESULT_ACCEPTED


def test_land_descends_touches_down_and_disarms():
    f = make("ardupilot")
    assert f.land() == fl.MAV_RESULT_ACCEPTED
    assert f.mode.name == "LAND"
    advance(f, 14.0)
    assert f.model.state.on_ground
    assert not f.armed


def test_rtl_flies_home_and_lands():
    f = make("px4")
    f.model.state.pos_ned_m[:2] = [40.0, -30.0]
    assert f.return_to_launch() == fl.MAV_RESULT_ACCEPTED
    advance(f, 60.0)
    s = f.model.state
    assert math.hypot(s.pos_ned_m[0], s.pos_ned_m[1]) < 0.6
    assert s.on_ground and not f.armed


def test_mission_modes_are_refused_without_a_mission():
    assert make("px4").set_mode(Personality("px4", "copter").mode_named("AUTO.MISSION")) == \
        fl.MAV_RESULT_TEMPORARILY_REJECTED
    assert make("ardupilot").set_mode(Personality("ardupilot", "copter").mode_named("AUTO")) == fl.MAV_RESULT_FAILED


def test_arduplane_ignores_velocity_targets_and_turns_from_the_attitude_target():
    f = make("ardupilot", vehicle="plane")
    f.set_mode(f.pers.mode_named("GUIDED"))
    assert f.set_position_target(*vel_setpoint(0.0, 5.0)) == "ignored_by_plane"
    roll = math.radians(20.0)
    q = (math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0)
    for _ in range(round(4.0 / DT_S)):
        if _ % 40 == 0:
            assert f.set_attitude_target(0b0000_0111, q) is None
        f.step(DT_S)
    s = f.model.state
    assert s.roll_rad == pytest.approx(roll, abs=1e-3)
    assert s.yaw_rate_rad_s == pytest.approx(9.80665 * math.tan(roll) / s.airspeed_m_s, rel=1e-3)


def test_arduplane_attitude_override_expires_and_the_plane_loiters():
    f = make("ardupilot", vehicle="plane", timeout_s=1.0)
    f.set_mode(f.pers.mode_named("GUIDED"))
    roll = math.radians(-30.0)
    f.set_attitude_target(0b0000_0111, (math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0))
    advance(f, 0.9)
    assert f.model.state.roll_rad < math.radians(-25.0)
    advance(f, 60.0)
    # Loitering clockwise: banked right, turning right.
    assert f.model.state.roll_rad > 0.0 and f.model.state.yaw_rate_rad_s > 0.0


def test_plane_airspeed_change_is_clipped_to_the_band():
    f = make("ardupilot", vehicle="plane")
    assert f.change_speed(0, 40.0) == fl.MAV_RESULT_ACCEPTED
    assert f.airspeed_target_m_s == 25.0
    advance(f, 5.0)
    assert f.model.state.airspeed_m_s == pytest.approx(25.0)


def test_ardupilot_reposition_needs_guided_or_the_change_mode_flag():
    f = make("ardupilot")  # LOITER
    assert f.reposition((10.0, 0.0, None), change_mode=False) == fl.MAV_RESULT_FAILED
    assert f.mode.name == "LOITER"
    assert f.reposition((10.0, 0.0, None), change_mode=True) == fl.MAV_RESULT_ACCEPTED
    assert f.mode.name == "GUIDED"
    advance(f, 12.0)
    assert f.model.state.pos_ned_m == pytest.approx([10.0, 0.0, -10.0], abs=0.05)


def test_out_of_range_velocity_setpoints_are_clamped_to_the_vehicle_limits():
    f = make("ardupilot", v_max_m_s=12.0)
    f.set_mode(f.pers.mode_named("GUIDED"))
    advance(f, 8.0, vel_setpoint(1e30, -1e30, -1e30))
    v = f.model.state.vel_ned_m_s
    assert math.hypot(v[0], v[1]) == pytest.approx(12.0, abs=1e-6)
    assert v[2] == pytest.approx(-fl.VERTICAL_SPEED_UP_MAX_M_S, abs=1e-6)
    assert all(math.isfinite(c) for c in f.model.state.pos_ned_m)


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_plane_takes_off_from_the_ground_then_loiters_at_the_target_altitude(autopilot):
    f = make(autopilot, vehicle="plane", airborne=False)
    assert f.arm(True) == fl.MAV_RESULT_ACCEPTED
    assert f.takeoff(30.0 if autopilot == "ardupilot" else 488.0 + 30.0, 488.0) == fl.MAV_RESULT_ACCEPTED
    advance(f, 1.0)
    s = f.model.state
    assert s.on_ground and s.pos_ned_m[0] > 0.0  # rolling along the runway (heading north)
    advance(f, 60.0)
    assert f.mode == f.pers.hold_mode
    assert -f.model.state.pos_ned_m[2] == pytest.approx(30.0, abs=1.0)
    assert f.model.state.airspeed_m_s >= 10.0


VEL_NO_YAW = VEL_ONLY | fl.MASK_YAW_RATE  # velocity only, neither yaw nor yaw rate


@pytest.mark.parametrize("autopilot, behaviour, expected_yaw_deg", [
    ("ardupilot", 2, 90.0),  # ArduCopter default: the nose follows the direction of travel
    ("ardupilot", 0, 0.0),  # WP_YAW_BEHAVIOR 0: heading kept
    ("px4", None, 0.0),  # PX4 keeps the heading when the setpoint has no yaw
])
def test_heading_when_the_velocity_target_carries_no_yaw(autopilot, behaviour, expected_yaw_deg):
    f = make(autopilot)
    if behaviour is not None:
        f.params["WP_YAW_BEHAVIOR"] = type(f.params["WP_YAW_BEHAVIOR"])(behaviour, f.params["WP_YAW_BEHAVIOR"].param_type)
    east = (fl.MAV_FRAME_LOCAL_NED, VEL_NO_YAW, (0.0, 0.0, 0.0), (0.0, 3.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0)
    advance(f, 0.3, east)
    assert f.set_mode(f.pers.guided_mode) == fl.MAV_RESULT_ACCEPTED
    advance(f, 8.0, east)
    assert math.degrees(f.model.state.yaw_rad) == pytest.approx(expected_yaw_deg, abs=0.5)
    assert f.model.state.vel_ned_m_s[1] == pytest.approx(3.0, abs=0.01)


def test_arducopter_rtl_climbs_to_rtl_alt_in_centimetres_before_going_home():
    f = make("ardupilot")
    f.params["RTL_ALT"] = type(f.params["RTL_ALT"])(2500.0, f.params["RTL_ALT"].param_type)  # 25 m
    f.model.state.pos_ned_m[:2] = [30.0, 0.0]
    assert f.return_to_launch() == fl.MAV_RESULT_ACCEPTED
    highest = 0.0
    for _ in range(round(60.0 / DT_S)):
        f.step(DT_S)
        highest = max(highest, -f.model.state.pos_ned_m[2])
    assert highest == pytest.approx(25.0, abs=0.3)
    assert f.model.state.on_ground and abs(f.model.state.pos_ned_m[0]) < 0.6
