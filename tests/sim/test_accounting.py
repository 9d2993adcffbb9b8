"""One accounting for every law: the vehicle's limits saturate every command before it is flown,
and the metrics charge what was flown (``docs/benchmarks.md``, "Accounting")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.geometry.paths import function_path
from companion.guidance.factory import make_law
from companion.guidance.types import GuidanceParams, VehicleState
from companion.sim.simulator import LagModel, simulate

LAWS = ("fixed_l1", "corrector", "ap_l1", "npfg", "pure_pursuit", "predictive")
SINE = function_path(lambda x: 10.0 * np.sin(0.078 * x) + 20.0 * np.cos(0.082 * x), (-15.0, 60.0))
RATE_HZ = 50.0
V_M_S = 5.0
A_LIMIT = 1.5  # well below what the laws ask for from this start (2 V^2 / L1 = 5 m/s^2 and more)
TAU_S, DELAY_S = 0.3, 0.1


def _flown_by_hand(a_cmd: np.ndarray) -> np.ndarray:
    """The flown acceleration from the raw commands, written out from the model's definition:
    clip to the limit, delay by whole ticks, then the first-order lag whose exact solution over
    a tick from a0 towards a constant target u is u + (a0 - u) exp(-t / tau); the flown value is
    its mean over the tick, u + (a0 - u) tau / dt (1 - exp(-dt / tau))."""
    dt = 1.0 / RATE_HZ
    k = int(round(DELAY_S * RATE_HZ))
    clipped = [min(max(a, -A_LIMIT), A_LIMIT) for a in a_cmd]
    acting = [0.0] * k + clipped
    e = math.exp(-dt / TAU_S)
    a0, out = 0.0, []
    for i in range(len(a_cmd)):
        u = acting[i]
        out.append(u + (a0 - u) * TAU_S / dt * (1.0 - e))
        a0 = u + (a0 - u) * e
    return np.array(out)


@pytest.mark.parametrize("method", LAWS)
def test_every_law_is_charged_for_what_the_vehicle_flies_within_its_limit(method):
    params = GuidanceParams(method=method, l1_m=10.0, rate_hz=RATE_HZ, speed_m_s=V_M_S)
    law = make_law(SINE, params, RATE_HZ, V_M_S)
    # 12 m to the right of the path start, heading across it: every law turns hard at first.
    start = VehicleState(-15.0, -14.5, math.radians(80.0), V_M_S)
    model = LagModel(tau_s=TAU_S, a_max_m_s2=A_LIMIT, delay_s=DELAY_S)
    res = simulate(SINE, law, start, params, model=model, t_max_s=12.0)
    n = res.t_s.size
    assert n > 100
    a_cmd = res.a_cmd_m_s2
    # The law asked for more than the vehicle can fly (else the test would prove nothing) ...
    assert np.max(np.abs(a_cmd)) > A_LIMIT
    # ... the vehicle flew at most its limit, and the metrics say so.
    flown = res.a_achieved_m_s2
    assert np.all(np.abs(flown) <= A_LIMIT + 1e-12)
    assert res.metrics["a_max_m_s2"] <= A_LIMIT + 1e-12
    assert np.all(res.a_sat_m_s2 == np.clip(a_cmd, -A_LIMIT, A_LIMIT))
    assert np.allclose(flown, _flown_by_hand(a_cmd), atol=1e-12)
    # a_rms and a_max of the flown column, by plain arithmetic.
    a_rms = math.sqrt(sum(float(a) * float(a) for a in flown) / n)
    assert res.metrics["a_rms_m_s2"] == pytest.approx(a_rms, rel=1e-12)
    assert res.metrics["a_max_m_s2"] == pytest.approx(max(abs(float(a)) for a in flown), rel=1e-12)
    assert res.metrics["samples"] == n
