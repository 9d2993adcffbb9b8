"""ENU <-> NED conversions, checked against hand geometry and round trips across the +-pi wrap."""

import math

import pytest
from hypothesis import given, strategies as st

from companion.geometry import frames

finite = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)
angles = st.floats(min_value=-20.0, max_value=20.0, allow_nan=False)


def test_ten_metres_north_five_up_is_y_ten_z_five_in_enu():
    assert frames.enu_from_ned(10.0, 0.0, -5.0) == (0.0, 10.0, 5.0)
    assert frames.ned_from_enu(3.0, 0.0, 0.0) == (0.0, 3.0, -0.0)


@pytest.mark.parametrize(
    "yaw_ned_deg, course_enu_deg",
    [(0.0, 90.0), (90.0, 0.0), (180.0, -90.0), (-90.0, 180.0), (45.0, 45.0), (135.0, -45.0)],
)
def test_compass_directions_map_to_enu_angles(yaw_ned_deg, course_enu_deg):
    got = math.degrees(frames.course_enu_from_ned(math.radians(yaw_ned_deg)))
    assert abs(frames.wrap_pi(math.radians(got - course_enu_deg))) < 1e-12


def test_heading_just_either_side_of_west_stays_continuous():
    # West is +-pi in ENU; NED yaw -90 deg +- 1 deg lands either side of the wrap.
    a = frames.course_enu_from_ned(math.radians(-89.0))
    b = frames.course_enu_from_ned(math.radians(-91.0))
    assert a == pytest.approx(math.radians(179.0))
    assert b == pytest.approx(math.radians(-179.0))
    assert frames.angle_diff_rad(b, a) == pytest.approx(math.radians(2.0))


@given(finite, finite, finite)
def test_positions_round_trip_both_ways(x, y, z):
    assert frames.enu_from_ned(*frames.ned_from_enu(x, y, z)) == (x, y, z)
    assert frames.ned_from_enu(*frames.enu_from_ned(x, y, z)) == (x, y, z)


@given(angles)
def test_angles_round_trip_both_ways_within_wrap(theta):
    back = frames.course_enu_from_ned(frames.yaw_ned_from_enu(theta))
    assert abs(frames.angle_diff_rad(back, theta)) < 1e-9
    back2 = frames.yaw_ned_from_enu(frames.course_enu_from_ned(theta))
    assert abs(frames.angle_diff_rad(back2, theta)) < 1e-9
    assert -math.pi < frames.wrap_pi(theta) <= math.pi


def test_velocity_course_north_east_and_south_west():
    assert frames.course_enu_from_vel_ned(1.0, 0.0) == pytest.approx(math.pi / 2)
    assert frames.course_enu_from_vel_ned(0.0, 1.0) == pytest.approx(0.0)
    assert frames.course_enu_from_vel_ned(-1.0, -1.0) == pytest.approx(-3 * math.pi / 4)


@given(st.floats(min_value=-math.pi, max_value=math.pi), st.floats(min_value=-2.0, max_value=2.0))
def test_left_turn_in_enu_is_a_clockwise_negative_rate_in_ned(theta, rate_enu):
    # Integrating the ENU rate then converting equals converting then integrating the NED rate.
    dt = 0.1
    ned_after = frames.yaw_ned_from_enu(theta + rate_enu * dt)
    ned_integrated = frames.yaw_ned_from_enu(theta) + frames.yaw_rate_ned_from_enu(rate_enu) * dt
    assert abs(frames.angle_diff_rad(ned_after, ned_integrated)) < 1e-9
    assert frames.yaw_rate_enu_from_ned(frames.yaw_rate_ned_from_enu(rate_enu)) == rate_enu


def test_wrap_helpers_boundaries():
    assert frames.wrap_pi(math.pi) == pytest.approx(math.pi)
    assert frames.wrap_pi(-math.pi) == pytest.approx(math.pi)
    assert frames.wrap_2pi(2 * math.pi) == pytest.approx(0.0)
    assert frames.wrap_2pi(-0.5) == pytest.approx(2 * math.pi - 0.5)
