"""The ground-speed hold: an integral of the speed error, bounded, on the reports' own clock."""

from __future__ import annotations

import math

import pytest

from companion.guidance.speed_hold import MAX_GAP_S, SpeedHold


def fly(hold: SpeedHold, t0: float, seconds: float, speed: float, v_east: float, rate_hz: float = 50.0) -> float:
    n = int(round(seconds * rate_hz))
    c = math.nan
    for k in range(n + 1):
        c = hold.update(t0 + k / rate_hz, speed, 0.0, v_east)
    return c


def test_a_steady_speed_error_ramps_the_correction_by_error_times_time_over_tc():
    hold = SpeedHold(tc_s=2.0)
    # 4 m/s flown for 5 asked: +1 m/s of error, 1.5 s integrated over 2 s -> 0.75 m/s
    assert fly(hold, 0.0, 1.5, 5.0, 4.0) == pytest.approx(0.75, abs=1e-9)
    # a vehicle 0.5 m/s too fast brings it back down at 0.25 m/s per second
    assert fly(hold, 10.0, 1.0, 5.0, 5.5) == pytest.approx(0.75 - 0.25, abs=1e-9)


def test_the_correction_is_bounded_both_ways():
    # -20 % and +40 % of V = 5 m/s: -1 and +2 m/s, however long the error lasts
    hold = SpeedHold(tc_s=0.5)
    assert fly(hold, 0.0, 10.0, 5.0, 1.0) == pytest.approx(2.0)
    assert fly(hold, 20.0, 10.0, 5.0, 9.0) == pytest.approx(-1.0)


def test_repeated_non_finite_and_gapped_reports_do_not_integrate():
    hold = SpeedHold(tc_s=1.0)
    assert hold.update(0.0, 5.0, 0.0, 4.0) == 0.0  # the first report only starts the clock
    assert hold.update(0.1, 5.0, 0.0, 4.0) == pytest.approx(0.1)
    assert hold.update(0.1, 5.0, 0.0, 1.0) == pytest.approx(0.1)  # the same report again
    assert hold.update(0.05, 5.0, 0.0, 1.0) == pytest.approx(0.1)  # an older one
    assert hold.update(0.2, 5.0, math.nan, 1.0) == pytest.approx(0.1)
    assert hold.update(0.2, math.inf, 0.0, 1.0) == pytest.approx(0.1)
    # a gap longer than MAX_GAP_S restarts the clock: nothing of the gap is integrated
    assert hold.update(0.1 + MAX_GAP_S + 0.01, 5.0, 0.0, 4.0) == pytest.approx(0.1)
    assert hold.update(0.1 + MAX_GAP_S + 0.11, 5.0, 0.0, 4.0) == pytest.approx(0.2)


def test_a_pause_holds_the_correction_and_restarts_the_clock():
    hold = SpeedHold(tc_s=1.0)
    fly(hold, 0.0, 1.0, 5.0, 4.0)
    assert hold.pause() == pytest.approx(1.0)
    assert hold.update(3.0, 5.0, 0.0, 4.0) == pytest.approx(1.0)  # the clock starts again here
    assert hold.update(3.1, 5.0, 0.0, 4.0) == pytest.approx(1.1)


@pytest.mark.parametrize("tc", [0.0, -1.0, math.nan, math.inf, True, "2"])
def test_a_bad_integral_time_is_refused(tc):
    with pytest.raises(ValueError, match="tc_s"):
        SpeedHold(tc)
