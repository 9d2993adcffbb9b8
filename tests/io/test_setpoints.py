"""Lateral acceleration -> setpoint fields: hand geometry, sign conventions, the one-tick claim."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from companion.geometry import frames
from companion.io import setpoints as sp

HOLD = sp.AltitudeHold(10.0)


def test_flying_east_without_turn_commands_pure_east_velocity():
    s = sp.velocity_setpoint(0.0, 0.0, 5.0, 0.02, 10.0, HOLD)
    assert s.vx_ned_m_s == pytest.approx(0.0, abs=1e-12)
    assert s.vy_ned_m_s == pytest.approx(5.0)
    assert s.vz_ned_m_s == 0.0
    assert s.yaw_rate_ned_rad_s == 0.0
    assert s.type_mask == 1479 and s.coordinate_frame == 1


def test_type_mask_ignores_all_three_position_bits_and_uses_vz():
    # ArduCopter treats x, y, z as one group (ignored when any bit is set), PX4 each axis: all three
    # ignored, so that both fly the velocity and neither a position.
    m = sp.TYPE_MASK_VELOCITY_YAW_RATE
    assert m & 0b111 == 0b111
    assert m & (8 | 16 | 32) == 0  # vx, vy, vz used
    assert m & 2048 == 0 and m & 1024  # yaw rate used, yaw ignored
    assert m == 0x05C7


def test_left_turn_east_bends_velocity_north_and_yaw_rate_is_clockwise_negative():
    a, v, dt = 2.0, 5.0, 0.1
    s = sp.velocity_setpoint(a, 0.0, v, dt, 10.0, HOLD)
    expected_course = a / v * dt  # 0.04 rad left of east
    assert s.course_cmd_enu_rad == pytest.approx(expected_course)
    assert s.vx_ned_m_s == pytest.approx(v * math.sin(expected_course))  # north component
    assert s.vy_ned_m_s == pytest.approx(v * math.cos(expected_course))
    assert s.yaw_rate_ned_rad_s == pytest.approx(-a / v)


def test_velocity_magnitude_is_the_mission_speed_whatever_the_command():
    for a in (-30.0, -1.0, 0.0, 0.5, 12.0):
        for course in (-3.1, -1.0, 0.0, 2.0, 3.14):
            s = sp.velocity_setpoint(a, course, 4.0, 0.02, 10.0, HOLD)
            assert math.hypot(s.vx_ned_m_s, s.vy_ned_m_s) == pytest.approx(4.0)


def test_altitude_held_by_vertical_velocity_clamped():
    hold = sp.AltitudeHold(10.0, gain_1_s=1.0, max_climb_m_s=2.0)
    assert hold.vz_ned_m_s(9.5) == pytest.approx(-0.5)  # climb 0.5 m/s = negative down
    assert hold.vz_ned_m_s(0.0) == pytest.approx(-2.0)  # clamped climb
    assert hold.vz_ned_m_s(30.0) == pytest.approx(2.0)  # clamped descent
    assert hold.vz_ned_m_s(float("nan")) == 0.0


def test_hold_is_zero_velocity_zero_yaw_rate():
    h = sp.hold_setpoint(10.0, HOLD)
    assert h.is_hold and h.vz_ned_m_s == 0.0


def test_position_hold_points_back_at_the_anchor_proportionally_then_limited():
    # 0.3 m north and 0.4 m east of the anchor: 0.5 m off, gain 1/s -> 0.5 m/s back, south-west
    h = sp.position_hold_setpoint(10.3, -4.6, 10.0, -5.0, 10.0, HOLD)
    assert (h.vx_ned_m_s, h.vy_ned_m_s) == (pytest.approx(-0.3), pytest.approx(-0.4))
    assert h.yaw_rate_ned_rad_s == 0.0 and h.vz_ned_m_s == sp.hold_setpoint(10.0, HOLD).vz_ned_m_s
    # 30 m off (3-4-5): limited to 1 m/s, same direction
    h = sp.position_hold_setpoint(-18.0, 24.0, 0.0, 0.0, 10.0, HOLD, gain_1_s=1.0, max_speed_m_s=1.0)
    assert (h.vx_ned_m_s, h.vy_ned_m_s) == (pytest.approx(0.6), pytest.approx(-0.8))
    # on the anchor: the plain hold
    assert sp.position_hold_setpoint(1.0, 2.0, 1.0, 2.0, 10.0, HOLD).is_hold


def test_position_hold_on_a_non_finite_position_is_the_plain_hold_never_nan():
    for bad in (math.nan, math.inf):
        h = sp.position_hold_setpoint(bad, 0.0, 0.0, 0.0, 10.0, HOLD)
        assert h.is_hold and math.isfinite(h.vz_ned_m_s)


def test_velocity_vector_reaches_the_commanded_turn_within_one_tick():
    """A vehicle that flies each tick's velocity exactly follows the ideal unicycle with no lag.

    Unicycle: course(t) = c0 + (a/V) t. The vehicle holds the velocity commanded at tick k for one
    tick. Its course during tick k equals the ideal course at t_{k+1} (one tick ahead, never
    behind), and its position stays within the chord/arc bound V dt * |omega| dt / 2 per tick of
    the exact circle, i.e. at most one tick's displacement of lag.
    """
    a, v, dt, n = 1.5, 5.0, 0.02, 400
    omega = a / v
    x = y = 0.0
    course = 0.0
    max_err = 0.0
    for k in range(n):
        s = sp.velocity_setpoint(a, course, v, dt, 10.0, HOLD)
        ve, vn = s.vy_ned_m_s, s.vx_ned_m_s
        flown_course = math.atan2(vn, ve)
        ideal_next = frames.wrap_pi(omega * (k + 1) * dt)
        assert abs(frames.angle_diff_rad(flown_course, ideal_next)) < 1e-9
        x += ve * dt
        y += vn * dt
        course = flown_course  # the measured course at the next tick
        t = (k + 1) * dt
        # exact circle from the origin heading east, turning left with radius V/omega
        r = v / omega
        xe, ye = r * math.sin(omega * t), r * (1 - math.cos(omega * t))
        max_err = max(max_err, math.hypot(x - xe, y - ye))
    # The error is a constant half-tick lead along the arc: bounded by one tick's travel V dt.
    assert max_err <= v * dt


def test_coordinated_turn_bank_is_atan_a_over_g_and_limited():
    assert sp.bank_angle_rad(sp.G_M_S2, 60.0) == pytest.approx(math.pi / 4)
    assert sp.bank_angle_rad(100.0, 35.0) == pytest.approx(math.radians(35.0))
    assert sp.bank_angle_rad(-100.0, 35.0) == pytest.approx(-math.radians(35.0))


def test_left_turn_command_rolls_left_wing_down_in_ned():
    s = sp.attitude_setpoint(3.0, 0.0, 45.0)
    assert s.roll_ned_rad == pytest.approx(-math.atan(3.0 / sp.G_M_S2))
    w, qx, qy, qz = s.q
    # roll from the quaternion (aerospace 3-2-1)
    roll = math.atan2(2 * (w * qx + qy * qz), 1 - 2 * (qx * qx + qy * qy))
    yaw = math.atan2(2 * (w * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    assert roll == pytest.approx(s.roll_ned_rad)
    assert yaw == pytest.approx(math.pi / 2)  # flying east: NED yaw 90 deg
    assert math.isclose(w * w + qx * qx + qy * qy + qz * qz, 1.0)


# ----------------------------------------------------------------- acceleration feed-forward


def test_feed_forward_mask_uses_all_acceleration_bits_and_still_ignores_position_and_yaw():
    # ArduCopter ignores the whole acceleration target if any of its three bits is set.
    m = sp.TYPE_MASK_VELOCITY_ACCEL_YAW_RATE
    assert m & (64 | 128 | 256) == 0 and m & 0b111 == 0b111
    assert m & (8 | 16 | 32) == 0 and m & 2048 == 0 and m & 1024
    assert m == 0x0407 == 1031


def test_feed_forward_points_left_of_the_commanded_course_and_is_limited():
    # Flying north (ENU 90 deg), a right turn of 1.5 m/s^2: the acceleration points east.
    s = sp.velocity_setpoint(-1.5, math.pi / 2, 5.0, 0.0, 10.0, HOLD, accel_ff_max_m_s2=2.5)
    assert (s.afx_ned_m_s2, s.afy_ned_m_s2) == pytest.approx((0.0, 1.5), abs=1e-12)
    assert s.type_mask == sp.TYPE_MASK_VELOCITY_ACCEL_YAW_RATE
    # 4 m/s^2 asked, 2.5 allowed: the acceleration is limited, the yaw rate and velocity are not.
    big = sp.velocity_setpoint(4.0, 0.0, 5.0, 0.02, 10.0, HOLD, accel_ff_max_m_s2=2.5)
    plain = sp.velocity_setpoint(4.0, 0.0, 5.0, 0.02, 10.0, HOLD)
    assert math.hypot(big.afx_ned_m_s2, big.afy_ned_m_s2) == pytest.approx(2.5)
    assert (big.vx_ned_m_s, big.vy_ned_m_s, big.yaw_rate_ned_rad_s) == (
        plain.vx_ned_m_s, plain.vy_ned_m_s, plain.yaw_rate_ned_rad_s)
    assert (plain.afx_ned_m_s2, plain.afy_ned_m_s2, plain.type_mask) == (0.0, 0.0, 1479)


@given(a=st.floats(-20, 20), course=st.floats(-math.pi, math.pi), a_max=st.floats(0.1, 10))
def test_feed_forward_is_perpendicular_to_the_velocity_and_turns_it_the_commanded_way(a, course, a_max):
    s = sp.velocity_setpoint(a, course, 5.0, 0.02, 10.0, HOLD, accel_ff_max_m_s2=a_max)
    f_n, f_e, v_n, v_e = s.afx_ned_m_s2, s.afy_ned_m_s2, s.vx_ned_m_s, s.vy_ned_m_s
    assert abs(f_n * v_n + f_e * v_e) <= 1e-9 * 5.0 * max(1.0, a_max)
    assert math.hypot(f_n, f_e) == pytest.approx(min(abs(a), a_max), abs=1e-9)
    # NED: v x f (down component) < 0 is a left (anticlockwise seen from above) turn, as a > 0.
    cross_down = v_n * f_e - v_e * f_n
    assert cross_down == pytest.approx(-5.0 * max(-a_max, min(a_max, a)), abs=1e-9)
