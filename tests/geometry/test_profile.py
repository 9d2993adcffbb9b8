"""Altitude and speed profiles along a path, checked against hand arithmetic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.profile import ProfileLimits, build_profile, knots_table, moving_average

LIMITS = ProfileLimits(climb_max_m_s=2.0, sink_max_m_s=1.5, vert_accel_max_m_s2=1.0,
                       along_accel_max_m_s2=1.0)


def vertical_accel_m_s2(p):
    """d(climb)/dt = V d(V h')/ds, by finite differences on the table."""
    c = p.climb_table_m_s()
    return p.speed_m_s_table[1:] * np.diff(c) / np.diff(p.s_m)


def test_a_gentle_linear_ramp_climbs_at_constant_v_dh_ds():
    # 10 m to 30 m over 400 m at 5 m/s: dh/ds = 0.05, climb = 5 * 0.05 = 0.25 m/s everywhere
    # (a single slope: no corner for the acceleration limit to round).
    p = build_profile(400.0, False, LIMITS, alt_target=lambda s: 10.0 + 0.05 * s, speed_target=5.0)
    for s in (0.0, 37.5, 200.0, 399.0, 400.0):
        assert p.altitude_m(s) == pytest.approx(10.0 + 0.05 * s, abs=1e-9)
        assert p.climb_m_s(s) == pytest.approx(0.25, abs=1e-9)


def test_a_ramp_too_steep_is_clipped_to_the_climb_limit_and_centred():
    # 0 -> 100 m over the middle 100 m of a 600 m path at 5 m/s asks dh/ds = 1 (5 m/s); the limit
    # 2 m/s allows 0.4: the climb takes 250 m, centred on the requested ramp (mean of the forward
    # pass, late, and the backward pass, early), so h = 50 m at s = 300 m as asked.
    target = lambda s: np.interp(s, [0, 250, 350, 600], [10, 10, 110, 110])  # noqa: E731
    p = build_profile(600.0, False, LIMITS, alt_target=target, speed_target=5.0)
    c = p.climb_table_m_s()
    assert c.max() <= 2.0 and c.max() == pytest.approx(2.0, rel=1e-3)
    assert p.altitude_m(300.0) == pytest.approx(60.0, abs=1e-6)
    assert p.altitude_m(0.0) == pytest.approx(10.0) and p.altitude_m(600.0) == pytest.approx(110.0)
    # Mid-climb the slope is the limit: 2 m/s / 5 m/s.
    assert p.slope(300.0) == pytest.approx(0.4, rel=1e-4)


@pytest.mark.parametrize("v", [3.0, 5.0, 12.0])
def test_the_smoothed_profile_never_exceeds_the_climb_sink_or_vertical_acceleration_limits(v):
    heights = [10, 40, 12, 35, 35, 5, 20]
    knots = np.linspace(0.0, 600.0, len(heights))
    p = build_profile(600.0, False, LIMITS, alt_target=lambda s: np.interp(s, knots, heights),
                      speed_target=v)
    c = p.climb_table_m_s()
    assert c.max() <= LIMITS.climb_max_m_s
    assert c.min() >= -LIMITS.sink_max_m_s
    # Vertical acceleration: the moving-average bound, plus the finite-difference error.
    assert np.abs(vertical_accel_m_s2(p)).max() <= LIMITS.vert_accel_max_m_s2 * 1.01


def test_the_limits_hold_where_the_speed_changes_too():
    heights = [10, 40, 12, 35]
    knots = [0.0, 100.0, 200.0, 300.0]
    speed = lambda s: np.where(s < 150.0, 3.0, 9.0)  # noqa: E731
    p = build_profile(300.0, False, LIMITS, alt_target=lambda s: np.interp(s, knots, heights),
                      speed_target=speed)
    c = p.climb_table_m_s()
    assert c.max() <= LIMITS.climb_max_m_s and c.min() >= -LIMITS.sink_max_m_s


def test_a_corner_is_rounded_by_at_most_dg_w_over_8():
    # Flat at 10 m, then a climb at dh/ds = 0.2 (1 m/s at 5 m/s): the slope jumps by 0.2, the
    # window is w = V^2 * 0.2 / a = 5 m, and the blend leaves the corner by dg w / 8 = 0.125 m.
    target = lambda s: np.where(s < 100.0, 10.0, 10.0 + 0.2 * (s - 100.0))  # noqa: E731
    p = build_profile(200.0, False, LIMITS, alt_target=target, speed_target=5.0)
    assert p.altitude_m(100.0) == pytest.approx(10.125, abs=2e-3)
    # Away from the corner (beyond w/2 = 2.5 m) the profile is the ramp itself.
    assert p.altitude_m(90.0) == pytest.approx(10.0, abs=1e-9)
    assert p.altitude_m(150.0) == pytest.approx(20.0, abs=1e-9)


def test_a_speed_change_ramps_v_squared_linearly_from_where_it_is_given():
    # 5 -> 8 m/s at s = 100 m with 1 m/s^2: V^2 = 25 + 2 (s - 100) until 64, i.e. for 19.5 m.
    p = build_profile(300.0, False, LIMITS, alt_target=10.0,
                      speed_target=lambda s: np.where(s < 100.0, 5.0, 8.0))
    assert p.speed_m_s(99.9) == pytest.approx(5.0)
    for d in (2.0, 10.0, 19.0):
        assert p.speed_m_s(100.0 + d) == pytest.approx(math.sqrt(25.0 + 2.0 * d), abs=2e-3)
    assert p.speed_m_s(119.6) == pytest.approx(8.0)
    # Slowing 8 -> 3 at s = 200 m: reached (64 - 9) / 2 = 27.5 m later.
    q = build_profile(300.0, False, LIMITS, alt_target=10.0,
                      speed_target=lambda s: np.where(s < 200.0, 8.0, 3.0))
    assert q.speed_m_s(200.0 + 27.0) == pytest.approx(math.sqrt(64.0 - 2.0 * 27.0), abs=2e-3)
    assert q.speed_m_s(228.0) == pytest.approx(3.0)


def test_constant_targets_give_constant_tables():
    p = build_profile(50.0, True, LIMITS, alt_target=12.0, speed_target=4.0)
    assert p.constant_speed and p.constant_altitude
    assert p.altitude_m(17.3) == 12.0 and p.speed_m_s(-3.0) == 4.0 and p.slope(10.0) == 0.0


def test_closed_profiles_are_periodic():
    # A loop of 400 m: 10 m at s = 0, 30 m at s = 200 m, back to 10 m at s = 400 m (= 0).
    p = build_profile(400.0, True, LIMITS,
                      alt_target=lambda s: knots_table(s, [0.0, 200.0], [10.0, 30.0], True, 400.0, False),
                      speed_target=5.0)
    assert p.altitude_m(0.0) == pytest.approx(p.altitude_m(400.0))
    assert p.altitude_m(100.0) == pytest.approx(20.0, abs=1e-6)
    assert p.altitude_m(-100.0) == pytest.approx(p.altitude_m(300.0))
    assert p.climb_table_m_s().max() <= LIMITS.climb_max_m_s


def test_knots_held_or_interpolated():
    s = np.array([0.0, 5.0, 10.0, 15.0, 20.0])
    assert knots_table(s, [0.0, 10.0], [4.0, 6.0], False, 20.0, True).tolist() == [4, 4, 6, 6, 6]
    assert knots_table(s, [0.0, 10.0], [4.0, 6.0], False, 20.0, False).tolist() == [4, 5, 6, 6, 6]


def test_moving_average_keeps_the_ends_and_a_straight_line():
    line = np.linspace(3.0, 7.0, 41)
    out = moving_average(line, 5, closed=False)
    assert np.allclose(out, line)
    bump = np.r_[np.zeros(20), np.ones(21)]
    avg = moving_average(bump, 2, closed=False)
    assert avg[0] == 0.0 and avg[-1] == 1.0
    assert avg[20] == pytest.approx(3.0 / 5.0)


def test_limits_refuse_non_positive_values():
    with pytest.raises(ValueError, match="climb_max_m_s"):
        ProfileLimits(climb_max_m_s=0.0)
