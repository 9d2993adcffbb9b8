"""The per-tick function shared by the live loop and replay: hand-computed inputs and outputs."""

import math

import pytest

from companion.guidance.types import GuidanceOutput
from companion.io.state import PositionSample
from companion.loop.tick import DEBUG_FIELDS, TickConfig, coast_setpoint, compute_tick, hold_for

IDX = {name: i for i, name in enumerate(DEBUG_FIELDS)}
CFG = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, stale_s=0.3)


class ConstantTurn:
    def __init__(self, a=1.0, phase="close_range"):
        self.a, self.phase, self.calls = a, phase, []

    def step(self, t_s, state):
        self.calls.append((t_s, state))
        return GuidanceOutput(a_cmd_m_s2=self.a, phase=self.phase, crosstrack_m=state.y_m,
                              s_proj_m=state.x_m, k1=0.5, k2=2.0)


def sample(x_ned=0.0, y_ned=0.0, z_ned=-10.0, vx=0.0, vy=5.0, t_ms=1000):
    return PositionSample(t_ms, x_ned, y_ned, z_ned, vx, vy, 0.0, received_s=0.0)


def test_fresh_sample_flying_east_turning_left():
    g = ConstantTurn(a=1.0)
    r = compute_tick(g, 7, 0.14, sample(x_ned=2.0, y_ned=3.0), 0.01, CFG)
    (t, st), = g.calls
    assert (t, st.x_m, st.y_m, st.course_rad, st.speed_m_s) == (0.14, 3.0, 2.0, 0.0, 5.0)
    assert r.phase == "close_range" and not r.is_hold
    # course one tick ahead: a / V * dt = 1/5 * 0.02 = 0.004 rad left of east
    assert r.course_cmd_rad == pytest.approx(0.004)
    assert r.setpoint.yaw_rate_ned_rad_s == pytest.approx(-0.2)
    row = r.debug
    assert len(row) == len(DEBUG_FIELDS)
    assert row[IDX["tick"]] == 7 and row[IDX["phase_code"]] == 1
    assert row[IDX["x_enu_m"]] == 3.0 and row[IDX["y_enu_m"]] == 2.0
    assert row[IDX["k1"]] == 0.5 and row[IDX["k2"]] == 2.0
    assert row[IDX["ve_cmd_m_s"]] == pytest.approx(5 * math.cos(0.004))
    assert row[IDX["alt_m"]] == 10.0 and row[IDX["hold_reason"]] == 0
    assert math.isnan(row[IDX["prev_course_cmd_rad"]])


@pytest.mark.parametrize("age, reason", [(0.31, "stale"), (math.inf, "stale"), (math.nan, "stale")])
def test_old_sample_holds_without_stepping_the_guidance(age, reason):
    g = ConstantTurn()
    r = compute_tick(g, 0, 0.0, sample(z_ned=-5.0), age, CFG)  # 5 m below the 10 m target
    assert g.calls == []
    assert r.is_hold and r.hold_reason == reason and r.setpoint.is_hold
    assert r.setpoint.vz_ned_m_s == 0.0  # not even the altitude hold uses the old sample
    assert r.debug[IDX["phase_code"]] == 3 and r.debug[IDX["hold_reason"]] == 1


def test_no_sample_yet_holds():
    g = ConstantTurn()
    r = compute_tick(g, 0, 0.0, None, math.inf, CFG)
    assert g.calls == [] and r.hold_reason == "no_position" and r.setpoint.vz_ned_m_s == 0.0


def test_sample_exactly_at_the_limit_is_still_used():
    g = ConstantTurn()
    r = compute_tick(g, 0, 0.0, sample(), 0.3, CFG)
    assert len(g.calls) == 1 and not r.is_hold


def test_commanded_course_integrates_across_ticks_despite_a_lagging_measurement():
    """Measured course stuck at 0 (a slow velocity loop): the command keeps turning at a/V."""
    g = ConstantTurn(a=1.0)
    prev_cmd = None
    for k in range(10):
        r = compute_tick(g, k, k * 0.02, sample(), 0.0, CFG, prev_course_cmd_rad=prev_cmd)
        prev_cmd = r.course_cmd_rad
    assert prev_cmd == pytest.approx(10 * 0.004)


def test_commanded_course_lead_is_clamped():
    g = ConstantTurn(a=0.0)
    r = compute_tick(g, 0, 0.0, sample(), 0.0, CFG, prev_course_cmd_rad=2.0)
    assert r.course_cmd_rad == pytest.approx(math.pi / 4)


def test_slow_vehicle_uses_yaw_for_the_course():
    g = ConstantTurn()
    compute_tick(g, 0, 0.0, sample(vx=0.0, vy=0.1), 0.0, CFG, yaw_ned_rad=math.pi)  # facing south
    assert g.calls[0][1].course_rad == pytest.approx(-math.pi / 2)


def test_finished_phase_sends_a_hold():
    r = compute_tick(ConstantTurn(phase="finished"), 0, 0.0, sample(), 0.0, CFG)
    assert r.phase == "finished" and r.setpoint.is_hold


def test_coast_keeps_turning_but_never_on_stale_data():
    g = ConstantTurn(a=1.0)
    last = compute_tick(g, 0, 0.0, sample(), 0.0, CFG)
    sp = coast_setpoint(last, sample(), 0.02, CFG, last.course_cmd_rad)
    assert sp.course_cmd_enu_rad == pytest.approx(0.008)
    assert coast_setpoint(last, sample(), 0.5, CFG, last.course_cmd_rad).is_hold


def test_attitude_output_holds_wings_level():
    cfg = TickConfig(speed_m_s=15.0, rate_hz=50.0, altitude_m=50.0, output="attitude")
    r = compute_tick(ConstantTurn(), 0, 0.0, sample(), 1.0, cfg, prev_course_rad=0.0)
    assert r.is_hold and r.setpoint.roll_ned_rad == 0.0


def test_recorded_tick_time_restores_the_float64_time_through_float32_fields():
    import struct

    def f32(x):
        return struct.unpack("<f", struct.pack("<f", x))[0]

    for t in (0.02, 35.3, 1234.56789, 3599.98):
        r = compute_tick(ConstantTurn(), 0, t, sample(), 0.0, CFG)
        hi, lo = f32(r.debug[IDX["t_s"]]), f32(r.debug[IDX["t_s_residual"]])
        assert abs((hi + lo) - t) < 1e-9
    assert abs(f32(35.3) - 35.3) > 1e-7  # float32 alone loses it (the re-optimisation clock)


def test_a_long_coast_flies_straight_instead_of_circling():
    last = compute_tick(ConstantTurn(a=3.0), 0, 0.0, sample(), 0.0, CFG)
    sp = coast_setpoint(last, sample(), 0.02, CFG, 0.5, turning=False)
    assert sp.course_cmd_enu_rad == pytest.approx(0.5) and sp.yaw_rate_ned_rad_s == 0.0


def test_the_hold_keeps_an_anchor_only_with_a_fresh_sample_and_velocity_output():
    # 2 m south of the anchor at 8 m (altitude 10 m): back north at the 1 m/s limit, climbing
    h = hold_for(CFG, 8.0, True, 0.0, position_ne_m=(-2.0, 0.0), anchor_ne_m=(0.0, 0.0))
    assert (h.vx_ned_m_s, h.vy_ned_m_s, h.yaw_rate_ned_rad_s) == (pytest.approx(1.0), pytest.approx(0.0), 0.0)
    assert h.vz_ned_m_s < 0.0  # NED: up
    # no fresh sample: zero velocity, whatever the anchor
    assert hold_for(CFG, 8.0, False, 0.0, position_ne_m=(-2.0, 0.0), anchor_ne_m=(0.0, 0.0)).is_hold
    # no anchor: zero velocity
    assert hold_for(CFG, 8.0, True, 0.0, position_ne_m=(-2.0, 0.0)).is_hold
    # a plane's hold is wings level, never a position
    plane = TickConfig(speed_m_s=15.0, rate_hz=50.0, altitude_m=50.0, output="attitude")
    assert hold_for(plane, 50.0, True, 0.0, position_ne_m=(-2.0, 0.0), anchor_ne_m=(0.0, 0.0)).roll_ned_rad == 0.0


@pytest.mark.parametrize("vx, vy, gathering", [(0.5, 1.0, True), (0.0, 2.49, True), (1.0, 2.4, False)])
def test_below_half_the_speed_the_course_is_the_commanded_one(vx, vy, gathering):
    """A copter gathering speed (1.1 m/s, 26.6 deg north of east; 2.49 m/s east) flies towards its
    commanded course (-0.1 rad), whatever its velocity's direction yet: the guidance gets that
    course and the command integrates from it, unclamped; on the first tick, its yaw. From V/2 (2.6 m/s at 22.6 deg) on the
    measured course stands, and the command leads it by at most 45 deg."""
    g = ConstantTurn(a=1.0)
    r = compute_tick(g, 1, 0.02, sample(vx=vx, vy=vy), 0.0, CFG, prev_course_cmd_rad=-0.1)
    measured = math.atan2(vx, vy)
    given = g.calls[0][1].course_rad
    if gathering:
        assert given == -0.1 and r.course_cmd_rad == pytest.approx(-0.1 + 0.004)
    else:
        assert given == pytest.approx(measured) and r.course_cmd_rad == pytest.approx(-0.1 + 0.004)
    # the first tick (no commanded course yet): the yaw (facing south) while gathering speed,
    # else the measured course; without a yaw, the measured course
    g0 = ConstantTurn(a=0.0)
    compute_tick(g0, 0, 0.0, sample(vx=vx, vy=vy), 0.0, CFG, yaw_ned_rad=math.pi)
    compute_tick(g0, 0, 0.0, sample(vx=vx, vy=vy), 0.0, CFG)
    assert g0.calls[0][1].course_rad == pytest.approx(-math.pi / 2 if gathering else measured)
    assert g0.calls[1][1].course_rad == pytest.approx(measured)


@pytest.mark.parametrize("vx, vy, share", [(0.0, 0.0, 0.0), (0.6, 0.8, 0.2), (0.0, 2.4, 0.48), (0.0, 2.5, 1.0),
                                           (0.0, 4.0, 1.0), (0.0, 6.0, 1.0)])
def test_the_acceleration_target_of_a_copter_gathering_speed_is_its_speed_over_v(vx, vy, share):
    """The setpoint turns at a / V = 2 / 5 rad/s; a copter moving at |v| turns with it on |v| a / V,
    so while it gathers speed (below V / 2 = 2.5 m/s) the target sent is 2 |v| / 5 m/s^2 (hovering:
    none), and from V / 2 on the whole command (faster than V too: the target is the setpoint's
    turn). The direction is the left normal of the commanded course, east + 0.008 rad: north."""
    cfg = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, accel_ff_max_m_s2=2.5)
    r = compute_tick(ConstantTurn(a=2.0), 1, 0.02, sample(vx=vx, vy=vy), 0.0, cfg, prev_course_cmd_rad=0.0)
    c = 2.0 / 5.0 * 0.02
    assert r.setpoint.afx_ned_m_s2 == pytest.approx(2.0 * share * math.cos(c), abs=1e-12)
    assert r.setpoint.afy_ned_m_s2 == pytest.approx(-2.0 * share * math.sin(c), abs=1e-12)
    # the velocity setpoint itself is not scaled: V along the commanded course
    assert math.hypot(r.setpoint.vx_ned_m_s, r.setpoint.vy_ned_m_s) == pytest.approx(5.0)
    # a coast from that tick sends the same share
    sp = coast_setpoint(r, sample(vx=vx, vy=vy), 0.02, cfg, r.course_cmd_rad)
    assert math.hypot(sp.afx_ned_m_s2, sp.afy_ned_m_s2) == pytest.approx(2.0 * share, abs=1e-12)


def test_the_speed_hold_lengthens_the_setpoint_but_not_the_v_it_turns_with():
    """A copter flying 4 m/s east for 5 asked, reported at 50 Hz, integral time 2 s: after the
    first report starts the clock, each report adds (5 - 4) * 0.02 / 2 = 0.01 m/s to the
    setpoint's length. The course still steps by a / V dt with V = 5 (not the length). While
    the copter gathers speed (below 2.5 m/s) the correction is held; the coast sends the last one."""
    from companion.guidance.speed_hold import SpeedHold

    cfg = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, speed_hold_tc_s=2.0)
    hold = SpeedHold(cfg.speed_hold_tc_s)
    law = ConstantTurn(a=2.0)
    for k in range(11):
        r = compute_tick(law, k, 0.02 * k, sample(vx=0.0, vy=4.0, t_ms=1000 + 20 * k), 0.0, cfg,
                         prev_course_cmd_rad=0.0, speed_hold=hold)
    assert r.speed_hold_m_s == pytest.approx(0.1, abs=1e-12)
    assert math.hypot(r.setpoint.vx_ned_m_s, r.setpoint.vy_ned_m_s) == pytest.approx(5.1, abs=1e-12)
    assert r.course_cmd_rad == pytest.approx(2.0 / 5.0 * 0.02, abs=1e-12)
    assert r.setpoint.yaw_rate_ned_rad_s == pytest.approx(-2.0 / 5.0, abs=1e-12)
    row = r.debug
    assert row[IDX["speed_hold_m_s"]] == pytest.approx(0.1) and row[IDX["speed_hold_tc_s"]] == 2.0
    sp = coast_setpoint(r, sample(vx=0.0, vy=4.0, t_ms=1220), 0.02, cfg, r.course_cmd_rad)
    assert math.hypot(sp.vx_ned_m_s, sp.vy_ned_m_s) == pytest.approx(5.1, abs=1e-12)
    # gathering speed (1 m/s): held at 0.1 however long, and the setpoint is 5.1 long
    for k in range(11, 30):
        r = compute_tick(law, k, 0.02 * k, sample(vx=0.0, vy=1.0, t_ms=1000 + 20 * k), 0.0, cfg,
                         prev_course_cmd_rad=0.0, speed_hold=hold)
    assert r.speed_hold_m_s == pytest.approx(0.1, abs=1e-12)
    assert math.hypot(r.setpoint.vx_ned_m_s, r.setpoint.vy_ned_m_s) == pytest.approx(5.1, abs=1e-12)
    # off (the default): no correction, NaN in the row, the plain length
    r = compute_tick(law, 0, 0.0, sample(vx=0.0, vy=4.0), 0.0, CFG, prev_course_cmd_rad=0.0)
    assert math.isnan(r.debug[IDX["speed_hold_m_s"]]) and r.debug[IDX["speed_hold_tc_s"]] == 0.0
    assert math.hypot(r.setpoint.vx_ned_m_s, r.setpoint.vy_ned_m_s) == pytest.approx(5.0, abs=1e-12)


def test_the_tail_compensation_adds_s_f_to_the_setpoint_records_it_and_a_hold_restarts_it():
    """A copter reported flying 4 m/s east (NED y) for a setpoint of 5 east, no turn, PX4's tail:
    the first report starts the clock; the second integrates one interval of the sent 5 less the
    reported 4: f = 1 * (1 - exp(-0.02 / 0.958)), and the setpoint is 5 + 0.857 f east. The coast
    sends the same correction; a hold resets it."""
    from companion.guidance.tail_comp import TailCompensator

    cfg = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, tail_share=0.857, tail_tc_s=0.958)
    tail = TailCompensator(cfg.tail_share, cfg.tail_tc_s)
    law = ConstantTurn(a=0.0)
    r0 = compute_tick(law, 0, 0.0, sample(vx=0.0, vy=4.0, t_ms=1000), 0.0, cfg, prev_course_cmd_rad=0.0, tail=tail)
    assert r0.setpoint.vy_ned_m_s == pytest.approx(5.0, abs=1e-12) and r0.tail_comp_e_m_s == 0.0
    r1 = compute_tick(law, 1, 0.02, sample(vx=0.0, vy=4.0, t_ms=1020), 0.0, cfg, prev_course_cmd_rad=0.0, tail=tail)
    expected = 0.857 * 1.0 * (1.0 - math.exp(-0.02 / 0.958))
    assert r1.tail_comp_e_m_s == pytest.approx(expected, abs=1e-12) and r1.tail_comp_n_m_s == pytest.approx(0.0)
    assert r1.setpoint.vy_ned_m_s == pytest.approx(5.0 + expected, abs=1e-12)
    row = r1.debug
    assert row[IDX["tail_comp_e_m_s"]] == pytest.approx(expected)
    assert (row[IDX["tail_share"]], row[IDX["tail_tc_s"]]) == (0.857, 0.958)
    sp = coast_setpoint(r1, sample(vx=0.0, vy=4.0, t_ms=1040), 0.02, cfg, r1.course_cmd_rad)
    assert sp.vy_ned_m_s == pytest.approx(5.0 + expected, abs=1e-12)
    # a stale sample: a hold, and the compensation starts again from zero
    h = compute_tick(law, 2, 0.04, sample(vx=0.0, vy=4.0, t_ms=1040), 1.0, cfg, prev_course_cmd_rad=0.0, tail=tail)
    assert h.is_hold and math.isnan(h.tail_comp_e_m_s) and tail.f_m_s == (0.0, 0.0)
    r3 = compute_tick(law, 3, 0.06, sample(vx=0.0, vy=4.0, t_ms=1060), 0.0, cfg, prev_course_cmd_rad=0.0, tail=tail)
    assert r3.tail_comp_e_m_s == 0.0
    r4 = compute_tick(law, 4, 0.08, sample(vx=0.0, vy=4.0, t_ms=1080), 0.0, cfg, prev_course_cmd_rad=0.0, tail=tail)
    assert r4.tail_comp_e_m_s > 0.0
    # gathering speed (1 m/s, below half of V): no correction, and the compensation starts again
    r5 = compute_tick(law, 5, 0.10, sample(vx=0.0, vy=1.0, t_ms=1100), 0.0, cfg, prev_course_cmd_rad=0.0, tail=tail)
    assert (r5.tail_comp_n_m_s, r5.tail_comp_e_m_s) == (0.0, 0.0) and tail.f_m_s == (0.0, 0.0)
    assert r5.setpoint.vy_ned_m_s == pytest.approx(5.0, abs=1e-12)
    # off (the default): NaN in the row
    r = compute_tick(law, 0, 0.0, sample(vx=0.0, vy=4.0), 0.0, CFG, prev_course_cmd_rad=0.0)
    assert math.isnan(r.debug[IDX["tail_comp_e_m_s"]]) and r.debug[IDX["tail_share"]] == 0.0
