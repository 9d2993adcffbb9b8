"""The predictive law's rollout horizon at a large lambda (``PredictiveParams.horizon``): four
closed-loop time constants of the cost, checked against the regulator's poles, and what it is
for: a smooth setting that cuts a figure-eight's bends by decimetres only where it flies less
acceleration for it."""

from __future__ import annotations


import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

import companion.guidance.predictive as predictive
from companion.bench import tracking
from companion.guidance.predictive import PredictiveParams


@pytest.mark.parametrize("lam", [0.03, 1.0, 10.0])
def test_the_time_constant_is_that_of_the_regulators_poles(lam):
    # d'' = u with cost d^2 + lam u^2: the closed loop's poles have real part -1 / (sqrt(2) lam^(1/4)).
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    b = np.array([[0.0], [1.0]])
    p = solve_continuous_are(a, b, np.diag([1.0, 0.0]), np.array([[lam]]))
    poles = np.linalg.eigvals(a - b @ (b.T @ p) / lam)
    tc = -1.0 / float(np.max(poles.real))
    horizon, segments = PredictiveParams(lambda_s4=lam).horizon()
    assert horizon == pytest.approx(max(5.0, 4.0 * tc), rel=1e-9)
    assert horizon / segments == pytest.approx(0.5, rel=0.05)  # the segments keep their length


def test_the_default_horizon_holds_up_to_lambda_0_61():
    # 4 sqrt(2) lam^(1/4) = 5 s at lam = (5 / (4 sqrt(2)))^4 = 625 / 1024
    assert PredictiveParams(lambda_s4=625 / 1024).horizon() == (pytest.approx(5.0), 10)
    assert PredictiveParams(lambda_s4=0.03).horizon() == (5.0, 10)
    assert PredictiveParams(lambda_s4=0.7).horizon()[0] > 5.0
    assert PredictiveParams(lambda_s4=10.0, horizon_s=12.0, plan_segments=6).horizon() == (12.0, 6)


def test_at_a_large_lambda_the_plan_trades_error_for_acceleration(monkeypatch):
    # The bench's figure-eight (lag model) at lambda 3. With the horizon held at 5 s (2.7 time
    # constants) the plan eased off the corrections whose effect fell past it: the vehicle drifted
    # a quarter of a metre off the path and flew no less acceleration than at lambda 1.
    task = tracking.Task(tracking.named_spec("figure_eight"), tracking.ModelSpec("lag"), "predictive", 3.0)
    scaled = tracking.run_one(task)
    monkeypatch.setattr(predictive, "HORIZON_TIME_CONSTANTS", 0.0)
    fixed = tracking.run_one(task)
    cost = {name: r["d_rms_m"] ** 2 + 3.0 * r["a_rms_m_s2"] ** 2 for name, r in (("scaled", scaled), ("fixed", fixed))}
    assert scaled["d_rms_m"] < 0.6 * fixed["d_rms_m"]
    assert scaled["a_rms_m_s2"] < fixed["a_rms_m_s2"]
    assert cost["scaled"] < cost["fixed"]
