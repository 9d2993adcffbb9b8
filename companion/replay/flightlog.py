"""Extract from a tlog what replay needs: one entry per guidance tick, in the order flown.

Two kinds of log are understood:

``companion``
    The companion recorded, with each tick's setpoint, one ``DEBUG_FLOAT_ARRAY`` named
    ``"guidance"`` (layout :data:`companion.loop.tick.DEBUG_FIELDS`). Its ``time_usec`` is
    ``time_boot_ms * 1000`` of the ``LOCAL_POSITION_NED`` sample the tick used, so the tick is
    rebuilt exactly: that sample (looked up by ``time_boot_ms`` among the samples received before
    the record), the tick counter, the tick time ``t_s``, the sample age and the carried course
    state from the record, the newest ``ATTITUDE`` yaw received before it, and the setpoint the
    same sender sent with it (see :func:`_pair_setpoints`).

``setpoints``
    Any other log with ``SET_POSITION_TARGET_LOCAL_NED`` (another controller, a script): each
    setpoint is paired with the newest valid ``LOCAL_POSITION_NED`` of its target system received
    before it; the tick time is the sample's autopilot time since the first paired sample, and the
    sample age is the tlog time between the sample and the setpoint.

Samples whose fields the live link would have rejected (NaN, out of range; see
:func:`companion.io.state.position_problem`) are ignored here too, and so are positions and
attitudes from senders whose HEARTBEAT says they are no autopilot (a ground station, a camera).
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, NamedTuple

from companion.errors import LogError
from companion.io.state import GlobalOrigin, global_origin_from_wire
from companion.io.link import MAV_AUTOPILOT_INVALID, MAV_PARAM_TYPE_REAL32
from companion.io.logread import MSG_ID, LogWarning, TlogReader
from companion.io.state import MAX_POSITION_M, MAX_VELOCITY_M_S, PositionSample, position_problem
from companion.loop.tick import (
    DEBUG_FIELDS,
    LAYOUT_WITH_DRIFT,
    LAYOUT_WITH_RATE,
    LAYOUT_WITH_SPEED_HOLD,
    LAYOUT_WITH_TAIL_COMP,
    LAYOUT_WITH_YAW,
    PHASE_CODES,
)
from companion.replay.progress import ByteProgress

GUIDANCE_ARRAY_NAME = "guidance"
ID_LPN = MSG_ID["LOCAL_POSITION_NED"]
ID_SPT = MSG_ID["SET_POSITION_TARGET_LOCAL_NED"]
ID_DFA = MSG_ID["DEBUG_FLOAT_ARRAY"]
ID_ATTITUDE = MSG_ID["ATTITUDE"]
ID_SAT = MSG_ID["SET_ATTITUDE_TARGET"]
ID_HEARTBEAT = MSG_ID["HEARTBEAT"]
ID_GPS_GLOBAL_ORIGIN = MSG_ID["GPS_GLOBAL_ORIGIN"]
ID_PARAM_VALUE = MSG_ID["PARAM_VALUE"]
PROGRESS_EVERY_RECORDS = 4096
#: A guidance row and the setpoint after it are one tick's when less than this many periods apart
#: (a coasting setpoint follows a late row only after the runner's step budget, half a period).
PAIR_GAP_PERIODS = 0.45
N_DEBUG = len(DEBUG_FIELDS)
DEBUG_INDEX = {name: i for i, name in enumerate(DEBUG_FIELDS)}


class LoggedSetpoint(NamedTuple):
    """The velocity, yaw-rate and horizontal acceleration fields of one logged
    SET_POSITION_TARGET_LOCAL_NED (NED; the acceleration as sent, whether or not the mask uses it)."""

    vx_ned_m_s: float
    vy_ned_m_s: float
    vz_ned_m_s: float
    yaw_rate_ned_rad_s: float
    type_mask: int
    coordinate_frame: int
    afx_ned_m_s2: float = 0.0
    afy_ned_m_s2: float = 0.0


class LoggedAttitude(NamedTuple):
    """The fields of one logged SET_ATTITUDE_TARGET (fixed-wing output): quaternion w, x, y, z
    (NED body) and thrust."""

    q: tuple[float, float, float, float]
    thrust: float
    type_mask: int


@dataclass
class LoggedTick:
    """Everything known about one tick of the logged flight.

    ``debug`` is the recorded internals row (companion logs, float32 ``array``) or None; ``setpoint`` is None when
    the setpoint of a recorded tick was lost (damaged log).
    """

    time_unix_s: float
    tick: int
    t_s: float
    sample: PositionSample | None
    sample_age_s: float
    yaw_ned_rad: float | None
    setpoint: LoggedSetpoint | LoggedAttitude | None
    debug: array | None = None
    sample_reconstructed: bool = False

    def debug_value(self, name: str) -> float:
        return math.nan if self.debug is None else self.debug[DEBUG_INDEX[name]]


@dataclass
class LoggedCoast:
    """A setpoint the loop sent without a guidance result of its own: the tick *coasted* while a
    slow guidance step was still running (``companion.loop.tick.coast_setpoint``).

    ``after_tick`` is the index (in :attr:`LoggedFlight.ticks`) of the last guidance row recorded
    before it: that row's result is the one the coast continues. ``sample`` is the newest position
    received before it and ``sample_age_s`` the tlog time between the two.
    """

    time_unix_s: float
    after_tick: int
    sample: PositionSample | None
    sample_age_s: float
    setpoint: LoggedSetpoint | LoggedAttitude


@dataclass
class LoggedFlight:
    """The ticks of a logged flight plus what was noticed while reading it."""

    path: Path
    kind: str  # "companion" or "setpoints"
    ticks: list[LoggedTick]
    coasts: list[LoggedCoast] = field(default_factory=list)
    warnings: list[LogWarning] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    records: int = 0
    # The commanded autopilot's GPS_GLOBAL_ORIGIN (its local frame's origin), if the log holds one:
    # a geodetic mission is placed in the flight's frame about it, as the runner did in flight.
    origin: GlobalOrigin | None = None
    # The autopilots' float parameters the log holds (PARAM_VALUE): the flight's acceleration limit
    # was read from them (companion.loop.limits), and replay reads it back from here.
    params: dict[str, float] = field(default_factory=dict)


def _param_value(msg, params: dict[str, float]) -> None:
    """Keep a float PARAM_VALUE (an integer one is in the autopilot's own encoding)."""
    if int(msg.param_type) == MAV_PARAM_TYPE_REAL32 and math.isfinite(msg.param_value):
        name = msg.param_id.decode("ascii", "replace") if isinstance(msg.param_id, bytes) else str(msg.param_id)
        params[name.rstrip("\x00")] = float(msg.param_value)


def _setpoint(msg) -> LoggedSetpoint:
    return LoggedSetpoint(msg.vx, msg.vy, msg.vz, msg.yaw_rate, msg.type_mask, msg.coordinate_frame, msg.afx, msg.afy)


def _sample(msg) -> PositionSample | None:
    t, x, y, z, vx, vy, vz = msg.time_boot_ms, msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz
    # The usual sample (decoded floats in range, NaN fails every comparison) skips the general
    # check; anything else gets position_problem's verdict.
    if not (type(x) is float and type(y) is float and type(z) is float and type(vx) is float
            and type(vy) is float and type(vz) is float and type(t) is int and t >= 0
            and -MAX_POSITION_M <= x <= MAX_POSITION_M and -MAX_POSITION_M <= y <= MAX_POSITION_M
            and -MAX_POSITION_M <= z <= MAX_POSITION_M and -MAX_VELOCITY_M_S <= vx <= MAX_VELOCITY_M_S
            and -MAX_VELOCITY_M_S <= vy <= MAX_VELOCITY_M_S and -MAX_VELOCITY_M_S <= vz <= MAX_VELOCITY_M_S):
        if position_problem(t, x, y, z, vx, vy, vz) is not None:
            return None
    return PositionSample(t, x, y, z, vx, vy, vz)


def _tick_yaw(row, newest_logged: float | None) -> float | None:
    """The attitude yaw a tick was given: its own record's (``debug_layout`` >= 2; NaN: none), else,
    in logs written before that field, the newest ``ATTITUDE.yaw`` before the record (which can
    be one that arrived while the tick was computing)."""
    if row[DEBUG_INDEX["debug_layout"]] >= LAYOUT_WITH_YAW:  # False for the NaN padding of older logs
        yaw = float(row[DEBUG_INDEX["yaw_ned_rad"]])
        return yaw if math.isfinite(yaw) else None
    return newest_logged


def _sample_from_debug(row: list[float], time_boot_ms: int) -> PositionSample | None:
    """Rebuild a lost sample from the recorded internals (position exact, velocity from course)."""
    x_enu, y_enu = row[DEBUG_INDEX["x_enu_m"]], row[DEBUG_INDEX["y_enu_m"]]
    course, speed = row[DEBUG_INDEX["course_enu_rad"]], row[DEBUG_INDEX["ground_speed_m_s"]]
    alt = row[DEBUG_INDEX["alt_m"]]
    if not all(math.isfinite(v) for v in (x_enu, y_enu, course, speed)):
        return None
    return PositionSample(time_boot_ms, y_enu, x_enu, -alt if math.isfinite(alt) else 0.0,
                          speed * math.sin(course), speed * math.cos(course), 0.0)


# size: the per-record loop is one pass over an hour's log (millions of records), every piece of
# state a local of this frame; a helper call per record costs a measurable share of the read.
def read_flight(
    path: str | Path,
    on_warning: Callable[[LogWarning], None] | None = None,
    progress: bool | None = None,
) -> LoggedFlight:
    """Read a tlog into a :class:`LoggedFlight` (see the module docstring for the two kinds).

    Raises :class:`LogError` when the file has no setpoints to compare (or cannot be read).
    """
    path = Path(path)
    wanted = {ID_LPN, ID_SPT, ID_DFA, ID_ATTITUDE, ID_SAT, ID_HEARTBEAT, ID_GPS_GLOBAL_ORIGIN, ID_PARAM_VALUE}
    reader = TlogReader(path, decode_ids=wanted, on_warning=on_warning, light=True)
    samples_by_ms: dict[int, dict[int, PositionSample]] = {}  # system -> time_boot_ms -> sample
    newest_sample: dict[int, tuple[float, PositionSample]] = {}  # system -> (tlog time, sample)
    newest_yaw: dict[int, float] = {}
    origins: dict[int, GlobalOrigin] = {}  # system -> newest GPS_GLOBAL_ORIGIN (autopilots only)
    params: dict[str, float] = {}  # newest float PARAM_VALUE by name (autopilots only)
    # per sender, in file order: (tlog time, LoggedSetpoint / LoggedAttitude / LoggedTick,
    # (tlog time, newest sample of the target) for setpoints)
    events: dict[tuple[int, int], list[tuple]] = {}
    last_target: dict[tuple[int, int], int] = {}  # sender -> target system of its last setpoint
    not_autopilots: set[tuple[int, int]] = set()  # senders whose HEARTBEAT says MAV_AUTOPILOT_INVALID
    companion_ticks: list[LoggedTick] = []
    setpoint_pairs: list[tuple] = []  # (tlog time, (tlog time, sample), yaw, setpoint)
    coasts: list[LoggedCoast] = []
    notes: list[str] = []
    reconstructed = 0

    with ByteProgress(reader.size_bytes, "reading", enabled=progress) as bar:
        for count, rec in enumerate(reader, 1):
            if count % PROGRESS_EVERY_RECORDS == 0:
                bar.update_to(rec.offset)
            msg = rec.msg
            if msg is None:
                continue
            mid = rec.msg_id
            if mid == ID_LPN:
                if not_autopilots and (rec.src_system, rec.src_component) in not_autopilots:
                    continue
                sample = _sample(msg)
                if sample is not None:
                    system = rec.src_system
                    by_ms = samples_by_ms.get(system)
                    if by_ms is None:
                        by_ms = samples_by_ms[system] = {}
                    by_ms[sample.time_boot_ms] = sample
                    newest_sample[system] = (rec.time_s, sample)
            elif mid == ID_HEARTBEAT:
                if msg.autopilot == MAV_AUTOPILOT_INVALID:  # a GCS, a companion, a camera
                    not_autopilots.add((rec.src_system, rec.src_component))
            elif mid == ID_PARAM_VALUE and (rec.src_system, rec.src_component) not in not_autopilots:
                _param_value(msg, params)
            elif mid == ID_GPS_GLOBAL_ORIGIN and (rec.src_system, rec.src_component) not in not_autopilots:
                origin = global_origin_from_wire(msg.latitude, msg.longitude, msg.altitude, rec.time_s)
                if origin is not None:
                    origins[rec.src_system] = origin
            elif mid == ID_ATTITUDE and (rec.src_system, rec.src_component) not in not_autopilots:
                if math.isfinite(msg.yaw):
                    newest_yaw[rec.src_system] = msg.yaw
            elif mid == ID_SPT:
                sp = _setpoint(msg)
                sender = (rec.src_system, rec.src_component)
                events.setdefault(sender, []).append((rec.time_s, sp, newest_sample.get(msg.target_system)))
                last_target[sender] = msg.target_system
                found = newest_sample.get(msg.target_system)
                if found is not None:  # a "setpoints" tick, built below if the log is of that kind
                    setpoint_pairs.append((rec.time_s, found, newest_yaw.get(msg.target_system), sp))
            elif mid == ID_SAT:
                sender = (rec.src_system, rec.src_component)
                events.setdefault(sender, []).append(
                    (rec.time_s, LoggedAttitude(tuple(msg.q), msg.thrust, msg.type_mask),
                     newest_sample.get(msg.target_system)))
                last_target[sender] = msg.target_system
            elif mid == ID_DFA:
                name = msg.name.decode("ascii", "replace") if isinstance(msg.name, bytes) else str(msg.name)
                if name != GUIDANCE_ARRAY_NAME:
                    continue
                # As recorded, float32 (an hour's log holds 180,000 rows: a list of Python floats
                # would take five times the memory, and filling it, time).
                row = msg.data[:N_DEBUG]  # the light decoder's float arrays are array("f")
                if type(row) is not array:
                    row = array("f", row)
                sender = (rec.src_system, rec.src_component)
                # the autopilot this sender commands: its last setpoint's target, else its own
                # system (a companion shares its vehicle's system id), else the first to send positions
                target = last_target.get(sender)
                if target not in samples_by_ms:
                    target = rec.src_system if rec.src_system in samples_by_ms else next(iter(samples_by_ms), None)
                boot_ms = int(msg.time_usec // 1000)
                hold_reason = int(row[DEBUG_INDEX["hold_reason"]])
                sample = samples_by_ms.get(target, {}).get(boot_ms)
                rebuilt = False
                if sample is None and hold_reason != 2:  # 2: no position had arrived yet
                    sample = _sample_from_debug(row, boot_ms)
                    rebuilt = sample is not None
                    reconstructed += rebuilt
                tick = LoggedTick(
                    time_unix_s=rec.time_s, tick=int(row[DEBUG_INDEX["tick"]]),
                    t_s=row[DEBUG_INDEX["t_s"]], sample=sample,
                    sample_age_s=row[DEBUG_INDEX["sample_age_s"]],
                    yaw_ned_rad=_tick_yaw(row, newest_yaw.get(target)), setpoint=None, debug=row,
                    sample_reconstructed=rebuilt)
                companion_ticks.append(tick)
                events.setdefault(sender, []).append((rec.time_s, tick, None))

    if reader.records == 0:
        raise LogError(f"{path}: no MAVLink records could be read ({reader.size_bytes} bytes)")
    if companion_ticks:
        kind, ticks = "companion", companion_ticks
        coasts = _pair_companion_ticks(events, companion_ticks, reconstructed, notes)
    elif setpoint_pairs:
        kind, ticks = "setpoints", _setpoint_ticks(setpoint_pairs)
        notes.append("no companion guidance records: each logged setpoint is paired with the newest "
                     "LOCAL_POSITION_NED before it (another controller's setpoints are expected to differ)")
    else:
        raise LogError(f"{path}: no SET_POSITION_TARGET_LOCAL_NED paired with a LOCAL_POSITION_NED; "
                       "nothing to replay")
    return LoggedFlight(path, kind, ticks, coasts, list(reader.warnings), notes, reader.records,
                        _commanded_origin(last_target, origins), params)


def _pair_companion_ticks(events: dict[tuple[int, int], list[tuple]], ticks: list[LoggedTick],
                          reconstructed: int, notes: list[str]) -> list[LoggedCoast]:
    """Pair the recorded ticks with their setpoints; say what was left unpaired or rebuilt."""
    unpaired_ticks, unpaired_setpoints, coasts = _pair_setpoints(events, _tick_rate_hz(ticks), ticks)
    if unpaired_ticks:
        notes.append(f"{unpaired_ticks} recorded ticks have no setpoint of their own (a result that "
                     "arrived after its tick had coasted, or a damaged log): stepped, not compared")
    if coasts:
        notes.append(f"{len(coasts)} setpoints were sent while a slow guidance step ran (coasting): "
                     "compared with coast_setpoint of the previous result")
    if unpaired_setpoints - len(coasts):
        notes.append(f"{unpaired_setpoints - len(coasts)} setpoints were sent outside the guidance loop "
                     "(before its first tick or after its last): not compared")
    if reconstructed:
        notes.append(f"{reconstructed} ticks used a LOCAL_POSITION_NED sample missing from the log; "
                     "rebuilt from the recorded internals (velocity approximate)")
    return coasts


def _commanded_origin(last_target: dict[tuple[int, int], int],
                      origins: dict[int, GlobalOrigin]) -> GlobalOrigin | None:
    """The GPS_GLOBAL_ORIGIN of the commanded autopilot: the target of the setpoints (the most
    common), else the only autopilot that sent one."""
    targets = list(last_target.values())
    commanded = max(set(targets), key=targets.count) if targets else None
    return origins.get(commanded) if commanded in origins else (
        next(iter(origins.values())) if len(origins) == 1 else None)


def _setpoint_ticks(pairs: list[tuple]) -> list[LoggedTick]:
    """The ticks of a "setpoints" log: each setpoint with the newest sample before it, the tick
    time the sample's autopilot time since the first one, the age the tlog time between them."""
    first_boot_ms = pairs[0][1][1].time_boot_ms
    return [LoggedTick(time_unix_s=time_s, tick=i, t_s=(sample.time_boot_ms - first_boot_ms) / 1000.0,
                       sample=sample, sample_age_s=max(0.0, time_s - sample_time), yaw_ned_rad=yaw,
                       setpoint=sp)
            for i, (time_s, (sample_time, sample), yaw, sp) in enumerate(pairs)]


def _recorded(ticks: list[LoggedTick], layout: int, field: str) -> float | None:
    """The first positive ``field`` the ticks of ``debug_layout`` >= ``layout`` record, or None.

    The record is float32: the value comes back as its 7 significant digits, so that a setting
    typed as 0.3 replays as 0.3, not 0.30000001."""
    for tk in ticks:
        row = tk.debug
        if row is not None and row[DEBUG_INDEX["debug_layout"]] >= layout:
            value = float(row[DEBUG_INDEX[field]])
            if math.isfinite(value) and value > 0:
                return float(f"{value:.7g}")
    return None


def recorded_rate_hz(ticks: list[LoggedTick]) -> float | None:
    """The loop rate the flight's ticks record (``debug_layout`` >= 3), or None (older logs)."""
    return _recorded(ticks, LAYOUT_WITH_RATE, "rate_hz")


def recorded_drift_tc_s(ticks: list[LoggedTick]) -> float:
    """The drift compensation's time constant the flight's ticks record (``debug_layout`` >= 4),
    0 when it was off or the log predates it."""
    return _recorded(ticks, LAYOUT_WITH_DRIFT, "drift_tc_s") or 0.0


def recorded_speed_hold_tc_s(ticks: list[LoggedTick]) -> float:
    """The speed hold's integral time the flight's ticks record (``debug_layout`` >= 5), 0 when it
    was off or the log predates it."""
    return _recorded(ticks, LAYOUT_WITH_SPEED_HOLD, "speed_hold_tc_s") or 0.0


def recorded_tail(ticks: list[LoggedTick]) -> tuple[float, float]:
    """The slow tail's share and time that the flight's ticks compensated (``debug_layout`` >= 6),
    ``(0, 0)`` when the compensation was off or the log predates it."""
    share = _recorded(ticks, LAYOUT_WITH_TAIL_COMP, "tail_share")
    if share is None:
        return 0.0, 0.0
    return share, _recorded(ticks, LAYOUT_WITH_TAIL_COMP, "tail_tc_s") or 0.0


def _tick_rate_hz(ticks: list[LoggedTick]) -> float:
    """Loop rate: the one recorded, else from the median spacing of the tick times (50 Hz if unknown)."""
    recorded = recorded_rate_hz(ticks)
    if recorded is not None:
        return recorded
    times = sorted(tk.t_s for tk in ticks if math.isfinite(tk.t_s))
    steps = [b - a for a, b in zip(times, times[1:]) if b > a]
    if not steps:
        return 50.0
    steps.sort()
    return 1.0 / steps[len(steps) // 2]


def _pair_setpoints(events: dict[tuple[int, int], list[tuple]], rate_hz: float,
                    ticks: list[LoggedTick]) -> tuple[int, int, list[LoggedCoast]]:
    """Give each recorded tick the setpoint its sender sent with it; find the coasting setpoints.

    The loop records a tick's guidance row and then sends that tick's setpoint, normally
    microseconds apart. A row recorded late (its step outlived its tick, which coasted) is
    followed either by the row of a fresh step or, when that one is slow too, by a coasting
    setpoint sent only after the step budget (half a period) has run out. So a row is paired
    with the next record of the same sender when that is a setpoint less than
    :data:`PAIR_GAP_PERIODS` of a period later (a pair delayed longer by a busy machine is left
    unpaired: not compared, never mis-compared). The other setpoints of a sender between its first
    and its last row are coasts.
    Returns ``(rows without a setpoint, setpoints without a row, coasts)``.
    """
    max_gap_s = PAIR_GAP_PERIODS / rate_hz
    index = {id(tk): i for i, tk in enumerate(ticks)}
    unpaired_rows = 0
    paired = 0
    setpoints = 0
    coasts: list[LoggedCoast] = []
    for seq in events.values():
        rows_at = [i for i, ev in enumerate(seq) if isinstance(ev[1], LoggedTick)]
        first_row, last_row = (rows_at[0], rows_at[-1]) if rows_at else (len(seq), -1)
        taken = set()
        last_tick = None
        for i, (time_s, item, newest) in enumerate(seq):
            if not isinstance(item, LoggedTick):
                setpoints += 1
                if i not in taken and first_row < i < last_row and last_tick is not None:
                    sample_time, sample = newest if newest is not None else (math.nan, None)
                    coasts.append(LoggedCoast(time_s, last_tick, sample, max(0.0, time_s - sample_time)
                                              if sample is not None else math.inf, item))
                continue
            last_tick = index[id(item)]
            nxt = seq[i + 1] if i + 1 < len(seq) else None
            if nxt is not None and isinstance(nxt[1], (LoggedSetpoint, LoggedAttitude)) \
                    and nxt[0] - time_s <= max_gap_s:
                item.setpoint = nxt[1]
                taken.add(i + 1)
                paired += 1
            else:
                unpaired_rows += 1
    return unpaired_rows, setpoints - paired, coasts


def phase_name(code: float) -> str:
    """Phase name of a recorded phase code (``"unknown"`` for anything else)."""
    return _PHASE_NAMES.get(int(code), "unknown") if math.isfinite(code) else "unknown"


_PHASE_NAMES = {v: k for k, v in PHASE_CODES.items()}
