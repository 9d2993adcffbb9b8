"""Fixed-rate scheduler with an injectable clock: absolute deadlines, no drift, missed ticks skipped.

Tick ``k`` is due at ``t0 + k / rate_hz`` (absolute deadlines: a slow tick does not push the
following ones later, so the rate does not drift). When the loop falls behind by more than one
period, the deadlines already passed are *skipped* (counted, never run in a burst) except the
most recent one, which runs at once; a tick late by less than a period simply runs at once.

The clock is anything with ``now() -> float`` (seconds) and ``wait_until(t)``; the flight runner
passes one whose ``wait_until`` services the MAVLink link while it waits, and a test passes
:class:`FakeClock`. Statistics (:meth:`FixedRateScheduler.stats`): achieved rate in the
scheduler's clock, tick work time p50/p99 (wall time measured by ``work_timer``), missed ticks.

Examples
--------
>>> clock = FakeClock()
>>> sched = FixedRateScheduler(10.0, clock)
>>> [round(sched.wait_next().deadline_s, 3) for _ in range(3)]
[0.0, 0.1, 0.2]
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np


class Clock(Protocol):
    def now(self) -> float: ...

    def wait_until(self, t_s: float) -> None: ...


class MonotonicClock:
    """Wall clock on ``time.monotonic``; ``wait_until`` sleeps (or calls ``idle(timeout)``)."""

    def __init__(self, idle: Callable[[float], None] | None = None):
        self._idle = idle

    def now(self) -> float:
        return time.monotonic()

    def wait_until(self, t_s: float) -> None:
        while True:
            remaining = t_s - time.monotonic()
            if remaining <= 0:
                return
            if self._idle is not None:
                self._idle(remaining)
            else:
                time.sleep(remaining)


class FakeClock:
    """A clock for tests: ``wait_until`` jumps to the deadline; ``advance`` simulates slow work."""

    def __init__(self, start_s: float = 0.0):
        self.t_s = float(start_s)

    def now(self) -> float:
        return self.t_s

    def wait_until(self, t_s: float) -> None:
        if t_s > self.t_s:
            self.t_s = t_s

    def advance(self, dt_s: float) -> None:
        self.t_s += dt_s


@dataclass(frozen=True)
class Tick:
    index: int  # deadline index k (counts skipped deadlines too)
    count: int  # number of ticks actually run before this one
    deadline_s: float
    start_s: float  # clock time when the tick was released
    skipped: int  # deadlines skipped just before this tick


@dataclass(frozen=True)
class SchedulerStats:
    ticks: int
    skipped: int
    rate_hz_target: float
    rate_hz_achieved: float
    tick_ms_p50: float
    tick_ms_p99: float
    tick_ms_max: float

    def as_dict(self) -> dict:
        return {
            "ticks": self.ticks,
            "skipped_ticks": self.skipped,
            "rate_hz_target": self.rate_hz_target,
            "rate_hz_achieved": self.rate_hz_achieved,
            "tick_ms": {"p50": self.tick_ms_p50, "p99": self.tick_ms_p99, "max": self.tick_ms_max},
        }


class FixedRateScheduler:
    """Release ticks at ``rate_hz`` on ``clock`` with absolute deadlines.

    Use :meth:`wait_next` to block until the next tick, then run the work and call
    :meth:`done` (which records the work time measured by ``work_timer``, wall-clock
    ``time.perf_counter`` by default).
    """

    def __init__(self, rate_hz: float, clock: Clock, work_timer: Callable[[], float] = time.perf_counter):
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz: expected a finite number > 0, got {rate_hz!r}")
        self.rate_hz = float(rate_hz)
        self.period_s = 1.0 / self.rate_hz
        self.clock = clock
        self._work_timer = work_timer
        self._t0: float | None = None
        self._next_index = 0
        self._count = 0
        self._skipped = 0
        self._first_start: float | None = None
        self._last_start: float | None = None
        self._work_started: float | None = None
        self._work_ms: list[float] = []

    def deadline(self, index: int) -> float:
        assert self._t0 is not None
        return self._t0 + index * self.period_s

    def wait_next(self) -> Tick:
        """Block until the next due deadline and return the tick to run."""
        if self._t0 is None:
            self._t0 = self.clock.now()
        k = self._next_index
        now = self.clock.now()
        skipped = 0
        # Late by a full period or more: skip the deadlines already passed (no burst).
        if now - self.deadline(k) >= self.period_s:
            k_due = int(math.floor((now - self._t0) / self.period_s))
            skipped = k_due - k
            k = k_due
            # ``now`` lies in [deadline(k), deadline(k+1)): run k at once.
        self.clock.wait_until(self.deadline(k))
        start = self.clock.now()
        self._skipped += skipped
        tick = Tick(index=k, count=self._count, deadline_s=self.deadline(k), start_s=start, skipped=skipped)
        self._next_index = k + 1
        self._count += 1
        if self._first_start is None:
            self._first_start = start
        self._last_start = start
        self._work_started = self._work_timer()
        return tick

    def done(self) -> None:
        """Mark the end of the current tick's work (records its duration)."""
        if self._work_started is not None:
            self._work_ms.append((self._work_timer() - self._work_started) * 1000.0)
            self._work_started = None

    def current_rate_hz(self) -> float:
        """Achieved tick rate so far (cheap; for live status)."""
        if self._count < 2 or self._last_start is None or self._last_start <= self._first_start:
            return math.nan
        return (self._count - 1) / (self._last_start - self._first_start)

    def stats(self) -> SchedulerStats:
        span = (self._last_start - self._first_start) if self._count > 1 else 0.0
        rate = (self._count - 1) / span if span > 0 else math.nan
        if self._work_ms:
            arr = np.asarray(self._work_ms)
            p50, p99, mx = (float(np.percentile(arr, 50)), float(np.percentile(arr, 99)), float(arr.max()))
        else:
            p50 = p99 = mx = math.nan
        return SchedulerStats(self._count, self._skipped, self.rate_hz, rate, p50, p99, mx)
