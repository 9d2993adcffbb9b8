"""A start at a crossing of a closed path: every law, and the benches' measurement, take the
branch the vehicle flies along (``companion.guidance.path_frame.first_projection_s``), not
whichever branch the global projection found nearer by a centimetre."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import parametric_path
from companion.guidance.baselines import (ApL1Guidance, ApL1Params, NpfgGuidance, NpfgParams, PurePursuitGuidance,
                                          PurePursuitParams)
from companion.guidance.path_frame import first_projection_s
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.optimal import crosstrack_sequential_m
from companion.sim.simulator import LagModel, simulate

A_M = 60.0
V = 5.0
# x = A sin(2u), y = A sin(u) crosses itself at the origin: at u = 0 (s = 0) going (2, 1)/sqrt(5),
# at u = pi going (2, -1)/sqrt(5); the curvature there is 0 on both branches (x'' = y'' = 0), and
# at most 0.134 1/m (at u = pi/4: 3.4 m/s^2 at 5 m/s).
UP, DOWN = math.atan2(1.0, 2.0), math.atan2(-1.0, 2.0)


def eight():
    return parametric_path(lambda u: A_M * np.sin(2.0 * u), lambda u: A_M * np.sin(u), (0.0, 2.0 * math.pi),
                           closed=True)


@pytest.mark.parametrize("course", [UP, DOWN])
def test_the_first_projection_is_the_branch_flown_along(course):
    path = eight()
    s = first_projection_s(path, 0.0, 0.0, course)
    tx, ty = path.tangent(s)
    assert math.atan2(ty, tx) == pytest.approx(course, abs=1e-3)
    # without a course: the global projection, whichever branch it is (s = 0 or half a lap)
    assert first_projection_s(path, 0.0, 0.0, None) == path.project(0.0, 0.0, None)


def test_the_measurement_follows_the_branch_flown_along():
    # 10 m straight along the DOWN branch from the crossing: within a third-order term of it
    # (no curvature there), and 10 sin(53.13 deg) = 8.0 m from the UP branch.
    # The measurement takes the branch along the trajectory's first step.
    path = eight()
    t = np.linspace(0.0, 2.0, 101)
    x, y = V * t * math.cos(DOWN), V * t * math.sin(DOWN)
    along, _ = crosstrack_sequential_m(path, x, y)
    assert np.max(np.abs(along)) < 0.3
    # the same flight, its first step along the UP branch: measured against that branch
    x[1], y[1] = 0.1 * math.cos(UP), 0.1 * math.sin(UP)
    across, _ = crosstrack_sequential_m(path, x, y)
    assert abs(across[-1]) == pytest.approx(10.0 * math.sin(2.0 * math.atan(0.5)), abs=0.3)


def _laws(path):
    yield "predictive", PredictiveGuidance(path, PredictiveParams(lag_s=0.2, a_max_m_s2=5.0))
    yield "npfg", NpfgGuidance(path, NpfgParams(period_s=3.0))
    yield "ap_l1", ApL1Guidance(path, ApL1Params(period_s=6.0))
    yield "pure_pursuit", PurePursuitGuidance(path, PurePursuitParams(lookahead_m=10.0))
    yield "fixed_l1", TwoPhaseGuidance(path, GuidanceParams(method="fixed_l1", l1_m=10.0, speed_m_s=V))


@pytest.mark.parametrize("course", [UP, DOWN])
def test_every_law_started_at_the_crossing_flies_on_along_its_branch(course):
    # The other branch parts from it at 53 deg: a law that took it left the branch it flies along
    # at 4 m/s. Each law stays within a metre of it over the 50 m to the lobe's end.
    path = eight()
    for name, law in _laws(path):
        res = simulate(path, law, VehicleState(0.0, 0.0, course, V), GuidanceParams(speed_m_s=V),
                       model=LagModel(0.2, 5.0), t_max_s=10.0)
        d, _ = crosstrack_sequential_m(path, res.x_m, res.y_m)
        assert np.max(np.abs(d)) < 1.0, name
