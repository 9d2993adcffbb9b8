"""The flight runner behind ``companion fly``: link -> modes/arming -> fixed-rate guidance loop.

Sequence (details and the reasons in ``docs/flying.md`` and ``docs/failsafes.md``):

1. open the tlog (refuse to start if it cannot be written) and write the mission beside it;
2. open the link, wait for the autopilot's heartbeat, pair with it (PX4 or ArduPilot);
3. request LOCAL_POSITION_NED at the loop rate and ATTITUDE with SET_MESSAGE_INTERVAL (ACK checked);
4. wait for a valid position; refuse to start farther than ``max_start_distance_m`` from the path;
5. modes: PX4 -> stream hold setpoints >= 1 s, then OFFBOARD, then (``--arm``) arm;
   ArduPilot -> GUIDED, then (``--arm``) arm with retries until ``arm_timeout_s`` showing the
   autopilot's STATUSTEXT reasons, then NAV_TAKEOFF;
6. the loop: every tick :func:`companion.loop.tick.compute_tick` on the newest position, send the
   setpoint, record it; failsafes: stale position -> hold, heartbeat lost -> stop and exit, the
   vehicle leaving OFFBOARD/GUIDED -> stop commanding at once and never switch back;
7. at the end of the path, the ``on_finish`` action for this autopilot.

A ``geodetic`` mission is moved onto the autopilot's own local origin before step 4: the runner
asks for GPS_GLOBAL_ORIGIN (MAV_CMD_REQUEST_MESSAGE 49) and translates the path and start by the
ENU offset of the mission's origin from it (:func:`onto_autopilot_origin`); no origin within
``origin_timeout_s`` -> LinkError (exit 2), nothing flown. Local-frame missions are untouched.

Clocks: ``wall`` ticks on the monotonic clock; ``autopilot`` ticks on the autopilot's
``time_boot_ms`` (used with a simulator running faster than real time).
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import gc
import math
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from companion.errors import CompanionError, FlightAborted, LinkError
from companion.geometry import frames, geodetic
from companion.geometry.paths import Path as RefPath
from companion.io.link import (
    MAV_CMD_SET_MESSAGE_INTERVAL,
    GlobalOrigin,
    MAV_RESULT_NAMES,
    MSG_ID_ATTITUDE,
    MSG_ID_LOCAL_POSITION_NED,
    MavLink,
)
from companion.io.tlog import TlogWriter, default_tlog_path
from companion.loop.scheduler import FixedRateScheduler, MonotonicClock
from companion.loop.tick import DEBUG_FIELDS, TickConfig, coast_setpoint, compute_tick, hold_for
from companion.sim.metrics import profile_errors, tracking_metrics

ON_FINISH = ("hold", "loiter", "rtl", "land")


#: The interpreter's thread switch interval while flying (Python's default is 5 ms).
LOOP_SWITCH_INTERVAL_S = 0.0005


@dataclass(frozen=True)
class FlyOptions:
    """Everything ``companion fly`` takes besides the mission (validated on construction)."""

    connect: str
    rate_hz: float
    autopilot: str = "auto"
    stale_s: float = 0.3
    link_timeout_s: float = 5.0
    heartbeat_timeout_s: float = 15.0
    position_timeout_s: float = 10.0
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


class _Terminate(Exception):
    """SIGTERM, turned into an exception so that every ``finally`` runs (tlog closed)."""


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


class Status:
    """Live status: one rewritten line on a terminal, plain lines (1 per second) otherwise."""

    def __init__(self, stream=None, quiet: bool = False):
        self.stream = stream if stream is not None else sys.stderr
        self.quiet = quiet
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_line_s = -math.inf
        self._dirty = False

    def event(self, text: str) -> None:
        if self.quiet:
            return
        if self._dirty:
            self.stream.write("\n")
            self._dirty = False
        self.stream.write(f"companion: {text}\n")
        self.stream.flush()

    def live(self, text: str) -> None:
        if self.quiet:
            return
        now = time.monotonic()
        if self.tty:
            if now - self._last_line_s >= 0.1:
                self.stream.write("\r\x1b[K" + text)
                self.stream.flush()
                self._dirty = True
                self._last_line_s = now
        elif now - self._last_line_s >= 1.0:
            self.stream.write(text + "\n")
            self.stream.flush()
            self._last_line_s = now

    def close(self) -> None:
        if self._dirty and not self.quiet:
            self.stream.write("\n")
            self.stream.flush()
            self._dirty = False


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


def distance_to_path_m(path, x_m: float, y_m: float, n: int = 4000) -> float:
    """Distance from a point to a path (dense sampling; used only for the start check)."""
    _, xs, ys = path.sample(n)
    return float(np.min(np.hypot(xs - x_m, ys - y_m)))


@dataclass(frozen=True)
class OriginShift:
    """How a geodetic mission was moved onto the autopilot's local origin.

    Attributes
    ----------
    east_m, north_m : ENU position of the mission's ``origin`` in the autopilot's local frame
        (the translation applied to the path and the start).
    max_error_m : the largest horizontal distance, over the path's nodes, between the translated
        point and the exact WGS-84 transform of that point into the autopilot's frame.
    autopilot_origin : the GPS_GLOBAL_ORIGIN used.
    """

    east_m: float
    north_m: float
    max_error_m: float
    autopilot_origin: GlobalOrigin


def onto_autopilot_origin(mission, ap_origin: GlobalOrigin):
    """A geodetic mission with its path and start translated into the autopilot's local ENU frame.

    The mission's ENU frame is centred on ``mission.origin``; LOCAL_POSITION_NED is centred on the
    autopilot's EKF origin ``ap_origin``. The offset (east, north) of ``mission.origin`` seen from
    ``ap_origin`` is computed exactly (WGS-84 -> ECEF -> ENU, :mod:`companion.geometry.geodetic`)
    and added to every path node and to the start; tangents and curvature are unchanged.

    Both points are taken at one height, the mission's flight height ``origin.alt_m +
    altitude_m``: GPS_GLOBAL_ORIGIN's altitude is above mean sea level while ``origin.alt_m`` is
    above the ellipsoid, and the geoid separation (up to ~100 m) must not leak into the offset.
    Heights only scale horizontal distances by ~1.6e-7 per metre, so this costs nothing.

    A translation ignores the rotation between the two ENU frames (their axes differ by about
    d/R, d the distance between the origins, R the Earth's radius, plus a meridian convergence
    of about (d_east/R) tan(lat) about the vertical). A path point r metres from the mission's
    origin is therefore misplaced by about r d (1 + |tan lat|) / R: 1 km of path 100 m from the
    EKF origin at 47 deg gives ~3 cm. The exact error over the path's nodes is measured and
    returned in :class:`OriginShift` (``max_error_m``) so the flight can report it.

    Returns
    -------
    (mission, OriginShift)
    """
    o = mission.origin
    height_m = o.alt_m + mission.altitude_m
    e, n, _ = geodetic.enu_from_geodetic(o.lat_deg, o.lon_deg, height_m,
                                         ap_origin.lat_deg, ap_origin.lon_deg, height_m)
    east_m, north_m = float(e), float(n)
    path = mission.path
    xs = np.asarray(path.x_table_m)
    ys = np.asarray(path.y_table_m)
    # Exact: path nodes (ENU about the mission origin, at flight height) -> WGS-84 -> ENU about
    # the autopilot's origin at the same height.
    lat, lon, h = geodetic.geodetic_from_enu(xs, ys, np.zeros_like(xs), o.lat_deg, o.lon_deg, height_m)
    ex, ny, _ = geodetic.enu_from_geodetic(lat, lon, h, ap_origin.lat_deg, ap_origin.lon_deg, height_m)
    max_error_m = float(np.max(np.hypot(ex - (xs + east_m), ny - (ys + north_m))))
    moved = RefPath(path.s_table_m, xs + east_m, ys + north_m, path.tx_table, path.ty_table,
                    path.k_table_1_m, path.closed)
    start = mission.start
    if start is not None:
        start = dataclasses.replace(start, x_m=start.x_m + east_m, y_m=start.y_m + north_m)
    shifted = dataclasses.replace(mission, path=moved, start=start)
    return shifted, OriginShift(east_m, north_m, max_error_m, ap_origin)


def write_mission_beside(tlog_path: Path, mission) -> Path:
    out = Path(str(tlog_path) + ".mission.yaml")
    out.write_text(mission.source_text or "", encoding="utf-8")
    return out


def make_guidance(mission, rate_hz: float):
    """The mission's two-phase guidance at the loop's rate and the mission's speed."""
    from companion.guidance.two_phase import TwoPhaseGuidance

    params = mission.guidance
    changes = {}
    if hasattr(params, "rate_hz"):
        changes["rate_hz"] = float(rate_hz)
    if hasattr(params, "speed_m_s"):
        changes["speed_m_s"] = float(mission.speed_m_s)
    params = dataclasses.replace(params, **changes)
    law = TwoPhaseGuidance(mission.path, params)
    profile = getattr(mission, "profile", None)
    if profile is not None and not profile.constant_speed:
        from companion.guidance.profiled import ProfiledGuidance

        return ProfiledGuidance(law, profile)  # every law at the local speed V(s)
    return law


class FlightRunner:
    """One flight of one mission on one autopilot. Call :meth:`run`; read :attr:`summary`."""

    def __init__(self, mission, options: FlyOptions, status: Status | None = None, guidance=None):
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
        self.setpoints_sent = 0
        self.hold_ticks = 0
        self._scheduler: FixedRateScheduler | None = None
        self._in_hold = False
        self._mode_confirmed = False
        self.coast_ticks = 0
        self._guidance_ticks = 0
        # PX4 leaves OFFBOARD when setpoints stop: while arming/climbing, _idle streams holds.
        self._keepalive_config: TickConfig | None = None
        self._last_keepalive_s = -math.inf
        # The guidance steps in a worker thread; a step slower than this budget (wall seconds)
        # does not freeze the setpoint stream: that tick coasts (see tick.coast_setpoint).
        self._step_budget_s = 0.5 / options.rate_hz
        self._worker = concurrent.futures.ThreadPoolExecutor(max_workers=1,
                                                             thread_name_prefix="guidance")

    # ------------------------------------------------------------------ helpers

    def _event(self, text: str) -> None:
        self.events.append(text)
        self.status.event(text)

    def _idle(self) -> None:
        """Keep our heartbeat going while waiting for anything (and PX4's setpoint stream)."""
        self.link.heartbeat_if_due()
        if self._keepalive_config is not None:
            now = time.monotonic()
            if now - self._last_keepalive_s >= 1.0 / self.opt.rate_hz:
                self._last_keepalive_s = now
                self._hold_now(self._keepalive_config)

    def _pump(self, duration_s: float) -> None:
        end = time.monotonic() + duration_s
        while True:
            self._idle()
            remaining = end - time.monotonic()
            if remaining <= 0:
                return
            self.link.poll(min(0.02, remaining))

    def _check_link(self) -> None:
        age = self.link.link_age_s()
        if not (age <= self.opt.link_timeout_s):
            raise LinkError(
                f"{self.opt.connect}: heartbeat lost for {age:.1f} s (--link-timeout-s "
                f"{self.opt.link_timeout_s:g}); stopped sending setpoints"
            )

    def _check_mode(self, target_mode: str) -> None:
        """Before the loop (climb, takeoff): a mode change by the pilot ends the flight."""
        if not self.link.in_mode(target_mode):
            self._keepalive_config = None
            raise FlightAborted(f"pilot override: the vehicle left {target_mode.upper()} before the "
                                "path started; not switching back")

    def _statustext_since(self, n0: int) -> list[str]:
        return [t for _, t in self.link.state.statustext[n0:]]

    # ------------------------------------------------------------------ phases of a flight

    def _open(self) -> None:
        self.tlog = TlogWriter(self.tlog_path).open()
        write_mission_beside(self.tlog_path, self.mission)
        self.link = MavLink(
            self.opt.connect,
            source_system=self.opt.source_system,
            source_component=self.opt.source_component,
            signing_key=self.opt.signing_key,
            tlog=self.tlog,
            target_system=self.opt.target_system,
            autopilot=self.opt.autopilot,
        )
        info = self.link.wait_heartbeat(self.opt.heartbeat_timeout_s)
        self._event(f"paired with {info.autopilot} {info.vehicle} (system {info.system_id}, "
                    f"component {info.component_id}) on {self.opt.connect}")
        self.link.send_heartbeat()

    def _request_streams(self) -> None:
        for msg_id, name, rate in ((MSG_ID_LOCAL_POSITION_NED, "LOCAL_POSITION_NED", self.opt.rate_hz),
                                   (MSG_ID_ATTITUDE, "ATTITUDE", self.opt.attitude_rate_hz)):
            result = self.link.command_long(MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, 1.0e6 / rate),
                                            wait_ack_s=1.0, retries=3, idle=self._idle)
            if result != 0:
                why = "no COMMAND_ACK" if result is None else MAV_RESULT_NAMES.get(result, str(result))
                self._event(f"warning: SET_MESSAGE_INTERVAL {name} {rate:g} Hz: {why}")

    def _align_geodetic_mission(self) -> None:
        """Geodetic mission: move its path onto the autopilot's EKF origin (or refuse to fly)."""
        if self.mission.frame != "geodetic" or self.mission.origin is None:
            return
        origin = self.link.request_global_origin(self.opt.origin_timeout_s, idle=self._idle)
        if origin is None:
            raise LinkError(
                f"{self.opt.connect}: no GPS_GLOBAL_ORIGIN within --origin-timeout-s "
                f"{self.opt.origin_timeout_s:g} (the autopilot has no local origin yet: no GPS fix?); "
                f"{self.mission.source_name} is geodetic and cannot be placed; not flying"
            )
        self.mission, shift = onto_autopilot_origin(self.mission, origin)
        self.origin_shift = shift
        self._event(
            f"autopilot origin {origin.lat_deg:.7f}, {origin.lon_deg:.7f}: mission origin is at ENU "
            f"({shift.east_m:+.2f}, {shift.north_m:+.2f}) m; path translated (max error of the "
            f"translation {shift.max_error_m * 1000:.1f} mm)"
        )

    def _wait_position(self) -> None:
        end = time.monotonic() + self.opt.position_timeout_s
        while self.link.state.position is None:
            if self.link.state.heartbeats:
                self._check_link()
            if time.monotonic() > end:
                raise LinkError(
                    f"{self.opt.connect}: no valid LOCAL_POSITION_NED within "
                    f"{self.opt.position_timeout_s:g} s (position estimate not ready?)"
                )
            self._pump(0.05)

    def _check_start_distance(self) -> None:
        p = self.link.state.position
        x, y, _ = frames.enu_from_ned(p.x_ned_m, p.y_ned_m, p.z_ned_m)
        d = distance_to_path_m(self.mission.path, x, y)
        if d > self.opt.max_start_distance_m:
            raise FlightAborted(
                f"vehicle at ENU ({x:.1f}, {y:.1f}) m is {d:.0f} m from the path of "
                f"{self.mission.source_name}, more than --max-start-distance-m "
                f"{self.opt.max_start_distance_m:g} (wrong origin or frame?); not starting"
            )

    def _output_kind(self) -> str:
        if self.opt.output != "auto":
            return self.opt.output
        return "attitude" if self.link.info.vehicle == "plane" else "velocity"

    def _hold_now(self, config: TickConfig) -> None:
        """Send one hold setpoint (zero velocity, altitude held) for the pre-stream."""
        p = self.link.state.position
        fresh = p is not None and time.monotonic() - p.received_s <= self.opt.stale_s
        alt = -p.z_ned_m if p is not None else math.nan
        course = 0.0
        if p is not None and math.hypot(p.vx_ned_m_s, p.vy_ned_m_s) > config.min_course_speed_m_s:
            course = frames.course_enu_from_vel_ned(p.vx_ned_m_s, p.vy_ned_m_s)
        elif self.link.state.yaw_ned_rad is not None:
            course = frames.course_enu_from_ned(self.link.state.yaw_ned_rad)
        self._send(hold_for(config, alt, fresh, course))

    def _send(self, sp) -> None:
        self.link.send_setpoint(sp)
        self.setpoints_sent += 1

    def _enter_mode(self, config: TickConfig, clock) -> None:
        info = self.link.info
        target_mode = "offboard" if info.autopilot == "px4" else "guided"
        if info.autopilot == "px4":
            self._keepalive_config = config
            # PX4 refuses OFFBOARD unless setpoints already flow: stream holds >= prestream_s.
            t_end = clock.now() + self.opt.offboard_prestream_s
            wall_end = time.monotonic() + max(5.0, 3 * self.opt.offboard_prestream_s)
            while clock.now() < t_end and time.monotonic() < wall_end:
                self._hold_now(config)
                self._pump(1.0 / self.opt.rate_hz if self.opt.clock == "wall" else 0.0)
                if self.opt.clock == "autopilot":
                    clock.wait_until(clock.now() + 1.0 / self.opt.rate_hz)
        if not self.link.in_mode(target_mode):
            result = self.link.set_mode(target_mode, wait_ack_s=1.0, retries=3,
                                        idle=self._idle)
            if result != 0:
                why = "no COMMAND_ACK" if result is None else MAV_RESULT_NAMES.get(result, str(result))
                raise FlightAborted(f"the autopilot refused {target_mode.upper()} mode ({why})")
        end = time.monotonic() + 3.0
        while not self.link.in_mode(target_mode):
            if time.monotonic() > end:
                raise FlightAborted(f"the vehicle did not report {target_mode.upper()} mode within 3 s")
            self._pump(0.02)
        self._mode_confirmed = True
        self._event(f"in {target_mode.upper()} mode")
        if self.opt.arm and not self.link.state.armed:
            self._arm(config)
        if not self.link.state.armed:
            raise FlightAborted("the vehicle is not armed (arm it, or pass --arm)")
        if info.autopilot == "ardupilot" and self.opt.arm and info.vehicle == "copter":
            self._takeoff(config)
        if info.autopilot == "px4" and self.opt.arm and info.vehicle == "copter":
            self._climb(config)

    def _climb(self, config: TickConfig) -> None:
        """PX4 copter armed on the ground: climb with hold setpoints (vz) to the mission altitude."""
        alt = self.mission.altitude_m
        self._event(f"climbing to {alt:g} m in OFFBOARD")
        end = time.monotonic() + 120.0
        while True:
            p = self.link.state.position
            if p is not None and -p.z_ned_m >= 0.9 * alt:
                return
            if time.monotonic() > end:
                raise FlightAborted(f"did not climb to {0.9 * alt:.1f} m within 120 s")
            self._check_mode("offboard")
            self._check_link()
            self._pump(0.02)

    def _arm(self, config: TickConfig) -> None:
        end = time.monotonic() + self.opt.arm_timeout_s
        n0 = len(self.link.state.statustext)
        last_reason = ""
        while not self.link.state.armed:
            result = self.link.arm(wait_ack_s=1.0, retries=1,
                                   idle=self._idle)
            self._pump(0.3)
            if self.link.state.armed:
                break
            reasons = self._statustext_since(n0)
            n0 = len(self.link.state.statustext)
            reason = "; ".join(reasons) or (MAV_RESULT_NAMES.get(result, "no COMMAND_ACK")
                                            if result is not None else "no COMMAND_ACK")
            if reason != last_reason:
                self._event(f"arming refused: {reason} (retrying until --arm-timeout-s)")
                last_reason = reason
            if time.monotonic() > end:
                raise FlightAborted(f"could not arm within {self.opt.arm_timeout_s:g} s: {last_reason}")
            self._pump(1.0)
        self._event("armed")

    def _takeoff(self, config: TickConfig) -> None:
        alt = self.opt.takeoff_alt_m or self.mission.altitude_m
        result = self.link.takeoff(alt, wait_ack_s=1.0, retries=3, idle=self._idle)
        if result != 0:
            why = "no COMMAND_ACK" if result is None else MAV_RESULT_NAMES.get(result, str(result))
            raise FlightAborted(f"NAV_TAKEOFF to {alt:g} m refused ({why})")
        self._event(f"taking off to {alt:g} m")
        end = time.monotonic() + 120.0
        while True:
            p = self.link.state.position
            if p is not None and -p.z_ned_m >= 0.9 * alt:
                break
            if time.monotonic() > end:
                raise FlightAborted(f"takeoff did not reach {0.9 * alt:.1f} m within 120 s")
            self._check_mode("guided")
            self._check_link()
            self._pump(0.05)

    def _on_finish(self) -> None:
        action = self.opt.on_finish or self.mission.on_finish
        info = self.link.info
        if info.autopilot == "ardupilot" and info.vehicle == "copter" and action == "hold":
            p = self.link.state.position
            self.link.send_position_hold(p.x_ned_m, p.y_ned_m, p.z_ned_m)
            self.setpoints_sent += 1
            self._event("path finished: holding position in GUIDED")
            return
        try:
            result = self.link.set_mode(action, wait_ack_s=1.0, retries=3, idle=self._idle)
        except LinkError as err:
            self._event(f"path finished: {err}")
            return
        why = ("accepted" if result == 0 else
               "no COMMAND_ACK" if result is None else MAV_RESULT_NAMES.get(result, str(result)))
        self._event(f"path finished: on-finish {action} -> mode change {why}")

    # ------------------------------------------------------------------ the loop

    def _loop(self, guidance, config: TickConfig, clock) -> None:
        sched = FixedRateScheduler(self.opt.rate_hz, clock)
        self._scheduler = sched
        target_mode = "offboard" if self.link.info.autopilot == "px4" else "guided"
        t_first: float | None = None
        prev_course_cmd = None
        pending = None
        last_result = None
        coast_since: float | None = None
        worker = self._worker
        prev_course = self.mission.path.start_heading_rad
        p = self.link.state.position
        if p is not None and math.hypot(p.vx_ned_m_s, p.vy_ned_m_s) >= config.min_course_speed_m_s:
            prev_course = frames.course_enu_from_vel_ned(p.vx_ned_m_s, p.vy_ned_m_s)
        elif self.link.state.yaw_ned_rad is not None:
            prev_course = frames.course_enu_from_ned(self.link.state.yaw_ned_rad)
        while True:
            tick = sched.wait_next()
            self.link.poll(0.0)
            self._idle()
            self._check_link()
            if not self.link.in_mode(target_mode):
                mode = self.link.state.custom_mode
                self._event(f"vehicle left {target_mode.upper()} (custom_mode {mode}): pilot or "
                            "failsafe override; stopped commanding")
                if not self.opt.resume:
                    raise FlightAborted(
                        f"pilot override: the vehicle left {target_mode.upper()}; not switching back "
                        "(use --resume to continue when the pilot returns control)")
                self._wait_resume(target_mode)
                sched = FixedRateScheduler(self.opt.rate_hz, clock)
                self._scheduler = sched
                continue
            now = clock.now()
            if t_first is None:
                t_first = now
            t_s = now - t_first
            sample = self.link.state.position
            if sample is None:
                age = math.inf
            else:
                age = time.monotonic() - sample.received_s
                if self.opt.clock == "autopilot":
                    age = max(age, now - sample.time_s)
            result = None
            for _ in range(2):
                fresh = False
                if pending is None:
                    pending = worker.submit(
                        compute_tick, guidance, self._guidance_ticks, t_s, sample, age, config,
                        yaw_ned_rad=self.link.state.yaw_ned_rad, prev_course_rad=prev_course,
                        prev_course_cmd_rad=prev_course_cmd)
                    self._guidance_ticks += 1
                    fresh = True
                try:
                    done = pending.result(timeout=self._step_budget_s)
                except concurrent.futures.TimeoutError:
                    break  # still computing: coast this tick
                pending = None
                self._after_guidance(done, sent=fresh)
                last_result = done
                prev_course = done.course_rad
                if fresh:
                    result = done
                    prev_course_cmd = done.course_cmd_rad
                    break
                # A late result (its tick already coasted): compute this tick afresh.
            if result is not None:
                coast_since = None
                self._send(result.setpoint)
            else:
                if coast_since is None:
                    coast_since = now
                sp = coast_setpoint(last_result, sample, age, config,
                                    prev_course_cmd if prev_course_cmd is not None else math.nan,
                                    turning=(now - coast_since) <= self.opt.max_coast_turn_s)
                self._send(sp)
                self.coast_ticks += 1
                prev_course_cmd = getattr(sp, "course_cmd_enu_rad", math.nan)
            self.tlog.flush()
            sched.done()
            if result is None:
                continue
            self._live(result, sched)
            if result.phase == "finished":
                self.exit_reason = "finished"
                self._on_finish()
                return
            if self.opt.max_duration_s is not None and t_s >= self.opt.max_duration_s:
                self.exit_reason = "max duration"
                self._event(f"stopping after --max-duration-s {self.opt.max_duration_s:g}")
                return

    def _after_guidance(self, result, sent: bool = True) -> None:
        """Record a finished compute_tick (in the tlog and the flight record); report holds.

        ``sent`` is False for a result that arrived after its tick had coasted: its setpoint is
        not sent (the current tick is computed afresh) and its record says so (field 26).
        """
        sample = result.sample
        time_usec = sample.time_boot_ms * 1000 if sample is not None else 0
        row = list(result.debug)
        row[DEBUG_FIELDS.index("setpoint_sent")] = 1.0 if sent else 0.0
        self.link.record_debug("guidance", result.tick, time_usec, row)
        self._record(result, sample)
        self._plane_profile_targets(result)
        if result.is_hold != self._in_hold:
            self._in_hold = result.is_hold
            if result.is_hold:
                self._event(f"HOLD: position {result.hold_reason} (age {result.sample_age_s:.2f} s > "
                            f"--stale-s {self.opt.stale_s:g}); zero velocity, zero yaw rate")
            else:
                self._event("position fresh again: guidance resumed")

    def _wait_resume(self, target_mode: str) -> None:
        self._event(f"--resume: waiting for the pilot to select {target_mode.upper()} again")
        while not self.link.in_mode(target_mode):
            self._check_link()
            self._pump(0.05)
        self._event(f"back in {target_mode.upper()}: resuming")

    def _plane_profile_targets(self, result) -> None:
        """A fixed wing flying a mission with a profile gets its height and speed through the
        autopilot's own channels, sent (without waiting for an ack) when the target moves by
        0.5 m or 0.2 m/s, and the height at least once a second: the speed command (as at the
        start of the flight) and, on ArduPilot, GUIDED_CHANGE_ALTITUDE. PX4 takes the climb from
        the attitude setpoint's pitch (``companion.loop.tick``)."""
        profile = getattr(self.mission, "profile", None)
        if profile is None or result.output is None or type(result.setpoint).__name__ != "AttitudeSetpoint":
            return
        s_m = result.output.s_proj_m
        v = profile.speed_m_s(s_m)
        sent_v, sent_h, sent_t = getattr(self, "_plane_sent", (self.mission.speed_m_s, math.nan, -math.inf))
        if abs(v - sent_v) >= 0.2:
            self.link.change_speed(v, wait_ack_s=0.0, retries=1)
            sent_v = v
        if self.link.info is not None and self.link.info.autopilot == "ardupilot":
            h = profile.altitude_m(s_m)
            if not abs(h - sent_h) < 0.5 or result.t_s - sent_t >= 1.0:
                self.link.change_altitude(h, profile.limits.climb_max_m_s, wait_ack_s=0.0, retries=1)
                sent_h, sent_t = h, result.t_s
        self._plane_sent = (sent_v, sent_h, sent_t)

    def _record(self, result, sample) -> None:
        r = self.record
        r.t_s.append(result.t_s)
        r.time_boot_ms.append(sample.time_boot_ms if sample is not None else -1)
        r.phase.append(result.phase)
        out = result.output
        r.a_cmd_m_s2.append(out.a_cmd_m_s2 if out is not None else 0.0)
        r.crosstrack_m.append(out.crosstrack_m if out is not None else math.nan)
        r.x_m.append(result.state.x_m if result.state is not None else math.nan)
        r.y_m.append(result.state.y_m if result.state is not None else math.nan)
        r.sample_age_s.append(result.sample_age_s)
        r.hold.append(result.is_hold)
        r.s_proj_m.append(out.s_proj_m if out is not None else math.nan)
        r.alt_m.append(-sample.z_ned_m if sample is not None else math.nan)
        r.ground_speed_m_s.append(math.hypot(sample.vx_ned_m_s, sample.vy_ned_m_s) if sample is not None else math.nan)
        r.vz_cmd_ned_m_s.append(getattr(result.setpoint, "vz_ned_m_s", math.nan))
        if result.is_hold:
            self.hold_ticks += 1

    def _live(self, result, sched) -> None:
        out = result.output
        xt = f"{out.crosstrack_m:+6.2f}" if out is not None else "   n/a"
        a = f"{out.a_cmd_m_s2:+6.2f}" if out is not None else "  0.00"
        rej = sum(self.link.rejected.values())
        if rej:  # the split by reason, largest first (bad_data 12, nan 3, ...)
            split = sorted(((n, k) for k, n in self.link.rejected.items() if n), reverse=True)
            rej = f"{rej} ({', '.join(f'{k} {n}' for n, k in split)})"
        hb_age = self.link.link_age_s()
        link = "link ok" if hb_age < 1.5 else f"link quiet {hb_age:.1f} s"
        self.status.live(
            f"t {result.t_s:6.1f} s  {result.phase:<11} xtrack {xt} m  a_cmd {a} m/s2  "
            f"{sched.current_rate_hz():5.1f} Hz  {link}  rejected {rej}"
        )

    # ------------------------------------------------------------------ entry point

    def run(self) -> dict:
        """Fly the mission. Returns the summary; raises CompanionError on refusal/abort."""
        old_term = None
        frozen = False
        switch_interval = None
        try:
            old_term = signal.signal(signal.SIGTERM, _raise_terminate)
        except ValueError:
            old_term = None  # not in the main thread: SIGTERM handling left to the caller
        try:
            self._open()
            config = TickConfig(
                speed_m_s=self.mission.speed_m_s,
                rate_hz=self.opt.rate_hz,
                altitude_m=self.mission.altitude_m,
                profile=self.mission.profile,
                stale_s=self.opt.stale_s,
                output=self._output_kind(),
                max_bank_deg=self.opt.max_bank_deg,
            )
            if config.output == "attitude" and (self.opt.on_finish or self.mission.on_finish) == "land":
                raise FlightAborted("--on-finish land is not available for a fixed-wing flight; use rtl or loiter")
            self._request_streams()
            self._align_geodetic_mission()
            self._wait_position()
            self._check_start_distance()
            guidance = self._guidance or make_guidance(self.mission, self.opt.rate_hz)
            clock = (AutopilotClock(self.link, self._idle) if self.opt.clock == "autopilot"
                     else MonotonicClock(idle=lambda dt: (self._idle(), self.link.poll(min(dt, 0.02)))))
            self._enter_mode(config, clock)
            if config.output == "attitude":
                self.link.change_speed(self.mission.speed_m_s, wait_ack_s=1.0, retries=2, idle=self._idle)
            self._keepalive_config = None
            self._event(f"flying {self.mission.name} at {self.opt.rate_hz:g} Hz "
                        f"({config.output} setpoints, {self.opt.clock} clock)")
            # Everything alive now (modules, the path table, pymavlink's dialect: hundreds of
            # thousands of objects) leaves the collector's generations, so a full collection in
            # flight walks only what the flight allocates instead of stalling a tick.
            gc.collect()
            gc.freeze()
            frozen = True
            # The loop thread hands the interpreter to the guidance worker while it waits; when
            # the worker runs a long step (a re-optimisation) the loop must get it back within a
            # fraction of a tick, not after the default 5 ms switch interval.
            switch_interval = sys.getswitchinterval()
            sys.setswitchinterval(LOOP_SWITCH_INTERVAL_S)
            self._loop(guidance, config, clock)
        except _Terminate:
            self.exit_reason = "SIGTERM"
            raise FlightAborted("terminated (SIGTERM); flight log closed")
        except KeyboardInterrupt:
            self.exit_reason = "interrupted"
            raise
        except CompanionError as err:
            self.exit_reason = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise
        finally:
            if frozen:
                gc.unfreeze()
            if switch_interval is not None:
                sys.setswitchinterval(switch_interval)
            self._worker.shutdown(wait=False, cancel_futures=True)
            self.status.close()
            self.summary = self._summarise()
            if self.link is not None:
                self.link.close()
            if self.tlog is not None:
                self.tlog.close()
            if old_term is not None:
                signal.signal(signal.SIGTERM, old_term)
        return self.summary

    def _summarise(self) -> dict:
        r = self.record
        keep = [i for i, h in enumerate(r.hold) if not h and math.isfinite(r.crosstrack_m[i])]
        m = tracking_metrics([r.t_s[i] for i in keep], [r.crosstrack_m[i] for i in keep],
                             [r.a_cmd_m_s2[i] for i in keep], [r.phase[i] for i in keep],
                             **profile_errors(self.mission.profile, [r.s_proj_m[i] for i in keep],
                                              [r.alt_m[i] for i in keep],
                                              [r.ground_speed_m_s[i] for i in keep]))
        stats = self._scheduler.stats().as_dict() if self._scheduler is not None else {}
        m.update({
            "rate_hz_achieved": stats.get("rate_hz_achieved", math.nan),
            "tick_ms": stats.get("tick_ms", {"p50": math.nan, "p99": math.nan}),
            "ticks": len(r.t_s),
            "skipped_ticks": stats.get("skipped_ticks", 0),
            "hold_ticks": self.hold_ticks,
            "coast_ticks": self.coast_ticks,
            "setpoints_sent": self.setpoints_sent,
            "clock": self.opt.clock,
            "exit": self.exit_reason,
            "tlog": str(self.tlog_path),
            "link": self.link.counters() if self.link is not None else {},
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


def _raise_terminate(signum, frame):  # noqa: ARG001 - signal handler signature
    raise _Terminate()
