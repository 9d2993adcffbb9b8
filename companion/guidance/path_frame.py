"""Path-relative quantities the laws need at one tick (pure maths, ENU).

The laws (the predictive law and the baselines) talk to a :class:`companion.geometry.paths.Path` through the documented contract
only (``point``, ``tangent``, ``curvature``, ``project``, ``length_m``, ``closed``). This module
collects the few derived quantities they share, so that each law file reads like its equations:

- :func:`path_frame`: closest point, unit tangent, signed curvature and signed cross-track error
  (positive when the vehicle is LEFT of the path, i.e. on the side the left normal points to);
- :func:`first_projection_s`: where a vehicle should join a closed path that comes back near
  itself (the branch it is flying along, not merely the nearest);
- :func:`frame_samples`: point, tangent and curvature at many arc lengths at once;
- :func:`lookahead_s`: the first arc length forward of ``s_from`` whose point lies at Euclidean
  distance ``L`` from the vehicle (the look-ahead point of L1 guidance and pure pursuit);
- :func:`goal_point`: the same point, continuing an open path straight past its end;
- :func:`is_finished` (an open path is finished once the projection reaches its end).

Angles are wrapped by :func:`companion.geometry.frames.wrap_pi` (re-exported here for the laws).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from companion.geometry.frames import wrap_pi as wrap_pi
from companion.guidance.types import GuidanceOutput  # re-exported for the laws

class PathLike(Protocol):
    """The documented path contract the laws use (``docs/architecture.md``, "Path").

    :class:`companion.geometry.paths.Path` is one; a bench may hand a law another. Optional
    faster forms (``frame``, ``lookahead``, ``frame_array``) are looked up with ``getattr``.
    """

    length_m: float
    closed: bool

    def point(self, s_m: float) -> Any: ...

    def tangent(self, s_m: float) -> Any: ...

    def curvature(self, s_m: float) -> float: ...

    def project(self, x_m: float, y_m: float, s_hint: float | None = None) -> Any: ...


#: Arc-length tolerance used to decide that the projection has reached the end of an open path.
END_TOL_M = 1.0e-3


def _as_s(result: Any) -> float:
    """Arc length out of a projection/look-ahead result (a float, or a tuple whose first item is s)."""
    if isinstance(result, (tuple, list)):
        return float(result[0])
    s = getattr(result, "s_m", None)
    return float(result if s is None else s)


def _xy(v: Any) -> tuple[float, float]:
    return float(v[0]), float(v[1])


@dataclass(frozen=True)
class PathFrame:
    """The path seen from the vehicle at one tick (ENU metres, radians)."""

    s_m: float  # arc length of the closest point
    px_m: float  # closest point
    py_m: float
    tx: float  # unit tangent at the closest point
    ty: float
    curvature_1_m: float  # signed curvature at the closest point (left turn positive)
    crosstrack_m: float  # signed distance, positive = vehicle left of the path

    @property
    def tangent_rad(self) -> float:
        return math.atan2(self.ty, self.tx)


def wrap_s(path: PathLike, s_m: float) -> float:
    """Arc length mapped into ``[0, length_m]`` (modulo the length on a closed path, else clamped)."""
    length = float(path.length_m)
    if path.closed:
        return s_m % length
    return min(max(s_m, 0.0), length)


def path_frame(path: PathLike, x_m: float, y_m: float, s_hint_m: float | None,
               course_rad: float | None = None) -> PathFrame:
    """Closest point, tangent, curvature and signed cross-track error of the vehicle at (x, y).

    Without a hint (the first tick) the projection is :func:`first_projection_s`'s: at a crossing
    of a closed path, the branch along ``course_rad``."""
    s = first_projection_s(path, x_m, y_m, course_rad) if s_hint_m is None else _as_s(path.project(x_m, y_m, s_hint_m))
    frame = getattr(path, "frame", None)
    if frame is not None:  # companion.geometry.paths.Path: point, tangent and curvature in one call
        px, py, tx, ty, k = frame(s)
    else:
        px, py = _xy(path.point(s))
        tx, ty = _xy(path.tangent(s))
        k = float(path.curvature(s))
    norm = math.hypot(tx, ty) or 1.0
    tx, ty = tx / norm, ty / norm
    # cross(t, p_vehicle - p_path): positive when the vehicle is on the left of the direction of travel.
    d = tx * (y_m - py) - ty * (x_m - px)
    return PathFrame(s, px, py, tx, ty, float(k), d)


def frame_samples(path: PathLike, s_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Point, unit tangent and curvature at the arc lengths ``s_m`` (in ``[0, length_m]``): arrays
    ``(x, y, tx, ty, curvature)``, by the path's ``frame_array`` when it has one, else query by query."""
    frame_array = getattr(path, "frame_array", None)
    if frame_array is not None:
        x, y, tx, ty, k = frame_array(s_m)
        return x, y, tx, ty, k
    pts = np.array([_xy(path.point(v)) for v in s_m], dtype=float)
    tng = np.array([_xy(path.tangent(v)) for v in s_m], dtype=float)
    k = np.array([float(path.curvature(v)) for v in s_m], dtype=float)
    return pts[:, 0], pts[:, 1], tng[:, 0], tng[:, 1], k


#: A branch of a closed path within this distance of the nearest counts as near as it (at a crossing).
BRANCH_TIE_M = 1.0


def first_projection_s(path: PathLike, x_m: float, y_m: float, course_rad: float | None) -> float:
    """The projection with no previous one: on a closed path near a crossing, the branch flown along.

    A vehicle at a crossing of a closed path (a figure-eight, a limacon's loop) is as near to one
    branch as to the other; the global projection took whichever was nearer by a centimetre. A
    vehicle flying along one branch then turned round onto the other (at 13.8 m/s and 5 m/s^2 a
    circle of 38 m radius), and the benches measured it against whichever branch their own
    projection had taken. Here, of the branches within ``BRANCH_TIE_M`` of the nearest (local
    minima of the distance on a 1 m grid), the one whose direction is closest to ``course_rad`` is
    taken, refined by the path's own projection from there. Anywhere else (one branch that near,
    an open path, followed from its start, or no course given) it is ``path.project``'s answer.

    Examples
    --------
    >>> import numpy as np
    >>> from companion.geometry.paths import parametric_path
    >>> eight = parametric_path(lambda u: 60 * np.cos(u) / (1 + np.sin(u) ** 2),
    ...                         lambda u: 60 * np.sin(u) * np.cos(u) / (1 + np.sin(u) ** 2), (0, 2 * np.pi), closed=True)
    >>> def direction(course_deg):  # of the branch joined at the crossing (the origin)
    ...     tx, ty = eight.tangent(first_projection_s(eight, 0.0, 0.0, math.radians(course_deg)))
    ...     return round(math.degrees(math.atan2(ty, tx)))
    >>> direction(-140.0), direction(-50.0)
    (-135, -45)
    """
    s0 = _as_s(path.project(x_m, y_m, None))
    length = float(path.length_m)
    if course_rad is None or not path.closed or not length > 0.0:
        return s0
    s = np.linspace(0.0, length, max(int(math.ceil(length)), 8), endpoint=False)
    px, py, tx, ty, _ = frame_samples(path, s)
    dist = np.hypot(px - x_m, py - y_m)
    near = np.flatnonzero((dist <= np.roll(dist, 1)) & (dist <= np.roll(dist, -1))
                          & (dist <= float(np.min(dist)) + BRANCH_TIE_M))
    if near.size < 2:
        return s0
    turn = np.abs((course_rad - np.arctan2(ty[near], tx[near]) + math.pi) % (2.0 * math.pi) - math.pi)
    s_best = _as_s(path.project(x_m, y_m, float(s[near[int(np.argmin(turn))]])))
    # the global projection's branch chosen: its own answer (the same, to the last bit)
    gap = abs(s_best - s0)
    return s0 if min(gap, length - gap) < 2.0 else s_best


def lookahead_s(path: PathLike, x_m: float, y_m: float, l_m: float, s_from_m: float) -> float | None:
    """First arc length forward of ``s_from_m`` at Euclidean distance ``l_m`` from (x, y).

    Uses ``path.lookahead`` when the path has it (same contract). Otherwise marches forward in
    steps of ``l_m / 4`` until a point at least ``l_m`` away is found, then bisects the bracket
    (24 halvings, far below a millimetre). Returns ``None`` when there is no such point: either the vehicle is farther than ``l_m`` from the point at ``s_from_m`` (the
    look-ahead circle does not reach the path there), or the whole rest of an open path lies
    within ``l_m`` of the vehicle (it is about to finish).

    On a closed path the search covers one lap forward of ``s_from_m``; the returned arc length is
    unwrapped (it may exceed ``length_m``); use :func:`wrap_s` before evaluating the path.
    """
    native = getattr(path, "lookahead", None)
    if native is not None:  # companion.geometry.paths.Path has the same contract, faster
        result = native(x_m, y_m, l_m, s_from_m)
        return None if result is None else _as_s(result)
    length = float(path.length_m)
    s_end = s_from_m + length if path.closed else length

    def dist(s: float) -> float:
        qx, qy = _xy(path.point(wrap_s(path, s)))
        return math.hypot(qx - x_m, qy - y_m)

    if dist(s_from_m) >= l_m:
        return None  # the vehicle is farther than L from the closest point: no look-ahead circle crossing
    step = max(l_m / 4.0, 1.0e-3)
    lo = s_from_m
    hi = lo
    while True:
        hi = min(lo + step, s_end)
        if dist(hi) >= l_m:
            break
        if hi >= s_end:
            return None
        lo = hi
    for _ in range(24):
        mid = 0.5 * (lo + hi)
        if dist(mid) >= l_m:
            hi = mid
        else:
            lo = mid
    return hi


def goal_point(path: PathLike, x_m: float, y_m: float, l_m: float, s_from_m: float) -> tuple[float, float] | None:
    """The look-ahead point at distance ``l_m``, continuing an open path straight past its end.

    Near the end of an open path the whole rest of it lies within ``l_m`` of the vehicle and
    there is no look-ahead point; aiming at the end point itself would make ``sin(eta) / dist``
    blow up as the vehicle arrives. As ArduPilot and PX4 do past the last waypoint, the path is
    then continued along its end tangent ``t``: the goal is ``E + u t`` at distance ``l_m``, with
    ``w = E - P`` and ``u = -(w.t) + sqrt((w.t)^2 - |w|^2 + l^2)``. Returns ``None`` when the
    vehicle is farther than ``l_m`` from the path ahead (no look-ahead point exists).
    """
    s = lookahead_s(path, x_m, y_m, l_m, s_from_m)
    if s is not None:
        return _xy(path.point(wrap_s(path, s)))
    if path.closed:
        return None
    ex, ey = _xy(path.point(path.length_m))
    wx, wy = ex - x_m, ey - y_m
    w2 = wx * wx + wy * wy
    if w2 > l_m * l_m:
        return None
    tx, ty = _xy(path.tangent(path.length_m))
    wt = wx * tx + wy * ty
    u = -wt + math.sqrt(max(wt * wt - w2 + l_m * l_m, 0.0))
    return ex + u * tx, ey + u * ty


def frame_output(path: PathLike, f: PathFrame, a_cmd_m_s2: float, lookahead_xy_m: tuple[float, float] | None,
                 extra: dict[str, Any], reoptimised: bool = False) -> GuidanceOutput:
    """A law's close-range output at the frame ``f`` (``finished`` once the path's end is reached)."""
    return GuidanceOutput(
        a_cmd_m_s2=a_cmd_m_s2,
        phase="finished" if is_finished(path, f.s_m) else "close_range",
        crosstrack_m=f.crosstrack_m,
        s_proj_m=f.s_m,
        lookahead_xy_m=lookahead_xy_m,
        reoptimised=reoptimised,
        extra=extra,
    )


def is_finished(path: PathLike, s_m: float) -> bool:
    """An open path is finished once its closest point is its end; a closed path never finishes."""
    return (not path.closed) and s_m >= float(path.length_m) - END_TOL_M
