"""The flight loop: fixed-rate ticks on the newest position, a guidance worker, the tick driver.

Every tick (``docs/flying.md``): service the link, check the heartbeat (lost -> stop, exit) and
the mode (the vehicle left OFFBOARD/GUIDED -> stop commanding at once, never switch back unless
``--resume``), then :meth:`companion.loop.driver.TickDriver.run_tick` on the newest
LOCAL_POSITION_NED: the guidance steps in a worker thread, and a step slower than half a tick
does not freeze the setpoint stream (that tick coasts). Each finished step is recorded in the tlog
(``DEBUG_FLOAT_ARRAY "guidance"``) and in the :class:`FlightRecord`.

Clocks: ``wall`` ticks on the monotonic clock; ``autopilot`` (:class:`AutopilotClock`) on the
autopilot's ``time_boot_ms`` (a simulator running faster than real time).
"""

from __future__ import annotations

import concurrent.futures
import math
import time
from dataclasses import dataclass, field
from typing import Callable

from companion.errors import FlightAborted, LinkError
from companion.guidance.types import GuidanceLaw
from companion.io.link import MAV_SEVERITY_CRITICAL, MAV_SEVERITY_WARNING, MavLink
from companion.io.setpoints import AttitudeSetpoint, VelocitySetpoint
from companion.io.state import PositionSample
from companion.io.tlog import TlogWriter
from companion.loop.driver import TickDriver
from companion.loop.health import HealthMonitor, HealthVerdict, sample_from_tick
from companion.loop.scheduler import Clock, FixedRateScheduler
from companion.loop.session import LinkSession
from companion.loop.status_line import StatusFields, format_status_line
from companion.loop.tick import DEBUG_FIELDS, TickConfig, TickResult, course_from_sample, hold_for

_I_SETPOINT_SENT = DEBUG_FIELDS.index("setpoint_sent")


@dataclass
class FlightRecord:
    """Per-tick series of a flight (for metrics, plots and tests)."""

    t_s: list = field(default_factory=list)
    time_boot_ms: list = field(default_factory=list)
    phase: list = field(default_factory=list)
    a_cmd_m_s2: list = field(default_factory=list)
    crosstrack_m: list = field(default_factory=list)
    x_m: list = field(default_factory=list)
    y_m: list = field(default_factory=list)
    sample_age_s: list = field(default_factory=list)
    hold: list = field(default_factory=list)
    # For missions with an altitude / speed profile (vertical and speed errors, plots):
    s_proj_m: list = field(default_factory=list)
    alt_m: list = field(default_factory=list)
    ground_speed_m_s: list = field(default_factory=list)
    vz_cmd_ned_m_s: list = field(default_factory=list)

    def add(self, result: TickResult) -> None:
        """Append one finished tick."""
        sample = result.sample
        self.t_s.append(result.t_s)
        self.time_boot_ms.append(sample.time_boot_ms if sample is not None else -1)
        self.phase.append(result.phase)
        out = result.output
        self.a_cmd_m_s2.append(out.a_cmd_m_s2 if out is not None else 0.0)
        self.crosstrack_m.append(out.crosstrack_m if out is not None else math.nan)
        self.x_m.append(result.state.x_m if result.state is not None else math.nan)
        self.y_m.append(result.state.y_m if result.state is not None else math.nan)
        self.sample_age_s.append(result.sample_age_s)
        self.hold.append(result.is_hold)
        self.s_proj_m.append(out.s_proj_m if out is not None else math.nan)
        self.alt_m.append(-sample.z_ned_m if sample is not None else math.nan)
        self.ground_speed_m_s.append(math.hypot(sample.vx_ned_m_s, sample.vy_ned_m_s)
                                     if sample is not None else math.nan)
        self.vz_cmd_ned_m_s.append(getattr(result.setpoint, "vz_ned_m_s", math.nan))


class AutopilotClock:
    """Time = the newest ``time_boot_ms`` from the autopilot; waiting services the link.

    If the autopilot's time stops advancing (everything silent), ``wait_until`` returns after
    ``wall_step_s`` of wall time so that the loop still runs its failsafe checks.
    """

    def __init__(self, link: MavLink, idle: Callable[[], None], wall_step_s: float = 0.1):
        self.link = link
        self.idle = idle
        self.wall_step_s = wall_step_s

    def now(self) -> float:
        t = self.link.state.autopilot_time_s
        return t if math.isfinite(t) else 0.0

    def wait_until(self, t_s: float) -> None:
        wall_end = time.monotonic() + self.wall_step_s
        while self.now() < t_s and time.monotonic() < wall_end:
            self.link.poll(0.005)
            self.idle()


class FlightLoop:
    """The fixed-rate loop of one flight, from the first tick to the end of the path.

    Call :meth:`run` (returns the exit reason: ``"finished"`` or ``"max duration"``; raises on
    a lost link or a pilot override), then :meth:`close`.
    """

    def __init__(self, session: LinkSession, guidance: GuidanceLaw, config: TickConfig, clock: Clock,
                 target_mode: str, start_heading_rad: float, tlog: TlogWriter, record: FlightRecord,
                 *, health: HealthMonitor | None = None, path_length_m: float = math.nan):
        self.s = session
        self.health = health
        self.path_length_m = path_length_m
        self.verdict = HealthVerdict()
        self.config = config
        self.clock = clock
        self.target_mode = target_mode
        self.tlog = tlog
        self.record = record
        self.hold_ticks = 0
        self.scheduler: FixedRateScheduler | None = None
        self._in_hold = False
        # Speed, height and time of the last profile targets sent to a fixed wing.
        self._plane_sent = (config.speed_m_s, math.nan, -math.inf)
        state = session.link.state
        course = course_from_sample(state.position, state.yaw_ned_rad, start_heading_rad,
                                    config.min_course_speed_m_s)
        self.driver = TickDriver(guidance, config, course, session.opt.max_coast_turn_s)
        # The guidance steps in a worker thread; a step slower than this budget (wall seconds)
        # does not freeze the setpoint stream: that tick coasts (see tick.coast_setpoint).
        self._step_budget_s = 0.5 / session.opt.rate_hz
        self._worker = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="guidance")

    def close(self) -> None:
        self._worker.shutdown(wait=False, cancel_futures=True)

    def _new_scheduler(self) -> FixedRateScheduler:
        self.scheduler = FixedRateScheduler(self.s.opt.rate_hz, self.clock)
        return self.scheduler

    def _sample(self, now_s: float) -> tuple[PositionSample | None, float]:
        """The newest position and its age (wall clock; with the autopilot clock, the older)."""
        sample = self.s.link.state.position
        if sample is None:
            return None, math.inf
        age = time.monotonic() - sample.received_s
        if self.s.opt.clock == "autopilot":
            age = max(age, now_s - sample.time_s)
        return sample, age

    def run(self) -> str:
        s, opt, clock = self.s, self.s.opt, self.clock
        sched = self._new_scheduler()
        t_first: float | None = None
        while True:
            sched.wait_next()
            s.link.poll(0.0)
            s.idle()
            s.check_link()
            if not s.link.in_mode(self.target_mode):
                self._pilot_override()
                sched = self._new_scheduler()
                continue
            now = clock.now()
            if t_first is None:
                t_first = now
            t_s = now - t_first
            sample, age = self._sample(now)
            out = self.driver.run_tick(t_s, now, sample, age, s.link.state.yaw_ned_rad, self._worker.submit,
                                       self._step_budget_s, self._after_guidance)
            setpoint = out.setpoint
            if out.result is not None and self.health is not None:
                setpoint = self._check_health(out.result, t_s, setpoint)
            s.send(setpoint)
            self.tlog.flush()
            sched.done()
            if out.result is None:
                continue
            self._live(out.result, sched)
            if out.result.phase == "finished":
                return "finished"
            if opt.max_duration_s is not None and t_s >= opt.max_duration_s:
                s.event(f"stopping after --max-duration-s {opt.max_duration_s:g}")
                return "max duration"

    def _check_health(self, result: TickResult, t_s: float,
                      setpoint: VelocitySetpoint | AttitudeSetpoint) -> VelocitySetpoint | AttitudeSetpoint:
        """The flight-health verdict of a fresh tick (:mod:`companion.loop.health`): a change is an
        event and a STATUSTEXT in the tlog; ``hold`` replaces the setpoint with a hold; ``stop``
        sends the hold, asks the autopilot for its own hold mode and raises (exit 3)."""
        assert self.health is not None
        v = self.health.update(sample_from_tick(result, t_s, self.s.link.state.autopilot_time_s))
        self.verdict = v
        if v.changed and v.level in ("warn", "hold"):
            self.s.event(v.reason, MAV_SEVERITY_WARNING)
        elif v.changed and v.ok:
            self.s.event("flight health ok again")
        if v.level not in ("hold", "stop"):
            return setpoint
        p = result.sample
        alt = -p.z_ned_m if p is not None else math.nan
        s_m = result.output.s_proj_m if result.output is not None else 0.0
        hold = hold_for(self.config, alt, p is not None, result.course_rad, s_m)
        if v.level == "stop":
            self.s.link.record_event(v.error().args[0], MAV_SEVERITY_CRITICAL)
            self.s.send(hold)
            self._request_hold_mode()
            raise v.error()
        return hold

    def _request_hold_mode(self) -> None:
        """After a health stop: the autopilot's own hold (PX4 Hold, ArduPilot LOITER), unacknowledged
        modes reported but not retried for long (the flight ends either way)."""
        s = self.s
        try:
            result = s.link.set_mode("loiter", wait_ack_s=1.0, retries=2, idle=s.link.heartbeat_if_due)
        except LinkError as err:
            s.link.record_event(f"hold mode not requested: {err}", MAV_SEVERITY_WARNING)
            return
        if result != 0:
            s.link.record_event(f"hold mode refused ({result})", MAV_SEVERITY_WARNING)

    def _pilot_override(self) -> None:
        """The vehicle left the flight mode: abort, or (``--resume``) wait for the pilot to return."""
        s, mode = self.s, self.target_mode
        s.event(f"vehicle left {mode.upper()} (custom_mode {s.link.state.custom_mode}): pilot or "
                "failsafe override; stopped commanding")
        if not s.opt.resume:
            raise FlightAborted(
                f"pilot override: the vehicle left {mode.upper()}; not switching back "
                "(use --resume to continue when the pilot returns control)")
        s.event(f"--resume: waiting for the pilot to select {mode.upper()} again")
        while not s.link.in_mode(mode):
            s.check_link()
            s.pump(0.05)
        s.event(f"back in {mode.upper()}: resuming")

    def _after_guidance(self, result: TickResult, sent: bool = True) -> None:
        """Record a finished compute_tick (in the tlog and the flight record); report holds.

        ``sent`` is False for a result that arrived after its tick had coasted: its setpoint is
        not sent (the current tick is computed afresh) and its record says so (field 26).
        """
        sample = result.sample
        time_usec = sample.time_boot_ms * 1000 if sample is not None else 0
        row = list(result.debug)
        row[_I_SETPOINT_SENT] = 1.0 if sent else 0.0
        self.s.link.record_debug("guidance", result.tick, time_usec, row)
        self.record.add(result)
        self._plane_profile_targets(result)
        if result.is_hold:
            self.hold_ticks += 1
        if result.is_hold != self._in_hold:
            self._in_hold = result.is_hold
            if result.is_hold:
                self.s.event(f"HOLD: position {result.hold_reason} (age {result.sample_age_s:.2f} s > "
                             f"--stale-s {self.s.opt.stale_s:g}); zero velocity, zero yaw rate")
            else:
                self.s.event("position fresh again: guidance resumed")

    def _plane_profile_targets(self, result: TickResult) -> None:
        """A fixed wing flying a mission with a profile gets its height and speed through the
        autopilot's own channels, sent (without waiting for an ack) when the target moves by
        0.5 m or 0.2 m/s, and the height at least once a second: the speed command (as at the
        start of the flight) and, on ArduPilot, GUIDED_CHANGE_ALTITUDE. PX4 takes the climb from
        the attitude setpoint's pitch (``companion.loop.tick``)."""
        profile = self.config.profile
        if profile is None or result.output is None or not isinstance(result.setpoint, AttitudeSetpoint):
            return
        link = self.s.link
        s_m = result.output.s_proj_m
        v = profile.speed_m_s(s_m)
        sent_v, sent_h, sent_t = self._plane_sent
        if abs(v - sent_v) >= 0.2:
            link.change_speed(v, wait_ack_s=0.0, retries=1)
            sent_v = v
        if link.info is not None and link.info.autopilot == "ardupilot":
            h = profile.altitude_m(s_m)
            if not abs(h - sent_h) < 0.5 or result.t_s - sent_t >= 1.0:
                link.change_altitude(h, profile.limits.climb_max_m_s, wait_ack_s=0.0, retries=1)
                sent_h, sent_t = h, result.t_s
        self._plane_sent = (sent_v, sent_h, sent_t)

    def _live(self, result: TickResult, sched: FixedRateScheduler) -> None:
        link = self.s.link
        out, p, v = result.output, result.sample, self.verdict
        share = out.s_proj_m / self.path_length_m if out is not None and self.path_length_m > 0 else math.nan
        self.s.status.live(format_status_line(StatusFields(
            t_s=result.t_s, phase=result.phase,
            crosstrack_m=out.crosstrack_m if out is not None else None,
            a_cmd_m_s2=out.a_cmd_m_s2 if out is not None else None,
            rate_hz=sched.current_rate_hz(), link_age_s=link.link_age_s(), rejected=link.rejected,
            mode=link.mode_text(), armed=link.state.armed,
            altitude_m=-p.z_ned_m if p is not None else math.nan,
            ground_speed_m_s=math.hypot(p.vx_ned_m_s, p.vy_ned_m_s) if p is not None else math.nan,
            path_fraction=share, health="" if v.ok else f"{v.level.upper()} {v.check}",
            ignored=link.ignored)))
