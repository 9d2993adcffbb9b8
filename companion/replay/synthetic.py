"""Synthetic companion flights: a tlog exactly like the flight loop records, without a vehicle.

:func:`write_synthetic_flight` plays the flight loop against a simple kinematic vehicle and
records what the loop records: the autopilot's ``LOCAL_POSITION_NED`` (and ``ATTITUDE``,
``HEARTBEAT``), and per tick the companion's ``DEBUG_FLOAT_ARRAY "guidance"`` row followed by its
``SET_POSITION_TARGET_LOCAL_NED``, with the mission written beside the log as
``<tlog>.mission.yaml``. Each tick goes through :func:`companion.loop.tick.compute_tick` with the
guidance built by :func:`companion.loop.driver.make_guidance`, as in flight. The samples handed to
the guidance are rounded to float32 first, as they would be after crossing the wire.

The vehicle: its horizontal velocity follows the commanded velocity through a first-order lag
``vehicle_lag_s`` (0: it takes the commanded velocity at the next tick), altitude is held, one
``LOCAL_POSITION_NED`` per tick. The tick time carries a
small deterministic jitter (as a wall clock would), so ``t_s`` is not on the tick grid.

The rest of the autopilot's telemetry is what a recorded ArduCopter flight carries (the real
ArduCopter SITL log in the project's test data, ``TELEMETRY_STREAMS_HZ``): ``ATTITUDE`` at the
rate ``companion fly`` requests (20 Hz), ``GLOBAL_POSITION_INT`` 10 Hz, ``GPS_RAW_INT`` and
``VFR_HUD`` 5 Hz, ``SYS_STATUS`` 2 Hz and a ``HEARTBEAT`` from each side at 1 Hz: 3.9 records per
50 Hz tick, as in that log. Replay decodes the attitude and heartbeats and only checks and counts
the others.

:func:`replay_throughput` times the replay of such a flight (default: one hour at 50 Hz on a
closed racetrack) and is what ``companion bench perf`` reports.
"""

from __future__ import annotations

import concurrent.futures
import functools
import math
import struct
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from companion.geometry import frames, geodetic
from companion.io.logread import PacketEncoder
from companion.io.setpoints import AttitudeSetpoint, VelocitySetpoint
from companion.io.state import PositionSample
from companion.io.tlog import TlogWriter, write_mission_beside
from companion.loop.driver import TickDriver, make_guidance
from companion.loop.limits import mission_for_tail
from companion.loop.tick import DEFAULT_STALE_S, TickResult
from companion.mission import Mission, parse_mission
from companion.replay.replay import tick_config_for

SAMPLE_AGE_S = 0.004  # how long before the tick the newest sample arrived
TICK_JITTER_S = 0.0007  # amplitude of the tick-time jitter
START_UNIX_S = 1_795_000_000.0
BOOT_MS_AT_START = 120_000
MAV_TYPE_QUADROTOR = 2
MAV_TYPE_ONBOARD_CONTROLLER = 18
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_INVALID = 8
GUIDED_ARMED_BASE_MODE = 1 | 128  # custom mode enabled, armed
COPTER_GUIDED = 4
G_M_S2 = 9.80665

#: A closed racetrack (two 120 m straights, two 40 m radius half-circles) flown at 5 m/s with
#: the corrector-aided law: the default flight of :func:`replay_throughput`.
RACETRACK_MISSION = """\
name: synthetic-racetrack
frame: local_enu
speed_m_s: 5.0
altitude_m: 10.0
path:
  type: segments
  start_m: [0.0, 0.0]
  start_heading_deg: 0.0
  blend_m: 5.0
  closed: true
  segments:
    - {type: line, length_m: 120.0}
    - {type: arc, radius_m: 40.0, turn_deg: 180.0}
    - {type: line, length_m: 120.0}
    - {type: arc, radius_m: 40.0, turn_deg: 180.0}
guidance: {l1_m: 10.0, method: corrector, rate_hz: 50}
"""

#: Telemetry the autopilot streams besides LOCAL_POSITION_NED (one per tick), Hz: the streams of
#: the recorded ArduCopter SITL flight, with ATTITUDE at the rate ``companion fly`` requests.
TELEMETRY_STREAMS_HZ = {"ATTITUDE": 20.0, "GLOBAL_POSITION_INT": 10.0, "GPS_RAW_INT": 5.0,
                        "VFR_HUD": 5.0, "SYS_STATUS": 2.0, "HEARTBEAT": 1.0}
#: Where the synthetic flight's local frame sits on the Earth (for the geodetic streams).
ORIGIN_LAT_DEG, ORIGIN_LON_DEG, ORIGIN_ALT_M = 47.397742, 8.545594, 488.0

_F32x6 = struct.Struct("<6f")


def _due(k: int, rate_hz: float, stream_hz: float) -> bool:
    """Whether a ``stream_hz`` stream sends at tick ``k`` of a ``rate_hz`` loop (evenly spread)."""
    return k == 0 or int(k * stream_hz / rate_hz) != int((k - 1) * stream_hz / rate_hz)


def _float32(*values: float) -> tuple[float, ...]:
    return _F32x6.unpack(_F32x6.pack(*values)) if len(values) == 6 else tuple(
        struct.unpack("<f", struct.pack("<f", v))[0] for v in values)


@dataclass
class _Vehicle:
    """The kinematic vehicle of a synthetic flight (ENU metres, m/s; altitude held)."""

    x: float
    y: float
    ve: float
    vn: float
    alt: float
    dt: float
    alpha: float  # the velocity's first-order lag over one tick (1: none)
    drift_en: tuple[float, float] = (0.0, 0.0)  # the velocity estimate's error (ENU): the position moves by it too
    speed_share: float = 1.0  # the share of the commanded velocity it settles to (< 1: flies slower than asked)
    tail_share: float = 0.0  # the velocity loop's slow tail (docs/vehicle_model.md): its share of the error
    tail_alpha: float = 0.0  # and its low-pass over one tick
    f_en: tuple[float, float] = (0.0, 0.0)  # the error through that low-pass (ENU)

    @classmethod
    def at_start(cls, mission: Mission, offset_m: tuple[float, float], dt: float, lag_s: float,
                 drift_en: tuple[float, float] = (0.0, 0.0), speed_share: float = 1.0,
                 tail: tuple[float, float] = (0.0, 1.0)) -> _Vehicle:
        """At ``offset_m`` from the path's start, flying along it at the mission's speed."""
        (x0, y0), heading = mission.path.start_xy_m, mission.path.start_heading_rad
        speed = mission.speed_m_s
        return cls(x0 + offset_m[0], y0 + offset_m[1], speed * math.cos(heading), speed * math.sin(heading),
                   mission.altitude_m, dt, 1.0 - math.exp(-dt / lag_s) if lag_s > 0 else 1.0, drift_en, speed_share,
                   tail[0], 1.0 - math.exp(-dt / tail[1]))

    def follow(self, sp: VelocitySetpoint | AttitudeSetpoint) -> None:
        """One tick of the vehicle under the setpoint just sent."""
        if isinstance(sp, AttitudeSetpoint):
            # coordinated turn at the commanded bank (NED roll: right wing down positive)
            speed = math.hypot(self.ve, self.vn)
            omega = G_M_S2 * math.tan(-sp.roll_ned_rad) / speed if speed > 0 else 0.0
            course = math.atan2(self.vn, self.ve) + omega * self.dt
            self.ve, self.vn = speed * math.cos(course), speed * math.sin(course)
        else:
            # the vehicle follows the commanded horizontal velocity with a first-order lag, less
            # its slow tail's share of the error through the tail's low-pass
            cmd_ve, cmd_vn = self.speed_share * sp.vy_ned_m_s, self.speed_share * sp.vx_ned_m_s
            e_e, e_n = cmd_ve - self.ve, cmd_vn - self.vn
            fe, fn = self.f_en
            fe, fn = fe + (e_e - fe) * self.tail_alpha, fn + (e_n - fn) * self.tail_alpha
            self.f_en = (fe, fn)
            self.ve += self.alpha * (e_e - self.tail_share * fe)
            self.vn += self.alpha * (e_n - self.tail_share * fn)
        self.x += (self.ve + self.drift_en[0]) * self.dt
        self.y += (self.vn + self.drift_en[1]) * self.dt


def _write_telemetry(tlog: TlogWriter, autopilot: PacketEncoder, companion: PacketEncoder, k: int, rate_hz: float,
                     boot_ms: int, unix_s: float, v: _Vehicle) -> None:
    """The heartbeats and the autopilot's other streams due at tick ``k`` (they only fill the log)."""
    if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["HEARTBEAT"]):
        tlog.write(autopilot.heartbeat_packet(MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA,
                                              GUIDED_ARMED_BASE_MODE, COPTER_GUIDED), unix_s - 0.002)
        tlog.write(companion.heartbeat_packet(MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID), unix_s - 0.001)
    at_unix_s = unix_s - 0.003
    speed = math.hypot(v.ve, v.vn)
    course_deg = math.degrees(math.atan2(v.ve, v.vn)) % 360.0
    alt = v.alt
    if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["GLOBAL_POSITION_INT"]) or \
            _due(k, rate_hz, TELEMETRY_STREAMS_HZ["GPS_RAW_INT"]):
        lat, lon, _ = (float(c) for c in geodetic.geodetic_from_enu(
            v.x, v.y, alt, ORIGIN_LAT_DEG, ORIGIN_LON_DEG, ORIGIN_ALT_M))
    if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["GLOBAL_POSITION_INT"]):
        tlog.write(autopilot.global_position_int_packet(boot_ms, lat, lon, ORIGIN_ALT_M + alt, alt, v.vn, v.ve,
                                                        0.0, course_deg), at_unix_s)
    if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["GPS_RAW_INT"]):
        tlog.write(autopilot.gps_raw_int_packet(boot_ms * 1000, lat, lon, ORIGIN_ALT_M + alt, speed,
                                                course_deg), at_unix_s)
    if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["VFR_HUD"]):
        tlog.write(autopilot.vfr_hud_packet(speed, speed, course_deg, 45, ORIGIN_ALT_M + alt, 0.0), at_unix_s)
    if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["SYS_STATUS"]):
        tlog.write(autopilot.sys_status_packet(12_400, 1_250, 80), at_unix_s)


def _write_row(tlog: TlogWriter, companion: PacketEncoder, unix_s: float, result: TickResult, sent: bool) -> None:
    """A finished step's guidance row: a fresh one just before its setpoint, a late one earlier."""
    time_usec = result.sample.time_boot_ms * 1000 if result.sample is not None else 0
    tlog.write(companion.debug_float_array_packet("guidance", result.tick, time_usec, result.debug),
               unix_s + (20e-6 if sent else 10e-6))


class _SlowStep:
    """A finished step that reports itself done only after ``waits`` waits (a slow step in flight)."""

    def __init__(self, result: TickResult, waits: int):
        self._result = result
        self._waits = waits

    @classmethod
    def run(cls, coast_ticks: int, call: Callable[[], TickResult]) -> _SlowStep:
        """Run the step now; a re-optimisation (with ``coast_ticks``) is held back that many ticks."""
        res = call()
        slow = coast_ticks and res.output is not None and res.output.reoptimised
        return cls(res, coast_ticks if slow else 0)

    def result(self, timeout: float | None = None) -> TickResult:
        if self._waits > 0:
            self._waits -= 1
            raise concurrent.futures.TimeoutError
        return self._result


def _write_setpoint(tlog: TlogWriter, companion: PacketEncoder, sp: VelocitySetpoint | AttitudeSetpoint,
                    sent_at: float) -> None:
    if isinstance(sp, AttitudeSetpoint):
        tlog.write(companion.attitude_target_packet(1, 1, sp.type_mask, sp.q, sp.thrust), sent_at)
    else:
        tlog.write(companion.velocity_setpoint_packet(1, 1, sp.type_mask, sp.coordinate_frame, sp.vx_ned_m_s,
                                                      sp.vy_ned_m_s, sp.vz_ned_m_s, sp.yaw_rate_ned_rad_s), sent_at)


def write_synthetic_flight(
    tlog_path: str | Path,
    mission: Mission | str = RACETRACK_MISSION,
    duration_s: float = 60.0, rate_hz: float = 50.0,
    start_offset_m: tuple[float, float] = (0.0, 3.0),
    vehicle_lag_s: float = 0.2,
    output: str = "velocity",
    dropout_s: tuple[float, float] | None = None, stale_s: float = DEFAULT_STALE_S,
    coast_ticks: int = 0,
    drift_en_m_s: tuple[float, float] = (0.0, 0.0), drift_tc_s: float = 0.0,
    speed_share: float = 1.0, speed_hold_tc_s: float = 0.0,
    vehicle_tail: tuple[float, float] = (0.0, 1.0), compensated_tail: tuple[float, float] = (0.0, 0.0),
) -> dict:
    """Fly ``mission`` for ``duration_s`` against the kinematic vehicle and write the tlog.

    Parameters
    ----------
    tlog_path : where to write the log (``<tlog>.mission.yaml`` is written beside it).
    mission : a :class:`Mission` or mission YAML text.
    duration_s, rate_hz : length of the flight and the loop rate.
    start_offset_m : the vehicle's start, ENU, relative to the path's first point.
    vehicle_lag_s : time constant of the vehicle's velocity response (0: immediate).
    output : ``"velocity"`` (SET_POSITION_TARGET_LOCAL_NED, copter) or ``"attitude"``
        (SET_ATTITUDE_TARGET, fixed wing: the vehicle turns at ``g tan(bank) / V``).
    dropout_s : ``(start, end)`` tick times between which the position stream stops (the loop
        keeps the last sample, ageing, and holds once it is older than ``stale_s``).
    stale_s : the loop's stale-position limit (the runner's ``--stale-s``).
    coast_ticks : when > 0, every step that re-optimises k1, k2 is taken to last that many extra
        ticks, as a slow step in the flight loop's worker: it coasts, then its row is recorded
        late and that tick is computed afresh (:meth:`TickDriver.run_tick`).
    drift_en_m_s, drift_tc_s : the vehicle flies the reported velocity plus ``drift_en_m_s`` (ENU),
        a drifting estimate; the loop compensates it over ``drift_tc_s`` (``--drift-tc-s``; 0: off).
    speed_share, speed_hold_tc_s : the vehicle settles to ``speed_share`` times the commanded
        velocity (PX4 SIH flies about 0.86 of it); the loop holds the mission's speed with an
        integral time of ``speed_hold_tc_s`` (``--speed-hold-tc-s``; 0: off).
    vehicle_tail, compensated_tail : the velocity loop's slow tail, share and time (share 0: none;
        docs/vehicle_model.md), and the one the loop compensates (``guidance.tail_compensation``).

    Returns a dict with ``ticks``, ``records`` and ``generate_s``.
    """
    started = time.perf_counter()
    if isinstance(mission, str):
        mission = parse_mission(mission, "<synthetic>")
    write_mission_beside(tlog_path, mission.source_text)
    config = tick_config_for(mission, rate_hz, output, stale_s, drift_tc_s, False, speed_hold_tc_s, compensated_tail)
    guidance = make_guidance(mission_for_tail(mission, config.compensates_tail)[0], rate_hz)  # the runner's lambda
    dt = 1.0 / rate_hz
    autopilot, companion = PacketEncoder(1, 1), PacketEncoder(1, 191)
    v = _Vehicle.at_start(mission, start_offset_m, dt, vehicle_lag_s, drift_en_m_s, speed_share, vehicle_tail)
    driver = TickDriver(guidance, config, mission.path.start_heading_rad)
    n_ticks = int(round(duration_s * rate_hz))
    slow_steps = functools.partial(_SlowStep.run, coast_ticks)

    with TlogWriter(tlog_path, min_free_bytes=0) as tlog:
        for k in range(n_ticks):
            t_grid = k * dt
            unix = START_UNIX_S + t_grid
            boot_ms = BOOT_MS_AT_START + int(round(t_grid * 1000.0))
            _write_telemetry(tlog, autopilot, companion, k, rate_hz, boot_ms, unix, v)
            # the autopilot's sample, as it crosses the wire (float32)
            if dropout_s is None or not (dropout_s[0] <= t_grid < dropout_s[1]):
                fields = _float32(v.y, v.x, -v.alt, v.vn, v.ve, 0.0)
                tlog.write(autopilot.local_position_ned_packet(boot_ms, *fields), unix - SAMPLE_AGE_S)
                sample = PositionSample(boot_ms, *fields)
                sample_t = t_grid
            if _due(k, rate_hz, TELEMETRY_STREAMS_HZ["ATTITUDE"]):
                yaw_ned = frames.yaw_ned_from_enu(math.atan2(v.vn, v.ve))
                tlog.write(autopilot.attitude_packet(boot_ms, 0.0, 0.0, yaw_ned), unix - SAMPLE_AGE_S / 2)
                yaw_seen = _float32(yaw_ned)[0]
            t_s = t_grid + TICK_JITTER_S * math.sin(0.7 * k)
            age = SAMPLE_AGE_S + (t_grid - sample_t)
            tick_out = driver.run_tick(t_s, t_s, sample, age, yaw_seen, slow_steps, 0.0,
                                       functools.partial(_write_row, tlog, companion, unix))
            sp = tick_out.setpoint
            # as the runner: the tick's guidance row, then its setpoint; a coast after the budget
            _write_setpoint(tlog, companion, sp, unix + 40e-6 if tick_out.result is not None else unix + 0.5 * dt)
            v.follow(sp)
        records = tlog.records
    return {"ticks": n_ticks, "records": records, "generate_s": time.perf_counter() - started}


def replay_throughput(
    duration_s: float = 3600.0,
    rate_hz: float = 50.0,
    mission: str = RACETRACK_MISSION,
    workdir: str | Path | None = None,
) -> dict:
    """Generate a synthetic flight, replay it, and time the replay.

    Returns
    -------
    dict with ``duration_s`` (flight length), ``rate_hz``, ``ticks``, ``file_bytes``,
    ``generate_s`` (not part of the replay), ``read_s``, ``replay_s``, ``total_s`` (read +
    replay), ``ticks_per_s``, ``within_tolerance``, ``steps_compared``.
    """
    from companion.replay.replay import replay_log

    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tlog = Path(tmp) / "synthetic.tlog"
        info = write_synthetic_flight(tlog, mission, duration_s, rate_hz)
        size = tlog.stat().st_size
        result = replay_log(tlog, progress=False)
    total = result.timing_s["total_s"]
    return {
        "duration_s": float(duration_s),
        "rate_hz": float(rate_hz),
        "ticks": info["ticks"],
        "file_bytes": size,
        "generate_s": info["generate_s"],
        "read_s": result.timing_s["read_s"],
        "replay_s": result.timing_s["replay_s"],
        "total_s": total,
        "ticks_per_s": info["ticks"] / total if total > 0 else math.inf,
        "within_tolerance": result.within_tolerance,
        "steps_compared": result.steps_compared,
    }
