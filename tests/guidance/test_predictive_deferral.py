"""The predictive law's re-optimisation runs after the command of the tick it falls on
(``PredictiveGuidance.finish_tick``): the tick itself only computes a pursuit command, and the
commands are the same whether or not the caller runs the re-optimisation early."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import function_path
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate

PATH = function_path(lambda x: 10.0 * np.sin(0.078 * x) + 20.0 * np.cos(0.082 * x), (-15.0, 60.0))
START = VehicleState(-15.0, 0.0, math.radians(39.118), 5.0)
PARAMS = PredictiveParams(lag_s=0.3, a_max_m_s2=5.0)


class _NoFinish:
    """Hides ``finish_tick`` from the simulator: every re-optimisation then runs in the next step."""

    def __init__(self, law):
        self.law = law

    def step(self, t_s, state):
        return self.law.step(t_s, state)


def test_commands_are_the_same_whether_finish_tick_runs_or_the_next_step_does_it():
    gp = GuidanceParams(speed_m_s=5.0, rate_hz=50.0)
    lag = LagModel(0.3, 5.0)
    early = simulate(PATH, PredictiveGuidance(PATH, PARAMS), START, gp, model=lag)
    late = simulate(PATH, _NoFinish(PredictiveGuidance(PATH, PARAMS)), START, gp, model=lag)
    assert early.t_s.size == late.t_s.size > 500
    assert np.array_equal(early.a_cmd_m_s2, late.a_cmd_m_s2)
    assert np.array_equal(early.x_m, late.x_m)


def test_a_due_tick_commands_the_current_plan_and_leaves_the_search_for_after():
    law = PredictiveGuidance(PATH, PARAMS)
    first = law.step(0.0, START)
    assert first.reoptimised and law.reoptimisations == 1  # the first tick needs a plan at once
    t, state = 0.0, START
    while True:
        t += 0.02
        state = VehicleState(state.x_m + 0.1 * math.cos(state.course_rad),
                             state.y_m + 0.1 * math.sin(state.course_rad), state.course_rad, 5.0)
        out = law.step(t, state)
        if out.reoptimised:
            break
    assert t == pytest.approx(PARAMS.reopt_period_s, abs=0.021)
    # The due tick ran no search: its command came from the plan of t = 0 ...
    assert law.reoptimisations == 1
    law.finish_tick()
    assert law.reoptimisations == 2
    law.finish_tick()  # ... and finishing twice does the work once
    assert law.reoptimisations == 2


def test_two_phase_guidance_hands_finish_tick_to_its_predictive_phase():
    guidance = TwoPhaseGuidance(PATH, GuidanceParams(method="predictive", speed_m_s=5.0, rate_hz=50.0,
                                                     midcourse_trigger="off"))
    guidance.step(0.0, START)
    inner = guidance._predictive
    inner._pending = (0.0, START, 0.0, 0.0)
    guidance.finish_tick()
    assert inner._pending is None and inner.reoptimisations == 2
