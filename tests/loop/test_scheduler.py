"""Fixed-rate scheduler on a fake clock: absolute deadlines, no drift, skipped ticks, statistics."""

import pytest

from companion.loop.scheduler import FakeClock, FixedRateScheduler


class FakeTimer:
    def __init__(self, clock):
        self.clock = clock

    def __call__(self):
        return self.clock.now()


def test_fifty_hertz_deadlines_are_exact_multiples_of_the_period():
    clock = FakeClock(100.0)
    s = FixedRateScheduler(50.0, clock)
    ticks = [s.wait_next() for _ in range(101)]
    for k, t in enumerate(ticks):
        s.done()
        assert t.deadline_s == pytest.approx(100.0 + k * 0.02, abs=1e-9)
    assert s.stats().rate_hz_achieved == pytest.approx(50.0)
    assert s.current_rate_hz() == pytest.approx(50.0)
    assert s.stats().skipped == 0


def test_work_shorter_than_a_period_does_not_drift_the_schedule():
    clock = FakeClock()
    s = FixedRateScheduler(50.0, clock)
    for _ in range(1000):
        t = s.wait_next()
        clock.advance(0.015)  # 15 ms of work in a 20 ms period
        s.done()
    assert t.deadline_s == pytest.approx(999 * 0.02, abs=1e-9)
    assert t.start_s == pytest.approx(t.deadline_s)


def test_one_slow_tick_skips_missed_deadlines_instead_of_bursting():
    clock = FakeClock()
    s = FixedRateScheduler(50.0, clock)
    s.wait_next(); s.done()                       # tick at 0.00
    s.wait_next(); clock.advance(0.065); s.done()  # tick at 0.02 overruns to 0.085
    t = s.wait_next()
    # Deadlines 0.04 and 0.06 passed more than a period ago: skipped; 0.08 runs at once.
    assert t.skipped == 2
    assert t.deadline_s == pytest.approx(0.08)
    assert t.start_s == pytest.approx(0.085)
    t2 = s.wait_next()
    assert t2.deadline_s == pytest.approx(0.10) and t2.skipped == 0
    assert s.stats().skipped == 2


def test_slightly_late_tick_runs_at_once_without_skipping():
    clock = FakeClock()
    s = FixedRateScheduler(10.0, clock)
    s.wait_next(); clock.advance(0.15); s.done()  # next deadline 0.1, now 0.15 (< one period late)
    t = s.wait_next()
    assert t.skipped == 0 and t.deadline_s == pytest.approx(0.1) and t.start_s == pytest.approx(0.15)


def test_statistics_percentiles_of_tick_work_time():
    clock = FakeClock()
    s = FixedRateScheduler(100.0, clock, work_timer=FakeTimer(clock))
    for k in range(100):
        s.wait_next()
        clock.advance(0.001 if k < 99 else 0.009)  # 1 ms work, one 9 ms outlier
        s.done()
    st = s.stats()
    assert st.tick_ms_p50 == pytest.approx(1.0)
    assert st.tick_ms_max == pytest.approx(9.0)
    assert 1.0 < st.tick_ms_p99 <= 9.0
    assert st.ticks == 100


def test_rate_must_be_positive():
    with pytest.raises(ValueError, match="rate_hz"):
        FixedRateScheduler(0.0, FakeClock())
