"""The slow tail compensated: the recursion's closed form, and a tail loop made first-order.

The vehicle here is the identified loop of docs/vehicle_model.md written out afresh and stepped
finely (1 ms) between the 50 Hz reports, with the setpoint held between them:
``a = (e - s f) / lag``, ``f' = (e - f) / tc``, ``e = c - v``. With the compensation its step
response must be the first-order ``1 - exp(-t / lag)``; without it, it is not.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from companion.guidance.tail_comp import MAX_GAP_S, MAX_SHARE, TailCompensator

SHARE, TC_S, LAG_S = 0.857, 0.958, 0.437  # PX4 SIH's identified loop
DT = 0.02


def test_with_the_velocity_held_the_correction_follows_the_geometric_closed_form():
    # v held at v0, setpoint c0 + s f sent every report: f[k+1] = f[k] + a (c0 + s f[k] - v0 - f[k]),
    # a = 1 - exp(-dt / tc), so f[k] = f_ss (1 - r^k), r = 1 - a (1 - s), f_ss = (c0 - v0) / (1 - s).
    c0, v0 = 5.0, 4.8
    comp = TailCompensator(SHARE, TC_S)
    a = 1.0 - math.exp(-DT / TC_S)
    r = 1.0 - a * (1.0 - SHARE)
    f_ss = (c0 - v0) / (1.0 - SHARE)
    for k in range(400):
        n, e = comp.correction(k * DT, 5.0, v0, 0.0)
        # report 0 only starts the clock: at report k, k intervals have been integrated
        expected = SHARE * f_ss * (1.0 - r ** k)
        assert n == pytest.approx(expected, abs=1e-12) and e == 0.0
        comp.sent(c0 + n, e)
    assert n < MAX_SHARE * 5.0  # the closed form was not clipped


def _tail_vehicle_response(compensate: bool, c0: float = 1.0, t_end_s: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """The loop's velocity at each 50 Hz report after a setpoint step ``c0`` from hover."""
    h = 0.001
    v = f = 0.0
    comp = TailCompensator(SHARE, TC_S)
    times, speeds = [], []
    for k in range(int(round(t_end_s / DT)) + 1):
        t = k * DT
        times.append(t)
        speeds.append(v)
        c = c0
        if compensate:
            corr, _ = comp.correction(t, 5.0, v, 0.0)
            c = c0 + corr
            comp.sent(c, 0.0)
        for _ in range(int(round(DT / h))):  # the setpoint held until the next report
            e = c - v
            f += (e - f) * (1.0 - math.exp(-h / TC_S))
            v += (e - SHARE * f) * (1.0 - math.exp(-h / LAG_S))
    return np.array(times), np.array(speeds)


def test_the_compensated_tail_loop_answers_a_step_as_a_first_order_lag():
    t, v = _tail_vehicle_response(compensate=True)
    first_order = 1.0 - np.exp(-t / LAG_S)
    # the compensation starts one report late and sees the velocity only at the reports:
    # within 3 % of the step everywhere
    assert np.max(np.abs(v - first_order)) < 0.03
    # uncompensated, the same vehicle is the loop's transfer function (docs/vehicle_model.md)
    # (1 - s + tc p) / (lag tc p^2 + (lag + tc) p + 1 - s), which the tail holds far below it
    _, v0 = _tail_vehicle_response(compensate=False)
    tail = signal.lti([TC_S, 1.0 - SHARE], [LAG_S * TC_S, LAG_S + TC_S, 1.0 - SHARE])
    _, closed = signal.step(tail, T=t)
    assert np.max(np.abs(v0 - closed)) < 1e-3
    i = int(round(3 * LAG_S / DT))  # at three lags the first-order loop is at 95 %
    assert first_order[i] > 0.94 and v0[i] < first_order[i] - 0.2 and v[i] > 0.92


def test_the_correction_is_bounded_and_keeps_its_direction():
    comp = TailCompensator(SHARE, TC_S)
    for k in range(2000):  # a vehicle that never moves, asked 5 m/s north-east
        n, e = comp.correction(k * DT, 5.0, 0.0, 0.0)
        comp.sent(3.0 + n, 4.0 + e)
    assert math.hypot(n, e) == pytest.approx(MAX_SHARE * 5.0)
    assert math.atan2(e, n) == pytest.approx(math.atan2(comp.f_m_s[1], comp.f_m_s[0]))


def test_a_gap_a_stale_report_and_nonfinite_values_restart_or_change_nothing():
    comp = TailCompensator(SHARE, TC_S)
    comp.correction(0.0, 5.0, 0.0, 0.0)
    comp.sent(5.0, 0.0)
    first = comp.correction(DT, 5.0, 0.0, 0.0)
    assert first[0] > 0
    assert comp.correction(DT, 5.0, 1.0, 0.0) == first  # not newer
    assert comp.correction(2 * DT, 5.0, math.nan, 0.0) == first  # not finite
    assert comp.correction(2 * DT + MAX_GAP_S + 0.01, 5.0, 0.0, 0.0) == (0.0, 0.0)  # a gap: from zero
    comp.sent(5.0, 0.0)
    comp.reset()
    assert comp.correction(3.0, 5.0, 0.0, 0.0) == (0.0, 0.0)  # after a reset, only the clock starts
    assert comp.correction(3.0 + DT, 5.0, 0.0, 0.0) == (0.0, 0.0)  # and no setpoint sent since


@pytest.mark.parametrize("share, tc_s", [(0.0, 1.0), (0.96, 1.0), (0.5, 0.0), (0.5, math.nan), (True, 1.0)])
def test_bad_parameters_are_refused(share, tc_s):
    with pytest.raises(ValueError, match="expected a number"):
        TailCompensator(share, tc_s)
