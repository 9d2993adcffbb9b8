"""The state one guidance tick carries into the next, and the rules that update it.

:func:`companion.loop.tick.compute_tick` is pure: the course used on the previous tick, the
commanded course, the result to coast on are passed in. :class:`TickDriver` is the one place
that carries them from tick to tick, for the flight loop (:mod:`companion.loop.flight`), replay
(:mod:`companion.replay.replay`) and the synthetic-flight writer
(:mod:`companion.replay.synthetic`), so that the three cannot drift apart.

The rules (``docs/flying.md``, "slow guidance steps"):

* a **fresh** result (computed for this tick and sent) carries its course and its commanded
  course into the next tick, and ends a coast;
* a **late** result (it arrived after its tick had coasted; it is recorded, not sent) carries its
  course only: the commanded course stays the one the coasting setpoints built;
* a **coast** (this tick's step has not finished within the budget) sends
  :func:`companion.loop.tick.coast_setpoint` from the last result and carries the course it
  commanded; it keeps turning for ``max_coast_turn_s`` (loop clock) from the start of the
  coast, then flies straight;
* per tick at most two results are taken: a late one, then this tick's fresh one
  (:meth:`TickDriver.run_tick`).
"""

from __future__ import annotations

import concurrent.futures
import functools
import math
from dataclasses import dataclass
from typing import Callable, Protocol

from companion.guidance.drift import DriftEstimator
from companion.guidance.speed_hold import SpeedHold
from companion.guidance.tail_comp import TailCompensator
from companion.guidance.factory import make_law
from companion.guidance.profiled import ProfiledGuidance
from companion.guidance.types import GuidanceLaw
from companion.io.setpoints import AttitudeSetpoint, VelocitySetpoint
from companion.io.state import PositionSample
from companion.loop.tick import TickConfig, TickResult, coast_setpoint, compute_tick
from companion.mission.model import Mission


class PendingStep(Protocol):
    """A guidance step under way (``concurrent.futures.Future`` or a simulated slow step)."""

    def result(self, timeout: float | None = None) -> TickResult:
        """The result; raises ``concurrent.futures.TimeoutError`` if not done within ``timeout``."""
        ...


#: Starts a step: given the call with this tick's inputs bound, returns the step under way.
Submit = Callable[[Callable[[], TickResult]], PendingStep]


@dataclass(frozen=True)
class TickOutcome:
    """What one tick sends: ``result`` is None when the tick coasted."""

    setpoint: VelocitySetpoint | AttitudeSetpoint
    result: TickResult | None


class TickDriver:
    """Carries the tick state of one flight and applies the coasting and late-result rules.

    Parameters
    ----------
    guidance : the law stepped by every tick.
    config : the flight's tick settings.
    prev_course_rad : the course before the first tick (see :func:`initial_course_rad`).
    max_coast_turn_s : how long a coast keeps turning (loop clock); ``inf``: always.
    """

    def __init__(self, guidance: GuidanceLaw, config: TickConfig, prev_course_rad: float,
                 max_coast_turn_s: float = math.inf):
        self.guidance = guidance
        self.config = config
        self.max_coast_turn_s = max_coast_turn_s
        self.ticks_run = 0  # guidance ticks started (the tick counter of the next one)
        self.prev_course_rad = prev_course_rad
        self.prev_course_cmd_rad: float | None = None
        self.last_result: TickResult | None = None
        self.coast_since_s: float | None = None
        self.coast_ticks = 0
        self.pending: PendingStep | None = None
        # The velocity estimate's drift, fed by every tick's sample (companion.guidance.drift).
        self.drift = DriftEstimator(config.drift_tc_s) if config.compensates_drift else None
        # The ground-speed hold's integral (companion.guidance.speed_hold), off unless asked for.
        self.speed_hold = SpeedHold(config.speed_hold_tc_s) if config.holds_speed else None
        # The velocity loop's slow tail, run beside it (companion.guidance.tail_comp), when it has one.
        self.tail = TailCompensator(config.tail_share, config.tail_tc_s) if config.compensates_tail else None

    # ------------------------------------------------------------------ the inputs of a tick

    def bind(self, t_s: float, sample: PositionSample | None, sample_age_s: float,
             yaw_ned_rad: float | None) -> Callable[[], TickResult]:
        """The next tick as a call with the carried state bound now (to run here or in a worker)."""
        call = functools.partial(compute_tick, self.guidance, self.ticks_run, t_s, sample, sample_age_s,
                                 self.config, yaw_ned_rad=yaw_ned_rad, prev_course_rad=self.prev_course_rad,
                                 prev_course_cmd_rad=self.prev_course_cmd_rad, drift=self.drift, speed_hold=self.speed_hold,
                                 tail=self.tail)
        self.ticks_run += 1
        return call

    def step(self, tick: int, t_s: float, sample: PositionSample | None, sample_age_s: float,
             yaw_ned_rad: float | None, prev_course_rad: float,
             prev_course_cmd_rad: float | None) -> TickResult:
        """Run one tick with explicit carried inputs (replay: the ones the flight recorded).

        The result is not accepted: call :meth:`accept`.
        """
        return compute_tick(self.guidance, tick, t_s, sample, sample_age_s, self.config,
                            yaw_ned_rad=yaw_ned_rad, prev_course_rad=prev_course_rad,
                            prev_course_cmd_rad=prev_course_cmd_rad, drift=self.drift, speed_hold=self.speed_hold,
                            tail=self.tail)

    # ------------------------------------------------------------------ the rules

    def accept(self, result: TickResult, sent: bool) -> None:
        """A finished tick: ``sent`` (fresh) carries course and commanded course, a late one the course."""
        self.last_result = result
        self.prev_course_rad = result.course_rad
        if sent:
            self.prev_course_cmd_rad = result.course_cmd_rad
            self.coast_since_s = None

    def coast(self, sample: PositionSample | None, sample_age_s: float,
              now_s: float = 0.0) -> VelocitySetpoint | AttitudeSetpoint:
        """The setpoint of a tick whose step has not finished (``now_s``: the loop clock)."""
        if self.coast_since_s is None:
            self.coast_since_s = now_s
        cmd = self.prev_course_cmd_rad
        sp = coast_setpoint(self.last_result, sample, sample_age_s, self.config,
                            cmd if cmd is not None else math.nan,
                            turning=(now_s - self.coast_since_s) <= self.max_coast_turn_s)
        self.prev_course_cmd_rad = getattr(sp, "course_cmd_enu_rad", math.nan)
        self.coast_ticks += 1
        return sp

    def run_tick(self, t_s: float, now_s: float, sample: PositionSample | None, sample_age_s: float,
                 yaw_ned_rad: float | None, submit: Submit, budget_s: float,
                 on_result: Callable[[TickResult, bool], None]) -> TickOutcome:
        """One tick of a flight whose steps may outlive their tick.

        Starts this tick's step (unless one is still under way), waits ``budget_s`` for it; a
        late result is handed to ``on_result(result, False)`` and accepted, then this tick is
        computed afresh; a fresh one goes to ``on_result(result, True)`` and is sent. A step
        still running after the budget: this tick coasts.
        """
        for _ in range(2):
            fresh = False
            if self.pending is None:
                self.pending = submit(self.bind(t_s, sample, sample_age_s, yaw_ned_rad))
                fresh = True
            try:
                done = self.pending.result(timeout=budget_s)
            except concurrent.futures.TimeoutError:
                break  # still computing: coast this tick
            self.pending = None
            on_result(done, fresh)
            self.accept(done, sent=fresh)
            if fresh:
                return TickOutcome(done.setpoint, done)
            # A late result (its tick already coasted): compute this tick afresh.
        return TickOutcome(self.coast(sample, sample_age_s, now_s), None)



def make_guidance(mission: Mission, rate_hz: float) -> GuidanceLaw:
    """The mission's guidance at the loop's rate and the mission's speed (flight, replay, synthetic);
    a mission whose speed varies along the path flies every law at the local speed V(s)."""
    law = make_law(mission.path, mission.guidance, rate_hz, mission.speed_m_s)
    profile = mission.profile
    if profile is not None and not profile.constant_speed:
        return ProfiledGuidance(law, profile)
    return law
