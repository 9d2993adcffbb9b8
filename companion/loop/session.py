"""The companion's side of one link to one autopilot while a flight is set up and flown.

:class:`LinkSession` holds what every step of a flight needs: the link, the options, the operator
status, our heartbeat and (PX4, while arming and climbing) the stream of hold setpoints that keeps
OFFBOARD alive. The per-autopilot steps (:mod:`companion.loop.profiles`), the flight loop
(:mod:`companion.loop.flight`) and the runner (:mod:`companion.loop.runner`) all act through it.

Operator events go to the ``companion`` logger (standard :mod:`logging`), to :class:`Status`,
the stderr line a user watches, and into the tlog as STATUSTEXT from the companion's own
component (:meth:`companion.io.link.MavLink.record_event`), so that ``companion log summary`` and
``companion replay`` list the companion's decisions beside the autopilot's messages.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from dataclasses import replace
from typing import TYPE_CHECKING, TextIO

from companion.errors import FlightAborted, LinkError
from companion.geometry import frames
from companion.io.link import MAV_RESULT_NAMES, MAV_SEVERITY_INFO, MAV_SEVERITY_WARNING, MavLink
from companion.io.setpoints import AttitudeSetpoint, VelocitySetpoint, facing_yaw_rate_ned_rad_s
from companion.loop.tick import TickConfig, course_from_sample, hold_for

if TYPE_CHECKING:
    from companion.loop.runner import FlyOptions

log = logging.getLogger("companion")

FACE_TOLERANCE_RAD = math.radians(5.0)  # facing the start course: done within this of it
FACE_TIMEOUT_S = 10.0  # and the path starts anyway after this long (wall clock)


class Status:
    """Live status: one rewritten line on a terminal, plain lines (1 per second) otherwise."""

    def __init__(self, stream: TextIO | None = None, quiet: bool = False):
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


def result_text(result: int | None) -> str:
    """A COMMAND_ACK result in words (``None``: no ACK came)."""
    return "no COMMAND_ACK" if result is None else MAV_RESULT_NAMES.get(result, str(result))


class LinkSession:
    """The link, the options and the operator's view of one flight (see the module docstring)."""

    def __init__(self, link: MavLink, options: FlyOptions, status: Status, events: list[str]):
        self.link = link
        self.opt = options
        self.status = status
        self.events = events
        self.setpoints_sent = 0
        # PX4 leaves OFFBOARD when setpoints stop: while arming/climbing, idle() streams holds.
        self.keepalive_config: TickConfig | None = None
        self._last_keepalive_s = -math.inf
        # A copter's pre-stream and climb hold the horizontal position of their first fresh
        # sample (NED north, east), not zero velocity: the velocity loop holds its estimate,
        # and PX4 SIH's drifts by 0.1-0.25 m/s (docs/vehicle_model.md).
        self.hold_anchor_ne_m: tuple[float, float] | None = None

    def event(self, text: str, severity: int = MAV_SEVERITY_INFO, *, record: bool = True) -> None:
        """An operator event: the log, the event list, the status line and (``record``) the tlog
        as a STATUSTEXT of ``severity`` (a MAV_SEVERITY). The autopilot's own messages shown as
        events are not recorded again: the tlog already holds them."""
        log.info(text)
        self.events.append(text)
        self.status.event(text)
        if record:
            self.link.record_event(text, severity)

    def idle(self) -> None:
        """Keep our heartbeat going while waiting for anything (and PX4's setpoint stream)."""
        self.link.heartbeat_if_due()
        if self.keepalive_config is not None:
            now = time.monotonic()
            if now - self._last_keepalive_s >= 1.0 / self.opt.rate_hz:
                self._last_keepalive_s = now
                self.hold_now(self.keepalive_config)

    def pump(self, duration_s: float) -> None:
        """Service the link (and :meth:`idle`) for ``duration_s``."""
        end = time.monotonic() + duration_s
        while True:
            self.idle()
            remaining = end - time.monotonic()
            if remaining <= 0:
                return
            self.link.poll(min(0.02, remaining))

    def check_link(self) -> None:
        age = self.link.link_age_s()
        if not (age <= self.opt.link_timeout_s):
            raise LinkError(
                f"{self.opt.connect}: heartbeat lost for {age:.1f} s (--link-timeout-s "
                f"{self.opt.link_timeout_s:g}); stopped sending setpoints"
            )

    def check_mode(self, target_mode: str) -> None:
        """Before the loop (climb, takeoff): a mode change by the pilot ends the flight."""
        if not self.link.in_mode(target_mode):
            self.keepalive_config = None
            raise FlightAborted(f"pilot override: the vehicle left {target_mode.upper()} before the "
                                "path started; not switching back")

    def wait_altitude(self, alt_m: float, mode: str, timeout_s: float, poll_s: float, what: str) -> None:
        """Wait until the vehicle is at 90 % of ``alt_m``, in ``mode`` and linked; else abort."""
        end = time.monotonic() + timeout_s
        while True:
            p = self.link.state.position
            if p is not None and -p.z_ned_m >= 0.9 * alt_m:
                return
            if time.monotonic() > end:
                raise FlightAborted(f"{what} {0.9 * alt_m:.1f} m within {timeout_s:g} s")
            self.check_mode(mode)
            self.check_link()
            self.pump(poll_s)

    def statustext_since(self, n0: int) -> list[str]:
        """The autopilot's STATUSTEXTs since its ``statustext_count`` was ``n0`` (at most the last 50)."""
        new = self.link.state.statustext_count - n0
        return [t for _, t in self.link.state.statustext[-new:]] if new > 0 else []

    def hold_now(self, config: TickConfig, yaw_rate_ned_rad_s: float = 0.0) -> None:
        """Send one hold setpoint for the pre-stream, the climb and the turn to face the path:
        altitude held and, on a copter with a fresh sample, the horizontal position of the first
        fresh sample (else zero velocity); the yaw turning at ``yaw_rate_ned_rad_s``."""
        p = self.link.state.position
        fresh = p is not None and time.monotonic() - p.received_s <= self.opt.stale_s
        alt = -p.z_ned_m if p is not None else math.nan
        course = course_from_sample(p, self.link.state.yaw_ned_rad, 0.0, config.min_course_speed_m_s)
        here = None
        if fresh and self.link.info.vehicle == "copter" and config.output == "velocity":
            here = (p.x_ned_m, p.y_ned_m)
            if self.hold_anchor_ne_m is None and math.isfinite(here[0]) and math.isfinite(here[1]):
                self.hold_anchor_ne_m = here
                self.event(f"holding the position N {here[0]:.2f} m, E {here[1]:.2f} m until the path starts")
        sp = hold_for(config, alt, fresh, course, position_ne_m=here, anchor_ne_m=self.hold_anchor_ne_m)
        if yaw_rate_ned_rad_s and isinstance(sp, VelocitySetpoint):
            sp = replace(sp, yaw_rate_ned_rad_s=yaw_rate_ned_rad_s)
        self.send(sp)

    def face(self, course_enu_rad: float, config: TickConfig, mode: str) -> None:
        """A hovering copter turns its nose to ``course_enu_rad`` before the path starts, holding
        its position and height (docs/flying.md, "Facing the path"): until within
        :data:`FACE_TOLERANCE_RAD`, or for at most :data:`FACE_TIMEOUT_S` (then the path starts
        anyway, with a warning). A pilot's mode change or a lost link ends the flight as in the
        climb; so does a position gone stale (the flight loop then holds)."""
        yaw = self.link.state.yaw_ned_rad
        if yaw is None:
            return
        target_ned = frames.yaw_ned_from_enu(course_enu_rad)
        if abs(frames.angle_diff_rad(target_ned, yaw)) <= FACE_TOLERANCE_RAD:
            return
        self.event(f"facing the path: yaw {math.degrees(yaw) % 360:.0f} -> {math.degrees(target_ned) % 360:.0f} deg")
        keepalive, self.keepalive_config = self.keepalive_config, None  # this loop streams the setpoints
        end = time.monotonic() + FACE_TIMEOUT_S
        try:
            while True:
                yaw, p = self.link.state.yaw_ned_rad, self.link.state.position
                if yaw is None or abs(frames.angle_diff_rad(target_ned, yaw)) <= FACE_TOLERANCE_RAD:
                    return
                if p is None or not (time.monotonic() - p.received_s <= self.opt.stale_s):
                    return  # the flight loop holds on stale data, and says so
                if time.monotonic() > end:
                    self.event(f"did not face the path within {FACE_TIMEOUT_S:g} s (yaw "
                               f"{math.degrees(yaw) % 360:.0f} deg); starting the path anyway", MAV_SEVERITY_WARNING)
                    return
                self.check_mode(mode)
                self.check_link()
                self.hold_now(config, facing_yaw_rate_ned_rad_s(yaw, course_enu_rad))
                self.pump(1.0 / self.opt.rate_hz)
        finally:
            self.keepalive_config = keepalive

    def send(self, sp: VelocitySetpoint | AttitudeSetpoint) -> None:
        self.link.send_setpoint(sp)
        self.setpoints_sent += 1
