"""The mock autopilot: MAVLink message handling, telemetry streams and the fixed-step run loop.

:class:`MockAutopilot` owns the links, the flight logic and the vehicle model. Its run loop
advances simulated time in fixed physics steps paced against the wall clock divided by
``speedup``; after every step it sends the telemetry that is due (rates are in simulated time,
``time_boot_ms`` is simulated time), and between steps it waits on the sockets and handles what
arrives. Incoming messages act at the simulated time they are read.
"""

from __future__ import annotations

import math
import select
import sys
import threading
import time
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl_mock import flight as fl
from sitl_mock.flight import FlightLogic
from sitl_mock.links import DROP_REASONS, Link, LinkSpec, RxCounters, Tlog
from sitl_mock.personality import (
    ARDUPILOT_STREAM_GROUPS, MSG_ATTITUDE, MSG_AUTOPILOT_VERSION, MSG_EXTENDED_SYS_STATE, MSG_GLOBAL_POSITION_INT,
    MSG_GPS_GLOBAL_ORIGIN, MSG_GPS_RAW_INT, MSG_HOME_POSITION, MSG_LOCAL_POSITION_NED, MSG_POSITION_TARGET_LOCAL_NED, MSG_SYS_STATUS,
    MSG_SYSTEM_TIME, MSG_VFR_HUD, PX4_DEFAULT_STREAMS_HZ, STREAMABLE_MSG_IDS, Personality,
)
from sitl_mock.posctl import PosControlParams
from sitl_mock.vehicle import VehicleModel, VehicleParams

EARTH_RADIUS_M = 6378137.0
MSG_STATUSTEXT = mavlink.MAVLINK_MSG_ID_STATUSTEXT
HEARTBEAT_INTERVAL_S = 1.0
MAX_STREAM_HZ = 400.0
DEFAULT_ORIGIN = {"px4": (47.397742, 8.545594, 488.0), "ardupilot": (-35.363262, 149.165237, 584.0)}
MAV_STATE_STANDBY = 3
MAV_STATE_ACTIVE = 4
MAV_FRAME_LOCAL_NED = 1

# SYS_STATUS sensor bits: gyro, accel, mag, baro, GPS, angular rate, attitude, yaw, altitude, xy
# position, motor outputs, AHRS, pre-arm checks passed.
SENSORS_PRESENT = (0x1 | 0x2 | 0x4 | 0x8 | 0x20 | 0x400 | 0x800 | 0x1000 | 0x2000 | 0x4000 | 0x8000
                   | 0x200000 | 0x10000000)
# ArduPilot reports the geofence healthy (not breached) even when no fence is enabled.
SENSORS_HEALTH = SENSORS_PRESENT | 0x100000
# MAVLink FTP (FILE_TRANSFER_PROTOCOL payload) opcodes and errors the mock answers with.
FTP_OP_TERMINATE_SESSION = 1
FTP_OP_RESET_SESSIONS = 2
FTP_OP_ACK = 128
FTP_OP_NAK = 129
FTP_ERR_FAIL = 1
FTP_ERR_FILE_NOT_FOUND = 10
# AUTOPILOT_VERSION capabilities: PARAM_FLOAT, COMMAND_INT, SET_ATTITUDE_TARGET,
# SET_POSITION_TARGET_LOCAL_NED, MAVLINK2.
CAPABILITIES = 0x2 | 0x8 | 0x40 | 0x80 | 0x2000

@dataclass(frozen=True)
class MockConfig:
    """Everything the command line sets. Validated on construction (ValueError, one line)."""

    autopilot: str = "px4"
    vehicle: str = "copter"
    links: tuple[LinkSpec, ...] = ()
    sysid: int = 1
    compid: int = 1
    speedup: float = 1.0
    physics_hz: float = 400.0
    seed: int = 0
    start_ned_m: tuple[float, float] = (0.0, 0.0)
    start_alt_m: float = 0.0
    start_yaw_deg: float = 0.0
    start_airborne: bool = False
    origin: tuple[float, float, float] | None = None
    ekf_origin: bool = True  # False: the estimator has no global origin (no GPS): no GPS_GLOBAL_ORIGIN
    pace_lead_s: float | None = None  # wait for a setpoint client lagging more than this (simulated s)
    vehicle_params: VehicleParams = field(default_factory=VehicleParams)
    posctl: PosControlParams | None = None  # ArduCopter's position controller flies GUIDED velocity targets
    offboard_loss_s: float = 0.5
    guided_timeout_s: float = 3.0
    signing_key: bytes | None = None
    tlog_path: str | None = None
    duration_s: float | None = None
    quiet: bool = False

    def __post_init__(self) -> None:
        if not self.links:
            raise ValueError("--link: expected at least one link")
        if not (1 <= self.sysid <= 255 and 0 <= self.compid <= 255):
            raise ValueError("--sysid/--compid: expected 1..255 and 0..255")
        for name in ("speedup", "physics_hz", "offboard_loss_s", "guided_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"--{name.replace('_', '-')}: expected a positive number, got {value}")
        if self.physics_hz < 50:
            raise ValueError(f"--physics-hz: expected at least 50, got {self.physics_hz}")
        if self.start_alt_m < 0 or (self.start_airborne and self.vehicle != "rover" and self.start_alt_m <= 0):
            raise ValueError("--start-alt-m: expected >= 0, and > 0 with --start-airborne")
        if self.duration_s is not None and not self.duration_s > 0:
            raise ValueError("--duration-s: expected a positive number")
        if self.origin is not None:
            lat, lon, _ = self.origin
            if not (-90 < lat < 90 and -180 <= lon <= 180):
                raise ValueError(f"--origin: latitude/longitude out of range: {self.origin}")
        if self.signing_key is not None and len(self.signing_key) != 32:
            raise ValueError("signing key: expected 32 bytes")
        if self.posctl is not None and (self.autopilot, self.vehicle) != ("ardupilot", "copter"):
            raise ValueError("ArduCopter's position controller: only the ardupilot copter personality has it")
        if self.pace_lead_s is not None and not (math.isfinite(self.pace_lead_s) and self.pace_lead_s > 0):
            raise ValueError(f"--pace-lead-s: expected a positive number, got {self.pace_lead_s}")


class MockAutopilot:
    """A mock PX4 or ArduPilot autopilot on one or more UDP links.

    Parameters
    ----------
    config : MockConfig
        The command-line configuration.
    out, err : text streams
        Where the ready line and the log / summary lines go.

    Raises
    ------
    ValueError
        If a link cannot be opened or the tlog cannot be created (reported before flight).
    """

    def __init__(self, config: MockConfig, out=None, err=None) -> None:
        self.config = config
        self.out = out or sys.stdout
        self.err = err or sys.stderr
        self.pers = Personality(config.autopilot, config.vehicle)
        self.origin = config.origin or DEFAULT_ORIGIN[config.autopilot]
        self.counters = RxCounters()
        self.stop_event = threading.Event()
        # Set by signal handlers: a plain bool, because Event.set() takes a lock, and a second signal
        # arriving while the first handler holds it would deadlock the main thread on itself.
        self.stop_requested = False
        self.dt_s = 1.0 / config.physics_hz
        self.sim_t_s = 0.0
        self.steps = 0
        self.overruns = 0
        self._start_unix_s = time.time()
        self.tlog = Tlog(config.tlog_path) if config.tlog_path else None
        self.links: list[Link] = []
        try:
            for index, spec in enumerate(config.links):
                self.links.append(Link(spec, index, config.sysid, config.compid, config.signing_key, self.counters,
                                       self.tlog, self._tlog_clock))
        except ValueError:
            self.close()
            raise
        start = (config.start_ned_m[0], config.start_ned_m[1], -config.start_alt_m)
        vp = config.vehicle_params
        self.model = VehicleModel(vp, start, math.radians(config.start_yaw_deg), config.start_airborne)
        # With ArduCopter's position controller, WPNAV_ACCEL is the limit its trajectory keeps to.
        a_max_param = config.posctl.accel_max_m_s2 if config.posctl is not None else vp.a_max_m_s2
        self.params = self.pers.default_params(
            config.sysid, config.offboard_loss_s, config.guided_timeout_s, a_max_param,
            math.degrees(vp.yaw_rate_max_rad_s), vp.v_max_m_s,
            (vp.airspeed_cruise_m_s, vp.airspeed_min_m_s, vp.airspeed_max_m_s), math.degrees(vp.roll_max_rad))
        self.home_ned_m = (config.start_ned_m[0], config.start_ned_m[1], 0.0)
        self.flight = FlightLogic(self.pers, self.model, self.params, config.start_airborne, self.home_ned_m,
                                  config.posctl)
        self._heartbeat_next_s = 0.0
        for link in self.links:
            if self.pers.streams_by_default:
                for msgid, hz in PX4_DEFAULT_STREAMS_HZ.items():
                    self._set_stream(link, msgid, 1.0 / hz)
        self._last_mode_name = self.flight.mode.name
        self._last_armed = self.flight.armed
        # PX4's GPS_GLOBAL_ORIGIN stream and ArduPilot's EKF both announce the origin once, when the
        # estimator sets it (here: the first physics step); afterwards only on request.
        self._origin_announced = False
        # --pace-lead-s: the newest time_boot_ms a setpoint carried (the client's view of our
        # clock, seconds) and the wall time it arrived.
        self._client_time_s = -math.inf
        self._client_wall_s = -math.inf
        self._time_told_wall_s = -math.inf  # when SYSTEM_TIME was last sent to a waiting client

    # ------------------------------------------------------------------ time
    def _tlog_clock(self) -> float:
        """tlog timestamps: the start's UNIX time plus simulated time, consistent with time_boot_ms."""
        return self._start_unix_s + self.sim_t_s

    @property
    def time_boot_ms(self) -> int:
        return int(self.sim_t_s * 1000.0) & 0xFFFFFFFF

    def log(self, text: str) -> None:
        if not self.config.quiet:
            print(f"sitl_mock: {text}", file=self.err, flush=True)

    # ------------------------------------------------------------------ streams
    def _set_stream(self, link: Link, msgid: int, interval_s: float | None) -> None:
        if interval_s is None:
            link.stream_interval_s.pop(msgid, None)
            link.stream_next_s.pop(msgid, None)
            return
        # A message goes out at most once per physics step (and at most 400 Hz).
        interval_s = max(interval_s, 1.0 / MAX_STREAM_HZ, self.dt_s)
        link.stream_interval_s[msgid] = interval_s
        link.stream_next_s[msgid] = self.sim_t_s

    def _default_interval_s(self, msgid: int) -> float | None:
        if self.pers.streams_by_default and msgid in PX4_DEFAULT_STREAMS_HZ:
            return 1.0 / PX4_DEFAULT_STREAMS_HZ[msgid]
        return None

    def _service_streams(self) -> None:
        t = self.sim_t_s
        if t >= self._heartbeat_next_s:
            self._heartbeat_next_s += HEARTBEAT_INTERVAL_S
            hb = self._build(0)
            for link in self.links:
                link.send(hb)
        if not self._origin_announced:
            # After the first heartbeat: a peer pairs (and pins the address) on a heartbeat.
            self._origin_announced = True
            origin = self._build(MSG_GPS_GLOBAL_ORIGIN)
            if origin is not None:
                for link in self.links:
                    link.send(origin)
        cache: dict[int, object] = {}
        for link in self.links:
            for msgid, due in link.stream_next_s.items():
                if t + 1e-9 < due:
                    continue
                interval = link.stream_interval_s[msgid]
                nxt = due + interval
                link.stream_next_s[msgid] = nxt if nxt > t else t + interval
                if msgid not in cache:
                    cache[msgid] = self._build(msgid)
                msg = cache[msgid]
                if msg is not None:
                    link.send(msg)

    def _build(self, msgid: int):
        """Build the current instance of a telemetry message (None if there is nothing to say)."""
        mav = self.links[0].mav
        s = self.model.state
        f = self.flight
        ms = self.time_boot_ms
        if msgid == 0:
            return mav.heartbeat_encode(self.pers.mav_type, self.pers.mav_autopilot,
                                        self.pers.base_mode(f.mode, f.armed), f.mode.custom_mode,
                                        MAV_STATE_ACTIVE if f.armed else MAV_STATE_STANDBY, 3)
        if msgid == MSG_LOCAL_POSITION_NED:
            x, y, z = self.model.measured_pos_ned_m()
            v = self.model.reported_vel_ned_m_s()
            return mav.local_position_ned_encode(ms, x, y, z, v[0], v[1], v[2])
        if msgid == MSG_ATTITUDE:
            return mav.attitude_encode(ms, s.roll_rad, s.pitch_rad, s.yaw_rad, 0.0, 0.0, s.yaw_rate_rad_s)
        if msgid == MSG_GLOBAL_POSITION_INT:
            lat, lon, alt = self.geodetic(self.model.measured_pos_ned_m())
            v = self.model.reported_vel_ned_m_s()
            hdg = int(round(math.degrees(s.yaw_rad) * 100.0)) % 36000
            return mav.global_position_int_encode(ms, lat, lon, int(alt * 1000), int(-s.pos_ned_m[2] * 1000),
                                                  int(v[0] * 100), int(v[1] * 100), int(v[2] * 100), hdg)
        if msgid == MSG_SYS_STATUS:
            return mav.sys_status_encode(SENSORS_PRESENT, SENSORS_PRESENT, SENSORS_HEALTH, 250, 12600, 500, 90,
                                         0, 0, 0, 0, 0, 0)
        if msgid == MSG_GPS_RAW_INT:
            lat, lon, alt = self.geodetic(self.model.measured_pos_ned_m())
            v = s.vel_ned_m_s
            cog = int(round(math.degrees(math.atan2(v[1], v[0])) * 100.0)) % 36000
            return mav.gps_raw_int_encode(int(self.sim_t_s * 1e6), 3, lat, lon, int(alt * 1000), 80, 120,
                                          int(math.hypot(v[0], v[1]) * 100), cog, 12)
        if msgid == MSG_VFR_HUD:
            v = s.vel_ned_m_s
            alt = self.origin[2] - s.pos_ned_m[2]
            throttle = 0 if not f.armed else 50
            return mav.vfr_hud_encode(s.airspeed_m_s, math.hypot(v[0], v[1]),
                                      int(round(math.degrees(s.yaw_rad))) % 360, throttle, alt, -v[2])
        if msgid == MSG_EXTENDED_SYS_STATE:
            return mav.extended_sys_state_encode(0, f.landed_state())
        if msgid == MSG_HOME_POSITION:
            lat, lon, alt = self.geodetic(self.home_ned_m)
            h = self.home_ned_m
            return mav.home_position_encode(lat, lon, int(alt * 1000), h[0], h[1], h[2], [1.0, 0.0, 0.0, 0.0],
                                            0.0, 0.0, 0.0, int(self.sim_t_s * 1e6))
        if msgid == MSG_GPS_GLOBAL_ORIGIN:
            if not self.config.ekf_origin:
                return None
            lat0, lon0, alt0 = self.origin
            # time_usec: time since boot of the origin's setting (as PX4 sends it).
            return mav.gps_global_origin_encode(int(round(lat0 * 1e7)), int(round(lon0 * 1e7)),
                                                int(round(alt0 * 1000)), 0)
        if msgid == MSG_SYSTEM_TIME:
            return mav.system_time_encode(int(self._tlog_clock() * 1e6), ms)
        if msgid == MSG_POSITION_TARGET_LOCAL_NED:
            sp = f.setpoint
            if sp is None or f.mode.behaviour != "guided":
                return None
            z = [0.0 if v is None else v for v in sp.pos_ned_m]
            vv = [0.0 if v is None else v for v in sp.vel_ned_m_s]
            a = [0.0 if v is None else v for v in sp.acc_ned_m_s2]
            return mav.position_target_local_ned_encode(ms, MAV_FRAME_LOCAL_NED, sp.type_mask(), *z, *vv, *a,
                                                        sp.yaw_rad or 0.0, sp.yaw_rate_rad_s or 0.0)
        if msgid == MSG_AUTOPILOT_VERSION:
            if self.pers.is_px4:
                version = (1 << 24) | (15 << 16) | (0 << 8) | 255
            else:
                version = (4 << 24) | (5 << 16) | (7 << 8) | 255
            uid = 0x5173_4D4F_434B_0000 | self.config.sysid
            return mav.autopilot_version_encode(CAPABILITIES, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                                                0, 0, uid)
        return None

    def geodetic(self, pos_ned_m) -> tuple[int, int, float]:
        """Latitude, longitude (degE7) and altitude AMSL (m) of a local NED point (flat earth at the origin)."""
        lat0, lon0, alt0 = self.origin
        lat = lat0 + math.degrees(pos_ned_m[0] / EARTH_RADIUS_M)
        lon = lon0 + math.degrees(pos_ned_m[1] / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
        return int(round(lat * 1e7)), int(round(lon * 1e7)), alt0 - pos_ned_m[2]

    def local_from_geodetic(self, lat_deg: float, lon_deg: float, alt_amsl_m: float) -> tuple[float, float, float]:
        """Inverse of :meth:`geodetic`: local NED metres of a geodetic point."""
        lat0, lon0, alt0 = self.origin
        north = math.radians(lat_deg - lat0) * EARTH_RADIUS_M
        east = math.radians(lon_deg - lon0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
        return north, east, alt0 - alt_amsl_m

    def _reposition(self, p: tuple, int_frame: int | None) -> int:
        """MAV_CMD_DO_REPOSITION: p5/x latitude, p6/y longitude (degE7 in COMMAND_INT), p7/z altitude.

        The altitude is AMSL, or relative to home in the GLOBAL_RELATIVE_ALT frames of COMMAND_INT;
        NaN (COMMAND_LONG) or 0 / INT32_MAX (COMMAND_INT) leaves an axis where it is.
        """
        lat, lon, alt = p[4], p[5], p[6]
        if int_frame is not None:
            lat = lat * 1e-7 if lat not in (0.0, 2**31 - 1) else math.nan
            lon = lon * 1e-7 if lon not in (0.0, 2**31 - 1) else math.nan
            if int_frame in (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) \
                    and math.isfinite(alt):  # home is at the origin
                alt += self.origin[2]
        north, east, down = self.local_from_geodetic(lat if math.isfinite(lat) else self.origin[0],
                                                     lon if math.isfinite(lon) else self.origin[1],
                                                     alt if math.isfinite(alt) else self.origin[2])
        target = (north if math.isfinite(lat) else None, east if math.isfinite(lon) else None,
                  down if math.isfinite(alt) else None)
        if (target[0] is None) != (target[1] is None) or abs(lat) > 90.0 or abs(lon) > 180.0:
            return fl.MAV_RESULT_DENIED
        change_mode = math.isfinite(p[1]) and int(p[1]) & 1
        return self.flight.reposition(target, bool(change_mode))

    # ------------------------------------------------------------------ sending helpers
    def _statustext(self, severity: int, text: str, links: list[Link] | None = None) -> None:
        msg = self.links[0].mav.statustext_encode(severity, text.encode("ascii", "replace")[:50])
        for link in links or self.links:
            link.send(msg)

    def _ack(self, link: Link, command: int, result: int, src) -> None:
        msg = link.mav.command_ack_encode(command, result, 0, 0, src[0], src[1])
        link.send(msg)

    def _flush_events(self) -> None:
        f = self.flight
        for severity, text in f.events:
            self._statustext(severity, text)
            self.log(text)
        f.events.clear()
        if f.mode.name != self._last_mode_name or f.armed != self._last_armed:
            self._last_mode_name = f.mode.name
            self._last_armed = f.armed
            # A real autopilot announces a mode change at once with an extra HEARTBEAT.
            hb = self._build(0)
            for link in self.links:
                link.send(hb)

    # ------------------------------------------------------------------ receiving
    def _for_us(self, msg) -> bool:
        ts = getattr(msg, "target_system", 0)
        tc = getattr(msg, "target_component", 0)
        if ts not in (0, self.config.sysid) or tc not in (0, self.config.compid):
            self.counters.ignored_not_for_us += 1
            return False
        return True

    def handle(self, link: Link, msg) -> None:
        """Act on one checked message from a link."""
        mtype = msg.get_type()
        handler = self._handlers.get(mtype)
        if handler is None:
            return
        if mtype not in ("HEARTBEAT", "TIMESYNC") and not self._for_us(msg):
            return
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        try:
            handler(self, link, msg, src)
        except (ValueError, OverflowError, TypeError) as err:
            # A message with values no real sender would use (e.g. inf in an int parameter).
            self.counters.drop("bad_value")
            self.log(f"dropped {mtype}: {err}")
        except Exception as err:  # noqa: BLE001 - one bad message must not stop the autopilot
            self.counters.drop("handler_error")
            self.log(f"error handling {mtype}: {type(err).__name__}: {err}")

    def _on_command(self, link: Link, msg, src) -> None:
        if msg.get_type() == "COMMAND_INT":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y), msg.z)
        else:
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        frame = msg.frame if msg.get_type() == "COMMAND_INT" else None
        result = self.command(link, msg.command, params, src, frame)
        if result is not None:
            self._ack(link, msg.command, result, src)
        self._flush_events()

    def command(self, link: Link, command: int, p: tuple, src, int_frame: int | None = None) -> int | None:
        """Execute a MAV_CMD; return its MAV_RESULT (None if the reply was already sent).

        ``p`` holds param1..7 (COMMAND_INT: x and y as floats in p5, p6); ``int_frame`` is the
        COMMAND_INT frame, None for COMMAND_LONG.
        """
        f = self.flight
        if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if not math.isfinite(p[0]) or p[0] not in (0.0, 1.0):
                return fl.MAV_RESULT_DENIED
            force = math.isfinite(p[1]) and int(p[1]) == fl.ARM_FORCE_MAGIC
            return f.arm(p[0] == 1.0, force)
        if command == mavlink.MAV_CMD_DO_SET_MODE:
            mode = self.pers.mode_from_do_set_mode(p[0], p[1], p[2])
            if mode is None:
                return fl.MAV_RESULT_DENIED
            return f.set_mode(mode)
        if command == mavlink.MAV_CMD_NAV_TAKEOFF:
            return f.takeoff(p[6], self.origin[2])
        if command == mavlink.MAV_CMD_NAV_LAND:
            return f.land()
        if command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return f.return_to_launch()
        if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            return self._cmd_set_message_interval(link, p)
        if command == mavlink.MAV_CMD_GET_MESSAGE_INTERVAL:
            if not math.isfinite(p[0]):
                return fl.MAV_RESULT_DENIED
            msgid = int(p[0])
            interval = link.stream_interval_s.get(msgid)
            self._ack(link, command, fl.MAV_RESULT_ACCEPTED, src)
            link.send(link.mav.message_interval_encode(msgid, -1 if interval is None else int(interval * 1e6)))
            return None
        if command in (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
            msgid = MSG_AUTOPILOT_VERSION if command == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES else (int(p[0]) if math.isfinite(p[0]) else -1)
            if msgid == MSG_STATUSTEXT:
                self._ack(link, command, fl.MAV_RESULT_ACCEPTED, src)
                self._send_counters([link])
                return None
            requestable = STREAMABLE_MSG_IDS + (MSG_AUTOPILOT_VERSION, MSG_GPS_GLOBAL_ORIGIN, 0)
            msg = self._build(msgid) if msgid in requestable else None
            # Without an origin, a request for GPS_GLOBAL_ORIGIN is accepted and answered with
            # nothing (ArduPilot's send_gps_global_origin returns early when the EKF has no origin).
            if msg is None and msgid not in (MSG_POSITION_TARGET_LOCAL_NED, MSG_GPS_GLOBAL_ORIGIN):
                return fl.MAV_RESULT_DENIED
            self._ack(link, command, fl.MAV_RESULT_ACCEPTED, src)
            if msg is not None:
                link.send(msg)
            return None
        if command == mavlink.MAV_CMD_DO_CHANGE_SPEED:
            return f.change_speed(p[0], p[1])
        if command == mavlink.MAV_CMD_DO_REPOSITION:
            return self._reposition(p, int_frame)
        if command == mavlink.MAV_CMD_GUIDED_CHANGE_SPEED and self.pers.vehicle == "plane" and not self.pers.is_px4:
            if f.mode.behaviour != "guided":
                return f.refuse(fl.MAV_RESULT_FAILED, "GUIDED_CHANGE_SPEED: not in GUIDED")
            return f.change_speed(p[0], p[1])
        if command == mavlink.MAV_CMD_GUIDED_CHANGE_ALTITUDE and self.pers.vehicle == "plane" and not self.pers.is_px4:
            return f.set_altitude_target(p[6])
        return fl.MAV_RESULT_UNSUPPORTED

    def _cmd_set_message_interval(self, link: Link, p: tuple) -> int:
        if not (math.isfinite(p[0]) and math.isfinite(p[1])):
            return fl.MAV_RESULT_DENIED
        msgid = int(p[0])
        interval_us = p[1]
        if msgid not in STREAMABLE_MSG_IDS:
            return fl.MAV_RESULT_DENIED
        if interval_us < 0:
            self._set_stream(link, msgid, None)
        elif interval_us == 0:
            self._set_stream(link, msgid, self._default_interval_s(msgid))
        else:
            self._set_stream(link, msgid, interval_us * 1e-6)
        return fl.MAV_RESULT_ACCEPTED

    def _send_counters(self, links: list[Link]) -> None:
        c = self.counters
        self._statustext(fl.SEVERITY_INFO, f"rx datagrams={c.datagrams} ok={c.frames_ok} dropped={c.dropped_total}",
                         links)
        for reason in DROP_REASONS:
            if c.dropped[reason]:
                self._statustext(fl.SEVERITY_INFO, f"rx dropped {reason}={c.dropped[reason]}", links)

    def _on_set_mode(self, link: Link, msg, src) -> None:
        mode = self.pers.mode_for_custom(msg.custom_mode) if msg.base_mode & 1 else None
        result = fl.MAV_RESULT_DENIED if mode is None else self.flight.set_mode(mode)
        self._ack(link, mavlink.MAVLINK_MSG_ID_SET_MODE, result, src)  # ArduPilot acks SET_MODE by its id
        self._flush_events()

    def _note_client_time(self, time_boot_ms: int) -> None:
        if time_boot_ms > 0:
            self._client_time_s = max(self._client_time_s, time_boot_ms / 1000.0)
            self._client_wall_s = time.monotonic()

    def _tell_time(self, now_wall_s: float) -> None:
        """--pace-lead-s, while waiting: send SYSTEM_TIME (the held time) every 0.1 s of wall time.

        A client that lost the newest datagrams (a full socket buffer drops the latest ones) stamps
        its setpoints with an older time than the last one sent and would wait for telemetry that
        the held clock never produces: both sides waiting for ever. Telling it the time breaks that.
        """
        if now_wall_s - self._time_told_wall_s < 0.1:
            return
        self._time_told_wall_s = now_wall_s
        msg = self._build(MSG_SYSTEM_TIME)
        for link in self.links:
            link.send(msg)

    def _client_lagging(self, now_wall_s: float) -> bool:
        """--pace-lead-s: hold simulated time while a live setpoint client is that far behind.

        The client stamps each setpoint with the newest ``time_boot_ms`` it has seen; a client
        that has sent nothing for 1 s of wall time is not waited for (it stopped on purpose, or
        the test is about its silence).
        """
        lead = self.config.pace_lead_s
        if lead is None or now_wall_s - self._client_wall_s > 1.0:
            return False
        return self.sim_t_s - self._client_time_s > lead

    def _on_position_target(self, link: Link, msg, src) -> None:
        self._note_client_time(msg.time_boot_ms)
        reason = self.flight.set_position_target(
            msg.coordinate_frame, msg.type_mask, (msg.x, msg.y, msg.z), (msg.vx, msg.vy, msg.vz),
            (msg.afx, msg.afy, msg.afz), msg.yaw, msg.yaw_rate)
        if reason == "bad_value":
            self.counters.drop("bad_value")

    def _on_position_target_global(self, link: Link, msg, src) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT: the position converted to local NED, the rest as the local message."""
        frame = msg.coordinate_frame
        if frame not in (mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                         mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT):
            return
        if abs(msg.lat_int) > 900000000 or abs(msg.lon_int) > 1800000000:
            self.counters.drop("bad_value")
            return
        alt_amsl = msg.alt if frame == mavlink.MAV_FRAME_GLOBAL_INT else self.origin[2] + msg.alt  # home is on the ground at the origin
        north, east, down = self.local_from_geodetic(msg.lat_int * 1e-7, msg.lon_int * 1e-7, alt_amsl)
        reason = self.flight.set_position_target(
            fl.MAV_FRAME_LOCAL_NED, msg.type_mask, (north, east, down), (msg.vx, msg.vy, msg.vz),
            (msg.afx, msg.afy, msg.afz), msg.yaw, msg.yaw_rate)
        if reason == "bad_value":
            self.counters.drop("bad_value")

    def _on_attitude_target(self, link: Link, msg, src) -> None:
        self._note_client_time(msg.time_boot_ms)
        reason = self.flight.set_attitude_target(msg.type_mask, tuple(msg.q))
        if reason == "bad_value":
            self.counters.drop("bad_value")

    def _param_value_msg(self, link: Link, name: str):
        names = list(self.params)
        param = self.params[name]
        return link.mav.param_value_encode(name.encode("ascii"), self.pers.encode_param_value(param),
                                           param.param_type, len(names), names.index(name))

    def _on_param_request_list(self, link: Link, msg, src) -> None:
        for name in self.params:
            link.send(self._param_value_msg(link, name))

    def _on_param_request_read(self, link: Link, msg, src) -> None:
        names = list(self.params)
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode("ascii", "replace")
        if msg.param_index >= 0:
            if msg.param_index >= len(names):
                return
            name = names[msg.param_index]
        if name in self.params:
            link.send(self._param_value_msg(link, name))

    def _on_param_set(self, link: Link, msg, src) -> None:
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode("ascii", "replace")
        param = self.params.get(name)
        if param is None:
            self._statustext(fl.SEVERITY_WARNING, f"Unknown parameter {name}"[:50], [link])
            return
        value = self.pers.decode_param_value(msg.param_value, param.param_type)
        if not math.isfinite(value):
            self.counters.drop("bad_value")
            return
        self.params[name] = type(param)(value, param.param_type)
        for each in self.links:
            each.send(self._param_value_msg(each, name))

    def _on_request_data_stream(self, link: Link, msg, src) -> None:
        groups = list(ARDUPILOT_STREAM_GROUPS) if msg.req_stream_id == 0 else [msg.req_stream_id]
        for group in groups:
            for msgid in ARDUPILOT_STREAM_GROUPS.get(group, ()):
                if msg.start_stop and msg.req_message_rate > 0:
                    rate_hz = min(msg.req_message_rate, 1.0) if msgid == MSG_HOME_POSITION else msg.req_message_rate
                    self._set_stream(link, msgid, 1.0 / rate_hz)
                else:
                    self._set_stream(link, msgid, None)

    def _on_timesync(self, link: Link, msg, src) -> None:
        if msg.tc1 == 0:
            link.send(link.mav.timesync_encode(int(self.sim_t_s * 1e9), msg.ts1))

    def _on_mission_request_list(self, link: Link, msg, src) -> None:
        link.send(link.mav.mission_count_encode(src[0], src[1], 0, getattr(msg, "mission_type", 0)))

    def _on_heartbeat(self, link: Link, msg, src) -> None:
        pass

    def _on_ftp(self, link: Link, msg, src) -> None:
        """MAVLink FTP: the mock has no file system, so every open is answered "file not found".

        Ground stations (MAVProxy, QGroundControl) try FTP first for parameters and fall back to
        the PARAM protocol on a NAK; without an answer they wait for a timeout.
        """
        req = bytes(msg.payload)
        if len(req) < 12:
            self.counters.drop("bad_value")
            return
        seq = req[0] | (req[1] << 8)
        session, opcode = req[2], req[3]
        if opcode in (FTP_OP_TERMINATE_SESSION, FTP_OP_RESET_SESSIONS):
            reply_op, size, data = FTP_OP_ACK, 0, b""
        else:
            error = FTP_ERR_FILE_NOT_FOUND if opcode in (3, 4, 6, 11, 12) else FTP_ERR_FAIL
            reply_op, size, data = FTP_OP_NAK, 1, bytes([error])
        payload = bytes([(seq + 1) & 0xFF, ((seq + 1) >> 8) & 0xFF, session, reply_op, size, opcode, 0, 0,
                         0, 0, 0, 0]) + data
        payload += bytes(251 - len(payload))
        link.send(link.mav.file_transfer_protocol_encode(0, src[0], src[1], payload))

    _handlers = {
        "COMMAND_LONG": _on_command,
        "COMMAND_INT": _on_command,
        "SET_MODE": _on_set_mode,
        "SET_POSITION_TARGET_LOCAL_NED": _on_position_target,
        "SET_POSITION_TARGET_GLOBAL_INT": _on_position_target_global,
        "SET_ATTITUDE_TARGET": _on_attitude_target,
        "PARAM_REQUEST_LIST": _on_param_request_list,
        "PARAM_REQUEST_READ": _on_param_request_read,
        "PARAM_SET": _on_param_set,
        "REQUEST_DATA_STREAM": _on_request_data_stream,
        "TIMESYNC": _on_timesync,
        "MISSION_REQUEST_LIST": _on_mission_request_list,
        "HEARTBEAT": _on_heartbeat,
        "FILE_TRANSFER_PROTOCOL": _on_ftp,
    }

    # ------------------------------------------------------------------ run loop
    def announce(self) -> None:
        """Print the link ports (stderr) and the ready line (stdout)."""
        for link in self.links:
            self.log(f"link {link.describe()}")
        print(f"sitl_mock ready sysid={self.config.sysid} autopilot={self.config.autopilot} "
              f"vehicle={self.config.vehicle}", file=self.out, flush=True)

    def run(self) -> int:
        """Run until :attr:`stop_event` is set or ``duration_s`` of simulated time has passed."""
        cfg = self.config
        dt = self.dt_s
        wall_per_step = dt / cfg.speedup
        max_batch = max(1, int(0.05 / wall_per_step))  # at most 50 ms of wall time of steps per pass
        min_wait_s = 0.002 if wall_per_step < 0.002 else 0.0
        socks = {link.sock: link for link in self.links}
        wall0 = time.monotonic()
        self._wall0 = wall0
        last_flush = wall0
        try:
            while not (self.stop_requested or self.stop_event.is_set()):
                now = time.monotonic()
                due = int((now - wall0) / wall_per_step) - self.steps
                if due > 0 and self._client_lagging(now):
                    # Simulated time waits for the client (no burst afterwards either).
                    wall0 = now - self.steps * wall_per_step
                    due = 0
                    self._tell_time(now)
                if due > 4 * max_batch:
                    # Far behind (machine busy): let simulated time slip rather than burst.
                    self.overruns += 1
                    wall0 = now - (self.steps + max_batch) * wall_per_step
                    due = max_batch
                for _ in range(min(due, max_batch)):
                    if self._client_lagging(now):
                        wall0 = time.monotonic() - self.steps * wall_per_step
                        break
                    self.flight.step(dt)
                    self.steps += 1
                    self.sim_t_s = self.steps * dt
                    self._service_streams()
                    if self.flight.events:
                        self._flush_events()
                    if cfg.duration_s is not None and self.sim_t_s >= cfg.duration_s:
                        self.stop_event.set()
                        break
                if self.flight.events or self.flight.mode.name != self._last_mode_name:
                    self._flush_events()
                now = time.monotonic()
                timeout = wall0 + (self.steps + 1) * wall_per_step - now
                if due > max_batch:
                    timeout = 0.0
                timeout = max(timeout, min_wait_s, 0.0)
                readable, _, _ = select.select(list(socks), [], [], timeout)
                for sock in readable:
                    link = socks[sock]
                    for msg in link.receive():
                        self.handle(link, msg)
                if self.tlog is not None and now - last_flush > 0.2:
                    self.tlog.flush()
                    last_flush = now
        finally:
            self.close()
        return 0

    def request_stop(self, signum: int = 0, frame: object = None) -> None:  # noqa: ARG002 - handler signature
        """Stop the run loop; safe as a signal handler (takes no lock, may be re-entered)."""
        self.stop_requested = True

    def summary(self) -> str:
        """One line of run statistics: simulated time, messages, drops by reason."""
        wall = time.monotonic() - getattr(self, "_wall0", time.monotonic())
        tx = sum(link.tx_messages for link in self.links)
        return (f"sitl_mock summary sim_s={self.sim_t_s:.2f} wall_s={wall:.2f} steps={self.steps} "
                f"overruns={self.overruns} tx_messages={tx} {self.counters.summary_fields()} "
                f"tlog_records={self.tlog.records if self.tlog else 0}")

    def close(self) -> None:
        for link in self.links:
            link.close()
        if self.tlog is not None:
            self.tlog.close()
