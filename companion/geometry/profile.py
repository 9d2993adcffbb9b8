"""Altitude and speed along a path: h(s) and V(s) on the path's arc length, within vehicle limits.

A mission may fly its path at a height and speed that change along the way. The user gives
targets at places along the path (a height at each waypoint or segment end, a speed from each
waypoint or segment on, or expressions of the arc length ``s``); this module turns them into two
smooth tables on a uniform arc-length grid that a vehicle can fly:

**Speed** ``V(s)``. The target is held from where it is given until the next one (a step, as
``DO_CHANGE_SPEED`` acts on an autopilot). Each change is flown with the along-track acceleration
``a_long`` from where it is given: a forward pass on ``V^2``, whose change over ``ds`` at constant
acceleration is exactly ``2 a_long ds`` (``V dV/ds = dV/dt``). A slower speed is therefore reached
``(V1^2 - V2^2) / (2 a_long)`` metres after its waypoint (documented in docs/missions.md).

**Altitude** ``h(s)``. The target is the piecewise-linear interpolation of the given heights on
arc length (or the expression). Three steps make it flyable:

1. *climb limit*: along the path the climb rate is ``V(s) dh/ds``, so the slope must stay in
   ``[-sink_max / V(s), climb_max / V(s)]``. A forward pass clips the slope (it reaches each
   height late), a backward pass clips it too (early); their mean is centred on the target and,
   as a mean of two functions whose slopes lie in the band, its slope lies in the band too.
2. *vertical acceleration*: the profile is replaced by its moving average over a window ``w``.
   The averaged slope is the mean of the slope over the window, so it stays in the band, and its
   derivative is ``(g(s + w/2) - g(s - w/2)) / w``, at most ``(g_max - g_min) / w``. At speed V
   the vertical acceleration is ``V^2 h''`` (plus ``V dV/ds V h'`` where the speed changes), so
   ``w = V_max^2 (g_max - g_min) / a_vert`` keeps it at most ``a_vert`` on constant-speed
   stretches. A step of slope ``g`` becomes a parabolic blend of length ``w``; the height at a
   waypoint where the slope changes by ``dg`` moves by at most ``dg w / 8``.
3. open paths are continued by odd reflection about each end (``h(-x) = 2 h(0) - h(x)``), so the
   average keeps the first and last heights exactly; closed paths are periodic (circular passes
   and a circular average).

Pure numpy; no I/O. ``PathProfile`` answers ``altitude_m(s)``, ``slope(s)``, ``speed_m_s(s)``
and ``climb_m_s(s)`` by linear interpolation in its tables.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Union

import numpy as np
import numpy.typing as npt

from companion.geometry.checks import require_positive_finite

#: Grid spacing of the profile tables (finer for short paths; at most MAX_SAMPLES nodes).
GRID_M = 0.05
MAX_SAMPLES = 400_001


@dataclass(frozen=True)
class ProfileLimits:
    """The vehicle limits a profile is smoothed to (SI units, positive numbers).

    climb_max_m_s : largest climb rate (up).
    sink_max_m_s : largest sink rate (down).
    vert_accel_max_m_s2 : largest vertical acceleration of the profile.
    along_accel_max_m_s2 : largest along-track acceleration (speed changes).
    alt_gain_1_s : gain of the correction on altitude error, added to the feed-forward climb.
    turn_accel_share : share of the vehicle's horizontal acceleration limit the path's own turns
        may ask (``V^2 kappa``) once that limit is known; the speed is lowered where a turn asks
        more (:func:`turn_limited_speed`). In [0, 1]; 0: speeds as given.
    """

    climb_max_m_s: float = 2.0
    sink_max_m_s: float = 1.5
    vert_accel_max_m_s2: float = 1.0
    along_accel_max_m_s2: float = 1.0
    alt_gain_1_s: float = 1.0
    turn_accel_share: float = 0.8

    def __post_init__(self) -> None:
        require_positive_finite(self, ("climb_max_m_s", "sink_max_m_s", "vert_accel_max_m_s2",
                                       "along_accel_max_m_s2", "alt_gain_1_s"))
        if not (0.0 <= self.turn_accel_share <= 1.0):
            raise ValueError(f"turn_accel_share: expected a number in [0, 1], got {self.turn_accel_share!r}")


class PathProfile:
    """Height and speed tables on the arc length of one path (see the module docstring).

    Attributes
    ----------
    s_m, alt_m, speed_m_s_table, slope_table : the tables (read-only numpy arrays).
    length_m, closed : of the path.
    limits : the :class:`ProfileLimits` used.
    constant_speed, constant_altitude : True when that table is one value.
    """

    def __init__(self, s_m: npt.ArrayLike, alt_m: npt.ArrayLike, speed_m_s: npt.ArrayLike, closed: bool,
                 limits: ProfileLimits):
        s = np.asarray(s_m, dtype=float)
        h = np.asarray(alt_m, dtype=float)
        v = np.asarray(speed_m_s, dtype=float)
        if s.ndim != 1 or s.size < 2 or h.shape != s.shape or v.shape != s.shape:
            raise ValueError("profile tables: expected equal 1-D arrays of at least 2 nodes")
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(v)) and np.all(v > 0)):
            raise ValueError("profile tables: expected finite heights and finite speeds > 0")
        self.length_m = float(s[-1])
        self.closed = bool(closed)
        self.limits = limits
        self._ds = self.length_m / (s.size - 1)
        g: np.ndarray = np.gradient(h, self._ds)
        for arr in (s, h, v, g):
            arr.setflags(write=False)
        self.s_m, self.alt_m, self.speed_m_s_table, self.slope_table = s, h, v, g
        self.constant_speed = bool(np.all(v == v[0]))
        self.constant_altitude = bool(np.all(h == h[0]))
        # Python lists: the flight loop asks one value per tick.
        self._h: list[float] = h.tolist()
        self._v: list[float] = v.tolist()
        self._g: list[float] = g.tolist()

    def __repr__(self) -> str:
        return (f"PathProfile({self.length_m:.1f} m, alt {float(self.alt_m.min()):g}..{float(self.alt_m.max()):g} m, "
                f"speed {float(self.speed_m_s_table.min()):g}..{float(self.speed_m_s_table.max()):g} m/s)")

    def _interp(self, table: list[float], s_m: float) -> float:
        if not math.isfinite(s_m):
            s_m = 0.0
        if self.closed:
            s_m = s_m % self.length_m
        else:
            s_m = min(max(s_m, 0.0), self.length_m)
        u = s_m / self._ds
        i = min(int(u), len(table) - 2)
        f = u - i
        return table[i] + (table[i + 1] - table[i]) * f

    def altitude_m(self, s_m: float) -> float:
        """Height of the profile at arc length ``s_m`` (clamped to the ends; wrapped when closed)."""
        return self._interp(self._h, s_m)

    def slope(self, s_m: float) -> float:
        """dh/ds at ``s_m`` (metres of height per metre of path)."""
        return self._interp(self._g, s_m)

    def speed_m_s(self, s_m: float) -> float:
        """Speed along the path at ``s_m``."""
        return self._interp(self._v, s_m)

    def climb_m_s(self, s_m: float) -> float:
        """Climb rate (up) of a vehicle on the profile at ``s_m``: ``V(s) dh/ds``."""
        return self.speed_m_s(s_m) * self.slope(s_m)

    @property
    def start_altitude_m(self) -> float:
        return self._h[0]

    @property
    def end_altitude_m(self) -> float:
        return self._h[-1]

    def climb_table_m_s(self) -> np.ndarray:
        """Climb rate at every node of the table."""
        climb: np.ndarray = self.speed_m_s_table * self.slope_table
        return climb


# ------------------------------------------------------------------------------ construction
#: A target height or speed: one number, or a function of the grid's arc lengths (numpy array).
ProfileTarget = Union[float, Callable[[np.ndarray], npt.ArrayLike]]


def grid(length_m: float) -> np.ndarray:
    """The uniform arc-length grid of a profile over ``[0, length_m]``."""
    n = int(min(MAX_SAMPLES, max(2001, math.ceil(length_m / GRID_M) + 1)))
    return np.linspace(0.0, length_m, n)


def knots_table(s_grid: np.ndarray, knots_s_m: npt.ArrayLike, values: npt.ArrayLike, closed: bool, length_m: float,
                step: bool) -> np.ndarray:
    """Values at knots (arc lengths, increasing) on the grid: linear interpolation, or held
    from each knot to the next (``step``). Open paths hold the first and last values beyond the
    knots; closed paths wrap (the last knot joins the first one lap later)."""
    ks = np.asarray(knots_s_m, dtype=float)
    kv = np.asarray(values, dtype=float)
    if closed:
        ks = np.mod(ks, length_m)
        order = np.argsort(ks, kind="stable")
        ks, kv = ks[order], kv[order]
        ks = np.concatenate(([ks[-1] - length_m], ks, [ks[0] + length_m]))
        kv = np.concatenate(([kv[-1]], kv, [kv[0]]))
    if step:
        idx = np.searchsorted(ks, s_grid, side="right") - 1
        held: np.ndarray = kv[np.clip(idx, 0, kv.size - 1)]
        return held
    interpolated: np.ndarray = np.interp(s_grid, ks, kv)
    return interpolated


def speed_table(s_grid: np.ndarray, target_m_s: np.ndarray, accel_max_m_s2: float,
                closed: bool) -> np.ndarray:
    """Rate-limit a target speed along the path: ``|d(V^2)/ds| <= 2 a`` (forward pass)."""
    target2: np.ndarray = np.asarray(target_m_s, dtype=float) ** 2
    if np.all(target2 == target2[0]):
        constant: np.ndarray = np.sqrt(target2)
        return constant
    step = 2.0 * accel_max_m_s2 * (s_grid[1] - s_grid[0])
    laps = 2 if closed else 1
    out = target2.copy()
    v2 = target2[-1] if closed else target2[0]
    for _ in range(laps):
        t = target2.tolist()
        o = [0.0] * len(t)
        # Node i moves towards the target of node i - 1: a change given at s_k starts at s_k.
        prev = t[-1] if closed else t[0]
        for i, want in enumerate(t):
            v2 = min(max(prev, v2 - step), v2 + step)
            o[i] = v2
            prev = want
        out = np.asarray(o)
        v2 = out[-1]
    limited: np.ndarray = np.sqrt(out)
    return limited


def turn_limited_speed(speed_m_s: np.ndarray, curvature_1_m: np.ndarray, ds_m: float, lateral_accel_m_s2: float,
                       along_accel_m_s2: float, closed: bool, min_speed_m_s: float = 0.0) -> np.ndarray:
    """The speeds ``speed_m_s`` (on a uniform grid of step ``ds_m``) lowered where the path's own
    turn would ask more than ``lateral_accel_m_s2``, with the speed changes flown at
    ``along_accel_m_s2``.

    In a turn of curvature ``kappa`` at speed ``V`` the path alone asks ``V^2 |kappa|`` of lateral
    acceleration. So ``V^2`` is capped at ``lateral_accel / |kappa|``; then a backward pass makes
    the vehicle slow down *before* each cap (``V^2`` may fall by at most ``2 a_long ds`` per step
    forward: braking at ``a_long``) and a forward pass makes it speed up again after it (rising by
    at most ``2 a_long ds``). Both passes only lower values, and the forward pass keeps what the
    backward one ensured, so the result is never faster than asked, never faster than the cap, and
    changes at ``a_long`` or less everywhere. A closed path is passed twice round (its joint is
    then settled). Where the input already keeps those limits it is returned unchanged. The cap
    never goes below ``min_speed_m_s`` (a turn tighter than that speed allows is flown at it; a
    slower speed asked stays as asked).

    >>> ds = 0.5; s = np.arange(0.0, 100.0 + ds, ds)
    >>> kappa = np.where((s >= 60) & (s <= 70), 0.2, 0.0)  # a 5 m radius arc at 60..70 m
    >>> v = turn_limited_speed(np.full(s.size, 5.0), kappa, ds, 2.0, 1.0, closed=False)
    >>> round(float(v[s == 65][0] ** 2 * 0.2), 6)          # V^2 kappa = 2 m/s^2 in the arc
    2.0
    >>> float(s[np.argmax(v < 5.0)])       # braking starts (25 - 10) / (2 * 1) = 7.5 m before it
    53.0
    """
    v2 = np.asarray(speed_m_s, dtype=float) ** 2
    k = np.abs(np.asarray(curvature_1_m, dtype=float))
    cap = np.full_like(v2, np.inf)
    np.divide(lateral_accel_m_s2, k, out=cap, where=k > 1e-9)  # straighter than a 1e9 m radius: no cap
    cap = np.maximum(cap, min_speed_m_s * min_speed_m_s)
    if np.all(v2 <= cap):
        unchanged: np.ndarray = np.sqrt(v2)
        return unchanged
    limited = np.minimum(v2, cap).tolist()
    step = 2.0 * along_accel_m_s2 * ds_m
    n = len(limited) - 1 if closed else len(limited)  # a closed table's last node is its first
    for order in (range(n - 1, -1, -1), range(n)):  # brake before the caps, then speed up after
        prev = math.inf
        for _ in range(2 if closed else 1):
            for i in order:
                prev = limited[i] = min(limited[i], prev + step)
    if closed:
        limited[-1] = limited[0]
    out: np.ndarray = np.sqrt(np.asarray(limited))
    return out


def _clip_pass(target: list[float], up: list[float], down: list[float], start: float) -> list[float]:
    out = [0.0] * len(target)
    h = start
    for i, want in enumerate(target):
        h = min(max(want, h - down[i]), h + up[i])
        out[i] = h
    return out


def rate_limited(target_m: np.ndarray, up_m: np.ndarray, down_m: np.ndarray, closed: bool) -> np.ndarray:
    """Mean of a forward and a backward slope-clipping pass (``up``/``down`` per grid step)."""
    t = np.asarray(target_m, dtype=float)
    up, down = np.asarray(up_m, dtype=float), np.asarray(down_m, dtype=float)
    if closed:  # two laps settle the periodic solution; keep the second
        t2, u2, d2 = np.tile(t, 2), np.tile(up, 2), np.tile(down, 2)
        fwd: np.ndarray = np.asarray(_clip_pass(t2.tolist(), u2.tolist(), d2.tolist(), float(t[0])))[t.size:]
        # Backwards a climb is a descent: the roles of up and down swap.
        bwd: np.ndarray = np.asarray(_clip_pass(t2[::-1].tolist(), d2[::-1].tolist(), u2[::-1].tolist(),
                                    float(t[-1])))[t.size:][::-1]
    else:
        fwd = np.asarray(_clip_pass(t.tolist(), up.tolist(), down.tolist(), float(t[0])))
        bwd = np.asarray(_clip_pass(t[::-1].tolist(), down[::-1].tolist(), up[::-1].tolist(),
                                    float(t[-1])))[::-1]
    mean: np.ndarray = 0.5 * (fwd + bwd)
    return mean


def moving_average(values: np.ndarray, half_width: int, closed: bool) -> np.ndarray:
    """Centred moving average over ``2 half_width + 1`` nodes (odd reflection at the ends of an
    open table, which keeps the end values; periodic when closed)."""
    v = np.asarray(values, dtype=float)
    if half_width <= 0:
        unchanged: np.ndarray = v.copy()
        return unchanged
    if closed:
        core = v[:-1]  # the last node repeats the first
        reps = half_width // core.size + 1
        ext = np.concatenate([np.tile(core, reps)[-half_width:], core, np.tile(core, reps)[:half_width + 1]])
        c = np.concatenate(([0.0], np.cumsum(ext)))
        m = 2 * half_width + 1
        out = (c[m:] - c[:-m])[: core.size + 1] / m
        return out
    # Odd reflection about each end (h(-x) = 2 h(0) - h(x)): the average keeps the end values
    # exactly, and the slopes beyond the ends are those inside (no new slopes, no new jumps).
    n = v.size
    idx = np.arange(1, half_width + 1)
    before = 2.0 * v[0] - v[np.minimum(idx, n - 1)][::-1]
    after = 2.0 * v[-1] - v[np.maximum(n - 1 - idx, 0)]
    if half_width >= n:  # a window longer than the path: continue linearly past the reflection
        g0, g1 = v[1] - v[0], v[-1] - v[-2]
        before = v[0] - g0 * idx[::-1]
        after = v[-1] + g1 * idx
    ext = np.concatenate([before, v, after])
    c = np.concatenate(([0.0], np.cumsum(ext)))
    m = 2 * half_width + 1
    return (c[m:] - c[:-m]) / m


def _half_window(limited: np.ndarray, ds: float, v_max: float, limits: ProfileLimits) -> int:
    g = np.diff(limited) / ds
    w = v_max * v_max * float(np.max(g) - np.min(g)) / limits.vert_accel_max_m_s2
    return int(math.ceil(0.5 * w / ds - 1e-9))


def altitude_table(s_grid: np.ndarray, target_m: np.ndarray, speed_m_s: np.ndarray,
                   limits: ProfileLimits, closed: bool) -> np.ndarray:
    """The flyable height table for ``target_m`` at speeds ``speed_m_s`` (module docstring)."""
    target = np.asarray(target_m, dtype=float)
    if np.all(target == target[0]):
        flat: np.ndarray = target.copy()
        return flat
    ds = float(s_grid[1] - s_grid[0])
    v = np.asarray(speed_m_s, dtype=float)
    # A relative margin of 1e-6 absorbs the rounding of the tables and their interpolation.
    climb, sink = limits.climb_max_m_s * (1 - 1e-6), limits.sink_max_m_s * (1 - 1e-6)
    up = climb / v * ds
    down = sink / v * ds
    v_max = float(np.max(v))
    limited = rate_limited(target, up, down, closed)
    half = _half_window(limited, ds, v_max, limits)
    if half and not np.all(v == v[0]):
        # The average mixes slopes from up to w/2 away, clipped for other speeds: clip each with
        # the fastest speed within w/2 of it, so that the averaged slope at s is at most
        # climb_max / V(s) (every slope in the window is). The window may grow; repeat.
        for _ in range(4):
            size = 2 * half + 1
            from scipy.ndimage import maximum_filter1d  # here: the flight's imports stay light

            v_near = maximum_filter1d(v, size=min(size, 4 * v.size + 1), mode="wrap" if closed else "nearest")
            limited = rate_limited(target, climb / v_near * ds, sink / v_near * ds, closed)
            new_half = _half_window(limited, ds, v_max, limits)
            if new_half <= half:
                break
            half = new_half
    return moving_average(limited, half, closed)


def build_profile(length_m: float, closed: bool, limits: ProfileLimits, *,
                  alt_target: ProfileTarget, speed_target: ProfileTarget) -> PathProfile:
    """A :class:`PathProfile` from target functions of the grid.

    ``alt_target`` and ``speed_target`` are each a number, or a callable taking the grid (arc
    lengths, numpy array) and returning the target values on it.
    """
    s = grid(length_m)

    def on_grid(target: ProfileTarget) -> np.ndarray:
        if callable(target):
            values: np.ndarray = np.asarray(target(s), dtype=float) * np.ones_like(s)
            return values
        return np.full_like(s, float(target))

    v = speed_table(s, on_grid(speed_target), limits.along_accel_max_m_s2, closed)
    h = altitude_table(s, on_grid(alt_target), v, limits, closed)
    return PathProfile(s, h, v, closed, limits)
