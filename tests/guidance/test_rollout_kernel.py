"""The compiled rollouts (``companion.guidance.rollout_kernel``) against the numpy ones they stand
for: the same residuals to rounding on every kind of state the law meets (on and off the path,
open and closed paths, past an open path's end, with wind, with the capture reference, with the
band cut short by a self-crossing path), and the same flight."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.bench import tracking as T
from companion.bench.scenarios import random_spec
from companion.guidance import rollout_kernel
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams, tick_pursuit
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate

pytestmark = pytest.mark.skipif(not rollout_kernel.AVAILABLE, reason="numba is not installed (companion[fast])")


def both(law: PredictiveGuidance, state: VehicleState, look: np.ndarray, plans: np.ndarray, d_ref):
    law.compiled = True
    compiled = law.rollout(state, look, plans, d_ref)
    law.compiled = False
    plain = law.rollout(state, look, plans, d_ref)
    law.compiled = True
    return compiled, plain


# Random scenarios of every kind: open, closed and self-crossing paths, winds up to 40 % of the
# speed, lags 0.1-0.6 s, speeds 3-15 m/s (``companion.bench.scenarios``; tune-range seeds).
@pytest.mark.parametrize("seed", [3, 11, 26, 58, 91, 140])
def test_compiled_rollouts_give_the_numpy_residuals(seed):
    spec = random_spec(seed)
    law = T.make_law("predictive", 0.03, spec, T.ModelSpec("lag"))
    path = law.path
    rng = np.random.default_rng(seed)
    for trial in range(12):
        s = rng.uniform(-0.1, 1.1) * path.length_m  # beyond either end of an open path too
        s = min(max(s, 0.0), path.length_m)
        px, py = (float(c) for c in path.point(s))
        tx, ty = (float(c) for c in path.tangent(s))
        off = rng.choice([0.0, rng.normal(0.0, 2.0), rng.normal(0.0, 40.0)])
        state = VehicleState(px - off * ty, py + off * tx, math.atan2(ty, tx) + rng.normal(0.0, 1.0),
                             spec.speed_m_s)
        law._a_hat = float(rng.normal(0.0, 1.5))
        law.step(10.0 * trial, state)  # sets the window and the projection from this state
        look = np.geomspace(3.0, 30.0, 26)
        plans = rng.normal(0.0, 1.5, (26, law.params.plan_segments))
        for d_ref in (None, law._reference(state)):
            compiled, plain = both(law, state, look, plans, d_ref)
            assert compiled.shape == plain.shape
            np.testing.assert_allclose(compiled, plain, rtol=1e-9, atol=1e-9)


def test_a_compiled_flight_is_the_numpy_flight():
    spec = random_spec(26)
    path = T.build_path(spec)
    start = VehicleState(spec.x_m, spec.y_m, spec.heading_rad, spec.speed_m_s)
    params = PredictiveParams(lag_s=spec.lag_s, a_max_m_s2=spec.a_max_m_s2, wind_x_m_s=spec.wind_enu_m_s[0],
                              wind_y_m_s=spec.wind_enu_m_s[1])
    runs = []
    for compiled in (True, False):
        law = PredictiveGuidance(path, params)
        law.compiled = compiled
        runs.append(simulate(path, law, start, GuidanceParams(speed_m_s=spec.speed_m_s, rate_hz=50.0),
                             model=LagModel(spec.lag_s, spec.a_max_m_s2, wind_enu_m_s=spec.wind_enu_m_s),
                             t_max_s=30.0))
    a, b = runs
    assert a.t_s.size == b.t_s.size
    np.testing.assert_allclose(a.x_m, b.x_m, atol=1e-6)
    np.testing.assert_allclose(a.a_cmd_m_s2, b.a_cmd_m_s2, atol=1e-6)


@pytest.mark.parametrize("seed", [3, 26, 91, 140])
def test_the_compiled_tick_gives_the_numpy_command_goal_and_reference(seed):
    # The tick's own pursuit and the capture reference's projection, compiled and in numpy, on the
    # same kinds of state as above (on and off the path, past an open path's end, any course).
    spec = random_spec(seed)
    law = T.make_law("predictive", 0.03, spec, T.ModelSpec("lag"))
    path = law.path
    rng = np.random.default_rng(seed + 1)
    for trial in range(20):
        s = min(max(rng.uniform(-0.1, 1.1) * path.length_m, 0.0), path.length_m)
        px, py = (float(c) for c in path.point(s))
        tx, ty = (float(c) for c in path.tangent(s))
        off = rng.choice([0.0, rng.normal(0.0, 2.0), rng.normal(0.0, 40.0)])
        state = VehicleState(px - off * ty, py + off * tx, math.atan2(ty, tx) + rng.normal(0.0, 1.0),
                             spec.speed_m_s * rng.uniform(0.02, 1.5))
        law.step(10.0 * trial, state)
        law._look_m = float(rng.uniform(3.0, 30.0))
        def tick(kernel, state=state):
            return tick_pursuit(law._win, law._tick_band(state), state, law._look_m, law.params.curvature_ff,
                                law._lag_s, kernel)

        law.compiled = True
        compiled = tick(law._kernel), law._reference(state)
        law.compiled = False
        plain = tick(None), law._reference(state)
        law.compiled = True
        np.testing.assert_allclose(compiled[0], plain[0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(compiled[1], plain[1], rtol=1e-9, atol=1e-9)
        assert all(math.isfinite(v) for v in compiled[0])


def test_a_flight_calls_the_loops_only_as_they_were_compiled_when_loaded():
    # load() compiles the loops (or reads them from the cache) before the flight's first tick. A
    # call with other argument layouts (a strided view, a Fortran-ordered matrix) would compile a
    # new version on that tick: two seconds on a machine without the cache, a flight loop stalled.
    # Flying the figure-eight from off the path (captures, re-optimisations, the cost to go)
    # must add no version to any loop.
    from pathlib import Path

    from companion.guidance.factory import make_law
    from companion.mission import load_mission

    kernel = rollout_kernel.load()
    assert kernel is not None
    before = {name: len(getattr(kernel, name).signatures) for name in ("rollout", "pursuit", "project")}
    mission = load_mission(Path(__file__).resolve().parents[2] / "missions" / "figure_eight.yaml")
    params = GuidanceParams(method="predictive", lambda_s4=0.3, l1_m=10.0, rate_hz=50.0, speed_m_s=5.0)
    law = make_law(mission.path, params, 50.0, 5.0)
    simulate(mission.path, law, VehicleState(x_m=-8.0, y_m=4.0, course_rad=2.0, speed_m_s=5.0), params,
             model=LagModel(tau_s=0.3, a_max_m_s2=5.0), t_max_s=12.0)
    after = {name: len(getattr(kernel, name).signatures) for name in ("rollout", "pursuit", "project")}
    assert after == before
