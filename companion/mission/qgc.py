"""Imports from QGroundControl: ``.plan`` (JSON) and ``QGC WPL 110`` waypoint files.

Both formats list MAVLink mission items (command id, frame, seven parameters). The import keeps
what a mission file can represent and says what it drops:

- ``NAV_WAYPOINT`` (16) and ``NAV_SPLINE_WAYPOINT`` (82) become path waypoints (the path is a C^2
  cubic spline through them, so every waypoint lies on it). A hold time is dropped with a note.
- ``NAV_TAKEOFF`` / ``NAV_VTOL_TAKEOFF`` are skipped with a note (guidance starts airborne).
- A final ``NAV_RETURN_TO_LAUNCH`` / ``NAV_LAND`` / ``NAV_LOITER_UNLIM`` becomes ``on_finish:
  rtl | land | loiter`` (a land or loiter position becomes the last waypoint, flown at the mission
  altitude; a landing item's own altitude is ignored).
- ``DO_CHANGE_SPEED`` (a ground or air speed) applies from the waypoint before it on: several
  speeds make ``speed_m_s`` a per-waypoint profile. Climb / descent speeds are skipped with a note.
- Other non-navigation items (camera, servo, ROI, conditions...) are skipped with a note.
- Each waypoint keeps its altitude (frame 3 above home; frame 0 AMSL minus home's altitude):
  waypoints at different altitudes make ``altitude_m`` a per-waypoint profile (``altitude_m``
  given to :func:`convert` flattens them to one height).
- Refused, because a mission path cannot represent them: ``DO_JUMP`` loops, timed or counted
  loiters, navigation commands in the middle that end a flight, survey / corridor complex items,
  items in local or terrain-relative frames (no terrain model), positions at 0, 0.

Positions are converted from WGS-84 to local ENU metres about the plan's home
(``plannedHomePosition`` in a ``.plan``; item 0 of a WPL file, as QGroundControl and Mission
Planner write it), and the mission is written with ``frame: geodetic`` and that ``origin``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path as FilePath

import numpy as np

from companion.errors import MissionError
from companion.geometry import geodetic
from companion.mission.loader import MAX_FILE_BYTES, _decode, parse_mission

# MAVLink command ids (common.xml).
CMD_NAMES = {
    16: "NAV_WAYPOINT", 17: "NAV_LOITER_UNLIM", 18: "NAV_LOITER_TURNS", 19: "NAV_LOITER_TIME",
    20: "NAV_RETURN_TO_LAUNCH", 21: "NAV_LAND", 22: "NAV_TAKEOFF", 31: "NAV_LOITER_TO_ALT",
    82: "NAV_SPLINE_WAYPOINT", 84: "NAV_VTOL_TAKEOFF", 85: "NAV_VTOL_LAND", 93: "NAV_DELAY",
    112: "CONDITION_DELAY", 114: "CONDITION_DISTANCE", 115: "CONDITION_YAW",
    177: "DO_JUMP", 178: "DO_CHANGE_SPEED", 183: "DO_SET_SERVO", 195: "DO_SET_ROI_LOCATION",
    197: "DO_SET_ROI_NONE", 201: "DO_SET_ROI", 203: "DO_DIGICAM_CONTROL", 205: "DO_MOUNT_CONTROL",
    206: "DO_SET_CAM_TRIGG_DIST", 530: "SET_CAMERA_MODE", 601: "DO_JUMP_TAG",
    2000: "IMAGE_START_CAPTURE", 2001: "IMAGE_STOP_CAPTURE", 2500: "VIDEO_START_CAPTURE",
    2501: "VIDEO_STOP_CAPTURE",
}
WAYPOINT_CMDS = {16, 82}
TAKEOFF_CMDS = {22, 84}
FINISH_CMDS = {20: "rtl", 21: "land", 85: "land", 17: "loiter"}
REFUSED_CMDS = {
    177: "a DO_JUMP loop cannot be represented (a mission path is flown once, or closed)",
    601: "a DO_JUMP_TAG loop cannot be represented",
    18: "a loiter of N turns cannot be represented inside a path",
    19: "a timed loiter cannot be represented inside a path",
    31: "a loiter to altitude cannot be represented inside a path",
    93: "a timed delay cannot be represented (the path is flown at constant speed)",
}
# MAV_FRAME values with a geodetic position: altitude relative to home, or above mean sea level.
FRAMES_RELATIVE = {3, 6}  # GLOBAL_RELATIVE_ALT(_INT)
FRAMES_ABSOLUTE = {0, 5}  # GLOBAL(_INT), AMSL
FRAMES_TERRAIN = {10, 11}
FRAME_MISSION = 2
ALTITUDE_TOLERANCE_M = 0.5
DEFAULT_SPEED_M_S = 5.0


@dataclass
class Item:
    """One mission item, whatever file it came from. ``where`` names it in messages."""

    where: str
    command: int
    frame: int
    params: list[float]  # param1..param7; NaN where the file has null

    @property
    def name(self) -> str:
        return f"{CMD_NAMES.get(self.command, 'command')} ({self.command})"

    @property
    def lat_lon(self) -> tuple[float, float]:
        return self.params[4], self.params[5]


@dataclass
class PlanData:
    """What both file formats reduce to before conversion."""

    items: list[Item]
    home: tuple[float, float, float] | None  # lat_deg, lon_deg, alt_m (AMSL)
    home_where: str = "home"
    speed_hint_m_s: float | None = None  # from the plan's cruise / hover speed
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class ImportResult:
    """An imported mission: the YAML text to write, and the notes to show the user."""

    yaml_text: str
    notes: tuple[str, ...]
    points_enu_m: np.ndarray
    origin: tuple[float, float, float]


# -------------------------------------------------------------------------------- readers
def _num(value) -> float:
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError
    return float(value)


def read_plan(text: str, source: str) -> PlanData:
    """Parse a QGroundControl ``.plan`` (JSON) into items and home."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise MissionError(f"{source}: line {err.lineno}, column {err.colno}: expected a "
                           f"QGroundControl .plan (JSON), got {err.msg}") from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise MissionError(f"{source}: fileType: expected \"Plan\" (a QGroundControl .plan), got "
                           f"{doc.get('fileType')!r}" if isinstance(doc, dict) else
                           f"{source}: expected a QGroundControl .plan JSON object")
    mission = doc.get("mission")
    if not isinstance(mission, dict) or not isinstance(mission.get("items"), list):
        raise MissionError(f"{source}: mission.items: expected a list of mission items")
    data = PlanData(items=[], home=None, home_where="mission.plannedHomePosition")
    home = mission.get("plannedHomePosition")
    try:
        if isinstance(home, list) and len(home) == 3:
            lat, lon, alt = (_num(v) for v in home)
            if math.isfinite(lat) and math.isfinite(lon) and (lat, lon) != (0.0, 0.0):
                data.home = (lat, lon, alt if math.isfinite(alt) else 0.0)
    except TypeError:
        pass
    if data.home is None:
        data.notes.append(f"{source}: note: mission.plannedHomePosition: missing or unusable; the "
                          "first waypoint is the origin")
    vehicle = mission.get("vehicleType")
    speed_key = "cruiseSpeed" if vehicle == 1 else "hoverSpeed"  # MAV_TYPE_FIXED_WING = 1
    speed = mission.get(speed_key)
    if isinstance(speed, (int, float)) and not isinstance(speed, bool) and 0 < speed <= 100:
        data.speed_hint_m_s = float(speed)
    for i, raw in enumerate(mission["items"]):
        where = f"mission.items[{i}]"
        if not isinstance(raw, dict):
            data.problems.append(f"{source}: {where}: expected a mission item object")
            continue
        if raw.get("type") == "ComplexItem":
            kind = raw.get("complexItemType", "complex item")
            data.problems.append(f"{source}: {where}: {kind} cannot be represented; expected simple "
                                 "items (add the waypoints as simple items instead)")
            continue
        if raw.get("type") != "SimpleItem":
            data.problems.append(f"{source}: {where}.type: expected SimpleItem, got {raw.get('type')!r}")
            continue
        try:
            command = raw["command"]
            frame = raw["frame"]
            params = [_num(v) for v in raw["params"]]
            if isinstance(command, bool) or not isinstance(command, int) or \
                    isinstance(frame, bool) or not isinstance(frame, int) or len(params) != 7:
                raise TypeError
        except (KeyError, TypeError):
            data.problems.append(f"{source}: {where}: expected command (int), frame (int) and 7 params")
            continue
        data.items.append(Item(where, command, frame, params))
    return data


WPL_HEADER = "QGC WPL 110"


def read_wpl(text: str, source: str) -> PlanData:
    """Parse a ``QGC WPL 110`` text file: a header line, then one tab-separated item per line.

    Columns: index, current, frame, command, param1..param4, latitude, longitude, altitude,
    autocontinue. Item 0 is the home position.
    """
    lines = text.splitlines()
    if not lines or lines[0].strip() != WPL_HEADER:
        got = lines[0].strip()[:40] if lines else "an empty file"
        raise MissionError(f"{source}: line 1: expected the header {WPL_HEADER!r}, got {got!r}")
    data = PlanData(items=[], home=None, home_where="line 2 (item 0, home)")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split()
        where = f"line {number}"
        if len(fields) != 12:
            data.problems.append(f"{source}: {where}: expected 12 tab-separated fields, got {len(fields)}")
            continue
        try:
            index, _current, frame, command = (int(v) for v in fields[:4])
            params = [float(v) for v in fields[4:11]]
        except ValueError:
            data.problems.append(f"{source}: {where}: expected integers then numbers, got "
                                 f"{line.strip()[:60]!r}")
            continue
        if not all(math.isfinite(p) for p in params[4:6]):
            data.problems.append(f"{source}: {where}: expected a finite latitude and longitude")
            continue
        rows.append((index, Item(f"{where} (item {index})", command, frame, params)))
    if rows and rows[0][0] == 0:
        _, home = rows.pop(0)
        lat, lon = home.lat_lon
        if (lat, lon) != (0.0, 0.0):
            data.home = (lat, lon, home.params[6])
    if data.home is None:
        data.notes.append(f"{source}: note: item 0 (home): missing or at 0, 0; the first waypoint is "
                          "the origin")
    data.items = [item for _, item in rows]
    return data


# -------------------------------------------------------------------------------- conversion
class _ItemWalk:
    """One pass over the items: waypoints with their heights, speed changes, the finish."""

    def __init__(self, data: PlanData, source: str, problems: list[str], notes: list[str]):
        self.data = data
        self.source = source
        self.problems = problems
        self.notes = notes
        self.waypoints: list[tuple[Item, float | None]] = []  # (item, altitude above home)
        self.speeds: list[tuple[str, float]] = []
        self.speed_from: dict[int, float] = {}  # waypoint index -> the speed flown from it on
        self.first_speed: float | None = None  # a speed set before the first waypoint
        self.on_finish = "hold"
        self.finish_item: Item | None = None
        nav_items = [it for it in data.items if it.command < 100 and it.command not in TAKEOFF_CMDS]
        self.last_nav = nav_items[-1] if nav_items else None

    def run(self) -> None:
        source = self.source
        for item in self.data.items:
            cmd = item.command
            if cmd in WAYPOINT_CMDS:
                hold = item.params[0]
                if math.isfinite(hold) and hold > 0:
                    self.notes.append(f"{source}: note: {item.where}: hold time of {hold:g} s dropped (the "
                                      "path is flown without stopping)")
                self.add_position(item)
            elif cmd in TAKEOFF_CMDS:
                self.notes.append(f"{source}: note: {item.where}: skipped {item.name}: guidance starts "
                                  "airborne")
            elif cmd in FINISH_CMDS:
                self.finish(item)
            elif cmd in REFUSED_CMDS:
                self.problems.append(f"{source}: {item.where}: {item.name}: {REFUSED_CMDS[cmd]}")
            elif cmd < 100:
                self.problems.append(f"{source}: {item.where}: {item.name}: navigation command not "
                                     "supported; expected NAV_WAYPOINT, NAV_SPLINE_WAYPOINT, NAV_TAKEOFF, "
                                     "or a final NAV_LAND / NAV_RETURN_TO_LAUNCH / NAV_LOITER_UNLIM")
            elif cmd == 178:
                self.change_speed(item)
            else:
                self.notes.append(f"{source}: note: {item.where}: skipped {item.name}: not a navigation "
                                  "item")
        if self.finish_item is not None:
            self.notes.append(f"{source}: note: {self.finish_item.where}: {self.finish_item.name} becomes "
                              f"on_finish: {self.on_finish}")

    def altitude_of(self, item: Item) -> float | None:
        alt = item.params[6]
        source, home = self.source, self.data.home
        if item.frame in FRAMES_RELATIVE:
            return alt
        if item.frame in FRAMES_ABSOLUTE:
            if home is None:
                self.problems.append(f"{source}: {item.where}: expected a home position to convert an "
                                     "absolute (AMSL) altitude")
                return None
            return alt - home[2]
        if item.frame in FRAMES_TERRAIN:
            self.problems.append(f"{source}: {item.where}: terrain-relative altitude cannot be "
                                 "represented; expected frame 3 (relative to home) or 0 (AMSL)")
            return None
        self.problems.append(f"{source}: {item.where}: frame {item.frame} cannot be represented; "
                             "expected a global frame (0 or 3)")
        return None

    def add_position(self, item: Item, use_altitude: bool = True) -> None:
        lat, lon = item.lat_lon
        if not (math.isfinite(lat) and math.isfinite(lon)) or (lat, lon) == (0.0, 0.0):
            self.problems.append(f"{self.source}: {item.where}: {item.name} expected a latitude and "
                                 "longitude, got none (0, 0)")
            return
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            self.problems.append(f"{self.source}: {item.where}: expected latitude in -90..90 and "
                                 f"longitude in -180..180, got {lat:g}, {lon:g}")
            return
        if not use_altitude:  # a landing point: flown at the mission altitude, then landed
            self.waypoints.append((item, None))
            return
        alt = self.altitude_of(item)
        if alt is not None:
            self.waypoints.append((item, alt))

    def finish(self, item: Item) -> None:
        cmd = item.command
        if item is not self.last_nav:
            self.problems.append(f"{self.source}: {item.where}: {item.name} in the middle of the mission "
                                 "cannot be represented; expected it only as the last navigation item")
            return
        self.on_finish = FINISH_CMDS[cmd]
        self.finish_item = item
        lat, lon = item.lat_lon
        if cmd != 20 and math.isfinite(lat) and math.isfinite(lon) and (lat, lon) != (0.0, 0.0):
            self.add_position(item, use_altitude=(cmd == 17))

    def change_speed(self, item: Item) -> None:
        source = self.source
        value = item.params[1]
        kind = item.params[0]
        if math.isfinite(kind) and int(kind) in (2, 3):
            self.notes.append(f"{source}: note: {item.where}: skipped DO_CHANGE_SPEED of a "
                              f"{'climb' if int(kind) == 2 else 'descent'} speed (the climb and sink "
                              "limits are vertical.climb_max_m_s and vertical.sink_max_m_s)")
        elif math.isfinite(value) and value > 0:
            self.speeds.append((item.where, value))
            if self.waypoints:
                self.speed_from[len(self.waypoints) - 1] = value
                self.notes.append(f"{source}: note: {item.where}: DO_CHANGE_SPEED {value:g} m/s from "
                                  f"{self.waypoints[-1][0].where} on")
            else:
                self.first_speed = value
                self.notes.append(f"{source}: note: {item.where}: DO_CHANGE_SPEED {value:g} m/s from "
                                  "the start")
        else:
            self.notes.append(f"{source}: note: {item.where}: skipped DO_CHANGE_SPEED without a speed")


def _waypoint_altitudes(walk: _ItemWalk, altitude_m: float | None) -> list[float]:
    """One height above home per waypoint; a landing point is flown at the height before it."""
    altitudes: list[float] = []
    for _, alt in walk.waypoints:
        altitudes.append(alt if alt is not None else (altitudes[-1] if altitudes else math.nan))
    if altitude_m is not None:
        altitudes = [altitude_m] * len(walk.waypoints)
    elif altitudes and not math.isfinite(altitudes[0]):
        altitudes = [next((a for a in altitudes if math.isfinite(a)), math.nan)] * len(altitudes)
    for (item, _), alt in zip(walk.waypoints, altitudes):
        if math.isfinite(alt) and not alt > 0:
            walk.problems.append(f"{walk.source}: {item.where}: expected a waypoint above home "
                                 f"(altitude > 0), got {alt:g} m")
    return altitudes


def _waypoint_speeds(walk: _ItemWalk, speed_m_s: float | None) -> list[float]:
    """The user's speed, else each DO_CHANGE_SPEED from its waypoint on (the first from the plan's
    default speed, else 5 m/s, until a DO_CHANGE_SPEED sets it)."""
    if speed_m_s is not None:
        return [speed_m_s] * len(walk.waypoints)
    source = walk.source
    current = walk.first_speed
    if current is None:
        if walk.data.speed_hint_m_s is not None:
            current = walk.data.speed_hint_m_s
            walk.notes.append(f"{source}: note: speed {current:g} m/s from the plan's default speed"
                              + (" until the first DO_CHANGE_SPEED" if walk.speeds else ""))
        else:
            current = DEFAULT_SPEED_M_S
            walk.notes.append(f"{source}: note: no speed in the file before the first DO_CHANGE_SPEED: "
                              f"{current:g} m/s" if walk.speeds else
                              f"{source}: note: no speed in the file: speed_m_s {current:g}")
    speed_list: list[float] = []
    for i in range(len(walk.waypoints)):
        current = walk.speed_from.get(i, current)
        speed_list.append(current)
    return speed_list


@dataclass
class _Placed:
    """The waypoints in local ENU metres about the origin, repeated positions dropped."""

    origin: tuple[float, float, float]
    points: np.ndarray
    items: list[Item]
    heights: np.ndarray
    speeds: list[float]


def _place(walk: _ItemWalk, altitudes: list[float], speed_list: list[float]) -> _Placed:
    """Convert to ENU about home (else the first waypoint); a repeated position is dropped, its
    height and speed carried onto the waypoint kept."""
    data, waypoints, source = walk.data, walk.waypoints, walk.source
    if data.home is not None:
        origin = data.home
    else:
        first = waypoints[0][0]
        origin = (first.lat_lon[0], first.lat_lon[1], 0.0)
    lat = np.array([it.lat_lon[0] for it, _ in waypoints])
    lon = np.array([it.lat_lon[1] for it, _ in waypoints])
    heights = np.asarray(altitudes, dtype=float)
    east, north, _ = geodetic.enu_from_geodetic(lat, lon, origin[2] + heights, *origin)
    points = np.column_stack([east, north])
    keep = [0]
    for i in range(1, len(points)):
        if math.hypot(*(points[i] - points[keep[-1]])) < 1e-3:
            walk.notes.append(f"{source}: note: {waypoints[i][0].where}: same position as the previous "
                              "waypoint, dropped" + (f" (its altitude {heights[i]:g} m replaces "
                                                      f"{heights[keep[-1]]:g} m)"
                                                      if abs(heights[i] - heights[keep[-1]]) > 1e-9 else ""))
            heights[keep[-1]] = heights[i]
            speed_list[keep[-1]] = speed_list[i]  # a speed change at the dropped point still applies
        else:
            keep.append(i)
    return _Placed(origin, points[keep], [waypoints[i][0] for i in keep], heights[keep],
                   [speed_list[i] for i in keep])


def _profile_texts(placed: _Placed, walk: _ItemWalk) -> tuple[str, str]:
    """``altitude_m`` and ``speed_m_s`` as YAML: one number when they agree, else a list."""
    heights, kept_speeds = placed.heights, placed.speeds
    if float(np.max(heights) - np.min(heights)) <= ALTITUDE_TOLERANCE_M:
        altitude_text = f"{float(np.mean(heights)):.3f}"
    else:
        altitude_text = "[" + ", ".join(f"{h:.3f}" for h in heights) + "]"
        walk.notes.append(f"{walk.source}: note: waypoint altitudes from {float(np.min(heights)):g} m to "
                          f"{float(np.max(heights)):g} m above home: altitude_m is a profile along the path")
    if len(set(kept_speeds)) == 1:
        speed_text = f"{kept_speeds[0]:g}"
    else:
        speed_text = "[" + ", ".join(f"{v:g}" for v in kept_speeds) + "]"
    return altitude_text, speed_text


def _mission_yaml(data: PlanData, source: str, name: str, l1_m: float, on_finish: str, placed: _Placed,
                  altitude_text: str, speed_text: str) -> str:
    origin, points = placed.origin, placed.points
    lines = [
        f"# Imported from {FilePath(source).name} by `companion mission import`.",
        "# Waypoints: WGS-84 converted to local ENU metres (x east, y north) about the origin",
        f"# ({data.home_where if data.home is not None else 'the first waypoint'}).",
        "version: 1",
        f"name: {json.dumps(name)}",
        "frame: geodetic",
        f"origin: {{lat_deg: {origin[0]:.9f}, lon_deg: {origin[1]:.9f}, alt_m: {origin[2]:.3f}}}",
        f"speed_m_s: {speed_text}",
        f"altitude_m: {altitude_text}",
        "path:",
        "  type: waypoints",
        "  points_m:",
    ]
    for (x, y), item in zip(points, placed.items):
        lines.append(f"    - [{x:.4f}, {y:.4f}]  # {item.where}: {item.lat_lon[0]:.8f}, "
                     f"{item.lat_lon[1]:.8f}")
    lines += [
        f"guidance: {{method: corrector, l1_m: {l1_m:g}, rate_hz: 50}}",
        "midcourse: {circle_radius_m: 10.0}",
        f"on_finish: {on_finish}",
    ]
    if data.home is not None:
        # Simulations start where the vehicle is after take-off: above home, facing the first waypoint.
        x0, y0 = points[0]
        bearing = math.degrees(math.atan2(y0, x0)) if math.hypot(x0, y0) > 1e-3 else 0.0
        lines += [
            "# Simulations start above home, facing the first waypoint.",
            f"start: {{x_m: 0.0, y_m: 0.0, heading_deg: {bearing:.3f}}}",
        ]
    return "\n".join(lines) + "\n"


def convert(data: PlanData, source: str, *, name: str, speed_m_s: float | None = None,
            altitude_m: float | None = None, l1_m: float = 10.0) -> ImportResult:
    """Turn items into mission YAML, or raise :class:`MissionError` with every refusal."""
    walk = _ItemWalk(data, source, list(data.problems), list(data.notes))
    walk.run()
    altitudes = _waypoint_altitudes(walk, altitude_m)
    speed_list = _waypoint_speeds(walk, speed_m_s)
    if len(walk.waypoints) < 2 and not walk.problems:
        walk.problems.append(f"{source}: expected at least 2 waypoints with positions, got "
                             f"{len(walk.waypoints)}")
    if walk.problems:
        raise MissionError(walk.problems)
    placed = _place(walk, altitudes, speed_list)
    altitude_text, speed_text = _profile_texts(placed, walk)
    text = _mission_yaml(data, source, name, l1_m, walk.on_finish, placed, altitude_text, speed_text)
    mission = parse_mission(text, f"{source} (imported)")  # refuses what the format cannot fly
    notes = walk.notes + list(mission.warnings)
    return ImportResult(text, tuple(notes), placed.points, placed.origin)


def import_file(file, *, name: str | None = None, speed_m_s: float | None = None,
                altitude_m: float | None = None) -> ImportResult:
    """Import a ``.plan`` or ``QGC WPL 110`` file (chosen by content, then by extension)."""
    source = str(file)
    path = FilePath(file)
    if not path.is_file():
        raise MissionError(f"{source}: file not found")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise MissionError(f"{source}: expected a plan of at most {MAX_FILE_BYTES} bytes, got {size} bytes")
    text = _decode(path.read_bytes(), source)
    stripped = text.lstrip()
    if stripped.startswith("QGC WPL"):
        data = read_wpl(text, source)
    elif stripped.startswith("{") or path.suffix.lower() == ".plan":
        data = read_plan(text, source)
    elif path.suffix.lower() in (".waypoints", ".txt", ".wpl"):
        data = read_wpl(text, source)
    else:
        raise MissionError(f"{source}: expected a QGroundControl .plan (JSON) or a 'QGC WPL 110' "
                           "file, got neither")
    return convert(data, source, name=name or path.stem, speed_m_s=speed_m_s, altitude_m=altitude_m)
