"""Loading a mission file: YAML text -> validated :class:`~companion.mission.model.Mission`.

Steps, each collecting every problem it finds before giving up:

1. the file itself: exists, at most :data:`MAX_FILE_BYTES`, UTF-8 text, valid YAML without
   duplicate keys or aliases, a mapping at the top;
2. the schema (:mod:`companion.mission.schema`): key names, types, ranges, defaults;
3. the cross-key rules and the geometry: expressions in the whitelist and finite over their
   range, ranges in increasing order, enough distinct points, no duplicate consecutive points, the
   path at least one L1 long, a closed path that really closes;
4. warnings (the mission still loads): curvature tighter than the guidance can follow.

Every problem is one line ``<file>: <key.path>: <what was expected>``; they are raised together
as one :class:`companion.errors.MissionError`.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path as FilePath

import numpy as np
import yaml

from companion.errors import MissionError
from companion.geometry import geodetic
from companion.geometry.paths import Path, function_path, parametric_path, waypoint_path
from companion.geometry.profile import PathProfile, ProfileLimits, build_profile, knots_table
from companion.guidance.types import DEFAULT_LAMBDA_S4, VEHICLE_MODEL_KEYS, GuidanceParams, VehicleModel
from companion.mission import schema
from companion.mission.expressions import ExpressionError, compile_expression
from companion.mission.model import GeodeticOrigin, Mission, StartState

#: Files larger than this are refused before reading (a mission is a few kilobytes).
MAX_FILE_BYTES = 1_000_000
#: Points closer than this are "the same point".
DUPLICATE_TOLERANCE_M = 1e-3
#: Samples used to check that expressions are finite over their range.
CHECK_SAMPLES = 2001
#: A smoothed altitude profile further than this from a waypoint's height is warned about.
PROFILE_WARN_M = 0.5


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing duplicate keys and aliases (no silent overrides, no bombs)."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.MarkedYAMLError(None, None, "aliases (*name) are not supported",
                                       event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:
                duplicate = False
            if duplicate:
                raise yaml.MarkedYAMLError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            try:
                seen.add(key)
            except TypeError:
                pass
        return super().construct_mapping(node, deep=deep)


def read_mission_text(file) -> str:
    """The text of a mission file, refusing what is missing, huge or not UTF-8 text."""
    name = str(file)
    path = FilePath(file)
    if not path.exists():
        raise MissionError(f"{name}: file not found")
    if not path.is_file():
        raise MissionError(f"{name}: expected a mission file, got a directory or special file")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise MissionError(f"{name}: expected a mission file of at most {MAX_FILE_BYTES} bytes, "
                           f"got {size} bytes")
    try:
        data = path.read_bytes()
    except OSError as err:
        raise MissionError(f"{name}: cannot read the file ({err.strerror})") from None
    return _decode(data, name)


def _decode(data: bytes, name: str) -> str:
    if b"\x00" in data:
        raise MissionError(f"{name}: expected a YAML text file, got binary data")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise MissionError(f"{name}: expected a UTF-8 YAML text file, got an invalid byte at "
                           f"offset {err.start}") from None


def load_mission(file) -> Mission:
    """Load and validate a mission file.

    Parameters
    ----------
    file : path of the YAML mission (str or :class:`pathlib.Path`).

    Raises
    ------
    companion.errors.MissionError
        with every problem found, one line each: ``file: key.path: what was expected``.
    """
    return parse_mission(read_mission_text(file), str(file))


def mission_text_with_method(file, method: str) -> str:
    """The text of the (valid) mission ``file`` with its ``guidance.method`` replaced by ``method``
    (``companion bench sitl --method``); comments are not kept."""
    load_mission(file)  # one clear line for a bad mission
    doc = yaml.safe_load(read_mission_text(file))
    doc.setdefault("guidance", {})["method"] = method
    return dump_mission(doc, f"{file} (guidance.method: {method})")


def dump_mission(doc: dict, source_name: str, comments: tuple[str, ...] = ()) -> str:
    """The mission document ``doc`` as YAML text (its keys in their order, after ``comments`` as
    ``#`` lines), checked as :func:`parse_mission` checks a file (``source_name`` prefixes its
    errors)."""
    text = "".join(f"# {line}\n" for line in comments) + yaml.safe_dump(doc, sort_keys=False, width=1000)
    parse_mission(text, source_name)
    return text


def parse_mission(text: str, source_name: str = "<mission>") -> Mission:
    """Validate mission YAML ``text``; ``source_name`` prefixes every error line."""
    mission, problems, _warnings = check_mission_text(text, source_name)
    if problems:
        raise MissionError(problems)
    assert mission is not None
    return mission


def check_mission_text(text: str, source_name: str = "<mission>"):
    """Validate without raising: ``(mission or None, problem lines, warning lines)``.

    ``mission`` is None whenever there is at least one problem. The lines are complete
    (``file: key.path: message``); warnings are also on ``mission.warnings``.
    """
    if len(text) > MAX_FILE_BYTES:
        return None, [f"{source_name}: expected a mission of at most {MAX_FILE_BYTES} characters, "
                      f"got {len(text)}"], []
    if "\x00" in text:
        return None, [f"{source_name}: expected a YAML text file, got binary data"], []
    first_line = next((line.strip() for line in text.splitlines()
                       if line.strip() and not line.lstrip().startswith("#")), "")
    if first_line.startswith("QGC WPL"):
        return None, [f"{source_name}: expected a mission YAML, got a QGC WPL waypoint file; convert "
                      f"it with: companion mission import {source_name} -o mission.yaml"], []
    try:
        doc = yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        what = err.problem or err.context or "unreadable"
        return None, [f"{source_name}: {where}expected valid YAML, got {what}"], []
    except (yaml.YAMLError, RecursionError) as err:
        return None, [f"{source_name}: expected valid YAML ({type(err).__name__})"], []
    if not isinstance(doc, dict):
        got = "an empty file" if doc is None else f"{schema._got(doc)}"
        return None, [f"{source_name}: expected a YAML mapping of mission keys (name, speed_m_s, "
                      f"path, ...), got {got}"], []

    if doc.get("fileType") == "Plan":
        return None, [f"{source_name}: expected a mission YAML, got a QGroundControl .plan; convert "
                      f"it with: companion mission import {source_name} -o mission.yaml"], []

    clean, found = schema.validate(doc)
    problems = [f"{source_name}: {where}: {msg}" for where, msg in found]
    warnings: list[str] = []
    builder = _Builder(clean, source_name, problems, warnings)
    builder.origin_absent = "origin" not in doc
    builder.path_schema_ok = not any(where == "path" or where.startswith(("path.", "path["))
                                     for where, _ in found)
    mission = builder.build(text)
    if problems:
        return None, problems, warnings
    return mission, problems, warnings


@dataclasses.dataclass
class _Knots:
    """Where the profile lists give their values: arc lengths of the waypoints / segment ends."""

    s_m: np.ndarray | None = None
    key: str = ""  # "path.points_m" or "path.segments"
    count: int = 0  # how many values a list must have
    dropped_closing_point: bool = False


class _Checks:
    """What both builders share: the checked document, its frame, and where problems go."""

    def __init__(self, doc: dict, source: str, problems: list[str], warnings: list[str]):
        self.doc = doc
        self.source = source
        self.problems = problems
        self.warnings = warnings
        self.frame = doc.get("frame") or "local_enu"

    def problem(self, where: str, message: str) -> None:
        self.problems.append(f"{self.source}: {where}: {message}")

    def warn(self, where: str, message: str) -> None:
        self.warnings.append(f"{self.source}: {where}: warning: {message}")

    # --------------------------------------------------------------------- frame helpers
    def to_enu_xy(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mission-frame coordinate pairs to ENU (local_ned stores north, east)."""
        if self.frame == "local_ned":
            return b, a
        return a, b

    def to_enu_heading_rad(self, heading_deg: float) -> float:
        if self.frame == "local_ned":
            return math.radians(90.0 - heading_deg)
        return math.radians(heading_deg)


class _PathBuilder(_Checks):
    """The mission's path from ``path:`` (one method per path type), and its profile knots."""

    def __init__(self, doc: dict, source: str, problems: list[str], warnings: list[str]):
        super().__init__(doc, source, problems, warnings)
        self.knots = _Knots()

    def build(self, origin: GeodeticOrigin | None) -> Path | None:
        p = self.doc["path"]
        kind = p.get("type")
        builder = getattr(self, f"path_{kind}", None)
        if builder is None:
            return None
        try:
            return builder(p, origin)
        except ValueError as err:
            self.problem("path", f"expected a usable curve, got: {err}")
            return None

    def expression(self, text, variable: str, where: str):
        if text is None:
            return None
        try:
            return compile_expression(text, variable)
        except ExpressionError as err:
            for message in err.problems:
                self.problem(where, message)
            return None

    def range_(self, values, where: str):
        if values is None or any(v is None for v in values):
            return None
        lo, hi = values
        if not hi > lo:
            self.problem(where, f"expected [first, last] with first < last, got [{lo:g}, {hi:g}]")
            return None
        return lo, hi

    def finite_over(self, fn, lo: float, hi: float, variable: str, where: str) -> bool:
        u = np.linspace(lo, hi, CHECK_SAMPLES)
        values = fn(u)
        bad = ~np.isfinite(values)
        if np.any(bad):
            at = float(u[np.flatnonzero(bad)[0]])
            self.problem(where, f"expected finite values for {variable} in [{lo:g}, {hi:g}], got "
                         f"{values[np.flatnonzero(bad)[0]]} at {variable} = {at:g}")
            return False
        return True

    def path_function(self, p: dict, origin) -> Path | None:
        f = self.expression(p.get("y_of_x"), "x", "path.y_of_x")
        rng = self.range_(p.get("x_range_m"), "path.x_range_m")
        if f is None or rng is None or not self.finite_over(f, *rng, "x", "path.y_of_x"):
            return None
        if self.frame == "local_ned":  # x is north, y = f(x) is east: ENU (f(u), u)
            return parametric_path(f, lambda u: np.asarray(u, dtype=float), rng)
        return function_path(f, rng)

    def path_parametric(self, p: dict, origin) -> Path | None:
        fx = self.expression(p.get("x_of_s"), "s", "path.x_of_s")
        fy = self.expression(p.get("y_of_s"), "s", "path.y_of_s")
        rng = self.range_(p.get("s_range"), "path.s_range")
        if fx is None or fy is None or rng is None:
            return None
        ok_x = self.finite_over(fx, *rng, "s", "path.x_of_s")
        ok_y = self.finite_over(fy, *rng, "s", "path.y_of_s")
        if not (ok_x and ok_y):
            return None
        closed = bool(p.get("closed"))
        if closed and not self.check_closes(fx, fy, rng):
            return None
        ex, ey = self.to_enu_xy(fx, fy)
        return parametric_path(ex, ey, rng, closed=closed)

    def check_closes(self, fx, fy, rng) -> bool:
        lo, hi = rng
        eps = (hi - lo) * 1e-6
        u = np.array([lo, lo + eps, hi - eps, hi])
        x, y = fx(u), fy(u)
        gap = math.hypot(x[3] - x[0], y[3] - y[0])
        if gap > 1e-3:
            self.problem("path.closed", f"expected the curve to end where it starts for closed: true, "
                         f"got a gap of {gap:.4g} m")
            return False
        h0 = math.atan2(y[1] - y[0], x[1] - x[0])
        h1 = math.atan2(y[3] - y[2], x[3] - x[2])
        turn = math.degrees(math.remainder(h1 - h0, 2 * math.pi))
        if abs(turn) > 1.0:
            self.problem("path.closed", f"expected the same heading at both ends for closed: true, got "
                         f"a corner of {turn:.1f} deg")
            return False
        return True

    def waypoint_array(self, p: dict, origin) -> tuple[np.ndarray, str] | None:
        """The waypoints in ENU metres and the key they came from, or None after reporting."""
        has_m = p.get("points_m") is not None
        has_deg = p.get("points_deg") is not None
        if has_m and has_deg:
            self.problem("path", "expected one of points_m or points_deg, got both")
            return None
        if not has_m and not has_deg:
            self.problem("path.points_m", "missing; expected a list of at least 2 points [x_m, y_m]")
            return None
        key = "points_m" if has_m else "points_deg"
        raw = p[key]
        if any(pt is None or any(c is None for c in pt) for pt in raw):
            return None  # reported by the schema
        pts = np.asarray(raw, dtype=float)
        if key == "points_deg":
            if self.frame != "geodetic":
                self.problem("path.points_deg", f"expected points_m for frame: {self.frame} "
                             "(points_deg needs frame: geodetic and an origin)")
                return None
            if origin is None:
                return None
            bad = [i for i, (lat, lon) in enumerate(pts) if not (-90 <= lat <= 90 and -180 <= lon <= 180)]
            for i in bad:
                self.problem(f"path.points_deg[{i}]", "expected [lat_deg in -90..90, lon_deg in -180..180]")
            if bad:
                return None
            # Points at flight height above the origin (the horizontal scale depends on height).
            alt = self.doc.get("altitude_m")
            if isinstance(alt, list) and len(alt) == len(pts) and all(a is not None for a in alt):
                alt = np.asarray(alt, dtype=float)  # one height per point
            elif not isinstance(alt, float):
                alt = 0.0
            height_m = origin.alt_m + alt
            e, n, _ = geodetic.enu_from_geodetic(pts[:, 0], pts[:, 1], height_m,
                                                 origin.lat_deg, origin.lon_deg, origin.alt_m)
            pts = np.column_stack([e, n])
        else:
            x, y = self.to_enu_xy(pts[:, 0], pts[:, 1])
            pts = np.column_stack([x, y])
        closed = bool(p.get("closed"))
        ok = True
        for i in range(1, len(pts)):
            if math.hypot(*(pts[i] - pts[i - 1])) < DUPLICATE_TOLERANCE_M:
                if closed and i == len(pts) - 1 and math.hypot(*(pts[i] - pts[0])) < DUPLICATE_TOLERANCE_M:
                    continue
                self.problem(f"path.{key}[{i}]", f"expected a point distinct from point {i - 1}, got a "
                             "duplicate")
                ok = False
        if closed and len(pts) > 1 and math.hypot(*(pts[-1] - pts[0])) < DUPLICATE_TOLERANCE_M:
            pts = pts[:-1]
            self.knots.dropped_closing_point = True
        distinct = len({(round(a / DUPLICATE_TOLERANCE_M), round(b / DUPLICATE_TOLERANCE_M)) for a, b in pts})
        need = 3 if closed else 2
        if ok and distinct < need:
            self.problem(f"path.{key}", f"expected at least {need} distinct points"
                         f"{' for closed: true' if closed else ''}, got {distinct}")
            ok = False
        return (pts, key) if ok else None

    def path_waypoints(self, p: dict, origin) -> Path | None:
        got = self.waypoint_array(p, origin)
        if got is None:
            return None
        pts, key = got
        closed = bool(p.get("closed"))
        if p.get("corner_radius_m") is not None:
            from companion.mission.segments import filleted_waypoint_path

            path = filleted_waypoint_path(pts, p["corner_radius_m"], closed=closed,
                                          where="path", problem=self.problem)
        else:
            path = waypoint_path(pts, closed=closed)
        if path is not None:
            self.knots.s_m = waypoint_arc_lengths_m(path, pts)
            self.knots.key = f"path.{key}"
            self.knots.count = len(pts) + (1 if self.knots.dropped_closing_point else 0)
        return path

    def path_segments(self, p: dict, origin) -> Path | None:
        from companion.mission.segments import segments_path

        items = p.get("segments")
        if items is None or any(it is None for it in items) or p.get("start_m") is None \
                or any(c is None for c in p["start_m"]) or p.get("start_heading_deg") is None \
                or p.get("blend_m") is None:
            return None
        x0, y0 = self.to_enu_xy(*p["start_m"])
        heading = self.to_enu_heading_rad(p["start_heading_deg"])
        sign = -1.0 if self.frame == "local_ned" else 1.0  # NED turns are clockwise-positive
        segs = []
        for it in items:
            if it["type"] == "line":
                segs.append(("line", it["length_m"], 0.0))
            else:
                segs.append(("arc", it["radius_m"], sign * math.radians(it["turn_deg"])))
        path = segments_path((float(x0), float(y0)), heading, segs, p["blend_m"],
                             closed=bool(p.get("closed")), where="path", problem=self.problem)
        if path is not None:
            # Blending keeps every length: the segment ends are at the cumulative lengths.
            lengths = [it["length_m"] if it["type"] == "line" else it["radius_m"] * math.radians(abs(it["turn_deg"]))
                       for it in items]
            self.knots.s_m = np.concatenate(([0.0], np.cumsum(lengths))) * (path.length_m / sum(lengths))
            self.knots.key = "path.segments"
            self.knots.count = len(items)
        return path


class _Builder(_Checks):
    """Cross-key checks and construction, appending to ``problems`` instead of stopping."""

    def __init__(self, doc: dict, source: str, problems: list[str], warnings: list[str]):
        super().__init__(doc, source, problems, warnings)
        self.path_schema_ok = True  # False when the schema already reported a problem in path
        self.origin_absent = True  # False when the file has an origin key (even an unusable one)
        self.paths = _PathBuilder(doc, source, problems, warnings)
        self.knots = self.paths.knots

    # --------------------------------------------------------------------- top level
    def build(self, text: str) -> Mission | None:
        doc = self.doc
        origin = self.build_origin()
        path = self.paths.build(origin) if doc.get("path") and self.path_schema_ok else None
        guidance = self.build_guidance()
        start = self.build_start()
        profile = None
        if path is not None and guidance is not None:
            self.check_path_against_guidance(path, guidance)
            profile = self.build_profile(path)
            if profile is not None and guidance.speed_m_s != profile.speed_m_s(0.0):
                guidance = dataclasses.replace(guidance, speed_m_s=profile.speed_m_s(0.0))
        if self.problems:
            return None
        return Mission(
            name=doc["name"],
            path=path,
            speed_m_s=profile.speed_m_s(0.0) if profile is not None else doc["speed_m_s"],
            altitude_m=profile.start_altitude_m if profile is not None else doc["altitude_m"],
            guidance=guidance,
            start=start,
            on_finish=doc["on_finish"],
            source_text=text,
            source_name=self.source,
            frame=self.frame,
            origin=origin,
            warnings=tuple(self.warnings),
            profile=profile,
            vehicle=self.build_vehicle(),
            profile_limits=self.build_profile_limits() or ProfileLimits(),
            accel_feedforward=(doc.get("guidance") or {}).get("accel_feedforward"),
            tail_compensation=(doc.get("guidance") or {}).get("tail_compensation"),
            lambda_stated=(doc.get("guidance") or {}).get("lambda_s4") is not None,
        )

    def build_vehicle(self) -> VehicleModel | None:
        v = self.doc.get("vehicle")
        if v is None or any(v.get(k) is None for k in VEHICLE_MODEL_KEYS):
            return None  # absent, or already reported by the schema
        return VehicleModel(**{k: v[k] for k in VEHICLE_MODEL_KEYS})

    def build_origin(self) -> GeodeticOrigin | None:
        origin = self.doc.get("origin")
        if self.frame == "geodetic":
            if origin is None:  # absent (report it) or unusable (the schema reported it)
                if self.doc.get("origin") is None and self.origin_absent:
                    self.problem("origin", "missing; expected {lat_deg, lon_deg, alt_m} for frame: geodetic")
                return None
            if any(origin.get(k) is None for k in ("lat_deg", "lon_deg", "alt_m")):
                return None
            return GeodeticOrigin(origin["lat_deg"], origin["lon_deg"], origin["alt_m"])
        if origin is not None:
            self.problem("origin", f"expected no origin for frame: {self.frame} (only frame: geodetic "
                         "has one)")
        return None

    def build_guidance(self) -> GuidanceParams | None:
        g = self.doc.get("guidance") or {}
        m = self.doc.get("midcourse") or {}
        speed = self.doc.get("speed_m_s")
        if isinstance(speed, list):  # a profile: the guidance starts at the first speed
            speed = speed[0] if speed and all(v is not None for v in speed) else None
        elif isinstance(speed, str):  # an expression of s: checked with the path
            speed = 5.0
        values = {
            "method": g.get("method"), "l1_m": g.get("l1_m"), "rate_hz": g.get("rate_hz"),
            "k1_max": g.get("k1_max"), "k2_max": g.get("k2_max"),
            "d_limit_factor": g.get("d_limit_factor"), "circle_radius_m": m.get("circle_radius_m"),
            "midcourse_trigger": m.get("trigger"), "speed_m_s": speed,
        }
        if any(v is None for v in values.values()):
            return None  # already reported by the schema
        if g.get("rollout_tau_s") is None:
            return None  # already reported by the schema
        values["rollout_tau_s"] = g["rollout_tau_s"]
        # Absent: the default (a flight may choose another: Mission.lambda_stated). An unusable
        # value is None here too, but the schema reported it.
        values["lambda_s4"] = DEFAULT_LAMBDA_S4 if g.get("lambda_s4") is None else g["lambda_s4"]
        # Absent: no limit. (An unusable value is None here too, but the schema reported it.)
        values["a_max_m_s2"] = math.inf if g.get("a_max_m_s2") is None else g["a_max_m_s2"]
        values["period_s"] = g.get("period_s")  # absent: the baseline's own default
        values["lookahead_m"] = g.get("lookahead_m")
        values["course_tc_s"] = g.get("course_tc_s") or 0.0  # absent (or unusable, reported): off
        model = self.build_vehicle()
        if model is not None:
            # A vehicle model: the rollouts assume its lag (plus its dead time) and the law never
            # plans beyond its acceleration limit (docs/vehicle_model.md).
            values["rollout_tau_s"] = model.rollout_tau_s()
            values["a_max_m_s2"] = min(float(values["a_max_m_s2"]), model.a_max_m_s2)
            values["adapt_model"] = True
        try:
            return GuidanceParams(**values)
        except ValueError as err:  # the schema's ranges should make this unreachable
            self.problem("guidance", str(err))
            return None

    def build_start(self) -> StartState | None:
        start = self.doc.get("start")
        if start is None or any(start.get(k) is None for k in ("x_m", "y_m", "heading_deg")):
            return None
        x, y = self.to_enu_xy(start["x_m"], start["y_m"])
        return StartState(float(x), float(y), self.to_enu_heading_rad(start["heading_deg"]))

    # --------------------------------------------------------------------- path vs guidance
    def check_path_against_guidance(self, path: Path, g: GuidanceParams) -> None:
        if path.length_m < g.l1_m:
            self.problem("path", f"expected a path at least one L1 ({g.l1_m:g} m) long, got "
                         f"{path.length_m:.3g} m")
            return
        k = np.abs(path.k_table_1_m)
        i = int(np.argmax(k))
        k_max = float(k[i])
        if g.method not in ("fixed_l1", "corrector"):  # no guidance.l1_m: only the vehicle's limit matters
            v = g.speed_m_s
            if v * v * k_max > g.a_max_m_s2:
                self.warn("path", f"curvature radius {1.0 / k_max:.3g} m at s = "
                          f"{float(path.s_table_m[i]):.1f} m needs V^2/R = {v * v * k_max:.3g} m/s^2, "
                          f"more than guidance.a_max_m_s2 = {g.a_max_m_s2:g} m/s^2 at V = {v:g} m/s")
            return
        if k_max > 2.0 / g.l1_m:
            r = 1.0 / k_max
            v = g.speed_m_s
            self.warn("path", f"curvature radius {r:.3g} m at s = {float(path.s_table_m[i]):.1f} m is "
                      f"tighter than L1/2 = {g.l1_m / 2:g} m: it needs V^2/R = {v * v / r:.3g} m/s^2, "
                      f"more than fixed-L1 can command (2 V^2/L1 = {2 * v * v / g.l1_m:.3g} m/s^2) at "
                      f"V = {v:g} m/s, L1 = {g.l1_m:g} m")

    # --------------------------------------------------------------------- altitude and speed
    def build_profile(self, path: Path) -> PathProfile | None:
        """The altitude and speed profile, or None when both are one number (a flat mission)."""
        alt, speed = self.doc.get("altitude_m"), self.doc.get("speed_m_s")
        if alt is None or speed is None:
            return None  # reported by the schema
        if isinstance(alt, float) and isinstance(speed, float):
            return None
        limits = self.build_profile_limits()
        if limits is None:
            return None  # reported by the schema
        alt_target = self.profile_target(alt, "altitude_m", path, step=False, high=10000.0)
        speed_target = self.profile_target(speed, "speed_m_s", path, step=True, high=100.0)
        if alt_target is None or speed_target is None:
            return None
        profile = build_profile(path.length_m, path.closed, limits, alt_target=alt_target,
                                speed_target=speed_target)
        if isinstance(alt, list) and self.knots.s_m is not None:
            self.warn_unreached_heights(profile, alt)
        return profile

    def build_profile_limits(self) -> ProfileLimits | None:
        """The ``vertical:`` and ``along_track:`` limits; None when the schema reported a problem."""
        vert = self.doc.get("vertical") or {}
        along = self.doc.get("along_track") or {}
        values = (vert.get("climb_max_m_s"), vert.get("sink_max_m_s"), vert.get("accel_max_m_s2"),
                  along.get("accel_max_m_s2"), vert.get("alt_gain_1_s"), along.get("turn_accel_share"))
        if any(v is None for v in values):
            return None
        return ProfileLimits(*values)

    def profile_target(self, value, key: str, path: Path, step: bool, high: float):
        """A number, or a function of the arc-length grid; None after reporting a problem."""
        if isinstance(value, float):
            return value
        if isinstance(value, str):
            try:
                fn = compile_expression(value, "s")
            except ExpressionError as err:
                self.problem(key, f"expected a number, a list, or an expression of the arc length s, "
                             f"got {schema._got(value)} ({'; '.join(err.problems)})")
                return None
            s = np.linspace(0.0, path.length_m, CHECK_SAMPLES)
            got = np.asarray(fn(s), dtype=float) * np.ones_like(s)
            bad = ~(np.isfinite(got) & (got > 0) & (got <= high))
            if np.any(bad):
                i = int(np.flatnonzero(bad)[0])
                self.problem(key, f"expected values > 0 and <= {high:g} for s in [0, "
                             f"{path.length_m:.4g}] (the path's arc length), got {got[i]} at s = {s[i]:.4g}")
                return None
            return fn
        if any(v is None for v in value):
            return None  # reported by the schema
        if self.knots.s_m is None:
            kind = (self.doc.get("path") or {}).get("type")
            self.problem(key, f"expected a number or an expression of the arc length s for a {kind} "
                         f"path, got a list (lists are for waypoints and segments paths)")
            return None
        knots = self.knots.s_m
        values = list(value)
        if self.knots.key == "path.segments":
            if key == "altitude_m":
                need, what = self.knots.count + 1, "the start height, then one per segment end"
            else:
                need, what = self.knots.count, "one per segment"
                knots = knots[:-1]
        else:
            need, what = self.knots.count, f"one per point of {self.knots.key}"
        if len(values) != need:
            self.problem(key, f"expected {need} values ({what}), got {len(values)}")
            return None
        if self.knots.key == "path.segments" and key == "altitude_m" and path.closed:
            if abs(values[-1] - values[0]) > 1e-9:
                self.problem(key, f"expected the last height to equal the first for closed: true, got "
                             f"{values[0]:g} and {values[-1]:g}")
                return None
            knots, values = knots[:-1], values[:-1]
        elif self.knots.dropped_closing_point:
            values = values[:-1]
        closed = path.closed
        length = path.length_m
        return lambda s: knots_table(s, knots, values, closed, length, step)

    def warn_unreached_heights(self, profile: PathProfile, heights: list) -> None:
        if self.knots.key == "path.segments":
            names = ["path.start_m"] + [f"path.segments[{i}]" for i in range(len(heights) - 1)]
        else:
            names = [f"{self.knots.key}[{i}]" for i in range(len(heights))]
        for name, s, h in zip(names, self.knots.s_m, heights):
            got = profile.altitude_m(float(s))
            if abs(got - h) > PROFILE_WARN_M:
                self.warn(name, f"the altitude profile passes at {got:.1f} m instead of {h:g} m "
                          f"(s = {float(s):.1f} m): the climb or the vertical acceleration limits "
                          "(vertical:) spread the change over a longer stretch")


def waypoint_arc_lengths_m(path: Path, points_enu_m: np.ndarray) -> np.ndarray:
    """Arc length of each waypoint's closest path point, in flying order (unwrapped on loops)."""
    out = []
    hint = None
    for x, y in points_enu_m:
        s = path.project(float(x), float(y), hint)
        if out and path.closed:
            while s < out[-1] - 1e-9:
                s += path.length_m
        elif out:
            s = max(s, out[-1])
        out.append(s)
        hint = s % path.length_m if path.closed else s
    return np.asarray(out)
