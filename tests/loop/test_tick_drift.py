"""The tick's drift compensation: the course the law is given and the setpoint sent, by hand."""

import math

import pytest

from companion.guidance.drift import DriftEstimator
from companion.guidance.types import GuidanceOutput
from companion.io.state import PositionSample
from companion.loop.driver import TickDriver
from companion.loop.tick import DEBUG_FIELDS, TickConfig, compute_tick

IDX = {name: i for i, name in enumerate(DEBUG_FIELDS)}
ON = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, drift_tc_s=1.0)
OFF = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0)


class Straight:
    """A law that records the state it is given and commands nothing."""

    def __init__(self):
        self.states = []

    def step(self, t_s, state):
        self.states.append(state)
        return GuidanceOutput(a_cmd_m_s2=0.0, phase="close_range", crosstrack_m=0.0, s_proj_m=0.0)


def drifting_samples(n, drift_ne=(0.3, 0.0), v_ne=(0.0, 5.0)):
    """Reports of a vehicle flying east at 5 m/s (reported) whose position also moves by drift_ne."""
    for k in range(n):
        t = 0.02 * k
        yield PositionSample(1000 + 20 * k, drift_ne[0] * t + v_ne[0] * t, drift_ne[1] * t + v_ne[1] * t,
                             -10.0, v_ne[0], v_ne[1], 0.0)


def test_the_law_is_given_the_course_flown_and_the_setpoint_leaves_out_the_drift():
    law, est = Straight(), DriftEstimator(ON.drift_tc_s)
    for k, s in enumerate(drifting_samples(251)):  # 5 s: the estimate is 0.3 (1 - exp(-5)) north
        r = compute_tick(law, k, 0.02 * k, s, 0.01, ON, drift=est)
    b = 0.3 * (1.0 - math.exp(-5.0))
    assert (r.drift_n_m_s, r.drift_e_m_s) == (pytest.approx(b, abs=1e-9), pytest.approx(0.0, abs=1e-9))
    # The course handed to the law: of the velocity flown, 5 m/s east plus b north (ENU: from east).
    assert law.states[-1].course_rad == pytest.approx(math.atan2(b, 5.0), abs=1e-9)
    # The setpoint: the commanded course at V, less the drift, which the vehicle adds back.
    sp = r.setpoint
    flown_n, flown_e = sp.vx_ned_m_s + b, sp.vy_ned_m_s
    assert math.hypot(flown_n, flown_e) == pytest.approx(5.0, abs=1e-9)
    assert math.atan2(flown_n, flown_e) == pytest.approx(r.course_cmd_rad, abs=1e-9)
    row = r.debug
    assert row[IDX["drift_n_m_s"]] == pytest.approx(b) and row[IDX["drift_tc_s"]] == 1.0


def test_off_the_setpoint_and_course_are_the_reports_own():
    law = Straight()
    for k, s in enumerate(drifting_samples(251)):
        r = compute_tick(law, k, 0.02 * k, s, 0.01, OFF, drift=DriftEstimator(1.0))
    assert math.isnan(r.drift_n_m_s) and r.debug[IDX["drift_tc_s"]] == 0.0
    assert law.states[-1].course_rad == 0.0  # east, as reported
    assert r.setpoint.vx_ned_m_s == pytest.approx(0.0, abs=1e-12)


def test_the_driver_carries_one_estimate_and_a_coast_compensates_it_too():
    driver = TickDriver(Straight(), ON, prev_course_rad=0.0)
    assert driver.drift is not None
    assert TickDriver(Straight(), OFF, prev_course_rad=0.0).drift is None
    for k, s in enumerate(drifting_samples(251)):
        r = driver.step(k, 0.02 * k, s, 0.01, None, driver.prev_course_rad, driver.prev_course_cmd_rad)
        driver.accept(r, sent=True)
    sp = driver.coast(s, 0.01)
    assert sp.vx_ned_m_s == pytest.approx(-r.drift_n_m_s + 5.0 * math.sin(r.course_cmd_rad), abs=1e-9)
    # A plane's attitude output has no velocity to compensate: the driver keeps no estimate.
    plane = TickConfig(speed_m_s=15.0, rate_hz=50.0, altitude_m=50.0, output="attitude", drift_tc_s=1.0)
    assert TickDriver(Straight(), plane, prev_course_rad=0.0).drift is None


def test_a_negative_time_constant_is_refused():
    with pytest.raises(ValueError, match="drift_tc_s"):
        TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, drift_tc_s=-1.0)
