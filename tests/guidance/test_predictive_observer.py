"""The predictive law's course observer (``PredictiveParams.course_tc_s``,
:func:`companion.guidance.predictive.observe_course`): the lag model's own turn, pulled towards the
reported course with a time constant, so that a course estimate that jitters quicker than the
vehicle turns is not answered with acceleration."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.guidance.predictive import PredictiveGuidance, PredictiveParams, observe_course
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from bench_scenes import CirclePath, LinePath  # noqa: E402

DT_S = 0.02


def test_a_white_jitter_of_the_reported_course_is_cut_as_a_first_order_filter_cuts_it():
    # Flying straight (no model turn), the observer is x_k = x_{k-1} + g (y_k - x_{k-1}) with
    # g = 1 - exp(-dt / tc): white input of variance s^2 leaves the variance g s^2 / (2 - g)
    # (an AR(1) process), 0.0328 s^2 at dt 0.02 s and tc 0.3 s.
    rng = np.random.default_rng(3)
    tc, sigma = 0.3, 0.01
    reported = sigma * rng.standard_normal(200_000)
    hat, out = 0.0, np.empty(reported.size)
    for k, y in enumerate(reported):
        hat = observe_course(hat, float(y), 0.0, 0.0, 5.0, DT_S, tc)
        out[k] = hat
    g = 1.0 - math.exp(-DT_S / tc)
    assert np.var(out[1000:]) == pytest.approx(g / (2.0 - g) * sigma**2, rel=0.03)


def test_the_observer_wraps_across_the_back_of_the_circle():
    # A course reported just past -pi, observed just short of +pi: the gap is 0.02 rad, not 2 pi.
    hat = observe_course(math.pi - 0.01, -math.pi + 0.01, 0.0, 0.0, 5.0, DT_S, 0.3)
    g = 1.0 - math.exp(-DT_S / 0.3)
    assert math.remainder(hat - (math.pi - 0.01), 2.0 * math.pi) == pytest.approx(0.02 * g, rel=1e-9)


class _Jittered:
    """A law handed the course with a seeded jitter added: smoothed white noise (0.1 s), RMS ``rms_rad``."""

    def __init__(self, law, rms_rad: float, seed: int):
        self.law, self.rng = law, np.random.default_rng(seed)
        self.rms, self.state, self.g = rms_rad, 0.0, 1.0 - math.exp(-DT_S / 0.1)

    def step(self, t_s, state):
        # white through a first-order smoother of gain g keeps g / (2 - g) of its variance
        self.state += self.g * (self.rng.standard_normal() * self.rms / math.sqrt(self.g / (2.0 - self.g))
                                - self.state)
        return self.law.step(t_s, VehicleState(state.x_m, state.y_m, state.course_rad + self.state, state.speed_m_s))


def _fly(path, start, tc_s, rms_rad, seed=0, t_max_s=40.0):
    model = LagModel(tau_s=0.45, a_max_m_s2=3.5)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=0.3, lag_s=0.45, a_max_m_s2=3.5, course_tc_s=tc_s))
    law.compiled = False  # the numpy rollouts: the same numbers, no compile wait in the test
    res = simulate(path, _Jittered(law, rms_rad, seed) if rms_rad else law, start,
                   GuidanceParams(method="predictive", rate_hz=1.0 / DT_S), model=model, t_max_s=t_max_s)
    return res


def test_a_jittering_course_is_answered_with_less_acceleration_and_the_line_held_as_tightly():
    # On a line at 5 m/s, course jitter of 0.5 deg RMS (44 mm/s across the track at 5 m/s, twice
    # PX4 SIH's), the vehicle itself flying no jitter: with the observer (0.3 s) the commanded
    # acceleration (what a flight's a_rms measures) is less than 0.7 of the law's without it, and
    # the cross-track error no larger than 1.2 times.
    path = LinePath(x0=-20.0, length_m=400.0)
    start = VehicleState(0.0, 0.0, 0.0, 5.0)
    plain = _fly(path, start, 0.0, math.radians(0.5))
    observed = _fly(path, start, 0.3, math.radians(0.5))
    a_plain, a_obs = (float(np.sqrt(np.mean(r.a_cmd_m_s2**2))) for r in (plain, observed))
    d_plain, d_obs = (float(np.sqrt(np.mean(r.crosstrack_m**2))) for r in (plain, observed))
    assert a_obs < 0.7 * a_plain
    assert d_obs < 1.2 * d_plain


def test_with_a_model_that_turns_as_the_vehicle_does_the_observer_changes_little_on_a_circle():
    # No jitter, the simulator's vehicle is the law's lag model: the observed course follows the
    # flown one, so a 30 m circle at 5 m/s (0.83 m/s^2) is flown as without the observer: the
    # commands differ by under 2 % of the turn's acceleration at every tick past the first second.
    path = CirclePath(radius_m=30.0)
    start = VehicleState(*path.start_xy_m, path.start_heading_rad, 5.0)
    plain = _fly(path, start, 0.0, 0.0, t_max_s=20.0)
    observed = _fly(path, start, 0.3, 0.0, t_max_s=20.0)
    late = plain.t_s > 1.0
    turn = 5.0**2 / 30.0
    assert np.max(np.abs(observed.a_cmd_m_s2[late] - plain.a_cmd_m_s2[late])) < 0.02 * turn


def test_the_observer_is_off_by_default_and_refuses_a_negative_time_constant():
    assert PredictiveParams().course_tc_s == 0.0 and GuidanceParams().course_tc_s == 0.0
    with pytest.raises(ValueError, match="course_tc_s"):
        PredictiveParams(course_tc_s=-0.1)
    with pytest.raises(ValueError, match="course_tc_s"):
        GuidanceParams(course_tc_s=math.nan)


def test_a_missions_course_time_constant_reaches_the_law():
    from companion.guidance.two_phase import TwoPhaseGuidance
    from companion.mission import parse_mission

    text = ("{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], [50, 0]]}, "
            "guidance: {method: predictive%s}}")
    stated = parse_mission(text % ", course_tc_s: 0.3", "stated.yaml")
    assert stated.guidance.course_tc_s == 0.3
    law = TwoPhaseGuidance(stated.path, stated.guidance)
    assert law._predictive is not None and law._predictive.params.course_tc_s == 0.3
    assert parse_mission(text % "", "absent.yaml").guidance.course_tc_s == 0.0
