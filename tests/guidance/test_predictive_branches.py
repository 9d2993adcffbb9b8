"""The predictive law on paths that come back near themselves: its projection stays on the
vehicle's branch where the path crosses itself within the rollouts' window, and a loop ahead
that bends back within the look-ahead distance is followed, not taken for a vehicle pointing
away (which turns round, :mod:`companion.guidance.capture`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import parametric_path
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams, _band, _Window, pursuit_command
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.optimal import crosstrack_sequential_m
from companion.sim.simulator import LagModel, simulate

A_M = 12.0  # lobe size of the figure-eight below


def figure_eight():
    """x = A sin(2u), y = A sin(u): closed, crossing itself at the origin, where its two branches
    meet at right angles (at u = 0 going (2, 1)/sqrt(5), at u = pi going (2, -1)/sqrt(5))."""
    return parametric_path(lambda u: A_M * np.sin(2.0 * u), lambda u: A_M * np.sin(u), (0.0, 2.0 * math.pi),
                           closed=True)


def test_the_goal_stays_on_the_vehicles_branch_through_the_crossing():
    path = figure_eight()
    total = path.length_m
    # 1 m past the crossing on the branch u ~ 0 (going up-right), 0.6 m to its right: towards the
    # other branch (going down-right), which is nearer there (about 0.45 m; the branches part at
    # 53 deg), so the nearest sample of the whole window lies on it.
    s_vehicle = 1.0
    px, py = (float(c) for c in path.point(s_vehicle))
    tx, ty = (float(c) for c in path.tangent(s_vehicle))
    x, y = px + 0.6 * ty, py - 0.6 * tx
    course = math.atan2(ty, tx)
    win = _Window(path, s_vehicle, 90.0)  # longer than a lobe: the other branch is in it
    other = np.array([path.point(v) for v in np.linspace(0.3 * total, 0.7 * total, 4001)])
    assert np.min(np.hypot(other[:, 0] - x, other[:, 1] - y)) < 0.55  # the other branch is the nearer
    look = 6.0

    def goal(band):
        _, _, gx, gy, _ = pursuit_command(win, np.array([x]), np.array([y]), np.array([course]),
                                          np.array([5.0]), np.array([look]), math.inf, 1.0, 0.3, band)
        return float(gx[0]), float(gy[0])

    # Where the goal should be: the path point about `look` metres of chord ahead of the vehicle
    # on its own branch (the first lobe's start, u small: x > 0, y > 0, going up-right).
    s_ahead = np.linspace(s_vehicle, s_vehicle + 12.0, 2001) % total
    chord = np.array([math.hypot(*(np.asarray(path.point(v)) - (x, y))) for v in s_ahead])
    expected = np.asarray(path.point(float(s_ahead[np.argmax(chord >= look)])))
    gx, gy = goal(_band(win, np.array([win.index_of(s_vehicle)]), 5.0, 0.0, -0.6))
    assert math.hypot(gx - expected[0], gy - expected[1]) < 0.1
    assert gx > 0.0 and gy > 0.0
    # Searched over the whole window, the goal would be a lobe ahead, down-right of the crossing.
    gx, gy = goal(None)
    assert gy < 0.0


def test_rollouts_and_flight_follow_a_figure_eight_through_its_crossing():
    path = figure_eight()
    total = path.length_m
    s0 = total - 15.0
    x, y = (float(c) for c in path.point(s0))
    tx, ty = (float(c) for c in path.tangent(s0))
    V = 3.0  # the lobes' tightest bend (radius 3 m at the tips) needs 3 m/s^2 at this speed
    law = PredictiveGuidance(path, PredictiveParams(lag_s=0.2, a_max_m_s2=5.0))
    start = VehicleState(x, y, math.atan2(ty, tx), V)
    res = simulate(path, law, start, GuidanceParams(speed_m_s=V, rate_hz=50.0), model=LagModel(0.2, 5.0),
                   t_max_s=2.0 * total / V)
    # Measured as the benches measure it: the projection carried along the flight from its start.
    d = crosstrack_sequential_m(path, res.x_m, res.y_m)[0]
    assert res.t_s[-1] > 1.9 * total / V  # two laps flown, through the crossing four times
    assert np.max(np.abs(d)) < 1.0


def hairpin():
    """A straight 60 m east along y = 0, a half-circle of radius 4 m to the left, and 60 m back
    west along y = 8: the path ahead bends back within a 30 m look-ahead."""
    def xy(u):
        u = np.asarray(u, dtype=float)
        r = 4.0
        x = np.where(u <= 60.0, u, np.where(u <= 60.0 + math.pi * r,
                                            60.0 + r * np.sin((u - 60.0) / r), 60.0 - (u - 60.0 - math.pi * r)))
        y = np.where(u <= 60.0, 0.0, np.where(u <= 60.0 + math.pi * r, r - r * np.cos((u - 60.0) / r), 2.0 * r))
        return x, y
    return parametric_path(lambda u: xy(u)[0], lambda u: xy(u)[1], (0.0, 120.0 + math.pi * 4.0))


@pytest.mark.parametrize("lambda_s4", [0.03, 0.3])
def test_a_loop_ahead_within_the_look_ahead_is_followed_not_turned_round(lambda_s4):
    # On the path going its way with a 30 m look-ahead (the longest candidate, the only one
    # here): from 26 m before the hairpin the goal lies on the way back, behind the beam. The
    # vehicle is not pointing away: no turn round, and it follows the hairpin.
    path = hairpin()
    V = 3.0
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=lambda_s4, lag_s=0.2, a_max_m_s2=5.0, l_min_m=30.0,
                                                    l_max_m=30.0, n_candidates=1))
    sides = []
    step = law.step

    def watched(t_s, state):
        out = step(t_s, state)
        sides.append(out.extra["capture_side"])
        return out

    law.step = watched  # type: ignore[method-assign]
    res = simulate(path, law, VehicleState(20.0, 0.0, 0.0, V), GuidanceParams(speed_m_s=V, rate_hz=50.0),
                   model=LagModel(0.2, 5.0), t_max_s=45.0)
    d = crosstrack_sequential_m(path, res.x_m, res.y_m)[0]
    assert not any(sides)
    assert res.x_m[-1] < 40.0 and res.y_m[-1] == pytest.approx(8.0, abs=1.0)  # on the way back west
    assert np.max(np.abs(d)) < 2.0
