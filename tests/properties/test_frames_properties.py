"""Property tests: the ENU <-> NED conversions of ``companion.geometry.frames``.

The conversions are a fixed reflection (swap the horizontal axes, negate the vertical one), so
every conversion composed with its inverse is the identity, angles agree with vectors, and a
rotation in one frame is the opposite rotation in the other. Each property is checked against
independent arithmetic (unit vectors built with cos/sin), never against the module itself.
"""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from companion.geometry import frames

coord = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
angle = st.floats(min_value=-100.0, max_value=100.0, allow_nan=False, allow_infinity=False)
speed = st.floats(min_value=0.01, max_value=100.0, allow_nan=False, allow_infinity=False)


def same_direction(a_rad: float, b_rad: float, tol: float = 1e-9) -> bool:
    """Two angles point the same way (compared as unit vectors, immune to wrapping)."""
    return math.hypot(math.cos(a_rad) - math.cos(b_rad), math.sin(a_rad) - math.sin(b_rad)) <= tol


@settings(max_examples=200, deadline=None)
@given(coord, coord, coord)
def test_position_round_trip_enu_ned_enu_is_identity(x, y, z):
    assert frames.enu_from_ned(*frames.ned_from_enu(x, y, z)) == (x, y, z)
    assert frames.ned_from_enu(*frames.enu_from_ned(x, y, z)) == (x, y, z)


@settings(max_examples=200, deadline=None)
@given(coord, coord, coord)
def test_north_is_north_in_both_frames(north, east, down):
    # NED (north, east, down) -> ENU must read (east, north, up) component by component.
    e, n, u = frames.enu_from_ned(north, east, down)
    assert (e, n, u) == (east, north, -down)
    vx, vy, vz = frames.vel_ned_from_enu(e, n, u)
    assert (vx, vy, vz) == (north, east, down)


@settings(max_examples=200, deadline=None)
@given(angle)
def test_course_round_trip_is_the_same_direction_and_wrapped(theta):
    yaw = frames.yaw_ned_from_enu(theta)
    back = frames.course_enu_from_ned(yaw)
    assert -math.pi < yaw <= math.pi
    assert -math.pi < back <= math.pi
    assert same_direction(back, theta, 1e-9 * max(1.0, abs(theta)))


@settings(max_examples=200, deadline=None)
@given(angle, speed)
def test_course_angle_matches_the_velocity_vector(theta, v):
    # An ENU velocity along course theta, converted to NED, has NED course atan2(east, north)
    # equal to the NED yaw of theta, and the ENU course recovered from the NED velocity is theta.
    ve, vn = v * math.cos(theta), v * math.sin(theta)
    vx_ned, vy_ned, _ = frames.vel_ned_from_enu(ve, vn, 0.0)
    assert same_direction(math.atan2(vy_ned, vx_ned), frames.yaw_ned_from_enu(theta), 1e-9 * max(1, abs(theta)))
    assert same_direction(frames.course_enu_from_vel_ned(vx_ned, vy_ned), theta, 1e-9 * max(1, abs(theta)))


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=-50.0, max_value=50.0, allow_nan=False))
def test_yaw_rate_round_trip_and_sign(r):
    assert frames.yaw_rate_enu_from_ned(frames.yaw_rate_ned_from_enu(r)) == r
    # Turning left (anticlockwise, ENU positive) is turning towards the west from north: NED yaw
    # decreasing, so the NED rate has the opposite sign.
    assert frames.yaw_rate_ned_from_enu(r) == -r


@settings(max_examples=200, deadline=None)
@given(angle, st.floats(min_value=-3.0, max_value=3.0, allow_nan=False))
def test_a_left_turn_in_enu_is_a_clockwise_decrease_in_ned(theta, dtheta):
    # Rotating a course by +dtheta in ENU rotates the NED yaw by -dtheta.
    d_yaw = frames.angle_diff_rad(frames.yaw_ned_from_enu(theta + dtheta), frames.yaw_ned_from_enu(theta))
    assert math.isclose(d_yaw, -dtheta, abs_tol=1e-9 * max(1.0, abs(theta)))


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-1e4, max_value=1e4, allow_nan=False))
def test_wrap_pi_is_in_range_and_keeps_direction(a):
    w = frames.wrap_pi(a)
    assert -math.pi < w <= math.pi
    assert same_direction(w, a, 1e-9 * max(1.0, abs(a)))
    w2 = frames.wrap_2pi(a)
    assert 0.0 <= w2 < 2.0 * math.pi
    assert same_direction(w2, a, 1e-9 * max(1.0, abs(a)))
