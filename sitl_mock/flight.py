"""Flight logic of the mock autopilot: modes, arming, setpoints, failsafes and outer loops.

:class:`FlightLogic` sits between the MAVLink handlers (``sitl_mock.autopilot``) and the vehicle
model (``sitl_mock.vehicle``). Handlers call its command methods (``arm``, ``set_mode``,
``takeoff``, ``set_position_target`` ...), which return a MAV_RESULT and, for a refusal, the
STATUSTEXT a real autopilot would send; the run loop calls :meth:`FlightLogic.step` once per
physics step, which applies the mode's behaviour (hold, follow setpoints, take off, land, return)
and the failsafe rules, and advances the model.

Rules modelled (see ``docs/sitl_mock.md`` for the sources):

* PX4 refuses OFFBOARD unless setpoints are already streaming (the newest younger than
  ``COM_OF_LOSS_T``, PX4's own test), and falls back to Hold (``COM_OBL_RC_ACT`` = 5) when they
  stop for ``COM_OF_LOSS_T``.
* ArduPilot GUIDED velocity and acceleration targets expire after ``GUID_TIMEOUT``: the vehicle
  brakes to a stop and stays in GUIDED. Position targets do not expire. ArduCopter ignores
  guided targets on the ground until ``MAV_CMD_NAV_TAKEOFF``, and reads the position bits of
  ``type_mask`` as one group, ignored when any of them is set, as it does the velocity and
  acceleration bits; a combination GUIDED cannot fly makes it brake to a stop. ArduPilot Rover
  reads the groups the same way and ignores a target whose acceleration is not ignored.
* PX4 reads each axis of ``type_mask`` on its own.
* ArduPlane ignores SET_POSITION_TARGET_LOCAL_NED (velocity) and turns from SET_ATTITUDE_TARGET
  (roll) in GUIDED; the override expires after ``GUIDED_TIMEOUT`` and the plane loiters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sitl_mock.personality import Mode, Personality
from sitl_mock.posctl import NEPositionController, PosControlParams
from sitl_mock.vehicle import GRAVITY_M_S2, VehicleModel, wrap_pi

MAV_RESULT_ACCEPTED = 0
MAV_RESULT_TEMPORARILY_REJECTED = 1
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3
MAV_RESULT_FAILED = 4

MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_LOCAL_OFFSET_NED = 7
MAV_FRAME_BODY_NED = 8
MAV_FRAME_BODY_OFFSET_NED = 9
SUPPORTED_FRAMES = (MAV_FRAME_LOCAL_NED, MAV_FRAME_LOCAL_OFFSET_NED, MAV_FRAME_BODY_NED, MAV_FRAME_BODY_OFFSET_NED)

MAV_LANDED_STATE_ON_GROUND = 1
MAV_LANDED_STATE_IN_AIR = 2
MAV_LANDED_STATE_TAKEOFF = 3
MAV_LANDED_STATE_LANDING = 4

SEVERITY_CRITICAL = 2
SEVERITY_WARNING = 4
SEVERITY_NOTICE = 5
SEVERITY_INFO = 6

# type_mask bits (a set bit means "ignore this field").
MASK_POS = (1, 2, 4)
MASK_VEL = (8, 16, 32)
MASK_ACC = (64, 128, 256)
MASK_FORCE = 512
MASK_YAW = 1024
MASK_YAW_RATE = 2048

ARM_FORCE_MAGIC = 21196
KP_POS_MAX_1_S = 1.0  # position-loop gain ceiling (1/s)
KP_YAW_1_S = 2.0  # heading-loop gain (1/s)
KP_ALT_PLANE_1_S = 0.5
K_ROLL_PER_RAD = 1.0  # plane bank command per radian of course error
PLANE_CLIMB_MAX_M_S = 5.0
PLANE_LOITER_RADIUS_M = 60.0
TAKEOFF_DONE_M = 0.1
RTL_ALT_PX4_M = 30.0
RTL_ALT_ARDUPILOT_M = 15.0
HOLD_SPEED_MAX_M_S = 5.0
LOOK_AHEAD_MIN_SPEED_M_S = 1.0  # below this ArduCopter's look-ahead yaw keeps the heading
VERTICAL_SPEED_UP_MAX_M_S = 3.0  # PX4 MPC_Z_VEL_MAX_UP
VERTICAL_SPEED_DOWN_MAX_M_S = 1.5  # PX4 MPC_Z_VEL_MAX_DN


@dataclass
class Setpoint:
    """A guided target, already converted to LOCAL_NED; ``None`` marks an unused axis."""

    pos_ned_m: tuple
    vel_ned_m_s: tuple
    acc_ned_m_s2: tuple
    yaw_rad: float | None
    yaw_rate_rad_s: float | None
    hold_ned_m: tuple  # where each axis with nothing commanded is held
    received_s: float
    expires: bool  # ArduPilot velocity/acceleration targets time out

    def type_mask(self) -> int:
        """The type_mask of this setpoint as POSITION_TARGET_LOCAL_NED reports it."""
        mask = 0
        for bits, values in ((MASK_POS, self.pos_ned_m), (MASK_VEL, self.vel_ned_m_s), (MASK_ACC, self.acc_ned_m_s2)):
            for bit, value in zip(bits, values):
                if value is None:
                    mask |= bit
        if self.yaw_rad is None:
            mask |= MASK_YAW
        if self.yaw_rate_rad_s is None:
            mask |= MASK_YAW_RATE
        return mask


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def roll_from_quaternion(q: tuple[float, float, float, float]) -> float:
    """Roll angle (rad) of a unit quaternion (w, x, y, z), aerospace ZYX convention."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))


class FlightLogic:
    """Modes, arming, setpoints, failsafes and the outer control loops of the mock.

    Parameters
    ----------
    personality : Personality
        PX4 or ArduPilot, and the vehicle kind.
    model : VehicleModel
        The vehicle it flies.
    params : dict
        The live parameter store (name -> ``Param``); loss timeouts and speed limits are read
        from it on every use, so a PARAM_SET takes effect at once.
    start_airborne : bool
        Start armed, flying, in the hold mode.
    home_ned_m : tuple of float
        Home (north, east, down); RTL returns here.
    posctl : PosControlParams, optional
        Fly horizontal velocity targets in GUIDED through ArduCopter's position controller
        (``sitl_mock.posctl``) instead of the vehicle model's own response.
    """

    def __init__(self, personality: Personality, model: VehicleModel, params: dict, start_airborne: bool,
                 home_ned_m: tuple[float, float, float], posctl: PosControlParams | None = None) -> None:
        self.pers = personality
        self.model = model
        self.params = params
        self.home_ned_m = home_ned_m
        self.armed = start_airborne
        self.mode: Mode = personality.hold_mode if start_airborne else personality.boot_mode
        self.events: list[tuple[int, str]] = []
        self.setpoint: Setpoint | None = None
        self._last_setpoint_s = -math.inf
        self._attitude_roll_rad: float | None = None
        self._attitude_s = -math.inf
        self._takeoff_alt_m: float | None = None  # pending or active climb target (metres above home)
        self._landed_since_s: float | None = None
        self._rtl_phase = 0
        s = model.state
        self._hold_ned_m = tuple(s.pos_ned_m)
        self._loiter_center_ned_m = (s.pos_ned_m[0], s.pos_ned_m[1])
        self._alt_target_m = -s.pos_ned_m[2]
        self._yaw_hold_rad = s.yaw_rad
        self.posctl = NEPositionController(posctl) if posctl is not None else None
        self._posctl_flying = False  # the position controller's trajectory is running
        p = model.params
        self.speed_limit_m_s = p.v_max_m_s
        self.airspeed_target_m_s = p.airspeed_cruise_m_s
        self._enter_mode(self.mode)

    # ------------------------------------------------------------------ helpers
    @property
    def t_s(self) -> float:
        return self.model.state.t_s

    def _param(self, name: str, default: float) -> float:
        param = self.params.get(name)
        return float(param.value) if param is not None else default

    @property
    def setpoint_timeout_s(self) -> float:
        """PX4 ``COM_OF_LOSS_T`` or ArduPilot ``GUID_TIMEOUT`` / ``GUIDED_TIMEOUT``, live."""
        return self._param(self.pers.offboard_timeout_param, 1.0)

    def _say(self, severity: int, text: str) -> None:
        self.events.append((severity, text[:50]))

    def _refuse(self, result: int, text: str) -> int:
        self._say(SEVERITY_WARNING if result != MAV_RESULT_UNSUPPORTED else SEVERITY_INFO, text)
        return result

    @property
    def _refusal(self) -> int:
        """The result a refused command gets: PX4 TEMPORARILY_REJECTED/DENIED, ArduPilot FAILED."""
        return MAV_RESULT_TEMPORARILY_REJECTED if self.pers.is_px4 else MAV_RESULT_FAILED

    @property
    def in_air(self) -> bool:
        return not self.model.state.on_ground

    def _stopping_point(self) -> tuple[float, float, float]:
        """Where the vehicle comes to rest if it brakes now (used as the hold point)."""
        s = self.model.state
        a = self.model.params.a_max_m_s2
        tau = self.model.params.tau_vel_s
        out = []
        for i in range(3):
            v = s.vel_ned_m_s[i]
            out.append(s.pos_ned_m[i] + v * tau + v * abs(v) / (2.0 * a))
        if s.on_ground:
            out[2] = 0.0
        return (out[0], out[1], min(out[2], 0.0))

    def _enter_mode(self, mode: Mode) -> None:
        s = self.model.state
        self.mode = mode
        self._hold_ned_m = self._stopping_point() if self.pers.vehicle != "plane" else tuple(s.pos_ned_m)
        self._yaw_hold_rad = s.yaw_rad
        self._alt_target_m = -s.pos_ned_m[2]
        self._loiter_center_ned_m = (s.pos_ned_m[0], s.pos_ned_m[1])
        if mode.behaviour != "takeoff" and not (mode.behaviour == "guided" and not self.pers.is_px4):
            self._takeoff_alt_m = None
        if mode.behaviour == "guided" and not self.pers.is_px4:
            self.setpoint = None
            self._attitude_roll_rad = None
            self._takeoff_alt_m = None
        if mode.behaviour == "takeoff" and self._takeoff_alt_m is None:
            self._takeoff_alt_m = self._default_takeoff_alt_m()
        self._rtl_phase = 0
        self._landed_since_s = None

    def _default_takeoff_alt_m(self) -> float:
        if self.pers.is_px4:
            return self._param("MIS_TAKEOFF_ALT", 2.5)
        return self._param("TKOFF_ALT", 50.0) if self.pers.vehicle == "plane" else 2.5

    def offboard_stream_ok(self) -> bool:
        """PX4's offboard-signal check: the newest setpoint is younger than ``COM_OF_LOSS_T``.

        This is the test PX4 applies (``HealthAndArmingChecks/checks/offboardCheck.cpp``); the
        documented "stream at more than 2 Hz" follows from it together with the loss failsafe.
        """
        return self.t_s - self._last_setpoint_s < self.setpoint_timeout_s

    def landed_state(self) -> int:
        """MAV_LANDED_STATE for EXTENDED_SYS_STATE."""
        s = self.model.state
        if self.pers.vehicle == "rover":
            return MAV_LANDED_STATE_ON_GROUND
        if s.on_ground:
            climbing = self.armed and self._takeoff_alt_m is not None and self.mode.behaviour in ("takeoff", "guided")
            return MAV_LANDED_STATE_TAKEOFF if climbing else MAV_LANDED_STATE_ON_GROUND
        if self.mode.behaviour == "takeoff":
            return MAV_LANDED_STATE_TAKEOFF
        if self.mode.behaviour == "land" or (self.mode.behaviour == "rtl" and self._rtl_phase == 2):
            return MAV_LANDED_STATE_LANDING
        return MAV_LANDED_STATE_IN_AIR

    # ------------------------------------------------------------------ commands
    def arm(self, arm: bool, force: bool = False) -> int:
        """MAV_CMD_COMPONENT_ARM_DISARM. Returns a MAV_RESULT."""
        if arm:
            if self.armed:
                return MAV_RESULT_ACCEPTED
            if not force and self.mode.behaviour in ("land", "rtl", "mission"):
                return self._refuse(self._refusal, f"Arming denied: not in an armable mode ({self.mode.name})")
            self.armed = True
            self._say(SEVERITY_INFO, "Armed")
            if self.mode.behaviour not in ("takeoff", "guided"):
                self._enter_mode(self.mode)  # hold where it is now
            return MAV_RESULT_ACCEPTED
        if not self.armed:
            return MAV_RESULT_ACCEPTED
        if self.in_air and not force:
            result = MAV_RESULT_DENIED if self.pers.is_px4 else MAV_RESULT_FAILED
            return self._refuse(result, "Disarming denied: not landed")
        self.armed = False
        self._takeoff_alt_m = None
        self._say(SEVERITY_INFO, "Disarmed")
        return MAV_RESULT_ACCEPTED

    def set_mode(self, mode: Mode) -> int:
        """Switch mode (DO_SET_MODE or SET_MODE), applying the autopilot's refusal rules."""
        if mode == self.mode:
            return MAV_RESULT_ACCEPTED
        if mode.behaviour == "mission":
            return self._refuse(self._refusal, f"Mode change to {mode.name} failed: no mission")
        if mode.behaviour == "guided" and self.pers.is_px4 and not self.offboard_stream_ok():
            return self._refuse(MAV_RESULT_TEMPORARILY_REJECTED,
                                "Offboard refused: no setpoint stream")
        if mode.behaviour == "land" and self.pers.vehicle != "copter":
            return self._refuse(self._refusal, f"Mode change to {mode.name} failed")
        self._enter_mode(mode)
        self._say(SEVERITY_INFO, f"Mode {mode.name}")
        return MAV_RESULT_ACCEPTED

    def takeoff(self, altitude_param: float, home_alt_amsl_m: float) -> int:
        """MAV_CMD_NAV_TAKEOFF. ``altitude_param`` is param7: AMSL on PX4, relative on ArduPilot."""
        if self.pers.vehicle == "rover":
            return MAV_RESULT_UNSUPPORTED
        if self.pers.is_px4:
            alt = altitude_param - home_alt_amsl_m if math.isfinite(altitude_param) else self._default_takeoff_alt_m()
            if alt <= 0.0:
                return self._refuse(MAV_RESULT_DENIED, "Takeoff denied: altitude below home")
            self._takeoff_alt_m = alt
            if self.mode != self.pers.takeoff_mode:
                self._enter_mode(self.pers.takeoff_mode)
                self._takeoff_alt_m = alt
                self._say(SEVERITY_INFO, "Mode AUTO.TAKEOFF")
            return MAV_RESULT_ACCEPTED
        alt = altitude_param if math.isfinite(altitude_param) and altitude_param > 0.0 else None
        if self.pers.vehicle == "plane":
            if not self.armed:
                return self._refuse(MAV_RESULT_FAILED, "Takeoff: vehicle not armed")
            self._enter_mode(self.pers.takeoff_mode)
            self._takeoff_alt_m = alt if alt is not None else self._default_takeoff_alt_m()
            self._say(SEVERITY_INFO, "Mode TAKEOFF")
            return MAV_RESULT_ACCEPTED
        if self.mode.behaviour != "guided":
            return self._refuse(MAV_RESULT_FAILED, "Takeoff: only in GUIDED")
        if not self.armed:
            return self._refuse(MAV_RESULT_FAILED, "Takeoff: vehicle not armed")
        if self.in_air:
            return self._refuse(MAV_RESULT_FAILED, "Takeoff: already flying")
        if alt is None:
            return self._refuse(MAV_RESULT_FAILED, "Takeoff: bad altitude")
        self._takeoff_alt_m = alt
        self.setpoint = None
        return MAV_RESULT_ACCEPTED

    def land(self) -> int:
        """MAV_CMD_NAV_LAND."""
        if self.pers.land_mode is None or self.pers.vehicle != "copter":
            return MAV_RESULT_UNSUPPORTED if self.pers.vehicle == "rover" else self._refuse(
                self._refusal, "Land: needs a landing sequence")
        return self.set_mode(self.pers.land_mode)

    def return_to_launch(self) -> int:
        """MAV_CMD_NAV_RETURN_TO_LAUNCH."""
        return self.set_mode(self.pers.rtl_mode)

    def reposition(self, target_ned_m: tuple, change_mode: bool) -> int:
        """MAV_CMD_DO_REPOSITION: fly to a point (``None`` axes keep the current value).

        PX4 switches to Hold at the point (its reposition is a Hold with a new hold point);
        ArduPilot flies there in GUIDED, switching to GUIDED only when the command's
        ``MAV_DO_REPOSITION_FLAGS_CHANGE_MODE`` bit asks for it.
        """
        s = self.model.state
        target = tuple(s.pos_ned_m[i] if v is None else v for i, v in enumerate(target_ned_m))
        if self.pers.vehicle == "rover":
            target = (target[0], target[1], 0.0)
        if self.pers.is_px4:
            if self.mode != self.pers.hold_mode:
                self._enter_mode(self.pers.hold_mode)
                self._say(SEVERITY_INFO, f"Mode {self.mode.name}")
            self._hold_ned_m = target
            self._loiter_center_ned_m = (target[0], target[1])
            self._alt_target_m = -target[2]
            return MAV_RESULT_ACCEPTED
        if self.mode.behaviour != "guided":
            if not change_mode:
                return self._refuse(MAV_RESULT_FAILED, "Reposition: not in GUIDED")
            self._enter_mode(self.pers.guided_mode)
            self._say(SEVERITY_INFO, f"Mode {self.mode.name}")
        if self.pers.vehicle == "plane":
            self._attitude_roll_rad = None
            self._loiter_center_ned_m = (target[0], target[1])
            self._alt_target_m = -target[2]
            return MAV_RESULT_ACCEPTED
        self.setpoint = Setpoint(pos_ned_m=target, vel_ned_m_s=(None, None, None), acc_ned_m_s2=(None, None, None),
                                 yaw_rad=None, yaw_rate_rad_s=None, hold_ned_m=tuple(s.pos_ned_m),
                                 received_s=self.t_s, expires=False)
        return MAV_RESULT_ACCEPTED

    def refuse(self, result: int, text: str) -> int:
        """Refuse a command: queue its STATUSTEXT and return ``result``."""
        return self._refuse(result, text)

    def set_altitude_target(self, alt_m: float) -> int:
        """ArduPlane MAV_CMD_GUIDED_CHANGE_ALTITUDE: the altitude (m above home) to hold in GUIDED."""
        if self.mode.behaviour != "guided" or not math.isfinite(alt_m):
            return MAV_RESULT_FAILED
        self._alt_target_m = alt_m
        return MAV_RESULT_ACCEPTED

    def change_speed(self, speed_type: float, speed_m_s: float) -> int:
        """MAV_CMD_DO_CHANGE_SPEED / MAV_CMD_GUIDED_CHANGE_SPEED: plane airspeed or copter/rover speed limit."""
        if not math.isfinite(speed_m_s) or speed_m_s < -2.0:
            return MAV_RESULT_DENIED
        if speed_m_s <= 0.0:
            return MAV_RESULT_ACCEPTED  # -1 and 0 mean "no change"
        p = self.model.params
        if self.pers.vehicle == "plane":
            self.airspeed_target_m_s = max(p.airspeed_min_m_s, min(p.airspeed_max_m_s, speed_m_s))
        else:
            self.speed_limit_m_s = min(speed_m_s, p.v_max_m_s * 2.0)
        return MAV_RESULT_ACCEPTED

    def set_position_target(self, frame: int, type_mask: int, pos: tuple, vel: tuple, acc: tuple, yaw: float,
                            yaw_rate: float) -> str | None:
        """SET_POSITION_TARGET_LOCAL_NED. Returns None when applied, else the reason it was dropped.

        The message counts as part of the offboard stream (PX4) even when the vehicle is not in
        the guided mode, as on PX4; a target with a non-finite value in a used field is dropped.
        """
        if self.pers.vehicle == "plane" and not self.pers.is_px4:
            return "ignored_by_plane"
        if frame not in SUPPORTED_FRAMES:
            return "unsupported_frame"
        ign_pos = [bool(type_mask & b) for b in MASK_POS]
        ign_vel = [bool(type_mask & b) for b in MASK_VEL]
        ign_acc = [bool(type_mask & b) for b in MASK_ACC]
        if not self.pers.is_px4:
            # ArduPilot reads each group as a whole, ignored when any of its bits is set
            # (GCS_MAVLink_Copter.cpp / GCS_MAVLink_Rover.cpp: `bool pos_ignore = type_mask & ...`).
            ign_pos = [any(ign_pos)] * 3
            ign_vel = [any(ign_vel)] * 3
            ign_acc = [any(ign_acc)] * 3
            use_p, use_v, use_a = not ign_pos[0], not ign_vel[0], not ign_acc[0]
            if self.pers.vehicle == "rover" and use_a:
                self._say(SEVERITY_INFO, "Ignoring SET_POSITION_TARGET_LOCAL_NED; set ACC_IGNORE in mask")
                return "acc_not_ignored"
            if not ((use_p and use_v) or (use_p and not use_a) or (not use_p and (use_v or use_a))):
                if self.pers.vehicle == "copter" and self.mode.behaviour == "guided":
                    # ArduCopter's ModeGuided::init(true): brake to a stop (Rover does nothing)
                    self.setpoint = self._brake_setpoint()
                return "unsupported_type_mask"
        if self.pers.vehicle == "plane":
            # PX4 fixed-wing offboard flies to positions; it does not take velocities.
            ign_vel = [True] * 3
            ign_acc = [True] * 3
        use_yaw = not type_mask & MASK_YAW
        use_yaw_rate = not type_mask & MASK_YAW_RATE
        used = [v for v, ign in zip(pos, ign_pos) if not ign] + [v for v, ign in zip(vel, ign_vel) if not ign]
        used += [v for v, ign in zip(acc, ign_acc) if not ign]
        used += [yaw] if use_yaw else []
        used += [yaw_rate] if use_yaw_rate else []
        if not _finite(*used):
            return "bad_value"
        s = self.model.state
        body = frame in (MAV_FRAME_BODY_NED, MAV_FRAME_BODY_OFFSET_NED)
        offset = frame in (MAV_FRAME_LOCAL_OFFSET_NED, MAV_FRAME_BODY_NED, MAV_FRAME_BODY_OFFSET_NED)
        cy, sy = math.cos(s.yaw_rad), math.sin(s.yaw_rad)

        def convert(values: tuple, ignored: list[bool], is_position: bool) -> tuple:
            out = [None if ign else float(v) for v, ign in zip(values, ignored)]
            if body and (out[0] is not None or out[1] is not None):
                x, y = out[0] or 0.0, out[1] or 0.0
                rx, ry = cy * x - sy * y, sy * x + cy * y
                out[0] = rx if out[0] is not None else None
                out[1] = ry if out[1] is not None else None
            if is_position and offset:
                out = [None if v is None else v + s.pos_ned_m[i] for i, v in enumerate(out)]
            return tuple(out)

        now = self.t_s
        self._last_setpoint_s = now
        p_ned = convert(pos, ign_pos, True)
        v_ned = convert(vel, ign_vel, False)
        a_ned = convert(acc, ign_acc, False)
        expires = (not self.pers.is_px4) and all(v is None for v in p_ned)
        if (not self.pers.is_px4 and self.mode.behaviour == "guided" and self._takeoff_alt_m is not None
                and not s.on_ground):
            # ArduCopter: a target during a GUIDED take-off ends it (ModeGuided::set_velaccel and
            # set_destination switch the sub-mode from TakeOff at once); the target is flown from here.
            self._takeoff_alt_m = None
        self.setpoint = Setpoint(
            pos_ned_m=p_ned, vel_ned_m_s=v_ned, acc_ned_m_s2=a_ned,
            yaw_rad=float(yaw) if use_yaw else None, yaw_rate_rad_s=float(yaw_rate) if use_yaw_rate else None,
            hold_ned_m=self._hold_for_new_setpoint(), received_s=now, expires=expires)
        return None

    def _brake_setpoint(self) -> Setpoint:
        """ArduPilot GUIDED braking to a stop (a zero velocity target that does not expire)."""
        s = self.model.state
        return Setpoint(pos_ned_m=(None, None, None), vel_ned_m_s=(0.0, 0.0, 0.0), acc_ned_m_s2=(None, None, None),
                        yaw_rad=None, yaw_rate_rad_s=0.0, hold_ned_m=tuple(s.pos_ned_m), received_s=self.t_s,
                        expires=False)

    def _hold_for_new_setpoint(self) -> tuple[float, float, float]:
        """Hold point for axes a setpoint leaves free: the previous one's, else the current position."""
        s = self.model.state
        if self.setpoint is not None and self.mode.behaviour == "guided":
            return self.setpoint.hold_ned_m
        return (s.pos_ned_m[0], s.pos_ned_m[1], s.pos_ned_m[2])

    def set_attitude_target(self, type_mask: int, q: tuple[float, float, float, float]) -> str | None:
        """SET_ATTITUDE_TARGET: the bank angle of a plane in GUIDED (ArduPlane) or OFFBOARD (PX4)."""
        if self.pers.vehicle != "plane":
            return "ignored_by_vehicle"
        if type_mask & 128:
            return "attitude_ignored"
        if not _finite(*q) or abs(math.sqrt(sum(c * c for c in q)) - 1.0) > 0.1:
            return "bad_value"
        now = self.t_s
        self._last_setpoint_s = now
        if not self.pers.is_px4 and self.mode.behaviour != "guided":
            return "not_guided"
        self._attitude_roll_rad = roll_from_quaternion(q)
        self._attitude_s = now
        return None

    # ------------------------------------------------------------------ physics step
    def step(self, dt_s: float) -> None:
        """Apply failsafes and the current mode's behaviour, then advance the model by ``dt_s``."""
        self._failsafes()
        if self.pers.vehicle == "plane":
            self._step_plane(dt_s)
        else:
            self._step_multirotor(dt_s)
        self._after_step()

    def _failsafes(self) -> None:
        now = self.t_s
        timeout = self.setpoint_timeout_s
        if self.pers.is_px4:
            if self.mode.behaviour == "guided" and now - self._last_setpoint_s > timeout:
                self._enter_mode(self.pers.hold_mode)
                self._say(SEVERITY_CRITICAL, "Failsafe: offboard control lost, switching to Hold")
            return
        if self.mode.behaviour != "guided":
            return
        sp = self.setpoint
        if sp is not None and sp.expires and now - sp.received_s > timeout:
            # GUID_TIMEOUT: brake to a stop and stay in GUIDED.
            self.setpoint = self._brake_setpoint()
        if self._attitude_roll_rad is not None and now - self._attitude_s > timeout:
            self._attitude_roll_rad = None
            self._loiter_center_ned_m = (self.model.state.pos_ned_m[0], self.model.state.pos_ned_m[1])

    def _after_step(self) -> None:
        s = self.model.state
        behaviour = self.mode.behaviour
        alt = -s.pos_ned_m[2]
        if self._takeoff_alt_m is not None and self.armed and alt >= self._takeoff_alt_m - TAKEOFF_DONE_M:
            target = self._takeoff_alt_m
            self._takeoff_alt_m = None
            self._say(SEVERITY_INFO, "Takeoff complete")
            if behaviour == "takeoff":
                self._enter_mode(self.pers.hold_mode)
                self._alt_target_m = target
                self._hold_ned_m = (self._hold_ned_m[0], self._hold_ned_m[1], -target)
            else:  # ArduCopter GUIDED takeoff: hover at the target
                self.setpoint = Setpoint(pos_ned_m=(s.pos_ned_m[0], s.pos_ned_m[1], -target),
                                         vel_ned_m_s=(None, None, None), acc_ned_m_s2=(None, None, None),
                                         yaw_rad=None, yaw_rate_rad_s=None, hold_ned_m=tuple(s.pos_ned_m),
                                         received_s=self.t_s, expires=False)
        if self.armed and s.on_ground and (behaviour == "land" or (behaviour == "rtl" and self._rtl_phase == 2)):
            if self._landed_since_s is None:
                self._landed_since_s = self.t_s
                self._say(SEVERITY_INFO, "Landing detected")
            elif self.t_s - self._landed_since_s >= self._param("COM_DISARM_LAND", 1.0):
                self.armed = False
                self._say(SEVERITY_INFO, "Disarmed by landing")

    # ------------------------------------------------------------------ copter and rover
    def _kp_pos(self) -> float:
        """Position-loop gain: critically damped against the velocity lag, at most 1/s."""
        tau = self.model.params.tau_vel_s
        return KP_POS_MAX_1_S if tau <= 0.0 else min(KP_POS_MAX_1_S, 1.0 / (4.0 * tau))

    def _toward(self, target: tuple, speed_limit_m_s: float) -> list[float]:
        """Velocity command of the position loop toward a NED target, speed-limited."""
        s = self.model.state
        kp = self._kp_pos()
        v = [kp * (target[i] - s.pos_ned_m[i]) for i in range(3)]
        h = math.hypot(v[0], v[1])
        if h > speed_limit_m_s:
            v[0] *= speed_limit_m_s / h
            v[1] *= speed_limit_m_s / h
        p = self.model.params
        v[2] = max(-p.climb_rate_m_s, min(p.descent_rate_m_s * 2.0, v[2]))
        return v

    def _yaw_rate_to(self, yaw_target_rad: float) -> float:
        return KP_YAW_1_S * wrap_pi(yaw_target_rad - self.model.state.yaw_rad)

    def _step_multirotor(self, dt_s: float) -> None:
        s = self.model.state
        p = self.model.params
        behaviour = self.mode.behaviour
        vel = [0.0, 0.0, 0.0]
        acc_ff = (0.0, 0.0, 0.0)
        acc_ne = thrust_ne = None
        yaw_rate = 0.0
        posctl_flying, self._posctl_flying = self._posctl_flying, False
        if not self.armed:
            if s.on_ground:
                self.model.step_multirotor(dt_s, (0.0, 0.0, 0.0), 0.0, grounded=True)
                return
            vel = [0.0, 0.0, 10.0]  # motors stopped in the air: it falls
        elif self._takeoff_alt_m is not None and behaviour in ("takeoff", "guided"):
            hold = self._hold_ned_m
            vel = self._toward((hold[0], hold[1], -self._takeoff_alt_m), HOLD_SPEED_MAX_M_S)
            if s.pos_ned_m[2] > -self._takeoff_alt_m + 1.0:
                vel[2] = -p.climb_rate_m_s
            yaw_rate = self._yaw_rate_to(self._yaw_hold_rad)
        elif behaviour == "guided":
            sp = self.setpoint
            if sp is None or (not self.pers.is_px4 and s.on_ground and self.pers.vehicle == "copter"):
                vel = self._toward(self._hold_ned_m, HOLD_SPEED_MAX_M_S) if not s.on_ground else [0.0, 0.0, 0.0]
                yaw_rate = self._yaw_rate_to(self._yaw_hold_rad)
            else:
                vel, acc_ff, yaw_rate = self._follow(sp)
                if self.posctl is not None and sp.pos_ned_m[0] is None and sp.vel_ned_m_s[0] is not None:
                    # ArduCopter GUIDED velocity control: its trajectory starts where the vehicle is.
                    est = self.model.estimated_pos_ned_m()  # the controller flies on the estimate
                    pos_ne, vel_ne = (est[0], est[1]), (s.vel_ned_m_s[0], s.vel_ned_m_s[1])
                    if not posctl_flying:
                        self.posctl.reset(pos_ne, vel_ne, (s.acc_ned_m_s2[0], s.acc_ned_m_s2[1]))
                    acc_ne = self.posctl.update(dt_s, (vel[0], vel[1]), pos_ne, vel_ne, (acc_ff[0], acc_ff[1]),
                                                sp.received_s)
                    thrust_ne = self.posctl.thrust_ne_m_s2
                    self._posctl_flying = True
        elif behaviour in ("hold", "manual", "mission"):
            if s.on_ground:
                vel = [0.0, 0.0, 0.0]
            else:
                vel = self._toward(self._hold_ned_m, HOLD_SPEED_MAX_M_S)
            yaw_rate = self._yaw_rate_to(self._yaw_hold_rad)
        elif behaviour == "land":
            hold = self._hold_ned_m
            vel = self._toward((hold[0], hold[1], 0.0), HOLD_SPEED_MAX_M_S)
            vel[2] = p.descent_rate_m_s
            yaw_rate = self._yaw_rate_to(self._yaw_hold_rad)
        elif behaviour == "rtl":
            vel = self._rtl_multirotor()
        self.model.step_multirotor(dt_s, tuple(vel), yaw_rate, acc_ff, acc_ne_m_s2=acc_ne, thrust_ne_m_s2=thrust_ne)

    def _follow(self, sp: Setpoint) -> tuple[list[float], tuple, float]:
        """Velocity command, acceleration feed-forward and yaw-rate command from a guided setpoint."""
        s = self.model.state
        tau = self.model.params.tau_vel_s
        kp = self._kp_pos()
        vel = [0.0, 0.0, 0.0]
        acc_ff = [0.0, 0.0, 0.0]
        for i in range(3):
            pos_i, vel_i, acc_i = sp.pos_ned_m[i], sp.vel_ned_m_s[i], sp.acc_ned_m_s2[i]
            if pos_i is not None:
                vel[i] = kp * (pos_i - s.pos_ned_m[i]) + (vel_i or 0.0)
                acc_ff[i] = acc_i or 0.0
            elif vel_i is not None:
                vel[i] = vel_i
                acc_ff[i] = acc_i or 0.0
            elif acc_i is not None:
                vel[i] = s.vel_ned_m_s[i] + acc_i * max(tau, 1e-3)
            else:
                vel[i] = kp * (sp.hold_ned_m[i] - s.pos_ned_m[i])
        # Like the real position controllers, clamp what the setpoint asks to the vehicle's limits
        # (MPC_XY_VEL_MAX / WPNAV_SPEED horizontally, MPC_Z_VEL_MAX_UP/DN vertically).
        h = math.hypot(vel[0], vel[1])
        if h > self.speed_limit_m_s:
            vel[0] *= self.speed_limit_m_s / h
            vel[1] *= self.speed_limit_m_s / h
        vel[2] = max(-VERTICAL_SPEED_UP_MAX_M_S, min(VERTICAL_SPEED_DOWN_MAX_M_S, vel[2]))
        if sp.yaw_rad is not None:
            yaw_rate = self._yaw_rate_to(sp.yaw_rad) + (sp.yaw_rate_rad_s or 0.0)
        elif sp.yaw_rate_rad_s is not None:
            yaw_rate = sp.yaw_rate_rad_s
        elif self._look_ahead_yaw() and math.hypot(vel[0], vel[1]) > LOOK_AHEAD_MIN_SPEED_M_S:
            # ArduCopter with WP_YAW_BEHAVIOR 1 or 2 (default): no yaw in the target, so the nose
            # turns toward the direction of travel.
            self._yaw_hold_rad = math.atan2(vel[1], vel[0])
            yaw_rate = self._yaw_rate_to(self._yaw_hold_rad)
        else:
            yaw_rate = self._yaw_rate_to(self._yaw_hold_rad)
        if sp.yaw_rad is not None or sp.yaw_rate_rad_s is not None:
            self._yaw_hold_rad = s.yaw_rad
        return vel, tuple(acc_ff), yaw_rate

    def _look_ahead_yaw(self) -> bool:
        """ArduCopter's WP_YAW_BEHAVIOR: 1 (face next waypoint) or 2 (same except RTL) turn the nose."""
        if self.pers.is_px4 or self.pers.vehicle != "copter":
            return False
        return int(self._param("WP_YAW_BEHAVIOR", 0)) in (1, 2)

    def _rtl_multirotor(self) -> list[float]:
        s = self.model.state
        p = self.model.params
        home = self.home_ned_m
        if self.pers.is_px4:
            rtl_alt = self._param("RTL_RETURN_ALT", RTL_ALT_PX4_M)
        else:
            rtl_alt = self._param("RTL_ALT", RTL_ALT_ARDUPILOT_M * 100.0) / 100.0  # centimetres
        if self.pers.vehicle == "rover":
            self._rtl_phase = 1
            if math.hypot(home[0] - s.pos_ned_m[0], home[1] - s.pos_ned_m[1]) < 0.5:
                return [0.0, 0.0, 0.0]
            return self._toward((home[0], home[1], 0.0), self.speed_limit_m_s)
        if self._rtl_phase == 0:
            target_alt = max(-s.pos_ned_m[2], rtl_alt)
            self._alt_target_m = target_alt
            self._rtl_phase = 1
        if self._rtl_phase == 1:
            if -s.pos_ned_m[2] < self._alt_target_m - 1.0:
                vel = self._toward((self._hold_ned_m[0], self._hold_ned_m[1], -self._alt_target_m), HOLD_SPEED_MAX_M_S)
                vel[2] = -p.climb_rate_m_s
                return vel
            if math.hypot(home[0] - s.pos_ned_m[0], home[1] - s.pos_ned_m[1]) > 0.5:
                return self._toward((home[0], home[1], -self._alt_target_m), self.speed_limit_m_s)
            self._rtl_phase = 2
        vel = self._toward((home[0], home[1], 0.0), HOLD_SPEED_MAX_M_S)
        vel[2] = p.descent_rate_m_s
        return vel

    # ------------------------------------------------------------------ plane
    def _course_rad(self) -> float:
        v = self.model.state.vel_ned_m_s
        if math.hypot(v[0], v[1]) < 0.5:
            return self.model.state.yaw_rad
        return math.atan2(v[1], v[0])

    def _roll_toward_course(self, course_target_rad: float) -> float:
        return K_ROLL_PER_RAD * wrap_pi(course_target_rad - self._course_rad())

    def _roll_loiter(self, center_ne_m: tuple[float, float], radius_m: float = PLANE_LOITER_RADIUS_M) -> float:
        """Bank command to circle ``center`` clockwise at ``radius``."""
        s = self.model.state
        rn, re = s.pos_ned_m[0] - center_ne_m[0], s.pos_ned_m[1] - center_ne_m[1]
        d = math.hypot(rn, re)
        if d < 1e-6:
            return 0.0
        theta = math.atan2(re, rn)
        course_target = theta + 0.5 * math.pi + math.atan(2.0 * (d - radius_m) / radius_m)
        v = max(s.airspeed_m_s, self.model.params.airspeed_min_m_s)
        ff = math.atan(v * v / (GRAVITY_M_S2 * radius_m)) * max(0.0, 1.0 - abs(d - radius_m) / radius_m)
        return ff + self._roll_toward_course(course_target)

    def _climb_to(self, alt_m: float) -> float:
        alt = -self.model.state.pos_ned_m[2]
        return max(-PLANE_CLIMB_MAX_M_S, min(PLANE_CLIMB_MAX_M_S, KP_ALT_PLANE_1_S * (alt_m - alt)))

    def _step_plane(self, dt_s: float) -> None:
        s = self.model.state
        behaviour = self.mode.behaviour
        airspeed = self.airspeed_target_m_s
        roll = 0.0
        climb = 0.0
        grounded = not self.armed or (s.on_ground and behaviour != "takeoff")
        if behaviour == "takeoff" and self._takeoff_alt_m is not None:
            climb = self._climb_to(self._takeoff_alt_m + 5.0)
        elif behaviour == "hold":
            roll = self._roll_loiter(self._loiter_center_ned_m)
            climb = self._climb_to(self._alt_target_m)
        elif behaviour == "guided":
            climb = self._climb_to(self._alt_target_m)
            sp = self.setpoint
            if self._attitude_roll_rad is not None:
                roll = self._attitude_roll_rad
            elif self.pers.is_px4 and sp is not None and sp.pos_ned_m[0] is not None and sp.pos_ned_m[1] is not None:
                target = (sp.pos_ned_m[0], sp.pos_ned_m[1])
                if sp.pos_ned_m[2] is not None:
                    climb = self._climb_to(-sp.pos_ned_m[2])
                dist = math.hypot(target[0] - s.pos_ned_m[0], target[1] - s.pos_ned_m[1])
                if dist > 1.5 * PLANE_LOITER_RADIUS_M:
                    roll = self._roll_toward_course(math.atan2(target[1] - s.pos_ned_m[1], target[0] - s.pos_ned_m[0]))
                else:
                    roll = self._roll_loiter(target)
            else:
                roll = self._roll_loiter(self._loiter_center_ned_m)
        elif behaviour == "rtl":
            home = self.home_ned_m
            climb = self._climb_to(max(self._alt_target_m, RTL_ALT_PX4_M if self.pers.is_px4 else 100.0))
            dist = math.hypot(home[0] - s.pos_ned_m[0], home[1] - s.pos_ned_m[1])
            if dist > 1.5 * PLANE_LOITER_RADIUS_M:
                roll = self._roll_toward_course(math.atan2(home[1] - s.pos_ned_m[1], home[0] - s.pos_ned_m[0]))
            else:
                roll = self._roll_loiter((home[0], home[1]))
        else:  # manual: wings level, hold altitude
            climb = self._climb_to(self._alt_target_m)
        self.model.step_plane(dt_s, roll, airspeed, climb, grounded=grounded)
