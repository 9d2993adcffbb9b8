"""An open path that crosses itself, started at its crossing, is flown from its start.

The path: the lemniscate of Bernoulli (a = 60 m) ``x = a cos t / (1 + sin^2 t)``,
``y = a sin t cos t / (1 + sin^2 t)`` from 5 m before the crossing at the origin (t = pi / 2,
heading south-west) once round both lobes to 12 m before the origin again: an open path that
crosses itself once, at s = 5 m (first branch) and at s = 162.3 m (second branch), at right
angles. The vehicle starts 0.5 m from the crossing along the second branch, so the closest path
point is on the second branch, heading along the first. Every law must join the first branch
and fly the whole path in order (docs/frames.md, "Projection").
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import parametric_path
from companion.guidance.factory import make_law
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import simulate

A_M = 60.0
V_M_S = 5.0
RATE_HZ = 50.0
LAWS = ("fixed_l1", "corrector", "ap_l1", "npfg", "pure_pursuit", "predictive")


def _x(t):
    return A_M * np.cos(t) / (1.0 + np.sin(t) ** 2)


def _y(t):
    return A_M * np.sin(t) * np.cos(t) / (1.0 + np.sin(t) ** 2)


def _arc_length_table(t0: float, t1: float, n: int = 400_001):
    """Points and cumulative chord length of the closed form (independent of the Path class)."""
    t = np.linspace(t0, t1, n)
    x, y = _x(t), _y(t)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))))
    return t, x, y, s


def _crossing_path():
    t, _, _, s = _arc_length_table(0.0, 4.0 * math.pi)
    s_cross = float(np.interp(math.pi / 2.0, t, s))
    lap = float(np.interp(2.5 * math.pi, t, s)) - s_cross  # one lap: 5.2441 a
    t0 = float(np.interp(s_cross - 5.0, s, t))
    t1 = float(np.interp(s_cross + lap - 12.0, s, t))
    return parametric_path(_x, _y, (t0, t1)), (t0, t1)


PATH, T_RANGE = _crossing_path()
# The second branch crosses the origin heading south-east, (1, -1) / sqrt 2.
START = VehicleState(0.5 / math.sqrt(2.0), -0.5 / math.sqrt(2.0), math.radians(-135.0), V_M_S)


def test_the_path_crosses_itself_once_where_the_test_says():
    t, x, y, s = _arc_length_table(*T_RANGE)
    near = np.hypot(x, y) < 0.05
    s_near = s[near]
    first, second = s_near[s_near < 100.0], s_near[s_near > 100.0]
    assert first.mean() == pytest.approx(5.0, abs=0.05)
    assert second.mean() == pytest.approx(5.0 + 5.2441 * A_M / 2.0, abs=0.1)
    assert PATH.length_m == pytest.approx(5.2441 * A_M - 7.0, abs=0.05)
    # The start is nearer the second branch (0 m) than the first (0.5 m).
    d = np.hypot(x - START.x_m, y - START.y_m)
    assert d[s > 100.0].min() < 0.01 and d[s < 100.0].min() == pytest.approx(0.5, abs=0.01)


@pytest.mark.parametrize("method", LAWS)
def test_every_law_flies_a_self_crossing_open_path_from_its_start(method):
    params = GuidanceParams(method=method, l1_m=10.0, rate_hz=RATE_HZ, speed_m_s=V_M_S)
    law = make_law(PATH, params, RATE_HZ, V_M_S)
    res = simulate(PATH, law, START, params, keep_outputs=True)
    # The law's projection starts on the first branch and rises to the end.
    s_proj = np.array([o.s_proj_m for o in res.outputs])
    assert s_proj[0] < 10.0
    assert s_proj.max() > PATH.length_m - 15.0
    assert np.all(np.diff(s_proj) > -0.5)
    # Independently of the law: every point of the path from 20 m to 15 m before its end (bar
    # 15 m either side of the second pass through the crossing, where both branches are near)
    # is passed within 2.5 m, and in the order of the path.
    _, x, y, s = _arc_length_table(*T_RANGE, n=20_001)
    s_second = 5.0 + 5.2441 * A_M / 2.0
    check = (s >= 20.0) & (s <= s[-1] - 15.0) & (np.abs(s - s_second) > 15.0)
    first_pass_s = []
    for px, py in zip(x[check][::20], y[check][::20]):
        hits = np.flatnonzero(np.hypot(res.x_m - px, res.y_m - py) <= 2.5)
        assert hits.size, (method, px, py)
        first_pass_s.append(res.t_s[hits[0]])
    assert np.all(np.diff(first_pass_s) >= 0.0), method
