"""What makes the mock look like PX4 or like ArduPilot on the wire.

A :class:`Personality` holds the HEARTBEAT identity (autopilot, vehicle type, ``base_mode`` flags),
the flight-mode table with each mode's ``custom_mode`` encoding and behaviour, the default
telemetry streams, the parameter set served over the PARAM protocol and the parameter encoding.

Mode encodings (checked against the PX4 and ArduPilot sources):

* PX4: ``custom_mode = (main_mode << 16) | (sub_mode << 24)``; main modes 1 MANUAL, 2 ALTCTL,
  3 POSCTL, 4 AUTO, 5 ACRO, 6 OFFBOARD, 7 STABILIZED; AUTO sub modes 2 TAKEOFF, 3 LOITER (Hold),
  4 MISSION, 5 RTL, 6 LAND. The same table serves copter, plane and rover.
* ArduPilot: ``custom_mode`` is the vehicle's mode number (Copter GUIDED 4, LOITER 5, RTL 6,
  LAND 9; Plane GUIDED 15, LOITER 12, RTL 11, TAKEOFF 13; Rover GUIDED 15, HOLD 4, RTL 11).

Each mode has a *behaviour* the flight logic implements: ``manual`` (no pilot input: hold still /
fly wings level), ``hold`` (hold position, or loiter for a plane), ``guided`` (follow the
companion's setpoints: PX4 OFFBOARD, ArduPilot GUIDED), ``takeoff``, ``land``, ``rtl`` and
``mission`` (refused: the mock has no mission).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

# MAVLink enum values used here (common.xml); kept local so this module needs no pymavlink.
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
MAV_TYPE = {"copter": 2, "plane": 1, "rover": 10}  # QUADROTOR, FIXED_WING, GROUND_ROVER
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_AUTO_ENABLED = 4
MAV_MODE_FLAG_GUIDED_ENABLED = 8
MAV_MODE_FLAG_STABILIZE_ENABLED = 16
MAV_MODE_FLAG_MANUAL_INPUT_ENABLED = 64
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_PARAM_TYPE_INT8 = 2
MAV_PARAM_TYPE_INT32 = 6
MAV_PARAM_TYPE_REAL32 = 9

AUTOPILOTS = ("px4", "ardupilot")
PX4_TILTMAX_AIR_DEFAULT_DEG = 45.0  # PX4's MPC_TILTMAX_AIR default

# Message ids of the telemetry the mock can stream.
MSG_SYS_STATUS = 1
MSG_SYSTEM_TIME = 2
MSG_GPS_RAW_INT = 24
MSG_ATTITUDE = 30
MSG_LOCAL_POSITION_NED = 32
MSG_GLOBAL_POSITION_INT = 33
MSG_GPS_GLOBAL_ORIGIN = 49
MSG_VFR_HUD = 74
MSG_POSITION_TARGET_LOCAL_NED = 85
MSG_AUTOPILOT_VERSION = 148
MSG_HOME_POSITION = 242
MSG_EXTENDED_SYS_STATE = 245
STREAMABLE_MSG_IDS = (MSG_SYS_STATUS, MSG_SYSTEM_TIME, MSG_GPS_RAW_INT, MSG_ATTITUDE, MSG_LOCAL_POSITION_NED,
                      MSG_GLOBAL_POSITION_INT, MSG_VFR_HUD, MSG_POSITION_TARGET_LOCAL_NED, MSG_HOME_POSITION,
                      MSG_EXTENDED_SYS_STATE)

# PX4's default rates on an onboard (offboard API) link, in Hz of simulated time.
PX4_DEFAULT_STREAMS_HZ = {
    MSG_SYS_STATUS: 2.0,
    MSG_SYSTEM_TIME: 1.0,
    MSG_GPS_RAW_INT: 2.0,
    MSG_ATTITUDE: 20.0,
    MSG_LOCAL_POSITION_NED: 30.0,
    MSG_GLOBAL_POSITION_INT: 10.0,
    MSG_VFR_HUD: 4.0,
    MSG_POSITION_TARGET_LOCAL_NED: 10.0,
    MSG_HOME_POSITION: 0.5,
    MSG_EXTENDED_SYS_STATE: 2.0,
}

# ArduPilot's REQUEST_DATA_STREAM groups (MAV_DATA_STREAM_*) and the messages of each the mock has.
ARDUPILOT_STREAM_GROUPS = {
    1: (),  # RAW_SENSORS: no raw sensors in the mock
    2: (MSG_SYS_STATUS, MSG_GPS_RAW_INT, MSG_POSITION_TARGET_LOCAL_NED),  # EXTENDED_STATUS
    3: (),  # RC_CHANNELS
    4: (),  # RAW_CONTROLLER
    6: (MSG_GLOBAL_POSITION_INT, MSG_LOCAL_POSITION_NED),  # POSITION
    10: (MSG_ATTITUDE,),  # EXTRA1
    11: (MSG_VFR_HUD,),  # EXTRA2
    12: (MSG_SYSTEM_TIME, MSG_EXTENDED_SYS_STATE, MSG_HOME_POSITION),  # EXTRA3
}


# How each autopilot's copter flies velocity + yaw-rate setpoints, identified with
# ``companion identify`` from the real firmware's identification flights (docs/vehicle_model.md):
# ArduCopter SITL (ArduPilot master, default parameters, GUIDED: first order) and PX4 v1.18 SIH
# (OFFBOARD: first order with a slow tail). The keys are those of the ``vehicle:`` block
# (``--vehicle-model``). PX4's yaw rate never saturated in its flight: 92 deg/s is the most it was
# asked for and flew, a lower bound of its limit. The velocity estimate's bias and offset and the
# position's delay are not the identification flights' but the *tune set's*: real flights of the missions
# outside the gallery (paper_far_start, survey_terrain_steps, and for PX4 qgc_inspection, flown
# with corrector and npfg), each meeting other sensor noise (a SITL replays the same noise after
# every boot), one process fitted to all of them at once (the bias *across the track*, the part
# that moves a track; companion.sim.identify.pooled_across_track_bias). PX4's estimator in SIH:
# 0.259 m/s over 9.0 s, the process whose drift, measured as the flights measure theirs, matches
# the drift of six tune flights (with corrector and predictive; companion.sim.bias_match: a direct
# fit of minute-long flights comes out short of the correlation time); its position reported with
# its velocity. ArduCopter's: a position 19 ms
# older than its velocity (companion.sim.identify.position_delay, the median of eight flights), a
# constant offset of 0.0068 m/s per axis (pooled_velocity_offset) and beside it a bias over
# 1.63 s (pooled past each flight's offset) whose level grows with the manoeuvre's jerk: 0.0066
# m/s when still, plus 0.0232 s^2 times the jerk up to 1 m/s^3 (pooled_jerk_wander; the
# gallery's flights, not used, give 0.0059 and 0.0261), flown through a 0.7 s low-pass with
# both levels scaled by 1.29 (0.0085 and 0.0300): the smoothing and factor that give back the
# fast part and the 1-s changes of four later tune flights' drift (pooled_bias_smoothing).
# PX4's flights were not fitted for an
# offset: none. The mock flies the bias and the offset on both axes. The gallery's flights,
# which the mock is judged on, were not used to set them (docs/vehicle_model.md).
VEHICLE_MODEL_KEYS = ("a_max_m_s2", "delay_s", "lag_s", "accel_lag_s", "tail_share", "tail_tc_s", "speed_sag_s",
                      "yaw_rate_max_deg_s", "vel_bias_m_s", "vel_bias_tc_s", "vel_bias_jerk_s2",
                      "vel_bias_jerk_max_m_s3", "vel_bias_smooth_s", "vel_bias_loop_s", "vel_offset_m_s", "pos_delay_s",
                      "accel_ff_gain", "accel_ff_lag_s")
IDENTIFIED_COPTER_MODELS = {
    "ardupilot": {"a_max_m_s2": 2.43, "delay_s": 0.173, "lag_s": 0.457, "accel_lag_s": 0.0, "tail_share": 0.0,
                  "tail_tc_s": 1.0, "speed_sag_s": 0.049, "yaw_rate_max_deg_s": 60.6,
                  "vel_bias_m_s": 0.0085, "vel_bias_tc_s": 1.63, "vel_bias_jerk_s2": 0.0300,
                  "vel_bias_jerk_max_m_s3": 1.0, "vel_bias_smooth_s": 0.7, "vel_bias_loop_s": 0.0,
                  "vel_offset_m_s": 0.0068, "pos_delay_s": 0.019, "accel_ff_gain": 1.0, "accel_ff_lag_s": 0.0},
    "px4": {"a_max_m_s2": 3.86, "delay_s": 0.119, "lag_s": 0.437, "accel_lag_s": 0.0, "tail_share": 0.857,
            "tail_tc_s": 0.958, "speed_sag_s": 0.093, "yaw_rate_max_deg_s": 92.3,
            "vel_bias_m_s": 0.259, "vel_bias_tc_s": 9.0, "vel_bias_jerk_s2": 0.0, "vel_bias_jerk_max_m_s3": 1.0,
            "vel_bias_smooth_s": 0.0, "vel_bias_loop_s": 0.0,
            "vel_offset_m_s": 0.0, "pos_delay_s": 0.0, "accel_ff_gain": 1.31, "accel_ff_lag_s": 0.166},
}


@dataclass(frozen=True)
class Mode:
    """One flight mode: its name as ground stations show it, its wire encoding and its behaviour."""

    name: str
    custom_mode: int
    behaviour: str


def px4_custom_mode(main_mode: int, sub_mode: int = 0) -> int:
    """PX4's ``custom_mode`` for a main and sub mode."""
    return (main_mode << 16) | (sub_mode << 24)


_PX4_MODES = (
    Mode("MANUAL", px4_custom_mode(1), "manual"),
    Mode("ALTCTL", px4_custom_mode(2), "manual"),
    Mode("POSCTL", px4_custom_mode(3), "hold"),
    Mode("AUTO.TAKEOFF", px4_custom_mode(4, 2), "takeoff"),
    Mode("AUTO.LOITER", px4_custom_mode(4, 3), "hold"),
    Mode("AUTO.MISSION", px4_custom_mode(4, 4), "mission"),
    Mode("AUTO.RTL", px4_custom_mode(4, 5), "rtl"),
    Mode("AUTO.LAND", px4_custom_mode(4, 6), "land"),
    Mode("ACRO", px4_custom_mode(5), "manual"),
    Mode("OFFBOARD", px4_custom_mode(6), "guided"),
    Mode("STABILIZED", px4_custom_mode(7), "manual"),
)

_ARDUPILOT_MODES = {
    "copter": (
        Mode("STABILIZE", 0, "manual"), Mode("ACRO", 1, "manual"), Mode("ALT_HOLD", 2, "manual"),
        Mode("AUTO", 3, "mission"), Mode("GUIDED", 4, "guided"), Mode("LOITER", 5, "hold"),
        Mode("RTL", 6, "rtl"), Mode("CIRCLE", 7, "hold"), Mode("LAND", 9, "land"),
        Mode("POSHOLD", 16, "hold"), Mode("BRAKE", 17, "hold"),
    ),
    "plane": (
        Mode("MANUAL", 0, "manual"), Mode("CIRCLE", 1, "hold"), Mode("STABILIZE", 2, "manual"),
        Mode("FBWA", 5, "manual"), Mode("FBWB", 6, "manual"), Mode("CRUISE", 7, "manual"),
        Mode("AUTO", 10, "mission"), Mode("RTL", 11, "rtl"), Mode("LOITER", 12, "hold"),
        Mode("TAKEOFF", 13, "takeoff"), Mode("GUIDED", 15, "guided"),
    ),
    "rover": (
        Mode("MANUAL", 0, "manual"), Mode("ACRO", 1, "manual"), Mode("STEERING", 3, "manual"),
        Mode("HOLD", 4, "hold"), Mode("LOITER", 5, "hold"), Mode("AUTO", 10, "mission"),
        Mode("RTL", 11, "rtl"), Mode("SMART_RTL", 12, "rtl"), Mode("GUIDED", 15, "guided"),
    ),
}

# Mode names per (autopilot, vehicle): at boot on the ground, when starting airborne (hold), guided.
_BOOT_MODE = {"px4": "AUTO.LOITER", "copter": "STABILIZE", "plane": "MANUAL", "rover": "MANUAL"}
_HOLD_MODE = {"px4": "AUTO.LOITER", "copter": "LOITER", "plane": "LOITER", "rover": "HOLD"}


@dataclass(frozen=True)
class Param:
    """One parameter: its value and MAV_PARAM_TYPE."""

    value: float
    param_type: int


class Personality:
    """Identity, modes, streams and parameters of one autopilot and vehicle kind.

    Parameters
    ----------
    autopilot : str
        ``"px4"`` or ``"ardupilot"``.
    vehicle : str
        ``"copter"``, ``"plane"`` or ``"rover"``.
    """

    def __init__(self, autopilot: str, vehicle: str) -> None:
        if autopilot not in AUTOPILOTS:
            raise ValueError(f"autopilot: expected one of {', '.join(AUTOPILOTS)}, got {autopilot!r}")
        if vehicle not in MAV_TYPE:
            raise ValueError(f"vehicle: expected one of {', '.join(MAV_TYPE)}, got {vehicle!r}")
        self.autopilot = autopilot
        self.vehicle = vehicle
        self.is_px4 = autopilot == "px4"
        self.mav_autopilot = MAV_AUTOPILOT_PX4 if self.is_px4 else MAV_AUTOPILOT_ARDUPILOTMEGA
        self.mav_type = MAV_TYPE[vehicle]
        self.modes = _PX4_MODES if self.is_px4 else _ARDUPILOT_MODES[vehicle]
        self._by_name = {m.name: m for m in self.modes}
        self._by_custom = {m.custom_mode: m for m in self.modes}
        self.boot_mode = self._by_name[_BOOT_MODE["px4" if self.is_px4 else vehicle]]
        self.hold_mode = self._by_name[_HOLD_MODE["px4" if self.is_px4 else vehicle]]
        self.guided_mode = self._by_name["OFFBOARD" if self.is_px4 else "GUIDED"]
        self.land_mode = self.mode_for_behaviour("land")
        self.rtl_mode = self.mode_for_behaviour("rtl")
        self.takeoff_mode = self.mode_for_behaviour("takeoff")
        self.streams_by_default = self.is_px4
        # The vehicle model a copter flies unless told otherwise (None: the generic model).
        self.default_vehicle_model = dict(IDENTIFIED_COPTER_MODELS[autopilot]) if vehicle == "copter" else None

    def mode_named(self, name: str) -> Mode | None:
        """The mode with this name, or None."""
        return self._by_name.get(name)

    def mode_for_custom(self, custom_mode: int) -> Mode | None:
        """Decode a ``custom_mode`` value (HEARTBEAT, SET_MODE) into a mode, or None if unknown."""
        return self._by_custom.get(int(custom_mode))

    def mode_for_behaviour(self, behaviour: str) -> Mode | None:
        """The first mode with this behaviour, or None (e.g. no takeoff mode on ArduCopter or a rover)."""
        for mode in self.modes:
            if mode.behaviour == behaviour:
                return mode
        return None

    def mode_from_do_set_mode(self, p1: float, p2: float, p3: float) -> Mode | None:
        """Decode MAV_CMD_DO_SET_MODE parameters (base mode, custom/main mode, sub mode), or None."""
        if not all(math.isfinite(v) for v in (p1, p2)):
            return None
        if not int(p1) & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return None
        if self.is_px4:
            sub = int(p3) if math.isfinite(p3) else 0
            main = int(p2)
            if main == 4 and sub == 0:
                sub = 3  # AUTO without a sub mode: PX4 enters Hold
            return self.mode_for_custom(px4_custom_mode(main, sub if main == 4 else 0))
        return self.mode_for_custom(int(p2))

    def base_mode(self, mode: Mode, armed: bool) -> int:
        """HEARTBEAT ``base_mode`` flags for a mode, as the real autopilot sets them."""
        flags = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if armed:
            flags |= MAV_MODE_FLAG_SAFETY_ARMED
        if mode.behaviour == "manual":
            flags |= MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | MAV_MODE_FLAG_STABILIZE_ENABLED
        else:
            flags |= MAV_MODE_FLAG_STABILIZE_ENABLED
            if mode.behaviour in ("guided", "takeoff", "land", "rtl", "mission", "hold"):
                flags |= MAV_MODE_FLAG_GUIDED_ENABLED
            if mode.behaviour in ("takeoff", "land", "rtl", "mission") or (self.is_px4 and mode.name.startswith("AUTO")):
                flags |= MAV_MODE_FLAG_AUTO_ENABLED
            if self.is_px4 and mode.name == "POSCTL":
                flags = (flags | MAV_MODE_FLAG_MANUAL_INPUT_ENABLED) & ~MAV_MODE_FLAG_GUIDED_ENABLED
        return flags

    # ------------------------------------------------------------------ parameters
    def default_params(self, sysid: int, offboard_loss_s: float, guided_timeout_s: float, a_max_m_s2: float,
                       yaw_rate_max_deg_s: float, v_max_m_s: float, airspeed_m_s: tuple[float, float, float],
                       roll_max_deg: float) -> dict[str, Param]:
        """A small realistic parameter set, in the order PARAM_REQUEST_LIST serves it.

        Some of these drive the mock: ``COM_OF_LOSS_T`` (PX4) and ``GUID_TIMEOUT`` /
        ``GUIDED_TIMEOUT`` (ArduPilot) set the setpoint-loss times, and a PARAM_SET changes them.
        """
        f, i32, i8 = MAV_PARAM_TYPE_REAL32, MAV_PARAM_TYPE_INT32, MAV_PARAM_TYPE_INT8
        cruise, as_min, as_max = airspeed_m_s
        if self.is_px4:
            params = {
                "MAV_SYS_ID": Param(sysid, i32),
                "SYS_AUTOSTART": Param({"copter": 10016, "plane": 17000, "rover": 50000}[self.vehicle], i32),
                "COM_OF_LOSS_T": Param(offboard_loss_s, f),
                "COM_OBL_RC_ACT": Param(5, i32),  # 5: Hold
                "COM_DISARM_LAND": Param(2.0, f),
                "MIS_TAKEOFF_ALT": Param(2.5, f),
                "RTL_RETURN_ALT": Param(30.0, f),
                "NAV_ACC_RAD": Param(10.0, f),
                "MPC_XY_VEL_MAX": Param(v_max_m_s, f),
                "MPC_Z_VEL_MAX_UP": Param(3.0, f),
                "MPC_ACC_HOR_MAX": Param(a_max_m_s2, f),
                # OFFBOARD velocity control is bounded only by the tilt limit, a <= g tan(tilt); the
                # firmware's 45 deg (9.8 m/s^2) is well above what the SIH quadrotor flies at 5 m/s,
                # so the mock publishes it unless its own vehicle is faster than that.
                "MPC_TILTMAX_AIR": Param(max(PX4_TILTMAX_AIR_DEFAULT_DEG,
                                             math.degrees(math.atan(a_max_m_s2 / 9.80665))), f),
                "MPC_YAWRAUTO_MAX": Param(yaw_rate_max_deg_s, f),
            }
            if self.vehicle == "plane":
                params.update({"FW_AIRSPD_TRIM": Param(cruise, f), "FW_AIRSPD_MIN": Param(as_min, f),
                               "FW_AIRSPD_MAX": Param(as_max, f), "FW_R_LIM": Param(roll_max_deg, f)})
            return params
        params = {"SYSID_THISMAV": Param(sysid, i8), "ARMING_CHECK": Param(1, i32), "FS_GCS_ENABLE": Param(0, i8)}
        if self.vehicle == "copter":
            params.update({
                "FRAME_CLASS": Param(1, i8),
                "GUID_TIMEOUT": Param(guided_timeout_s, f),
                "WPNAV_SPEED": Param(v_max_m_s * 100.0, f),
                "WPNAV_ACCEL": Param(a_max_m_s2 * 100.0, f),
                "PILOT_SPEED_UP": Param(250.0, f),
                "LAND_SPEED": Param(50.0, f),
                "RTL_ALT": Param(1500.0, f),
                "ATC_RATE_Y_MAX": Param(yaw_rate_max_deg_s, f),
                "WP_YAW_BEHAVIOR": Param(2, i8),  # 2: face the direction of travel, except in RTL
            })
        elif self.vehicle == "plane":
            params.update({
                "GUIDED_TIMEOUT": Param(guided_timeout_s, f),
                "AIRSPEED_CRUISE": Param(cruise, f),
                "AIRSPEED_MIN": Param(as_min, f),
                "AIRSPEED_MAX": Param(as_max, f),
                "ROLL_LIMIT_DEG": Param(roll_max_deg, f),
                "TKOFF_ALT": Param(50.0, f),
                "WP_LOITER_RAD": Param(60.0, f),
            })
        else:
            params.update({
                "GUID_TIMEOUT": Param(guided_timeout_s, f),
                "CRUISE_SPEED": Param(v_max_m_s, f),
                "ATC_ACCEL_MAX": Param(a_max_m_s2, f),
                "WP_SPEED": Param(v_max_m_s, f),
            })
        return params

    @property
    def offboard_timeout_param(self) -> str:
        """Name of the parameter holding the setpoint-loss time."""
        if self.is_px4:
            return "COM_OF_LOSS_T"
        return "GUIDED_TIMEOUT" if self.vehicle == "plane" else "GUID_TIMEOUT"

    def encode_param_value(self, param: Param) -> float:
        """The float sent in PARAM_VALUE.

        PX4 sends integer parameters bytewise (the int32's bytes reinterpreted as a float32);
        ArduPilot sends every value cast to float.
        """
        if self.is_px4 and param.param_type != MAV_PARAM_TYPE_REAL32:
            return struct.unpack("<f", struct.pack("<i", int(param.value)))[0]
        return float(param.value)

    def decode_param_value(self, value: float, param_type: int) -> float:
        """Inverse of :meth:`encode_param_value` for a PARAM_SET."""
        if self.is_px4 and param_type != MAV_PARAM_TYPE_REAL32:
            return float(struct.unpack("<i", struct.pack("<f", value))[0])
        if param_type != MAV_PARAM_TYPE_REAL32:
            return float(round(value))
        return float(value)
