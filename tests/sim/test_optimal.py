"""The offline optimal bound (companion.sim.optimal): its gradient, a closed form, the causal laws
it must not lose to, and its agreement with the simulator.

Independent arithmetic throughout: on a straight path along +x the signed cross-track error is
``y`` itself, and the flown acceleration is recomputed here tick by tick from the first-order
lag's own formula, so neither the projection nor the module's filter is trusted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.bench.scenarios import ScenarioSpec, function_mission_text
from companion.bench.tracking import ModelSpec, make_law
from companion.geometry.paths import function_path, waypoint_path
from companion.guidance.types import GuidanceOutput, GuidanceParams, VehicleState
from companion.sim.optimal import (BoundFront, OptimalProblem, _crosstrack_newton, bound_d_rms,
                                   cost_and_gradient, crosstrack_sequential_m, gap_pct, solve_optimal,
                                   whole_flight_metrics)
from companion.sim.simulator import LagModel, simulate

LINE = function_path(lambda x: 0.0 * x, (-20.0, 400.0))  # the x axis: d = y
V_M_S = 5.0
RATE_HZ = 50.0
LAG = LagModel(tau_s=0.3, a_max_m_s2=5.0)


def flown_by_hand(a_cmd: np.ndarray, model: LagModel | None, dt_s: float) -> np.ndarray:
    """Mean achieved acceleration over each tick: saturate, delay, then the first-order lag
    solved over the tick (a(t) = target + (a0 - target) exp(-t / tau), averaged over dt)."""
    if model is None:
        return np.asarray(a_cmd, dtype=float)
    k = int(round(model.delay_s / dt_s))
    out, a0 = [], 0.0
    for i in range(len(a_cmd)):
        acting = a_cmd[i - k] if i >= k else 0.0
        target = max(-model.a_max_m_s2, min(model.a_max_m_s2, acting))
        if model.tau_s > 0:
            out.append(target + (a0 - target) * model.tau_s / dt_s * (1.0 - math.exp(-dt_s / model.tau_s)))
            a0 = target + (a0 - target) * math.exp(-dt_s / model.tau_s)
        else:
            out.append(target)
    return np.array(out)


class Replay:
    """A 'law' that plays back a fixed command sequence (0 once it runs out)."""

    def __init__(self, a_cmd: np.ndarray):
        self.a_cmd = a_cmd
        self.i = 0

    def step(self, t_s, state):
        a = float(self.a_cmd[self.i]) if self.i < self.a_cmd.size else 0.0
        self.i += 1
        return GuidanceOutput(a_cmd_m_s2=a, phase="close_range", crosstrack_m=state.y_m, s_proj_m=0.0)


def line_cost(x_m, y_m, a_flown, lambda_s4, n):
    """J on the x axis over the first n ticks: d = y."""
    del x_m
    return float(np.mean(np.asarray(y_m[:n]) ** 2) + lambda_s4 * np.mean(np.asarray(a_flown[:n]) ** 2))


# ----------------------------------------------------------------------------- gradient
@pytest.mark.parametrize("model", [None, LagModel(tau_s=0.3, a_max_m_s2=5.0, delay_s=0.06, wind_enu_m_s=(1.5, -1.0))],
                         ids=["ideal", "lag_delay_wind"])
def test_gradient_matches_central_differences_on_a_few_ticks_of_a_bend(model):
    path = function_path(lambda x: 6.0 * np.sin(0.15 * x), (0.0, 60.0))
    start = VehicleState(2.0, -1.5, 0.4, V_M_S)
    problem = OptimalProblem.build(path, start, rate_hz=10.0, horizon_s=1.2, model=model)
    u = np.random.default_rng(7).uniform(-3.0, 3.0, problem.n_ticks)
    lam = 0.2
    j, grad, s = cost_and_gradient(problem, lam, u)
    h = 1e-6
    fd = np.array([(cost_and_gradient(problem, lam, u + h * e)[0] - cost_and_gradient(problem, lam, u - h * e)[0]) / (2 * h)
                   for e in np.eye(problem.n_ticks)])
    assert np.max(np.abs(grad)) > 1e-3
    assert np.max(np.abs(grad - fd)) <= 1e-6 * np.max(np.abs(fd)) + 1e-9
    if model is not None and problem.delay_ticks:
        # Commands that only act after the horizon cannot matter.
        assert np.all(grad[problem.n_ticks - problem.delay_ticks:] == 0.0)
    # The hinted (vectorised) projection gives the same cost and gradient as the tick-by-tick one.
    j2, grad2, _ = cost_and_gradient(problem, lam, u, s)
    assert j2 == pytest.approx(j, rel=1e-12)
    assert np.max(np.abs(grad2 - grad)) <= 1e-9 * np.max(np.abs(grad))


def test_vectorised_projection_agrees_with_the_bench_rule_on_a_closed_track():
    track = waypoint_path([(0, 0), (40, 0), (50, 10), (40, 20), (0, 20), (-10, 10)], closed=True)
    t = np.linspace(0.0, 2.0 * math.pi, 400)
    x = 15.0 + 27.0 * np.cos(t)
    y = 10.0 + 12.0 * np.sin(t)
    d_ref, s_ref = crosstrack_sequential_m(track, x, y)
    hint = np.roll(s_ref, 3)  # stale hints, as between two evaluations of the optimiser
    d, s, nx, ny = _crosstrack_newton(track, x, y, hint)
    assert np.max(np.abs(d - d_ref)) < 1e-9
    assert np.allclose(np.hypot(nx, ny), 1.0)


# ----------------------------------------------------------------------------- closed form
@pytest.mark.parametrize("lambda_s4", [0.01, 0.1])
def test_small_angle_line_capture_approaches_the_continuous_riccati_cost(lambda_s4):
    # d'' = a (V sin(psi) ~ V psi), cost int (d^2 + lambda a^2) dt. The 2x2 algebraic Riccati
    # equation with A = [[0, 1], [0, 0]], B = [0, 1], Q = diag(1, 0), R = lambda gives
    # P = [[sqrt(2) l^(1/4), l^(1/2)], [l^(1/2), sqrt(2) l^(3/4)]], so from d0 = 0, d0' = V psi0
    # the optimal integral is sqrt(2) lambda^(3/4) (V psi0)^2, and J = that / T.
    # Tolerance 0.5 %: the small-angle error is of order psi0^2 / 2 = 0.13 %, the per-tick hold
    # and sampling of order (dt / lambda^(1/4))^2 <= 0.3 % at 100 Hz, the finite horizon
    # exp(-T / lambda^(1/4)) negligible for T = 10 s.
    psi0, horizon = 0.05, 10.0
    problem = OptimalProblem.build(LINE, VehicleState(0.0, 0.0, psi0, V_M_S), rate_hz=100.0, horizon_s=horizon)
    sol = solve_optimal(problem, lambda_s4)
    exact = math.sqrt(2.0) * lambda_s4 ** 0.75 * (V_M_S * psi0) ** 2 / horizon
    assert sol.cost == pytest.approx(exact, rel=5e-3)
    # Its own split: the continuous optimum spends int lambda a^2 = int d^2 / 3 ... checked
    # only loosely, through J = D + lambda A.
    assert sol.d_rms_m ** 2 + lambda_s4 * sol.a_rms_m_s2 ** 2 == pytest.approx(sol.cost, rel=1e-9)


# ----------------------------------------------------------------------------- the causal laws
LAWS = [("fixed_l1", 7.0), ("corrector", 7.0), ("ap_l1", 6.0), ("npfg", 4.0), ("pure_pursuit", 5.0),
        ("predictive", 0.03)]


def test_on_the_line_with_a_heading_error_the_optimum_beats_every_causal_law_and_bounds_them():
    heading = math.radians(30.0)
    start = VehicleState(0.0, 0.0, heading, V_M_S)
    horizon = 8.0
    n = int(horizon * RATE_HZ)
    problem = OptimalProblem.build(LINE, start, rate_hz=RATE_HZ, horizon_s=horizon, model=LAG)
    lambdas = (0.01, 0.1)
    # No law's commands as a warm start: the optimiser must find its way alone.
    sols = [solve_optimal(problem, lam) for lam in lambdas]
    front = BoundFront.from_solutions(sols)
    # The bench's lag model is LAG (0.3 s, 5 m/s^2): the laws that know the model are told that one.
    sc = ScenarioSpec("line", function_mission_text("line", "0*x", (-20.0, 400.0)), 0.0, 0.0, heading,
                      speed_m_s=V_M_S, lag_s=LAG.tau_s, a_max_m_s2=LAG.a_max_m_s2)
    for law, setting in LAWS:
        res = simulate(LINE, make_law(law, setting, sc, ModelSpec("lag")), start,
                       GuidanceParams(speed_m_s=V_M_S, rate_hz=RATE_HZ), model=LAG, t_max_s=horizon)
        assert res.t_s.size == n + 1, law
        a_flown = flown_by_hand(res.a_cmd_m_s2, LAG, 1.0 / RATE_HZ)
        d_rms = math.sqrt(np.mean(res.y_m[:n] ** 2))
        a_rms = math.sqrt(np.mean(a_flown[:n] ** 2))
        for sol in sols:
            j_law = line_cost(res.x_m, res.y_m, a_flown, sol.lambda_s4, n)
            assert 0.0 < sol.cost <= j_law, (law, sol.lambda_s4)
        assert d_rms >= front.d_rms_m(a_rms), law
        assert gap_pct(d_rms, a_rms, front) >= 0.0, law
        # The module's own whole-flight figures for the law are the ones computed here by hand.
        m = whole_flight_metrics(problem, res.a_cmd_m_s2)
        assert m["d_rms_m"] == pytest.approx(d_rms, rel=1e-9)
        assert m["a_rms_m_s2"] == pytest.approx(a_rms, rel=1e-9)
    # Each optimum sits on its own front: the bound at its a_rms is its d_rms.
    for sol in sols:
        assert front.d_rms_m(sol.a_rms_m_s2) == pytest.approx(sol.d_rms_m, rel=1e-6)


def test_bound_arithmetic_by_hand():
    front = BoundFront((0.01, 0.1), (0.02, 0.05))
    # At a_rms 0.5: max(0.02 - 0.0025, 0.05 - 0.025) = 0.025.
    assert bound_d_rms(0.5, front) == pytest.approx(math.sqrt(0.025))
    assert gap_pct(2.0 * math.sqrt(0.025), 0.5, front) == pytest.approx(100.0)
    assert bound_d_rms(10.0, front) == 0.0
    assert gap_pct(0.1, 10.0, front) == math.inf


# ----------------------------------------------------------------------------- the simulator
def test_optimum_respects_saturation_and_replays_through_simulate_at_the_same_cost():
    # 60 degrees off the line, heading away, with a small lambda: the optimum turns at the limit.
    # (Straight away from the line, at 90 degrees, all-zero commands are a saddle point: turning
    # left and right cost the same.)
    start = VehicleState(0.0, 3.0, math.radians(60.0), V_M_S)
    horizon = 6.0
    problem = OptimalProblem.build(LINE, start, rate_hz=RATE_HZ, horizon_s=horizon, model=LAG)
    lam = 0.003
    sol = solve_optimal(problem, lam)
    u = sol.a_cmd_m_s2
    assert np.max(np.abs(u)) <= LAG.a_max_m_s2 + 1e-12
    assert np.sum(np.abs(u) >= LAG.a_max_m_s2 - 1e-9) >= 10  # the limit is reached and held
    n = problem.n_ticks
    res = simulate(LINE, Replay(u), start, GuidanceParams(speed_m_s=V_M_S, rate_hz=RATE_HZ), model=LAG,
                   t_max_s=horizon)
    assert res.t_s.size == n + 1
    a_flown = flown_by_hand(res.a_cmd_m_s2, LAG, 1.0 / RATE_HZ)
    assert line_cost(res.x_m, res.y_m, a_flown, lam, n) == pytest.approx(sol.cost, rel=1e-9)
    assert np.max(np.abs(a_flown)) <= LAG.a_max_m_s2


def test_a_worse_start_is_never_returned_and_bad_input_is_named():
    problem = OptimalProblem.build(LINE, VehicleState(0.0, 1.0, 0.0, V_M_S), rate_hz=RATE_HZ, horizon_s=2.0,
                                   model=LAG)
    zero = solve_optimal(problem, 0.1, [np.zeros(problem.n_ticks)], max_iter=20)
    assert zero.cost <= zero.warm_costs[0]
    with pytest.raises(ValueError, match="warm start"):
        solve_optimal(problem, 0.1, [np.zeros(3)])
    with pytest.raises(ValueError, match="lambda_s4"):
        solve_optimal(problem, -1.0)
    with pytest.raises(ValueError, match="levels"):
        solve_optimal(problem, 0.1, levels=(5,))
    with pytest.raises(ValueError, match="horizon_s"):
        OptimalProblem.build(LINE, VehicleState(0.0, 1.0, 0.0, V_M_S), rate_hz=RATE_HZ, horizon_s=0.0)
