"""The predictive law's cost to go at the rollouts' horizon (``cost_to_go_factor``,
``PredictiveParams.terminal_cost``): the Riccati solution checked against its closed form and
against a simulated optimal return, and what it is for: at a large lambda a plan that sees nothing
past its horizon settles well inside a circle; charged for what it leaves at the horizon, it does
not."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from companion.guidance.predictive import PredictiveGuidance, PredictiveParams, cost_to_go_factor
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from bench_scenes import CirclePath  # noqa: E402

V = 5.0


@pytest.mark.parametrize("lam", [0.003, 0.03, 0.3, 1.0])
def test_ideal_vehicle_cost_to_go_is_the_double_integrators_closed_form(lam):
    # d'' = u, cost d^2 + lam u^2: P = [[sqrt(2) lam^(1/4), lam^(1/2)], [lam^(1/2), sqrt(2) lam^(3/4)]].
    m = cost_to_go_factor(0.0, lam)
    p = m.T @ m
    q = lam ** 0.25
    assert p[:2, :2] == pytest.approx(np.array([[math.sqrt(2.0) * q, q * q], [q * q, math.sqrt(2.0) * q**3]]),
                                      rel=1e-9, abs=1e-12)
    assert np.all(m[:, 2] == 0.0)  # no lag state


def _optimal_return_cost(lag_s: float, lam: float, x0: np.ndarray) -> float:
    """integral (d^2 + lam u^2) dt of the LQR return u = -K x from x0, summed by hand: the
    closed loop is linear, so the state after each 1 ms step is expm(A_cl dt) x exactly, and the
    integral is the trapezoid sum over 60 s."""
    from scipy.linalg import solve_continuous_are

    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0 / lag_s]])
    b = np.array([[0.0], [0.0], [1.0 / lag_s]])
    p = solve_continuous_are(a, b, np.diag([1.0, 0.0, 0.0]), np.array([[lam]]))
    k = (b.T @ p) / lam
    dt = 1e-3
    step = expm((a - b @ k) * dt)
    x = x0.astype(float)
    total = 0.0
    prev = None
    for _ in range(60000):
        u = float(-(k @ x)[0])
        rate = x[0] ** 2 + lam * u * u
        if prev is not None:
            total += 0.5 * (prev + rate) * dt
        prev = rate
        x = step @ x
    return total


@pytest.mark.parametrize("lag_s,lam", [(0.3, 0.03), (0.3, 1.0), (0.6, 0.3)])
def test_lag_cost_to_go_is_what_the_optimal_return_pays(lag_s, lam):
    m = cost_to_go_factor(lag_s, lam)
    for x0 in (np.array([0.5, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([-0.2, 0.3, 1.5])):
        assert float(np.sum((m @ x0) ** 2)) == pytest.approx(_optimal_return_cost(lag_s, lam, x0), rel=1e-3)


def test_a_small_lag_tends_to_the_ideal_cost_to_go():
    m, m0 = cost_to_go_factor(1e-3, 0.3), cost_to_go_factor(0.0, 0.3)
    assert (m.T @ m)[:2, :2] == pytest.approx((m0.T @ m0)[:2, :2], rel=2e-2)


def test_no_acceleration_weight_no_cost_to_go():
    assert np.all(cost_to_go_factor(0.3, 0.0) == 0.0)


def _steady_on_circle(lam: float, terminal: bool) -> tuple[float, float]:
    """Mean radial offset (m, + outside) and mean of d^2 + lam a^2 over the last 20 s of 40 s
    flown along a 30 m circle from on it, lag 0.3 s."""
    path = CirclePath(30.0)
    law = PredictiveGuidance(path, PredictiveParams(lambda_s4=lam, lag_s=0.3, a_max_m_s2=5.0,
                                                    terminal_cost=terminal))
    res = simulate(path, law, VehicleState(30.0, 0.0, math.pi / 2, V), GuidanceParams(speed_m_s=V),
                   model=LagModel(0.3, 5.0), t_max_s=40.0)
    late = res.t_s >= 20.0
    off = np.hypot(res.x_m, res.y_m)[late] - 30.0
    return float(np.mean(off)), float(np.mean(off**2 + lam * res.a_achieved_m_s2[late] ** 2))


def test_at_a_large_lambda_the_cost_to_go_keeps_the_plan_on_a_circle():
    # lambda 1 s^4 on a 30 m circle at 5 m/s (V^2/R = 0.833 m/s^2). The optimum of
    # d^2 + lambda a^2 flies a slightly larger circle: d (V^2/R)^2 (2 / R) lambda = 2 d, so
    # d = lambda (V^2/R)^2 / R = 2.3 cm outside. Without the cost to go the plan, which charges
    # the turn's acceleration to its end but not the way back past it, settles 9 cm *inside*.
    optimum = 1.0 * (V * V / 30.0) ** 2 / 30.0
    off_without, j_without = _steady_on_circle(1.0, False)
    off_with, j_with = _steady_on_circle(1.0, True)
    assert off_without < -0.05
    assert abs(off_with - optimum) < 0.06
    assert j_with < j_without
