"""The flight tick with an altitude and speed profile: vz carries V dh/ds plus the correction,
within the climb and sink limits; the horizontal speed is V(s); laws get the local speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.profile import ProfileLimits, build_profile
from companion.guidance.profiled import ProfiledGuidance
from companion.guidance.types import GuidanceOutput
from companion.io.setpoints import AltitudeHold, profile_targets
from companion.io.state import PositionSample
from companion.loop.tick import TickConfig, compute_tick

LIMITS = ProfileLimits(climb_max_m_s=2.0, sink_max_m_s=1.5, vert_accel_max_m_s2=1.0,
                       along_accel_max_m_s2=1.0, alt_gain_1_s=0.5)


def ramp_profile():
    # 10 m + 0.1 m per metre of path, 4 m/s up to s = 100 m, 6 m/s from there on.
    return build_profile(300.0, False, LIMITS, alt_target=lambda s: 10.0 + 0.1 * s,
                         speed_target=lambda s: np.where(s < 100.0, 4.0, 6.0))


class FixedLaw:
    """A stand-in law: reports a given projection and records the speed it was handed."""

    def __init__(self, s_m):
        self.s_m = s_m
        self.speeds = []

    def step(self, t_s, state):
        self.speeds.append(state.speed_m_s)
        return GuidanceOutput(a_cmd_m_s2=0.0, phase="close_range", crosstrack_m=0.0, s_proj_m=self.s_m)


def sample(alt_m, vn=0.0, ve=4.0):
    return PositionSample(time_boot_ms=0, x_ned_m=0.0, y_ned_m=0.0, z_ned_m=-alt_m,
                          vx_ned_m_s=vn, vy_ned_m_s=ve, vz_ned_m_s=0.0)


def test_altitude_hold_adds_feed_forward_and_clamps_asymmetrically():
    hold = AltitudeHold(20.0, gain_1_s=0.5, max_climb_m_s=2.0, max_sink_m_s=1.5, climb_ff_m_s=0.4)
    assert hold.vz_ned_m_s(19.0) == pytest.approx(-(0.4 + 0.5 * 1.0))   # 0.9 m/s up
    assert hold.vz_ned_m_s(10.0) == pytest.approx(-2.0)                  # 5.4 wanted, 2 allowed
    assert hold.vz_ned_m_s(30.0) == pytest.approx(1.5)                   # -4.6 wanted, 1.5 down
    assert hold.vz_ned_m_s(math.nan) == 0.0


def test_on_the_profile_vz_is_the_feed_forward_v_dh_ds():
    p = ramp_profile()
    v, hold = profile_targets(p, 50.0)
    assert v == pytest.approx(4.0)
    assert hold.altitude_m == pytest.approx(15.0, abs=1e-6)
    assert hold.vz_ned_m_s(15.0) == pytest.approx(-4.0 * 0.1, abs=1e-6)  # 0.4 m/s up
    v, hold = profile_targets(p, 200.0)
    assert v == pytest.approx(6.0)
    assert hold.vz_ned_m_s(30.0 - 0.4) == pytest.approx(-(6.0 * 0.1 + 0.5 * 0.4), abs=1e-6)


def test_the_copter_tick_commands_v_of_s_and_the_profile_vz():
    p = ramp_profile()
    config = TickConfig(speed_m_s=4.0, rate_hz=50.0, altitude_m=10.0, profile=p)
    law = FixedLaw(200.0)
    res = compute_tick(law, 0, 0.0, sample(29.0), 0.0, config, prev_course_rad=0.0)
    sp = res.setpoint
    assert math.hypot(sp.vx_ned_m_s, sp.vy_ned_m_s) == pytest.approx(6.0)
    # 6 * 0.1 + 0.5 * (30 - 29) = 1.1 m/s up.
    assert sp.vz_ned_m_s == pytest.approx(-1.1, abs=1e-6)


def test_the_end_hold_keeps_the_last_height():
    p = ramp_profile()
    config = TickConfig(speed_m_s=4.0, rate_hz=50.0, altitude_m=10.0, profile=p)

    class Done(FixedLaw):
        def step(self, t_s, state):
            return GuidanceOutput(a_cmd_m_s2=0.0, phase="finished", crosstrack_m=0.0, s_proj_m=300.0)

    res = compute_tick(Done(300.0), 0, 0.0, sample(40.0), 0.0, config)
    assert res.setpoint.is_hold
    assert res.setpoint.vz_ned_m_s == pytest.approx(0.0, abs=1e-9)  # at the end height, 40 m


def test_without_a_profile_the_tick_is_unchanged():
    config = TickConfig(speed_m_s=4.0, rate_hz=50.0, altitude_m=10.0)
    res = compute_tick(FixedLaw(200.0), 0, 0.0, sample(9.0), 0.0, config)
    assert math.hypot(res.setpoint.vx_ned_m_s, res.setpoint.vy_ned_m_s) == pytest.approx(4.0)
    assert res.setpoint.vz_ned_m_s == pytest.approx(-1.0)  # 1/s * 1 m, no feed-forward


def test_profiled_guidance_hands_each_law_the_local_speed_of_the_last_projection():
    p = ramp_profile()
    law = FixedLaw(150.0)
    g = ProfiledGuidance(law, p)
    config = TickConfig(speed_m_s=4.0, rate_hz=50.0, altitude_m=10.0, profile=p)
    compute_tick(g, 0, 0.0, sample(10.0), 0.0, config)
    compute_tick(g, 1, 0.02, sample(10.0), 0.0, config)
    # First step: s = 0 (4 m/s); then the projection 150 m, where V = 6 m/s.
    assert law.speeds == [pytest.approx(4.0), pytest.approx(6.0)]


def test_the_simulator_flies_the_speed_profile():
    from companion.geometry.paths import function_path
    from companion.guidance.two_phase import TwoPhaseGuidance
    from companion.guidance.types import GuidanceParams, VehicleState
    from companion.sim.simulator import simulate

    path = function_path(lambda x: 0.0 * x, (0.0, 300.0))
    p = build_profile(path.length_m, False, LIMITS, alt_target=10.0,
                      speed_target=lambda s: np.where(s < 100.0, 4.0, 6.0))
    params = GuidanceParams(method="fixed_l1", speed_m_s=4.0, l1_m=10.0, rate_hz=50.0)
    law = ProfiledGuidance(TwoPhaseGuidance(path, params), p)
    res = simulate(path, law, VehicleState(0.0, 0.0, 0.0, 4.0), params, profile=p)
    # Time on a straight line: 100 m at 4 m/s, the ramp 4 -> 6 m/s at 1 m/s^2 (2 s, 10 m), then
    # the rest at 6 m/s up to where the look-ahead reaches the end (L1 = 10 m before it):
    # 25 + 2 + (300 - 10 - 110) / 6 = 57 s, to a tick or two.
    assert res.finished
    assert res.t_s[-1] == pytest.approx(25.0 + 2.0 + 180.0 / 6.0, abs=0.1)
