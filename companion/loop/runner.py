"""The flight runner behind ``companion fly``: link -> modes/arming -> fixed-rate guidance loop.

Sequence (details and the reasons in ``docs/flying.md`` and ``docs/failsafes.md``):

1. check that the tlog can be written (creating nothing), open the link, wait for the
   autopilot's heartbeat with a status line, pair with it (PX4 or ArduPilot); only then create
   the tlog (with what the link kept in memory since it opened) and the mission beside it, so a
   failed connection leaves no file;
2. request LOCAL_POSITION_NED at the loop rate and ATTITUDE with SET_MESSAGE_INTERVAL (ACK checked);
3. wait up to ``--position-timeout-s`` for a valid position, showing what the autopilot says
   (GPS, EKF flags, STATUSTEXT); refuse to start farther than ``max_start_distance_m`` from the path;
4. armed state first: a disarmed vehicle without ``--arm`` is refused before any mode change;
   modes: PX4 -> stream hold setpoints >= 1 s, then OFFBOARD, then (``--arm``) arm;
   ArduPilot -> GUIDED, then (``--arm``) arm with retries until ``arm_timeout_s`` showing the
   autopilot's STATUSTEXT reasons, then NAV_TAKEOFF unless already airborne; an arming refusal
   puts back the mode the vehicle was in;
5. the loop: every tick :func:`companion.loop.tick.compute_tick` on the newest position, the
   flight-health checks (:mod:`companion.loop.health`), send the setpoint, record it; failsafes:
   stale position -> hold, heartbeat lost -> stop and exit, the vehicle leaving OFFBOARD/GUIDED
   -> stop commanding at once and never switch back, no progress / runaway -> hold, stop (exit 3);
6. at the end of the path, the ``on_finish`` action for this autopilot.

A ``geodetic`` mission is moved onto the autopilot's own local origin before step 4: the runner
asks for GPS_GLOBAL_ORIGIN (MAV_CMD_REQUEST_MESSAGE 49) and translates the path and start by the
ENU offset of the mission's origin from it (:func:`onto_autopilot_origin`); no origin within
``origin_timeout_s`` -> LinkError (exit 2), nothing flown. Local-frame missions are untouched.

Clocks: ``wall`` ticks on the monotonic clock; ``autopilot`` ticks on the autopilot's
``time_boot_ms`` (used with a simulator running faster than real time).
"""

from __future__ import annotations

import gc
import math
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from types import FrameType

import numpy as np

from companion.errors import CompanionError, FlightAborted, LinkError
from companion.geometry import frames
from companion.guidance.capture import start_course_rad
from companion.guidance.types import GuidanceLaw
from companion.io.link import (
    MAV_CMD_SET_MESSAGE_INTERVAL,
    MSG_ID_ATTITUDE,
    MSG_ID_LOCAL_POSITION_NED,
    READINESS_MSG_IDS,
    MavLink,
    connect_autopilot,
    hold_interrupts_during_sends,
    readiness_text,
    restore_handlers,
)
from companion.io.setpoints import G_M_S2
from companion.io.tlog import TlogWriter, default_tlog_path, write_mission_beside
from companion.loop.driver import make_guidance
from companion.loop.limits import accel_feedforward_max, apply_autopilot_limits, mission_for_tail, velocity_tail
from companion.loop.flight import AutopilotClock, FlightLoop, FlightRecord
from companion.loop.health import HealthMonitor, HealthOptions, turn_allowance_m
from companion.loop.profiles import AutopilotProfile, profile_for
from companion.loop.scheduler import Clock, MonotonicClock
from companion.loop.session import LinkSession, Status, result_text
from companion.loop.tick import DEFAULT_DRIFT_TC_S, DEFAULT_STALE_S, TickConfig
from companion.mission.model import ON_FINISH, Mission
from companion.mission.placement import OriginShift, onto_autopilot_origin
from companion.sim.metrics import profile_errors, tracking_metrics

__all__ = ["FlightRecord", "FlightRunner", "FlyOptions", "OriginShift", "Status", "make_guidance",
           "onto_autopilot_origin"]

#: The interpreter's thread switch interval while flying (Python's default is 5 ms).
LOOP_SWITCH_INTERVAL_S = 0.0005


@dataclass(frozen=True)
class FlyOptions:
    """Everything ``companion fly`` takes besides the mission (validated on construction)."""

    connect: str
    rate_hz: float
    autopilot: str = "auto"
    stale_s: float = DEFAULT_STALE_S
    link_timeout_s: float = 5.0
    heartbeat_timeout_s: float = 15.0
    position_timeout_s: float = 90.0  # a cold-started ArduCopter has a position ~40 s after boot
    arm: bool = False
    takeoff_alt_m: float | None = None
    arm_timeout_s: float = 90.0
    on_finish: str | None = None  # None: the mission's
    resume: bool = False
    max_start_distance_m: float = 300.0
    output: str = "auto"  # auto | velocity | attitude
    max_bank_deg: float = 35.0
    clock: str = "wall"  # wall | autopilot
    source_system: int = 1
    source_component: int = 191
    target_system: int | None = None
    signing_key: bytes | None = None
    tlog_path: str | None = None
    max_duration_s: float | None = None
    offboard_prestream_s: float = 1.0
    max_coast_turn_s: float = 0.3  # coasting keeps turning this long (loop clock), then flies straight
    attitude_rate_hz: float = 20.0
    origin_timeout_s: float = 10.0  # geodetic missions: wait this long for GPS_GLOBAL_ORIGIN
    drift_tc_s: float = DEFAULT_DRIFT_TC_S  # the velocity estimate's drift compensated over this long; 0: off
    speed_hold_tc_s: float = 0.0  # the ground-speed hold's integral time; 0: off
    health: HealthOptions = HealthOptions()

    def __post_init__(self) -> None:
        for name in ("rate_hz", "stale_s", "link_timeout_s", "heartbeat_timeout_s", "arm_timeout_s",
                     "max_start_distance_m", "position_timeout_s", "origin_timeout_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise CompanionError(f"--{name.replace('_', '-')}: expected a number > 0, got {value!r}")
        if self.clock not in ("wall", "autopilot"):
            raise CompanionError(f"--clock: expected wall or autopilot, got {self.clock!r}")
        if self.output not in ("auto", "velocity", "attitude"):
            raise CompanionError(f"--output: expected auto, velocity or attitude, got {self.output!r}")
        if self.on_finish is not None and self.on_finish not in ON_FINISH:
            raise CompanionError(f"--on-finish: expected one of {', '.join(ON_FINISH)}, got {self.on_finish!r}")
        if not (0 < self.max_bank_deg < 90):
            raise CompanionError(f"--max-bank-deg: expected 0 < value < 90, got {self.max_bank_deg!r}")
        for name in ("drift_tc_s", "speed_hold_tc_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise CompanionError(f"--{name.replace('_', '-')}: expected a number >= 0 (0: off), got {value!r}")


def announce_setpoint_options(event: Callable[[str], None], mission: Mission, info, config: TickConfig) -> None:
    """Say in the flight's log what the setpoints carry besides the law's velocity, and why
    (``info``: the autopilot's ``AutopilotInfo``)."""
    if config.accel_ff_max_m_s2 > 0:
        why = "guidance.accel_feedforward" if mission.accel_feedforward else f"{info.autopilot}'s default"
        event(f"acceleration feed-forward: the setpoints carry the command up to "
              f"{config.accel_ff_max_m_s2:.3g} m/s^2 ({why})")
    elif mission.accel_feedforward and config.output == "velocity":
        event(f"guidance.accel_feedforward not used: only a copter takes an acceleration target "
              f"(this is a {info.vehicle})")
    if config.compensates_tail:
        _, source = velocity_tail(mission, info.autopilot, info.vehicle, config.accel_ff_max_m_s2 > 0)
        event(f"velocity loop's slow tail compensated: share {config.tail_share:g}, {config.tail_tc_s:g} s ({source})")
    elif mission.tail_compensation and config.output == "velocity":
        event("guidance.tail_compensation not used: no tail known for this vehicle "
              "(a vehicle: block with tail_share states one)")


class _Terminate(BaseException):
    """SIGTERM, turned into an exception so that every ``finally`` runs (tlog closed).

    A ``BaseException``, like ``KeyboardInterrupt``: the handler raises it wherever the main thread
    happens to be, and the link's parser guards (``except Exception``: a malformed packet must not
    stop the loop) would otherwise swallow it and the flight would go on.
    """


def distance_to_path_m(path, x_m: float, y_m: float, n: int = 4000) -> float:
    """Distance from a point to a path (dense sampling; used only for the start check)."""
    _, xs, ys = path.sample(n)
    return float(np.min(np.hypot(xs - x_m, ys - y_m)))






class FlightRunner:
    """One flight of one mission on one autopilot. Call :meth:`run`; read :attr:`summary`.

    It sequences the steps (module docstring) and owns the tlog; the link's side of every step
    is :class:`LinkSession`, the autopilot's differences its :class:`AutopilotProfile`, the ticks
    the :class:`FlightLoop`.
    """

    def __init__(self, mission: Mission, options: FlyOptions, status: Status | None = None,
                 guidance: GuidanceLaw | None = None):
        self.mission = mission
        self.opt = options
        self._guidance = guidance  # injected (tests); default: the mission's TwoPhaseGuidance
        self.status = status or Status()
        self.record = FlightRecord()
        self.link: MavLink | None = None
        self.tlog: TlogWriter | None = None
        self.tlog_path = Path(options.tlog_path) if options.tlog_path else default_tlog_path()
        self.summary: dict = {}
        self.origin_shift: OriginShift | None = None
        self.events: list[str] = []
        self.exit_reason = "not started"
        self.session: LinkSession | None = None
        self.flight: FlightLoop | None = None
        self._failed_link_counters: dict = {}  # a pairing that failed: what its link counted

    @property
    def setpoints_sent(self) -> int:
        return self.session.setpoints_sent if self.session is not None else 0

    @property
    def coast_ticks(self) -> int:
        return self.flight.driver.coast_ticks if self.flight is not None else 0

    def _event(self, text: str) -> None:
        if self.session is not None:
            self.session.event(text)
        else:
            self.events.append(text)
            self.status.event(text)

    # ------------------------------------------------------------------ steps before the loop

    def _open(self) -> LinkSession:
        writer = TlogWriter(self.tlog_path).check_writable()
        try:
            self.link = connect_autopilot(
                self.opt.connect,
                heartbeat_timeout_s=self.opt.heartbeat_timeout_s,
                progress=self.status.live,
                source_system=self.opt.source_system,
                source_component=self.opt.source_component,
                signing_key=self.opt.signing_key,
                target_system=self.opt.target_system,
                autopilot=self.opt.autopilot,
            )
        except LinkError as err:
            self._failed_link_counters = err.counters or {}
            raise
        self.tlog = writer.open()
        write_mission_beside(self.tlog_path, self.mission.source_text or "")
        self.link.attach_tlog(self.tlog)
        info = self.link.info
        self.session = LinkSession(self.link, self.opt, self.status, self.events)
        self._event(f"paired with {info.autopilot} {info.vehicle} (system {info.system_id}, "
                    f"component {info.component_id}) on {self.opt.connect}")
        return self.session

    def _request_streams(self, s: LinkSession) -> None:
        for msg_id, name, rate in ((MSG_ID_LOCAL_POSITION_NED, "LOCAL_POSITION_NED", self.opt.rate_hz),
                                   (MSG_ID_ATTITUDE, "ATTITUDE", self.opt.attitude_rate_hz)):
            result = s.link.command_long(MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, 1.0e6 / rate),
                                         wait_ack_s=1.0, retries=3, idle=s.idle)
            if result != 0:
                s.event(f"warning: SET_MESSAGE_INTERVAL {name} {rate:g} Hz: {result_text(result)}")
        # What explains a wait for the position (GPS, EKF, landed state): 1 Hz, not waited for.
        for msg_id in READINESS_MSG_IDS:
            s.link.command_long(MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, 1.0e6), wait_ack_s=0.0, retries=1)

    def _align_geodetic_mission(self, s: LinkSession) -> None:
        """Geodetic mission: move its path onto the autopilot's EKF origin (or refuse to fly)."""
        if self.mission.frame != "geodetic" or self.mission.origin is None:
            return
        origin = s.link.request_global_origin(self.opt.origin_timeout_s, idle=s.idle)
        if origin is None:
            raise LinkError(
                f"{self.opt.connect}: no GPS_GLOBAL_ORIGIN within --origin-timeout-s "
                f"{self.opt.origin_timeout_s:g} (the autopilot has no local origin yet: no GPS fix?); "
                f"{self.mission.source_name} is geodetic and cannot be placed; not flying"
            )
        self.mission, shift = onto_autopilot_origin(self.mission, origin)
        self.origin_shift = shift
        s.event(
            f"autopilot origin {origin.lat_deg:.7f}, {origin.lon_deg:.7f}: mission origin is at ENU "
            f"({shift.east_m:+.2f}, {shift.north_m:+.2f}) m; path translated (max error of the "
            f"translation {shift.max_error_m * 1000:.1f} mm)"
        )

    def _wait_position(self, s: LinkSession) -> None:
        """Wait for the autopilot's position estimate (a cold-started ArduCopter: ~40 s), with a
        status line saying what is awaited and what the autopilot says; its STATUSTEXTs become
        events. No position within ``--position-timeout-s`` -> LinkError (exit 2)."""
        t0 = time.monotonic()
        end = t0 + self.opt.position_timeout_s
        n_text, last_text = 0, ""
        while s.link.state.position is None:
            if s.link.state.heartbeats:
                s.check_link()
            for text in s.statustext_since(n_text):
                if text != last_text:  # autopilots repeat their pre-arm reasons
                    s.event(f"autopilot: {text}", record=False)
                last_text = text
            n_text = s.link.state.statustext_count
            why = readiness_text(s.link.state)
            if time.monotonic() > end:
                raise LinkError(
                    f"{self.opt.connect}: no valid LOCAL_POSITION_NED within --position-timeout-s "
                    f"{self.opt.position_timeout_s:g} (position estimate not ready"
                    f"{': ' + why if why else ''})"
                )
            self.status.live(f"waiting for the position estimate (LOCAL_POSITION_NED): "
                             f"{time.monotonic() - t0:.0f} s of {self.opt.position_timeout_s:g} s"
                             f"{'; ' + why if why else ''}")
            s.pump(0.05)

    def _check_start_distance(self, s: LinkSession) -> None:
        p = s.link.state.position
        x, y, _ = frames.enu_from_ned(p.x_ned_m, p.y_ned_m, p.z_ned_m)
        d = distance_to_path_m(self.mission.path, x, y)
        if d > self.opt.max_start_distance_m:
            raise FlightAborted(
                f"vehicle at ENU ({x:.1f}, {y:.1f}) m is {d:.0f} m from the path of "
                f"{self.mission.source_name}, more than --max-start-distance-m "
                f"{self.opt.max_start_distance_m:g} (wrong origin or frame?); not starting"
            )

    def _tick_config(self, s: LinkSession) -> TickConfig:
        output = self.opt.output
        if output == "auto":
            output = "attitude" if s.link.info.vehicle == "plane" else "velocity"
        config = TickConfig(speed_m_s=self.mission.speed_m_s, rate_hz=self.opt.rate_hz,
                            altitude_m=self.mission.altitude_m, stale_s=self.opt.stale_s, output=output,
                            max_bank_deg=self.opt.max_bank_deg, profile=self.mission.profile,
                            drift_tc_s=self.opt.drift_tc_s, speed_hold_tc_s=self.opt.speed_hold_tc_s)
        if config.output == "velocity":
            info = s.link.info
            ff = accel_feedforward_max(self.mission, info.autopilot, info.vehicle)
            (share, tc_s), _ = velocity_tail(self.mission, info.autopilot, info.vehicle, ff > 0)
            config = replace(config, accel_ff_max_m_s2=ff, tail_share=share, tail_tc_s=tc_s)
        if config.output == "attitude" and self._on_finish_action() == "land":
            raise FlightAborted("--on-finish land is not available for a fixed-wing flight; use rtl or loiter")
        return config

    def _health_monitor(self, config: TickConfig) -> HealthMonitor:
        """The flight-health checks of this flight: the cross-track bound widened, while the vehicle
        turns onto the path, by the initiation circle, or for a fixed wing by its tightest turn at
        the bank limit if that is wider. The progress expected is that of the slowest speed the
        mission asks anywhere (its profile's, e.g. slowed for a tight turn)."""
        v = self.mission.speed_m_s
        slowest = v if self.mission.profile is None else min(v, float(self.mission.profile.speed_m_s_table.min()))
        a_max = (G_M_S2 * math.tan(math.radians(self.opt.max_bank_deg))
                 if config.output == "attitude" else math.inf)
        allowance = turn_allowance_m(self.mission.guidance.circle_radius_m, v, a_max)
        return HealthMonitor(self.opt.health, slowest, clock=self.opt.clock, turn_allowance_m=allowance)

    def _on_finish_action(self) -> str:
        return self.opt.on_finish or self.mission.on_finish

    def _clock(self, s: LinkSession) -> Clock:
        if self.opt.clock == "autopilot":
            return AutopilotClock(s.link, s.idle)
        return MonotonicClock(idle=lambda dt: (s.idle(), s.link.poll(min(dt, 0.02))))

    def _prepare(self) -> tuple[LinkSession, AutopilotProfile, TickConfig, Clock, GuidanceLaw]:
        """Steps 1-5: link, streams, placement, position, start distance, the guidance and the clock."""
        s = self._open()
        config = self._tick_config(s)
        self._request_streams(s)
        self._align_geodetic_mission(s)
        self._wait_position(s)
        self._check_start_distance(s)
        if self._guidance is None:  # the autopilot's own acceleration limit (companion.loop.limits)
            self.mission = apply_autopilot_limits(s.link, self.mission, s.event, s.idle)
            config = self._tick_config(s)  # again: the limit may slow the path's turns (a new profile)
            self.mission, line = mission_for_tail(self.mission, config.compensates_tail)
            if line:
                s.event(line)
        announce_setpoint_options(s.event, self.mission, s.link.info, config)
        guidance = self._guidance or make_guidance(self.mission, self.opt.rate_hz)
        profile = profile_for(s.link.info, s)
        clock = self._clock(s)
        return s, profile, config, clock, guidance

    def _enter(self, s: LinkSession, profile: AutopilotProfile, config: TickConfig, clock: Clock) -> None:
        """Step 6: the flight mode, arming and the climb; from here on the setpoints must not pause."""
        profile.enter(config, clock, self.mission.altitude_m)
        self._face_the_path(s, config, profile.target_mode)
        if config.output == "attitude":
            s.link.change_speed(self.mission.speed_m_s, wait_ack_s=1.0, retries=2, idle=s.idle)
        s.keepalive_config = None
        s.event(f"flying {self.mission.name} at {self.opt.rate_hz:g} Hz "
                f"({config.output} setpoints, {self.opt.clock} clock)")

    def _face_the_path(self, s: LinkSession, config: TickConfig, mode: str) -> None:
        """A copter hovering (slower than half the mission speed: a hovering PX4 SIH reports up to
        0.65 m/s, its velocity estimate's bias) turns to face the course it starts on
        (:func:`companion.guidance.capture.start_course_rad`): a velocity loop flies any direction,
        but every law reads a hovering copter's course from its nose (docs/flying.md)."""
        p = s.link.state.position
        if s.link.info.vehicle != "copter" or p is None or not config.gathering(p):
            return
        x, y, _ = frames.enu_from_ned(p.x_ned_m, p.y_ned_m, p.z_ned_m)
        s.face(start_course_rad(self.mission.path, x, y, self.mission.guidance.l1_m), config, mode)

    # ------------------------------------------------------------------ entry point

    def run(self) -> dict:
        """Fly the mission. Returns the summary; raises CompanionError on refusal/abort."""
        try:
            old_handlers = hold_interrupts_during_sends(_raise_terminate)
        except ValueError:
            old_handlers = {}  # not in the main thread: signal handling left to the caller
        try:
            s, profile, config, clock, guidance = self._prepare()
            # The interpreter is set up (a full collection, which can take a second on a busy
            # machine) before the mode change, not after it: in OFFBOARD or GUIDED the setpoint
            # stream must not pause (PX4 leaves OFFBOARD after COM_OF_LOSS_T without one).
            with _flight_interpreter():
                self._enter(s, profile, config, clock)
                self.flight = FlightLoop(s, guidance, config, clock, profile.target_mode,
                                         self.mission.path.start_heading_rad, self.tlog, self.record,
                                         health=self._health_monitor(config),
                                         path_length_m=self.mission.path.length_m)
                self.exit_reason = self.flight.run()
            if self.exit_reason == "finished":
                profile.finish(self._on_finish_action())
        except _Terminate:
            self.exit_reason = "SIGTERM"
            raise FlightAborted("terminated (SIGTERM); flight log closed") from None
        except KeyboardInterrupt:
            self.exit_reason = "interrupted"
            raise
        except CompanionError as err:
            self.exit_reason = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise
        finally:
            self._close(old_handlers)
        return self.summary

    def _close(self, old_handlers: dict) -> None:
        if self.flight is not None:
            self.flight.close()
        self.status.close()
        self.summary = self._summarise()
        if self.link is not None:
            self.link.close()
        if self.tlog is not None:
            self.tlog.close()
        restore_handlers(old_handlers)

    def _summarise(self) -> dict:
        r = self.record
        # The end-of-path tick (phase "finished", zero length) is not a phase of the flight:
        # sim, demo and fly report the same phases under the same names.
        keep = [i for i, h in enumerate(r.hold)
                if not h and math.isfinite(r.crosstrack_m[i]) and r.phase[i] != "finished"]
        m = tracking_metrics([r.t_s[i] for i in keep], [r.crosstrack_m[i] for i in keep],
                             [r.a_cmd_m_s2[i] for i in keep], [r.phase[i] for i in keep],
                             **profile_errors(self.mission.profile, [r.s_proj_m[i] for i in keep],
                                              [r.alt_m[i] for i in keep],
                                              [r.ground_speed_m_s[i] for i in keep]))
        sched = self.flight.scheduler if self.flight is not None else None
        stats = sched.stats().as_dict() if sched is not None else {}
        m.update({
            "rate_hz_achieved": stats.get("rate_hz_achieved", math.nan),
            "tick_ms": stats.get("tick_ms", {"p50": math.nan, "p99": math.nan}),
            "ticks": len(r.t_s),
            "skipped_ticks": stats.get("skipped_ticks", 0),
            "hold_ticks": self.flight.hold_ticks if self.flight is not None else 0,
            "coast_ticks": self.coast_ticks,
            "setpoints_sent": self.setpoints_sent,
            "clock": self.opt.clock,
            "exit": self.exit_reason,
            "tlog": str(self.tlog_path),
            "link": self.link.counters() if self.link is not None else self._failed_link_counters,
        })
        if self.origin_shift is not None:
            m["origin_offset_enu_m"] = [self.origin_shift.east_m, self.origin_shift.north_m]
            m["origin_translation_error_m"] = self.origin_shift.max_error_m
        if self.link is not None and self.link.info is not None:
            m["autopilot"] = self.link.info.autopilot
            m["vehicle"] = self.link.info.vehicle
        if self.tlog is not None and self.tlog.write_error:
            m["tlog_error"] = self.tlog.write_error
        return m


class _flight_interpreter:
    """The interpreter's settings while the loop runs (restored after).

    Everything alive when the loop starts (modules, the path table, pymavlink's dialect: hundreds
    of thousands of objects) leaves the collector's generations, so a full collection in flight
    walks only what the flight allocates instead of stalling a tick. The loop thread hands the
    interpreter to the guidance worker while it waits; when the worker runs a long step (a
    re-optimisation) the loop must get it back within a fraction of a tick, not after the
    default 5 ms switch interval.
    """

    def __enter__(self) -> None:
        gc.collect()
        gc.freeze()
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(LOOP_SWITCH_INTERVAL_S)

    def __exit__(self, *exc: object) -> None:
        gc.unfreeze()
        sys.setswitchinterval(self._switch_interval)


def _raise_terminate(signum: int, frame: FrameType | None) -> None:  # noqa: ARG001 - signal handler signature
    # A supervisor's second SIGTERM must not interrupt the clean-up (tlog flush, summary) the first
    # started; run() puts the previous handler back when it is done.
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise _Terminate()
