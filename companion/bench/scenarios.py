"""Bench scenarios as data, and the seeded generator of random ones.

A :class:`ScenarioSpec` is everything one bench scenario is: the path (as a mission document, so
the one mission loader builds it), the start pose, the speed, the vehicle's lag model and the
wind. It is a frozen, picklable record that round-trips through JSON (:meth:`ScenarioSpec.to_dict`,
:meth:`ScenarioSpec.from_dict`), so a worker on another machine rebuilds the scenario from its
description, and :func:`spec_id` names it stably (a campaign's resume key).

:func:`random_spec` draws scenario ``seed`` reproducibly (the standard library's Mersenne
Twister, seeded with the integer: the same stream on every machine and Python version), and
:func:`random_specs` draws ``n`` of them with seeds ``seed, seed + 1, ...``, so a range of seeds
can be split (tune on 0-199, test on 1000-1199: docs/benchmarks.md).

What is drawn
-------------
The category of scenario ``seed`` is ``CATEGORIES[seed % 14]``: a path kind (``open``,
``closed``, ``open_crossing``, ``closed_crossing``) and a start kind (``on_path``, ``far``,
``facing_away``, and ``crossing`` on the self-crossing kinds), so every 14 consecutive seeds
cover every category once. The rest is drawn:

- speed V uniform in 3-15 m/s, lag uniform in 0.1-0.6 s, no dead time, a_max 5 m/s^2 (the bench
  vehicle), a steady wind of uniform direction and a magnitude uniform in 0-40 % of V;
- the path: a few Fourier modes in a parameter ``s`` (written out as a mission ``parametric``
  path, so any tool that reads missions can fly it): a wave along a line (``open``), a perturbed
  ellipse (``closed``), a prolate trochoid with one or two loops (``open_crossing``), a
  figure-eight or a limacon with an inner loop (``closed_crossing``), a closed one starting
  anywhere along it; rotated and possibly
  mirrored at random, scaled to about ``V * T`` long (T uniform in 30-60 s), and scaled up
  further where needed so that its curvature never exceeds
  ``KAPPA_FRACTION * a_max / (V + |w|)^2`` (the lateral acceleration a turn at the downwind
  ground speed needs, with a margin), checked on a dense sample of the exact derivatives. The
  path kinds without ``crossing`` in their name are checked not to cross themselves, the others
  to cross at least once (polyline intersection), redrawing otherwise;
- the start: ``on_path`` on the path (in its first 30 % if open) with a heading within 15 deg
  of the tangent; ``far`` 20-60 m off the path along its normal, any heading; ``facing_away``
  5-25 m off and heading away from it (within 30 deg of the outward normal); ``crossing`` at
  the path's first self-crossing, heading along the earlier branch (within 10 deg). ``far`` and
  ``facing_away`` starts are kept at least 70 % of their offset from every point of the path.

This module does no I/O: missions come in as loaded :class:`~companion.mission.model.Mission`
objects.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import random
from dataclasses import asdict, dataclass, replace

import numpy as np

from companion.errors import CompanionError, MissionError

#: Bench defaults: the mock copter's lag model at the bench speed.
BENCH_SPEED_M_S = 5.0
BENCH_LAG_S = 0.3
BENCH_A_MAX_M_S2 = 5.0
BENCH_CIRCLE_RADIUS_M = 10.0

SPEED_RANGE_M_S = (3.0, 15.0)
LAG_RANGE_S = (0.1, 0.6)
WIND_MAX_FRACTION = 0.4
FLIGHT_TIME_RANGE_S = (30.0, 60.0)
#: A shape the curvature bound would stretch beyond this many times its drawn length is redrawn.
MAX_STRETCH = 6.0
FAR_RANGE_M = (20.0, 60.0)
AWAY_RANGE_M = (5.0, 25.0)
#: Curvature bound of random paths: kappa <= KAPPA_FRACTION * a_max / (V + |wind|)^2.
KAPPA_FRACTION = 0.7
#: Samples of the exact shape for the curvature, length, crossing and distance checks.
CHECK_SAMPLES = 6001
CROSSING_SAMPLES = 1200

PATH_KINDS = ("open", "closed", "open_crossing", "closed_crossing")
START_KINDS = ("on_path", "far", "facing_away", "crossing")
CATEGORIES: tuple[tuple[str, str], ...] = tuple(
    (p, s) for p in PATH_KINDS for s in START_KINDS if s != "crossing" or p.endswith("crossing"))


class ScenarioError(CompanionError, ValueError):
    """A scenario description is unusable (what, and what was expected)."""


@dataclass(frozen=True)
class ScenarioSpec:
    """One bench scenario, as data.

    Attributes
    ----------
    name : the scenario's name in the bench's rows (``paper_sine_h05``, ``random_1003``, ...).
    mission_text : a mission document (YAML or JSON) whose ``path`` (with its ``frame`` and
        ``origin``) is the scenario's path; its other keys are not used.
    x_m, y_m, heading_rad : the start pose, local ENU, heading anticlockwise from east.
    speed_m_s : the airspeed V flown.
    lag_s, delay_s, a_max_m_s2 : the lag model's first-order time constant, dead time and
        lateral-acceleration limit (the ``lag`` model of the bench; ``ideal`` ignores them).
    wind_enu_m_s : steady wind (east, north) of the ``lag`` model.
    circle_radius_m : the mid-course circle of the two-phase laws.
    category : ``path_kind/start_kind`` of a random scenario, ``mission`` or ``bench``.
    seed : the seed a random scenario was drawn with, else None.
    """

    name: str
    mission_text: str
    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float = BENCH_SPEED_M_S
    lag_s: float = BENCH_LAG_S
    delay_s: float = 0.0
    a_max_m_s2: float = BENCH_A_MAX_M_S2
    wind_enu_m_s: tuple[float, float] = (0.0, 0.0)
    circle_radius_m: float = BENCH_CIRCLE_RADIUS_M
    category: str = "bench"
    seed: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ScenarioError(f"scenario name: expected a non-empty string, got {self.name!r}")
        if not isinstance(self.mission_text, str) or not self.mission_text.strip():
            raise ScenarioError(f"{self.name}: mission_text: expected a mission document")
        wind = tuple(float(w) for w in self.wind_enu_m_s)
        if len(wind) != 2:
            raise ScenarioError(f"{self.name}: wind_enu_m_s: expected [east, north], got {self.wind_enu_m_s!r}")
        object.__setattr__(self, "wind_enu_m_s", wind)
        for key in ("x_m", "y_m", "heading_rad", "speed_m_s", "lag_s", "delay_s", "a_max_m_s2",
                    "circle_radius_m"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ScenarioError(f"{self.name}: {key}: expected a finite number, got {value!r}")
        if not all(math.isfinite(w) for w in wind):
            raise ScenarioError(f"{self.name}: wind_enu_m_s: expected finite numbers, got {self.wind_enu_m_s!r}")
        for key in ("speed_m_s", "a_max_m_s2", "circle_radius_m"):
            if not getattr(self, key) > 0:
                raise ScenarioError(f"{self.name}: {key}: expected a number > 0, got {getattr(self, key)!r}")
        for key in ("lag_s", "delay_s"):
            if getattr(self, key) < 0:
                raise ScenarioError(f"{self.name}: {key}: expected a number >= 0, got {getattr(self, key)!r}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["wind_enu_m_s"] = list(self.wind_enu_m_s)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "ScenarioSpec":
        known = {f for f in cls.__dataclass_fields__}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ScenarioError(f"scenario: unknown keys {', '.join(unknown)}; expected {', '.join(sorted(known))}")
        return cls(**{**d, "wind_enu_m_s": tuple(d.get("wind_enu_m_s", (0.0, 0.0)))})

    def summary(self) -> dict:
        """The spec without its mission text (for reports)."""
        d = self.to_dict()
        del d["mission_text"]
        d["id"] = spec_id(self)
        return d


def spec_id(spec: ScenarioSpec) -> str:
    """A stable id of the whole description (16 hex digits of SHA-256 over its canonical JSON)."""
    text = json.dumps(spec.to_dict(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def build_path(spec: ScenarioSpec):
    """The scenario's :class:`~companion.geometry.paths.Path` (built by the mission loader; the
    last few are cached, so a worker running several rows of one scenario builds it once)."""
    try:
        return _path_of_text(spec.mission_text)
    except MissionError as err:
        raise ScenarioError(f"scenario {spec.name}: {err.problems[0]}") from None


@functools.lru_cache(maxsize=8)
def _path_of_text(text: str):
    from companion.mission import parse_mission

    return parse_mission(text, "mission_text").path


def spec_from_mission(mission, name: str) -> ScenarioSpec:
    """The scenario of a loaded mission: its path, its start (else the path start along the path),
    its speed (the first of a profile), its ``vehicle:`` lag model (else the bench's), its mid-course
    circle; no wind."""
    start = mission.start
    if start is None:
        (x, y), heading = mission.path.start_xy_m, mission.path.start_heading_rad
    else:
        x, y, heading = start.x_m, start.y_m, start.heading_rad
    v = mission.vehicle
    lag = dict(lag_s=BENCH_LAG_S, delay_s=0.0, a_max_m_s2=BENCH_A_MAX_M_S2) if v is None else dict(
        lag_s=v.lag_s + v.accel_lag_s, delay_s=v.delay_s, a_max_m_s2=v.a_max_m_s2)
    return ScenarioSpec(name=name, mission_text=mission.source_text, x_m=float(x), y_m=float(y),
                        heading_rad=float(heading), speed_m_s=float(mission.speed_m_s),
                        circle_radius_m=float(mission.guidance.circle_radius_m), category="mission", **lag)


def scenario_mission_yaml(spec: ScenarioSpec) -> str:
    """A mission file (YAML) that is the scenario, the inverse of :func:`spec_from_mission`: its
    path, speed, ``start`` pose, ``vehicle:`` lag model and mid-course circle, with a comment
    that names the scenario and its wind. Missions carry no wind: ``companion bench tracking
    --mission FILE --wind E,N`` (the comment's figures) flies the bench's scenario; without
    ``--wind`` the same scenario in still air.

    Only a scenario whose mission text is a JSON document in the local ENU frame (every random
    one) can be written: the start is written in that frame.

    >>> text = scenario_mission_yaml(random_spec(3))
    >>> text.splitlines()[0]
    '# random_3: closed/on_path, seed 3, of companion bench tracking --random'
    """
    from companion.mission.loader import dump_mission

    try:
        doc = json.loads(spec.mission_text)
    except json.JSONDecodeError:
        doc = None
    if not isinstance(doc, dict) or doc.get("frame", "local_enu") != "local_enu":
        raise ScenarioError(f"{spec.name}: only a scenario whose path is a JSON document in the local_enu "
                            f"frame (every random one) can be written as a mission")
    doc.update(name=spec.name, speed_m_s=spec.speed_m_s,
               start={"x_m": spec.x_m, "y_m": spec.y_m, "heading_deg": math.degrees(spec.heading_rad)},
               vehicle={"a_max_m_s2": spec.a_max_m_s2, "lag_s": spec.lag_s, "delay_s": spec.delay_s})
    doc["midcourse"] = {**(doc.get("midcourse") or {}), "circle_radius_m": spec.circle_radius_m}
    origin = f", seed {spec.seed}, of companion bench tracking --random" if spec.seed is not None else ""
    east, north = spec.wind_enu_m_s
    comments = (f"{spec.name}: {spec.category}{origin}",
                f"wind (east, north) {east:g}, {north:g} m/s, which a mission does not carry: "
                f"companion bench tracking --mission THIS_FILE --wind={east:g},{north:g}")
    return dump_mission(doc, spec.name, comments)


def function_mission_text(name: str, y_of_x: str, x_range_m: tuple[float, float]) -> str:
    """A minimal mission document (JSON) whose path is ``y = y_of_x`` over ``x_range_m``."""
    return json.dumps({"name": name, "speed_m_s": BENCH_SPEED_M_S,
                       "path": {"type": "function", "y_of_x": y_of_x, "x_range_m": list(x_range_m)}})


# ----------------------------------------------------------------------------- shapes
# A shape is x(u), y(u) = sum of terms c * f(u), each term (kind, k, cx, cy) with f one of
# 1, u, cos(k u), sin(k u): its derivatives are exact, and it writes out as a mission expression.
Term = tuple[str, int, float, float]


def _basis(kind: str, k: int, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f, f', f'' of one term's function on ``u``."""
    if kind == "one":
        z = np.zeros_like(u)
        return np.ones_like(u), z, z
    if kind == "lin":
        return u, np.ones_like(u), np.zeros_like(u)
    c, s = np.cos(k * u), np.sin(k * u)
    if kind == "cos":
        return c, -k * s, -k * k * c
    return s, k * c, -k * k * s


def shape_derivatives(terms: tuple[Term, ...], u: np.ndarray) -> tuple[np.ndarray, ...]:
    """``x, y, x', y', x'', y''`` of a shape on ``u`` (derivatives in u)."""
    out = [np.zeros_like(u) for _ in range(6)]
    for kind, k, cx, cy in terms:
        f = _basis(kind, k, u)
        for j in range(3):
            out[2 * j] += cx * f[j]
            out[2 * j + 1] += cy * f[j]
    return tuple(out)


def _expression(terms: tuple[Term, ...], axis: int) -> str:
    parts = []
    for kind, k, cx, cy in terms:
        c = (cx, cy)[axis]
        if c == 0.0:
            continue
        f = {"one": "1", "lin": "s", "cos": f"cos({k}*s)", "sin": f"sin({k}*s)"}[kind]
        parts.append(f"({c!r})*{f}")
    return " + ".join(parts) or "0"


def _round_sig(v: float, digits: int = 7) -> float:
    return float(f"{v:.{digits}g}")


def _modes(rng: random.Random, ks: tuple[int, ...], amp: float) -> list[Term]:
    """Random cos/sin terms of frequencies ``ks`` whose derivative amplitudes sum to at most ``amp``."""
    terms: list[Term] = []
    share = amp / max(1, len(ks))
    for k in ks:
        a = rng.uniform(0.0, share) / k
        phx, phy = rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi)
        ax, ay = rng.uniform(-1, 1) * a, rng.uniform(-1, 1) * a
        terms += [("cos", k, ax * math.cos(phx), ay * math.cos(phy)),
                  ("sin", k, ax * math.sin(phx), ay * math.sin(phy))]
    return terms


def _draw_shape(rng: random.Random, kind: str) -> tuple[list[Term], tuple[float, float]]:
    """Unscaled terms and the parameter range of one path kind."""
    two_pi = 2.0 * math.pi
    if kind == "open":
        # x increases strictly (x' >= 1 - 0.4 > 0): a wave along a line never crosses itself.
        terms: list[Term] = [("lin", 0, 1.0, 0.0)]
        for k in (1, 2, 3):
            a, ph = rng.uniform(0.1, 0.5) / k, rng.uniform(0, two_pi)
            terms += [("cos", k, 0.0, a * math.sin(ph)), ("sin", k, 0.0, a * math.cos(ph))]
        terms += [(t[0], t[1], t[2], 0.0) for t in _modes(rng, (1, 2), 0.4)]
        return terms, (0.0, rng.uniform(1.5, 2.5) * math.pi)
    if kind == "closed":
        e = rng.uniform(0.6, 1.0)
        terms = [("cos", 1, e, 0.0), ("sin", 1, 0.0, 1.0)] + _modes(rng, (2, 3, 4), 0.35 * e)
        u0 = rng.uniform(0.0, two_pi)
        return terms, (u0, u0 + two_pi)
    if kind == "open_crossing":
        # Prolate trochoid x = u - q sin u, y = q cos u: a loop around every u = 2 pi n when q > 1.
        q = rng.uniform(2.0, 3.0)
        loops = 1 if rng.random() < 0.7 else 2
        terms = [("lin", 0, 1.0, 0.0), ("sin", 1, -q, 0.0), ("cos", 1, 0.0, q)] + _modes(rng, (2, 3), 0.3)
        return terms, (math.pi, math.pi + two_pi * loops)
    if rng.random() < 0.5:  # figure-eight (Lissajous 1:2)
        a = rng.uniform(2.0, 3.5)
        terms = [("sin", 1, a, 0.0), ("sin", 2, 0.0, 1.0)] + _modes(rng, (3, 4), 0.25)
    else:  # limacon with an inner loop: r = b + cos u, b < 1
        b = rng.uniform(0.15, 0.35)
        terms = [("cos", 1, b, 0.0), ("sin", 1, 0.0, b), ("one", 0, 0.5, 0.0), ("cos", 2, 0.5, 0.0),
                 ("sin", 2, 0.0, 0.5)] + _modes(rng, (3,), 0.1)
    u0 = rng.uniform(0.0, two_pi)  # a closed path starts anywhere on it (not always at its crossing)
    return terms, (u0, u0 + two_pi)


def _transform(terms: list[Term], angle: float, mirror: bool, scale: float) -> list[Term]:
    c, s = math.cos(angle), math.sin(angle)
    out = []
    for kind, k, cx, cy in terms:
        if mirror:
            cy = -cy
        out.append((kind, k, scale * (c * cx - s * cy), scale * (s * cx + c * cy)))
    return out


def curvature_of(terms: tuple[Term, ...], u: np.ndarray) -> np.ndarray:
    """Signed curvature (1/m) of a shape at ``u``, from its exact derivatives."""
    _, _, dx, dy, ddx, ddy = shape_derivatives(terms, u)
    return (dx * ddy - dy * ddx) / np.hypot(dx, dy) ** 3


def first_crossing(x: np.ndarray, y: np.ndarray, closed: bool) -> tuple[int, int, float, float] | None:
    """The first self-intersection of the polyline (x, y): segment indices ``i < j`` and the point,
    or None. Adjacent segments (and, closed, the last and the first) do not count."""
    ax, ay, bx, by = x[:-1], y[:-1], x[1:], y[1:]
    n = ax.size
    j = np.arange(n)
    for i0 in range(0, n, 64):  # 64 segments against all the others at a time
        i = np.arange(i0, min(i0 + 64, n))[:, None]
        rx, ry = (bx[i] - ax[i]), (by[i] - ay[i])
        sx, sy = bx[j] - ax[j], by[j] - ay[j]
        den = rx * sy - ry * sx
        qx, qy = ax[j] - ax[i], ay[j] - ay[i]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (qx * sy - qy * sx) / den
            v = (qx * ry - qy * rx) / den
        hit = (den != 0) & (t >= 0) & (t <= 1) & (v >= 0) & (v <= 1) & (j >= i + 2)
        if closed:
            hit &= ~((i == 0) & (j == n - 1))
        rows, cols = np.nonzero(hit)
        if rows.size:
            r, c = int(rows[0]), int(cols[0])
            ii = i0 + r
            return ii, c, float(ax[ii] + t[r, c] * rx[r, 0]), float(ay[ii] + t[r, c] * ry[r, 0])
    return None


@dataclass(frozen=True)
class _Drawn:
    terms: tuple[Term, ...]
    u_range: tuple[float, float]
    closed: bool
    kappa_max_1_m: float
    length_m: float


def _scaled_shape(rng: random.Random, kind: str, length_m: float, kappa_bound: float) -> _Drawn | None:
    """One shape of ``kind`` scaled to ``length_m`` (longer where the curvature bound needs it), its
    start at the origin; None if it fails its crossing check or would be over three times as long."""
    terms, (u0, u1) = _draw_shape(rng, kind)
    terms = _transform(terms, rng.uniform(0, 2 * math.pi), rng.random() < 0.5, 1.0)
    closed = kind in ("closed", "closed_crossing")
    u = np.linspace(u0, u1, CHECK_SAMPLES)
    x, y, dx, dy, _, _ = shape_derivatives(tuple(terms), u)
    speed = np.hypot(dx, dy)
    unit_length = float(np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(u)))
    scale = length_m / unit_length
    k_unit = float(np.max(np.abs(curvature_of(tuple(terms), u))))
    for _ in range(40):
        if k_unit / scale <= kappa_bound:
            break
        scale *= 1.01 * k_unit / scale / kappa_bound
    if scale * unit_length > MAX_STRETCH * length_m:
        return None
    # Start at the origin, then round the coefficients (readable missions) and re-check the bound.
    x0, y0 = float(x[0]), float(y[0])
    terms = [("one", 0, -x0, -y0)] + terms
    for _ in range(20):
        final = tuple((kd, k, _round_sig(scale * cx), _round_sig(scale * cy)) for kd, k, cx, cy in terms)
        kmax = float(np.max(np.abs(curvature_of(final, u))))
        if kmax <= kappa_bound:
            break
        scale *= 1.01
    else:  # pragma: no cover - rounding to 7 digits moves the curvature by about 1e-7
        return None
    xs, ys, *_ = shape_derivatives(final, np.linspace(u0, u1, CROSSING_SAMPLES))
    crossing = first_crossing(xs, ys, closed)
    if (crossing is not None) != kind.endswith("crossing"):
        return None
    return _Drawn(final, (u0, u1), closed, kmax, scale * unit_length)


def _parametric_text(name: str, drawn: _Drawn, speed_m_s: float) -> str:
    path = {"type": "parametric", "x_of_s": _expression(drawn.terms, 0), "y_of_s": _expression(drawn.terms, 1),
            "s_range": [drawn.u_range[0], drawn.u_range[1]], "closed": drawn.closed}
    return json.dumps({"name": name, "speed_m_s": speed_m_s, "path": path})


def _start(rng: random.Random, start_kind: str, drawn: _Drawn) -> tuple[float, float, float] | None:
    """``(x, y, heading)`` of a start of that kind, or None if the draw fails its distance check."""
    u0, u1 = drawn.u_range
    u = np.linspace(u0, u1, CHECK_SAMPLES)
    x, y, dx, dy, _, _ = shape_derivatives(drawn.terms, u)
    if start_kind == "crossing":
        xs, ys, dxs, dys, _, _ = shape_derivatives(drawn.terms, np.linspace(u0, u1, CROSSING_SAMPLES))
        hit = first_crossing(xs, ys, drawn.closed)
        if hit is None:
            return None
        i, _, cx, cy = hit
        heading = math.atan2(dys[i] + dys[i + 1], dxs[i] + dxs[i + 1]) + math.radians(rng.uniform(-10, 10))
        return cx, cy, heading
    top = 0.3 if not drawn.closed else 1.0
    m = min(int(rng.uniform(0.0, top) * (u.size - 1)), u.size - 1)
    tangent = math.atan2(dy[m], dx[m])
    if start_kind == "on_path":
        return float(x[m]), float(y[m]), tangent + math.radians(rng.uniform(-15, 15))
    side = rng.choice((-1.0, 1.0))
    normal = tangent + side * math.pi / 2
    lo, hi = FAR_RANGE_M if start_kind == "far" else AWAY_RANGE_M
    off = rng.uniform(lo, hi)
    sx, sy = x[m] + off * math.cos(normal), y[m] + off * math.sin(normal)
    if float(np.min(np.hypot(x - sx, y - sy))) < 0.7 * off:
        return None
    heading = rng.uniform(-math.pi, math.pi) if start_kind == "far" else normal + math.radians(rng.uniform(-30, 30))
    return float(sx), float(sy), heading


def random_spec(seed: int) -> ScenarioSpec:
    """Scenario ``seed``: drawn from ``random.Random(seed)`` (module docstring)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"random scenario seed: expected an integer >= 0, got {seed!r}")
    rng = random.Random(seed)
    path_kind, start_kind = CATEGORIES[seed % len(CATEGORIES)]
    speed = round(rng.uniform(*SPEED_RANGE_M_S), 3)
    lag = round(rng.uniform(*LAG_RANGE_S), 3)
    w_mag = round(rng.uniform(0.0, WIND_MAX_FRACTION) * speed, 3)
    w_dir = rng.uniform(-math.pi, math.pi)
    wind = (round(w_mag * math.cos(w_dir), 3), round(w_mag * math.sin(w_dir), 3))
    kappa_bound = KAPPA_FRACTION * BENCH_A_MAX_M_S2 / (speed + math.hypot(*wind)) ** 2
    length = speed * rng.uniform(*FLIGHT_TIME_RANGE_S)
    name = f"random_{seed}"
    for _ in range(200):
        drawn = _scaled_shape(rng, path_kind, length, kappa_bound)
        if drawn is None:
            continue
        start = _start(rng, start_kind, drawn)
        if start is None:
            continue
        x, y, heading = start
        return ScenarioSpec(
            name=name, mission_text=_parametric_text(name, drawn, speed), x_m=round(x, 3), y_m=round(y, 3),
            heading_rad=round(math.remainder(heading, 2 * math.pi), 6), speed_m_s=speed, lag_s=lag,
            delay_s=0.0, a_max_m_s2=BENCH_A_MAX_M_S2, wind_enu_m_s=wind,
            circle_radius_m=max(BENCH_CIRCLE_RADIUS_M, round(speed * speed / (0.8 * BENCH_A_MAX_M_S2), 1)),
            category=f"{path_kind}/{start_kind}", seed=seed)
    raise ScenarioError(f"random scenario {seed}: no {path_kind} path with a {start_kind} start in 200 draws")  # pragma: no cover


def random_specs(n: int, seed: int = 0) -> list[ScenarioSpec]:
    """Scenarios ``seed, seed + 1, ..., seed + n - 1``."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ScenarioError(f"random scenarios: expected a count >= 1, got {n!r}")
    return [random_spec(seed + i) for i in range(n)]


def with_wind(spec: ScenarioSpec, wind_enu_m_s: tuple[float, float]) -> ScenarioSpec:
    return replace(spec, wind_enu_m_s=tuple(wind_enu_m_s))
