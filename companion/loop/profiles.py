"""What differs between autopilots on the companion's side: one small class per autopilot.

As :mod:`sitl_mock.personality` does on the mock's side, every per-autopilot difference of a
flight lives here, not as ``if autopilot == ...`` through the runner:

=================  =====================================  =====================================
step               PX4 (:class:`Px4Offboard`)             ArduPilot (:class:`ArduPilotGuided`)
=================  =====================================  =====================================
mode flown in      OFFBOARD                               GUIDED
before the mode    stream hold setpoints for              nothing
                   ``--offboard-prestream-s`` (PX4
                   refuses OFFBOARD without a stream)
after arming       copter: climb with hold setpoints      copter: NAV_TAKEOFF, wait for 90 %
                   (vz) to 90 % of the mission altitude   of the altitude
on finish          the mode of the action                 copter ``hold``: a position hold in
                                                          GUIDED; otherwise the mode
=================  =====================================  =====================================

The mode names map to each autopilot's ``custom_mode`` numbers in :mod:`companion.io.link`
(``PX4_MODES``, ``ARDUPILOT_MODES``): that is the wire encoding, and the link is the one place
that speaks it.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from companion.errors import FlightAborted, LinkError
from companion.io.link import (
    MAV_LANDED_STATE_IN_AIR,
    MAV_LANDED_STATE_ON_GROUND,
    MAV_SEVERITY_WARNING,
    AutopilotInfo,
)
from companion.loop.session import LinkSession, result_text

if TYPE_CHECKING:
    from companion.loop.scheduler import Clock
    from companion.loop.tick import TickConfig

#: How long a climb or a takeoff may take before the flight is abandoned.
CLIMB_TIMEOUT_S = 120.0
#: How long the vehicle has to report the mode it was switched to.
MODE_REPORT_TIMEOUT_S = 3.0
#: After an ACCEPTED arm command, how long a HEARTBEAT has to show the armed flag (PX4 sends
#: its heartbeat at 1 Hz on some links).
ARM_REPORT_TIMEOUT_S = 2.5
#: Without EXTENDED_SYS_STATE, a vehicle armed before the flight and higher than this is flying.
AIRBORNE_MIN_ALT_M = 1.0


class AutopilotProfile:
    """The steps of a flight that depend on the autopilot (the base: what both share)."""

    name = ""
    target_mode = ""

    def __init__(self, session: LinkSession):
        self.s = session

    # ------------------------------------------------------------------ before the path

    def before_mode(self, config: TickConfig, clock: Clock) -> None:
        """Whatever the autopilot needs before it accepts :attr:`target_mode`."""

    def enter(self, config: TickConfig, clock: Clock, altitude_m: float) -> None:
        """Armed state first, then the mode, arming and (copters, with ``--arm``, unless already
        airborne) the climb to ``altitude_m``. A refusal after the mode change puts back the mode
        the vehicle was in."""
        s = self.s
        armed_before = s.link.state.armed
        if not armed_before and not s.opt.arm:
            raise FlightAborted("the vehicle is disarmed: arm it, or pass --arm (no mode changed, "
                                "no setpoint sent)")
        before = (s.link.state.custom_mode, s.link.mode_text())
        self.before_mode(config, clock)
        self._switch_to(self.target_mode)
        try:
            if not s.link.state.armed:
                if not s.opt.arm:
                    raise FlightAborted("the vehicle disarmed before the path started (arm it, or pass --arm)")
                self.arm()
            if s.opt.arm and s.link.info.vehicle == "copter":
                if self.airborne(armed_before):
                    p = s.link.state.position
                    s.event(f"already airborne at {-p.z_ned_m:.1f} m: no takeoff")
                else:
                    self.climb(config, altitude_m)
        except FlightAborted as err:
            raise FlightAborted(f"{err}{self._restore(*before)}") from None

    def _switch_to(self, mode: str) -> None:
        s = self.s
        if not s.link.in_mode(mode):
            result = s.link.set_mode(mode, wait_ack_s=1.0, retries=3, idle=s.idle)
            if result != 0:
                s.keepalive_config = None
                raise FlightAborted(f"the autopilot refused {mode.upper()} mode ({result_text(result)})")
        end = time.monotonic() + MODE_REPORT_TIMEOUT_S
        while not s.link.in_mode(mode):
            if time.monotonic() > end:
                s.keepalive_config = None
                raise FlightAborted(f"the vehicle did not report {mode.upper()} mode within 3 s")
            s.pump(0.02)
        s.event(f"in {mode.upper()} mode")

    def _restore(self, custom_mode: int | None, name: str) -> str:
        """After a refusal in the flight mode: ask for the mode the vehicle was in (never fights a
        pilot who already left it). Returns what was done, for the error line."""
        s = self.s
        s.keepalive_config = None
        if custom_mode is None or not s.link.in_mode(self.target_mode) or s.link.in_mode_value(custom_mode):
            return ""
        try:
            result = s.link.set_custom_mode(custom_mode, wait_ack_s=1.0, retries=3, idle=s.idle)
        except LinkError:
            result = None
        if result == 0:
            s.event(f"mode set back to {name or custom_mode}", MAV_SEVERITY_WARNING)
            return f"; mode set back to {name or custom_mode}"
        return (f"; could not set the mode back to {name or custom_mode} ({result_text(result)}): "
                "select it on the ground station")

    def airborne(self, armed_before: bool) -> bool:
        """Already flying: the autopilot says so (EXTENDED_SYS_STATE), or, when it does not say,
        it was armed before the companion started and is above :data:`AIRBORNE_MIN_ALT_M`."""
        st = self.s.link.state
        if st.landed_state in (MAV_LANDED_STATE_IN_AIR, MAV_LANDED_STATE_ON_GROUND):
            return st.landed_state == MAV_LANDED_STATE_IN_AIR
        p = st.position
        return armed_before and p is not None and -p.z_ned_m > AIRBORNE_MIN_ALT_M

    def arm(self) -> None:
        """Arm, retrying until ``--arm-timeout-s`` and reporting the autopilot's reasons.

        An ACCEPTED arm command is not yet an armed vehicle: PX4 acknowledges before its next
        HEARTBEAT carries the armed flag. After an ACCEPTED the flag is awaited for
        :data:`ARM_REPORT_TIMEOUT_S` before the attempt counts as refused.
        """
        s = self.s
        end = time.monotonic() + s.opt.arm_timeout_s
        n0 = s.link.state.statustext_count
        last_reason = ""
        while not s.link.state.armed:
            result = s.link.arm(wait_ack_s=1.0, retries=1, idle=s.idle)
            wait_end = time.monotonic() + (ARM_REPORT_TIMEOUT_S if result == 0 else 0.3)
            while not s.link.state.armed and time.monotonic() < wait_end:
                s.pump(0.02)
            if s.link.state.armed:
                break
            reasons = s.statustext_since(n0)
            n0 = s.link.state.statustext_count
            reason = "; ".join(reasons) or (
                f"ACCEPTED, but no HEARTBEAT showed the vehicle armed within {ARM_REPORT_TIMEOUT_S:g} s"
                if result == 0 else result_text(result))
            if reason != last_reason:
                s.event(f"arming refused: {reason} (retrying until --arm-timeout-s)", MAV_SEVERITY_WARNING)
                last_reason = reason
            if time.monotonic() > end:
                raise FlightAborted(f"could not arm within {s.opt.arm_timeout_s:g} s: {last_reason}")
            s.pump(1.0)
        s.event("armed")

    def climb(self, config: TickConfig, altitude_m: float) -> None:
        """A copter armed on the ground: reach the flight altitude before the path."""

    # ------------------------------------------------------------------ after the path

    def finish(self, action: str) -> None:
        """The ``on_finish`` action at the end of the path: switch to its mode."""
        s = self.s
        try:
            result = s.link.set_mode(action, wait_ack_s=1.0, retries=3, idle=s.idle)
        except LinkError as err:
            s.event(f"path finished: {err}")
            return
        why = "accepted" if result == 0 else result_text(result)
        s.event(f"path finished: on-finish {action} -> mode change {why}")


class Px4Offboard(AutopilotProfile):
    """PX4: OFFBOARD needs a setpoint stream first; a copter climbs on hold setpoints."""

    name = "px4"
    target_mode = "offboard"

    def before_mode(self, config: TickConfig, clock: Clock) -> None:
        s = self.s
        s.keepalive_config = config
        # PX4 refuses OFFBOARD unless setpoints already flow: stream holds >= prestream_s.
        t_end = clock.now() + s.opt.offboard_prestream_s
        wall_end = time.monotonic() + max(5.0, 3 * s.opt.offboard_prestream_s)
        while clock.now() < t_end and time.monotonic() < wall_end:
            s.hold_now(config)
            s.pump(1.0 / s.opt.rate_hz if s.opt.clock == "wall" else 0.0)
            if s.opt.clock == "autopilot":
                clock.wait_until(clock.now() + 1.0 / s.opt.rate_hz)

    def climb(self, config: TickConfig, altitude_m: float) -> None:
        """Climb with hold setpoints (vz) to the mission altitude."""
        self.s.event(f"climbing to {altitude_m:g} m in OFFBOARD")
        self.s.wait_altitude(altitude_m, "offboard", CLIMB_TIMEOUT_S, 0.02, "did not climb to")


class ArduPilotGuided(AutopilotProfile):
    """ArduPilot: GUIDED; a copter takes off with NAV_TAKEOFF; a copter's ``hold`` stays in GUIDED."""

    name = "ardupilot"
    target_mode = "guided"

    def climb(self, config: TickConfig, altitude_m: float) -> None:
        s = self.s
        alt = s.opt.takeoff_alt_m or altitude_m
        result = s.link.takeoff(alt, wait_ack_s=1.0, retries=3, idle=s.idle)
        if result != 0:
            raise FlightAborted(f"NAV_TAKEOFF to {alt:g} m refused ({result_text(result)})")
        s.event(f"taking off to {alt:g} m")
        s.wait_altitude(alt, "guided", CLIMB_TIMEOUT_S, 0.05, "takeoff did not reach")

    def finish(self, action: str) -> None:
        s = self.s
        if action == "hold" and s.link.info.vehicle == "copter":
            p = s.link.state.position
            s.link.send_position_hold(p.x_ned_m, p.y_ned_m, p.z_ned_m)
            s.setpoints_sent += 1
            s.event("path finished: holding position in GUIDED")
            return
        super().finish(action)


PROFILES: dict[str, type[AutopilotProfile]] = {"px4": Px4Offboard, "ardupilot": ArduPilotGuided}


def profile_for(info: AutopilotInfo, session: LinkSession) -> AutopilotProfile:
    """The profile of the paired autopilot (anything not PX4 flies as ArduPilot, as before)."""
    return PROFILES.get(info.autopilot, ArduPilotGuided)(session)
