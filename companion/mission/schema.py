"""The mission file format, described once in Python.

Everything about the format lives in :data:`MISSION`: the keys, their types, ranges, defaults and
descriptions. Two things are generated from it:

- the validator, :func:`validate`, which walks a parsed YAML document against the description and
  returns the document with defaults filled in plus every problem found (key path and message);
- the JSON Schema, :func:`json_schema`, committed as ``companion/mission/mission.schema.json`` for
  editors (regenerate with ``companion mission schema > companion/mission/mission.schema.json``;
  a test checks the committed file is current).

Checks that involve several keys at once (``origin`` required for ``frame: geodetic``, ranges in
increasing order, path geometry) are in :mod:`companion.mission.loader`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from companion.guidance.types import (
    DEFAULT_LAMBDA_S4,
    DEFAULT_METHOD,
    METHODS,
    MIDCOURSE_TRIGGERS,
    TAIL_COMPENSATED_LAMBDA_S4,
)
from companion.mission.expressions import ExpressionError, compile_expression
from companion.mission.model import ON_FINISH

_MISSING = object()


@dataclass(frozen=True)
class Number:
    """A finite real number (booleans refused), optionally an integer, with optional bounds."""

    minimum: float | None = None
    exclusive_minimum: float | None = None
    maximum: float | None = None
    exclusive_maximum: float | None = None
    integer: bool = False
    nonzero: bool = False

    def expected(self) -> str:
        what = "an integer" if self.integer else "a finite number"
        bounds = []
        if self.minimum is not None:
            bounds.append(f">= {self.minimum:g}")
        if self.exclusive_minimum is not None:
            bounds.append(f"> {self.exclusive_minimum:g}")
        if self.maximum is not None:
            bounds.append(f"<= {self.maximum:g}")
        if self.exclusive_maximum is not None:
            bounds.append(f"< {self.exclusive_maximum:g}")
        if self.nonzero:
            bounds.append("!= 0")
        return what + (" " + " and ".join(bounds) if bounds else "")


@dataclass(frozen=True)
class Constant:
    """A finite number, or a constant expression string such as ``"2*pi"``."""

    def expected(self) -> str:
        return "a finite number or a constant expression (e.g. 2*pi)"


@dataclass(frozen=True)
class String:
    """A string, optionally one of ``enum``, or an expression in ``variable``."""

    enum: tuple[str, ...] | None = None
    max_length: int = 2000
    variable: str | None = None  # set for expressions (checked by the loader's expression parser)

    def expected(self) -> str:
        if self.enum:
            return "one of " + ", ".join(self.enum)
        if self.variable:
            return f"an expression in {self.variable}"
        return "a string"


@dataclass(frozen=True)
class Boolean:
    def expected(self) -> str:
        return "true or false"


@dataclass(frozen=True)
class Array:
    """A list of ``items`` with a length in ``[min_items, max_items]``."""

    items: Any
    min_items: int = 0
    max_items: int | None = None
    description: str = ""

    def expected(self) -> str:
        if self.max_items == self.min_items:
            return f"a list of {self.min_items} items"
        if self.max_items is None:
            return f"a list of at least {self.min_items} items"
        return f"a list of {self.min_items} to {self.max_items} items"


@dataclass(frozen=True)
class Field:
    """One key of an :class:`Object`."""

    spec: Any
    description: str
    required: bool = False
    default: Any = _MISSING


@dataclass(frozen=True)
class Object:
    """A mapping with exactly the keys in ``fields`` (unknown keys are errors)."""

    fields: dict[str, Field]
    description: str = ""

    def expected(self) -> str:
        return "a mapping with keys " + ", ".join(self.fields)


@dataclass(frozen=True)
class Tagged:
    """A mapping whose ``tag`` key selects which :class:`Object` describes the rest."""

    variants: dict[str, Object]
    tag: str = "type"
    description: str = ""

    def expected(self) -> str:
        return f"a mapping with {self.tag}: one of " + ", ".join(self.variants)


@dataclass(frozen=True)
class OneOf:
    """One of several kinds of value, told apart by the YAML type: a number, a list or a string.

    At most one variant per kind (``Number``, ``Array``, ``String``); the value's type picks it.
    """

    variants: tuple
    description: str = ""

    def expected(self) -> str:
        return " or ".join(v.expected() for v in self.variants)


def _kind_of(spec: Any) -> type:
    if isinstance(spec, Number):
        return float
    if isinstance(spec, Array):
        return list
    if isinstance(spec, String):
        return str
    raise TypeError(f"OneOf variant {spec!r}: expected Number, Array or String")


# --------------------------------------------------------------------------------------------
# The format
# --------------------------------------------------------------------------------------------

FRAMES = ("local_enu", "local_ned", "geodetic")
# ON_FINISH (companion.mission.model), METHODS, MIDCOURSE_TRIGGERS, DEFAULT_METHOD and
# DEFAULT_LAMBDA_S4 (companion.guidance.types: a mission that names no method gets DEFAULT_METHOD;
# ``GuidanceParams()`` itself keeps the paper's law) are defined once, where they belong.
MAX_POINTS = 10000

_FINITE = Number()
_POSITIVE = Number(exclusive_minimum=0)
_XY = Array(_FINITE, 2, 2, "a point [x_m, y_m] in the mission frame")
_RANGE = Array(Constant(), 2, 2, "[first, last], first < last; numbers or constant expressions")
_LATLON = Array(_FINITE, 2, 2, "[lat_deg, lon_deg] on WGS-84")

PATH = Tagged(
    description="The reference path, in the mission frame.",
    variants={
        "function": Object(
            description="y as a function of x over a range of x.",
            fields={
                "type": Field(String(enum=("function",)), "path kind", required=True),
                "y_of_x": Field(String(variable="x"), "y in metres as an expression in x (metres)",
                                required=True),
                "x_range_m": Field(_RANGE, "[x_first_m, x_last_m], x_first_m < x_last_m; the path "
                                   "is flown towards increasing x", required=True),
            },
        ),
        "parametric": Object(
            description="x(s), y(s) over a parameter range; s need not be arc length.",
            fields={
                "type": Field(String(enum=("parametric",)), "path kind", required=True),
                "x_of_s": Field(String(variable="s"), "x in metres as an expression in s", required=True),
                "y_of_s": Field(String(variable="s"), "y in metres as an expression in s", required=True),
                "s_range": Field(_RANGE, "[s_first, s_last], s_first < s_last", required=True),
                "closed": Field(Boolean(), "a loop flown continuously (the curve must end where it "
                                "starts, with the same heading)", default=False),
            },
        ),
        "waypoints": Object(
            description="Points joined into a C^2 curve: an interpolating cubic spline through every "
                        "point (chord-length parameter), or, with corner_radius_m, straight legs "
                        "with rounded corners and curvature ramps (the path cuts the corners).",
            fields={
                "type": Field(String(enum=("waypoints",)), "path kind", required=True),
                "points_m": Field(Array(_XY, 2, MAX_POINTS), "points [x_m, y_m] in the mission frame"),
                "points_deg": Field(Array(_LATLON, 2, MAX_POINTS),
                                    "points [lat_deg, lon_deg] (frame: geodetic only)"),
                "corner_radius_m": Field(Number(exclusive_minimum=0, maximum=10000), "round each corner with an arc of this radius "
                                         "(and curvature ramps) instead of a spline"),
                "closed": Field(Boolean(), "a loop: the last point joins the first", default=False),
            },
        ),
        "segments": Object(
            description="Straight lines and circular arcs, tangent to each other; each curvature "
                        "jump is replaced by a linear curvature ramp (clothoid) of length blend_m so "
                        "that the path is C^2.",
            fields={
                "type": Field(String(enum=("segments",)), "path kind", required=True),
                "start_m": Field(_XY, "first point [x_m, y_m]", default=[0.0, 0.0]),
                "start_heading_deg": Field(_FINITE, "heading at the first point, in the frame's angle "
                                           "convention", default=0.0),
                "blend_m": Field(Number(exclusive_minimum=0, maximum=1000), "length of each curvature "
                                 "ramp (clothoid) replacing a "
                                 "curvature jump", default=5.0),
                "segments": Field(
                    Array(
                        Tagged(
                            variants={
                                "line": Object(
                                    fields={
                                        "type": Field(String(enum=("line",)), "segment kind",
                                                      required=True),
                                        "length_m": Field(Number(exclusive_minimum=0, maximum=100000), "length",
                                                          required=True),
                                    },
                                ),
                                "arc": Object(
                                    fields={
                                        "type": Field(String(enum=("arc",)), "segment kind",
                                                      required=True),
                                        "radius_m": Field(Number(exclusive_minimum=0, maximum=100000), "radius",
                                                          required=True),
                                        "turn_deg": Field(
                                            Number(minimum=-360, maximum=360, nonzero=True),
                                            "turn angle, positive = left in ENU (anticlockwise)",
                                            required=True),
                                    },
                                ),
                            },
                            description="one line or arc",
                        ),
                        1, 1000,
                    ),
                    "the segments in flying order", required=True),
                "closed": Field(Boolean(), "a loop: the segments must end where they start",
                                default=False),
            },
        ),
    },
)

_ALTITUDE = Number(exclusive_minimum=0, maximum=10000)
_SPEED = Number(exclusive_minimum=0, maximum=100)

MISSION = Object(
    description="A companion mission: a reference path in local metres and how to fly it.",
    fields={
        "version": Field(Number(minimum=1, maximum=1, integer=True), "format version", default=1),
        "name": Field(String(max_length=200), "a short name", required=True),
        "frame": Field(String(enum=FRAMES), "local_enu: x east, y north, angles anticlockwise from "
                       "east; local_ned: x north, y east, angles clockwise from north; geodetic: "
                       "local ENU metres about origin (waypoints may be given in degrees)",
                       default="local_enu"),
        "origin": Field(
            Object(
                fields={
                    "lat_deg": Field(Number(minimum=-90, maximum=90), "latitude", required=True),
                    "lon_deg": Field(Number(minimum=-180, maximum=180), "longitude", required=True),
                    "alt_m": Field(_FINITE, "height above the WGS-84 ellipsoid", default=0.0),
                },
            ),
            "the local origin on WGS-84 (frame: geodetic only)"),
        "speed_m_s": Field(
            OneOf((_SPEED, Array(_SPEED, 1, 10000), String(variable="s"))),
            "ground speed V: one number, or a profile along the path (a list: the speed from each "
            "waypoint on, or of each segment; or an expression of the arc length s for a function "
            "or parametric path), changed at along_track.accel_max_m_s2", required=True),
        "altitude_m": Field(
            OneOf((_ALTITUDE, Array(_ALTITUDE, 2, 10000), String(variable="s"))),
            "flight height above the local origin: one number, or a profile along the path (a "
            "list: one height per waypoint of a waypoints path, or the start height then one per "
            "segment end of a segments path; or an expression of the arc length s in metres for a "
            "function or parametric path), smoothed to the limits in vertical", default=10.0),
        "vertical": Field(
            Object(
                fields={
                    "climb_max_m_s": Field(Number(exclusive_minimum=0, maximum=50), "largest climb "
                                           "rate of the altitude profile and of every vertical "
                                           "command", default=2.0),
                    "sink_max_m_s": Field(Number(exclusive_minimum=0, maximum=50), "largest sink "
                                          "rate of the altitude profile and of every vertical "
                                          "command", default=1.5),
                    "accel_max_m_s2": Field(Number(exclusive_minimum=0, maximum=50), "largest "
                                            "vertical acceleration of the altitude profile",
                                            default=1.0),
                    "alt_gain_1_s": Field(Number(exclusive_minimum=0, maximum=20), "gain of the "
                                          "correction on altitude error added to the profile's "
                                          "climb rate", default=1.0),
                },
            ),
            "vertical limits of the vehicle, used to smooth the altitude profile", default={}),
        "along_track": Field(
            Object(
                fields={
                    "accel_max_m_s2": Field(Number(exclusive_minimum=0, maximum=50), "largest "
                                            "along-track acceleration of a speed change",
                                            default=1.0),
                    "turn_accel_share": Field(Number(minimum=0, maximum=1), "share of the "
                                              "vehicle's acceleration limit the path's own turns "
                                              "may ask (V^2 kappa) in a flight: slower where a "
                                              "turn asks more (0: the speeds as given)",
                                              default=0.8),
                },
            ),
            "along-track limits of the vehicle, used to smooth the speed profile and to slow "
            "down for turns", default={}),
        "path": Field(PATH, "the reference path", required=True),
        "guidance": Field(
            Object(
                fields={
                    "method": Field(String(enum=METHODS), "guidance law: fixed_l1 (Park), corrector "
                                    "(the paper's law), predictive (ours; the default, ahead of "
                                    "the others under an inner-loop lag, docs/benchmarks.md), or "
                                    "the baselines ap_l1 (ArduPilot L1), npfg (PX4 NPFG), "
                                    "pure_pursuit (no mid-course phase, docs/guidance.md)",
                                    default=DEFAULT_METHOD),
                    "period_s": Field(Number(exclusive_minimum=0, maximum=100), "ap_l1 and npfg: "
                                      "tracking-loop period T (absent: the autopilot's default, "
                                      "NAVL1_PERIOD 17 s, NPFG_PERIOD 10 s)"),
                    "lookahead_m": Field(Number(exclusive_minimum=0, maximum=1000), "pure_pursuit: "
                                         "look-ahead distance L_d (absent: 10 m)"),
                    "course_tc_s": Field(Number(minimum=0, maximum=10), "predictive: time constant "
                                         "of the course observer, which reads the course the lag "
                                         "model turns, pulled towards the reported one (absent or "
                                         "0: the course as reported; docs/guidance.md)"),
                    "l1_m": Field(_POSITIVE, "look-ahead distance L1", default=10.0),
                    "rate_hz": Field(Number(exclusive_minimum=0, maximum=1000), "guidance rate",
                                     default=50.0),
                    "k1_max": Field(Number(minimum=0), "upper bound of the corrector weight k1",
                                    default=1.0),
                    "k2_max": Field(Number(minimum=0), "upper bound of the corrector weight k2",
                                    default=1.0e4),
                    "d_limit_factor": Field(_POSITIVE, "re-optimisation window: min(d_limit_factor "
                                            "* L1, R_proj) / V", default=2.0),
                    "rollout_tau_s": Field(Number(minimum=0, maximum=5), "time constant of the "
                                           "vehicle's inner loop (first-order lag from commanded to "
                                           "flown lateral acceleration) assumed by the rollouts of "
                                           "corrector and predictive; 0 = ideal (the paper)",
                                           default=0.0),
                    "lambda_s4": Field(Number(minimum=0, maximum=100), "predictive: weight of the "
                                       "squared acceleration against the squared cross-track error "
                                       "(s^4); smaller tracks tighter, larger flies smoother "
                                       f"(absent: {DEFAULT_LAMBDA_S4:g}, and "
                                       f"{TAIL_COMPENSATED_LAMBDA_S4:g} on a flight that compensates "
                                       "the velocity loop's slow tail; docs/flying.md)"),
                    "a_max_m_s2": Field(Number(exclusive_minimum=0, maximum=100), "predictive: the "
                                        "vehicle's lateral-acceleration limit; every command is "
                                        "clipped to it (absent: no limit)"),
                    "accel_feedforward": Field(Boolean(), "copters (never rovers): send "
                                               "the lateral command as the setpoint's acceleration "
                                               "target too, so the autopilot turns with it (absent: "
                                               "on for ArduPilot, off for PX4; docs/flying.md)"),
                    "tail_compensation": Field(Boolean(), "copters: compensate the slow tail of the "
                                               "autopilot's velocity loop (vehicle.tail_share and "
                                               "tail_tc_s, else the autopilot's identified one) "
                                               "(absent: on for PX4 unless the acceleration target "
                                               "is sent, off otherwise; docs/flying.md)"),
                },
            ),
            "guidance tuning", default={}),
        "vehicle": Field(
            Object(
                description="How the vehicle flies velocity setpoints (docs/vehicle_model.md), as "
                            "`companion identify` writes it; the guidance plans within it and the "
                            "simulator flies it.",
                fields={
                    "a_max_m_s2": Field(Number(exclusive_minimum=0, maximum=100), "horizontal (in a "
                                        "turn: lateral) acceleration limit", required=True),
                    "delay_s": Field(Number(minimum=0, maximum=5), "dead time from setpoint to "
                                     "response", default=0.0),
                    "lag_s": Field(Number(minimum=0, maximum=5), "time constant of the first-order "
                                   "velocity response", required=True),
                    "accel_lag_s": Field(Number(minimum=0, maximum=5), "time constant of a second "
                                         "lag on the acceleration (0: first-order model)", default=0.0),
                    "tail_share": Field(Number(minimum=0, maximum=0.95), "share of the velocity error "
                                        "answered only slowly (the slow tail; 0: none)", default=0.0),
                    "tail_tc_s": Field(Number(exclusive_minimum=0, maximum=60), "time constant of the "
                                       "slow tail's low-pass", default=1.0),
                    "speed_sag_s": Field(Number(minimum=0, maximum=10), "speed lost in a turn per "
                                         "unit of lateral acceleration (m/s per m/s^2)", default=0.0),
                    "yaw_rate_max_deg_s": Field(Number(exclusive_minimum=0, maximum=3600),
                                                "yaw-rate limit", default=90.0),
                    "vel_bias_m_s": Field(Number(minimum=0, maximum=10), "standard deviation of the "
                                          "autopilot's velocity-estimate bias, per horizontal axis "
                                          "(the mock flies it; the guidance does not use it)", default=0.0),
                    "vel_bias_tc_s": Field(Number(exclusive_minimum=0, maximum=600), "correlation time "
                                           "of that bias", default=3.0),
                    "vel_bias_jerk_s2": Field(Number(minimum=0, maximum=10), "how much that bias's level "
                                              "grows per m/s^3 of the manoeuvre's jerk (0: one level; the "
                                              "mock flies it)", default=0.0),
                    "vel_bias_jerk_max_m_s3": Field(Number(exclusive_minimum=0, maximum=100), "the jerk above "
                                                    "which the bias's level grows no more", default=1.0),
                    "vel_bias_smooth_s": Field(Number(minimum=0, maximum=60), "time constant of the low-pass "
                                               "through which the vehicle flies that bias (0: as it is)",
                                               default=0.0),
                    "vel_bias_loop_s": Field(Number(minimum=0, maximum=60), "time constant of the lag through "
                                             "which the vehicle's velocity loop follows that bias; the rest "
                                             "shows in the reported velocity (0: the whole bias is flown)",
                                             default=0.0),
                    "vel_offset_m_s": Field(Number(minimum=0, maximum=10), "standard deviation of the "
                                            "velocity estimate's offset, drawn once per flight on each "
                                            "horizontal axis (the mock flies it; the guidance does not "
                                            "use it)", default=0.0),
                    "pos_delay_s": Field(Number(minimum=0, maximum=1), "how much older the reported "
                                         "position is than the reported velocity (the mock reports it "
                                         "so; the guidance does not use it)", default=0.0),
                    "accel_ff_gain": Field(Number(minimum=0, maximum=10), "gain on the acceleration "
                                           "target (guidance.accel_feedforward), which joins the velocity "
                                           "loop's demand before the slow tail", default=1.0),
                    "accel_ff_lag_s": Field(Number(minimum=0, maximum=5), "time constant of a lag on "
                                            "the acceleration target", default=0.0),
                },
            ),
            "the vehicle model (absent: the guidance block's rollout_tau_s and a_max_m_s2 alone)"),
        "midcourse": Field(
            Object(
                fields={
                    "circle_radius_m": Field(_POSITIVE, "radius R of the initiation circles",
                                             default=10.0),
                    "trigger": Field(String(enum=MIDCOURSE_TRIGGERS), "when the mid-course phase "
                                     "runs (see docs/guidance.md)", default="auto"),
                },
            ),
            "mid-course (path acquisition) phase", default={}),
        "on_finish": Field(String(enum=ON_FINISH), "what the vehicle does at the end of the path",
                           default="hold"),
        "start": Field(
            Object(
                fields={
                    "x_m": Field(_FINITE, "first coordinate in the mission frame", required=True),
                    "y_m": Field(_FINITE, "second coordinate in the mission frame", required=True),
                    "heading_deg": Field(_FINITE, "initial course, in the frame's angle convention",
                                         required=True),
                },
            ),
            "initial vehicle state for simulations"),
    },
)


# --------------------------------------------------------------------------------------------
# Validator
# --------------------------------------------------------------------------------------------


def _got(value: Any) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        text = value if len(value) <= 40 else value[:37] + "..."
        return repr(text)
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)} items"
    return type(value).__name__


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def validate(value: Any, spec: Any = MISSION, path: str = "") -> tuple[Any, list[tuple[str, str]]]:
    """Check ``value`` (parsed YAML) against ``spec``.

    Returns
    -------
    (clean, problems)
        ``clean`` is ``value`` with defaults filled in (``None`` where a value was unusable);
        ``problems`` lists ``(key_path, message)`` for every problem, ``key_path`` like
        ``path.points_m[3]`` and ``message`` like ``expected a finite number, got 'abc'``.
    """
    problems: list[tuple[str, str]] = []
    clean = _validate(value, spec, path, problems)
    return clean, problems


def _validate(value, spec, path, problems):
    validator = _VALIDATORS.get(type(spec))
    if validator is None:
        raise TypeError(f"unknown schema node {spec!r}")  # a bug in this module, not in the file
    return validator(value, spec, path, problems)


def _refuse(problems, path, message):
    """Record ``message`` for ``path`` and give the unusable value's ``None``."""
    problems.append((path or "(top level)", message))
    return None


def _refuse_got(problems, path, spec, value):
    return _refuse(problems, path, f"expected {spec.expected()}, got {_got(value)}")


def _in_bounds(spec: Number, v: float) -> bool:
    return not ((spec.minimum is not None and v < spec.minimum)
                or (spec.exclusive_minimum is not None and v <= spec.exclusive_minimum)
                or (spec.maximum is not None and v > spec.maximum)
                or (spec.exclusive_maximum is not None and v >= spec.exclusive_maximum)
                or (spec.nonzero and v == 0))


def _validate_number(value, spec, path, problems):
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if ok and not math.isfinite(value):
        return _refuse(problems, path, f"expected {spec.expected()}, got {value!r}")
    if ok and spec.integer and float(value) != int(value):
        ok = False
    if not (ok and _in_bounds(spec, float(value))):
        return _refuse_got(problems, path, spec, value)
    return int(value) if spec.integer else float(value)


def _validate_one_of(value, spec, path, problems):
    kind = (list if isinstance(value, list) else str if isinstance(value, str)
            else float if isinstance(value, (int, float)) and not isinstance(value, bool) else None)
    for variant in spec.variants:
        if _kind_of(variant) is kind:
            return _validate(value, variant, path, problems)
    return _refuse_got(problems, path, spec, value)


def _validate_constant(value, spec, path, problems):
    if not isinstance(value, str):
        return _validate(value, _FINITE, path, problems)
    try:
        number = float(compile_expression(value, "")(0.0))
    except ExpressionError as err:
        return _refuse(problems, path, f"expected {spec.expected()}: {err.problems[0]}")
    if not math.isfinite(number):
        return _refuse(problems, path, f"expected {spec.expected()}, got {value!r} = {number}")
    return number


def _validate_string(value, spec, path, problems):
    if value is False and spec.enum and "off" in spec.enum:
        value = "off"  # YAML 1.1 reads an unquoted `off` as false
    if not isinstance(value, str) or (spec.enum and value not in spec.enum):
        return _refuse_got(problems, path, spec, value)
    if len(value) > spec.max_length:
        return _refuse(problems, path, f"expected at most {spec.max_length} characters, got {len(value)}")
    if not spec.enum and not value.strip():
        return _refuse(problems, path, f"expected {spec.expected()}, got an empty string")
    return value


def _validate_boolean(value, spec, path, problems):
    if not isinstance(value, bool):
        return _refuse_got(problems, path, spec, value)
    return value


def _validate_array(value, spec, path, problems):
    if not isinstance(value, list):
        return _refuse_got(problems, path, spec, value)
    if len(value) < spec.min_items or (spec.max_items is not None and len(value) > spec.max_items):
        return _refuse(problems, path, f"expected {spec.expected()}, got {len(value)}")
    return [_validate(item, spec.items, f"{path}[{i}]", problems) for i, item in enumerate(value)]


def _validate_tagged(value, spec, path, problems):
    if not isinstance(value, dict):
        return _refuse_got(problems, path, spec, value)
    kind = value.get(spec.tag)
    if not isinstance(kind, str) or kind not in spec.variants:
        return _refuse(problems, _join(path, spec.tag),
                       f"expected one of {', '.join(spec.variants)}, got {_got(kind)}")
    return _validate(value, spec.variants[kind], path, problems)


def _validate_object(value, spec, path, problems):
    if not isinstance(value, dict):
        return _refuse_got(problems, path, spec, value)
    for key in value:
        if key not in spec.fields:
            problems.append((_join(path, str(key)), f"unknown key; expected one of {', '.join(spec.fields)}"))
    out = {}
    for key, fld in spec.fields.items():
        if key in value:
            out[key] = _validate(value[key], fld.spec, _join(path, key), problems)
        elif fld.required:
            out[key] = _refuse(problems, _join(path, key), f"missing; expected {fld.spec.expected()}")
        elif fld.default is not _MISSING and isinstance(fld.spec, Object) and isinstance(fld.default, dict):
            out[key] = _validate(fld.default, fld.spec, _join(path, key), problems)
        elif fld.default is not _MISSING:
            out[key] = fld.default
        else:
            out[key] = None
    return out


_VALIDATORS = {
    Number: _validate_number, OneOf: _validate_one_of, Constant: _validate_constant,
    String: _validate_string, Boolean: _validate_boolean, Array: _validate_array,
    Tagged: _validate_tagged, Object: _validate_object,
}


# --------------------------------------------------------------------------------------------
# JSON Schema
# --------------------------------------------------------------------------------------------


def _json(spec: Any, description: str = "") -> dict:
    if isinstance(spec, Number):
        out: dict = {"type": "integer" if spec.integer else "number"}
        for attr, key in (("minimum", "minimum"), ("exclusive_minimum", "exclusiveMinimum"),
                          ("maximum", "maximum"), ("exclusive_maximum", "exclusiveMaximum")):
            if getattr(spec, attr) is not None:
                out[key] = getattr(spec, attr)
        if spec.nonzero:
            out["not"] = {"const": 0}
    elif isinstance(spec, OneOf):
        out = {"oneOf": [_json(v) for v in spec.variants]}
    elif isinstance(spec, Constant):
        out = {"oneOf": [{"type": "number"}, {"type": "string", "maxLength": 200}]}
    elif isinstance(spec, String):
        out = {"type": "string"}
        if spec.enum:
            out["enum"] = list(spec.enum)
        out["maxLength"] = spec.max_length
    elif isinstance(spec, Boolean):
        out = {"type": "boolean"}
    elif isinstance(spec, Array):
        out = {"type": "array", "items": _json(spec.items), "minItems": spec.min_items}
        if spec.max_items is not None:
            out["maxItems"] = spec.max_items
        description = description or spec.description
    elif isinstance(spec, Object):
        out = {
            "type": "object",
            "properties": {},
            "additionalProperties": False,
        }
        for key, fld in spec.fields.items():
            prop = _json(fld.spec, fld.description)
            if fld.default is not _MISSING:
                prop["default"] = fld.default
            out["properties"][key] = prop
        required = [k for k, f in spec.fields.items() if f.required]
        if required:
            out["required"] = required
        description = description or spec.description
    elif isinstance(spec, Tagged):
        out = {"type": "object", "required": [spec.tag],
               "oneOf": [_json(v, v.description) for v in spec.variants.values()]}
        description = description or spec.description
    else:
        raise TypeError(f"unknown schema node {spec!r}")
    if description:
        out = {"description": description, **out}
    return out


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a mission file, generated from :data:`MISSION`."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "companion mission",
        **_json(MISSION),
    }


def json_schema_text() -> str:
    """:func:`json_schema` as the text committed in ``mission.schema.json``."""
    return json.dumps(json_schema(), indent=2) + "\n"
