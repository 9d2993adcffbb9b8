"""Reference paths: C^2 planar curves parameterised by arc length.

Every path, whatever it was built from (a function ``y = f(x)``, a parametric curve, or
waypoints smoothed by a cubic spline), becomes the same object: a :class:`Path` sampled on a
fine uniform arc-length table. Queries on the guidance hot path (50 Hz and inside the
corrector's rollouts) then cost a table index and a cubic Hermite evaluation, with no scipy call.

Frame: local ENU metres (x east, y north). Angles anticlockwise from +x. Signed curvature is
positive for a left (anticlockwise) turn.

The table
---------
At ``n + 1`` uniform arc-length nodes ``s_i = i h`` the table stores the point ``(x_i, y_i)``,
the unit tangent ``(tx_i, ty_i)`` and the signed curvature ``k_i``, all taken from the exact
derivatives of a dense cubic spline of the source curve. Between nodes:

- the point is the cubic Hermite interpolant of positions and unit tangents (the tangent is the
  derivative with respect to arc length), error O(h^4);
- the tangent is the cubic Hermite interpolant of tangents and their derivatives
  ``k * normal``, renormalised;
- the curvature is interpolated linearly (error O(h^2)).

With ``h`` about 2 cm the positions are exact to far below a millimetre and the curvature of the
paper's sine path to about 1e-6 1/m; ``tests/geometry/test_paths.py`` checks both against
closed forms.

Projection and look-ahead
-------------------------
``project(x, y, s_hint)`` returns the arc length of the closest point. With a hint (the previous
projection) it only searches a window around the hint, sized by how far the vehicle is from the
hinted point, so a path that comes back near itself (a racetrack, a hairpin) never makes the
projection jump to the other branch. Without a hint (the first projection of a flight):

- a closed path is searched whole (the global closest point);
- an open path is followed from its start: walking from ``s = 0`` forward, the result is the
  first local minimum of the distance that is about as near as the nearest point, i.e. within
  the same window a hint allows (``2 d_min + 2 m``, ``d_min`` the distance to the closest
  point). On a path that crosses itself, a vehicle near the crossing joins the branch flown
  first, not the later one; a branch much farther than the nearest is passed over, so a vehicle
  on the path far along a meandering open path is not sent back to an earlier meander
  (docs/frames.md, "Projection").

``lookahead(x, y, l1_m, s_from)`` returns the first arc length forward of ``s_from`` where the
path leaves the circle of radius L1 around the vehicle (the Park 2007 reference point), or
``None`` when the path ends first or never comes within L1.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

ArrayFn = Callable[[np.ndarray], np.ndarray]

# Table spacing: the finest of TARGET_SPACING_M and length / MIN_NODES, capped at MAX_NODES nodes.
TARGET_SPACING_M = 0.02
MIN_NODES = 2000
MAX_NODES = 400_000
# Dense sampling of the source curve (in its own parameter) before the arc-length resampling.
SOURCE_SAMPLES = 20_001
# Projection with a hint searches |s - s_hint| <= PROJECT_WINDOW_FACTOR * dist + PROJECT_WINDOW_MIN_M.
PROJECT_WINDOW_FACTOR = 2.0
PROJECT_WINDOW_MIN_M = 2.0
# Coarse stride of the look-ahead scan.
LOOKAHEAD_STRIDE_M = 0.5


# (x_m, y_m, tx, ty, curvature_1_m) at one arc length: what :meth:`Path.frame` returns.
PathFrame = tuple[float, float, float, float, float]
_NO_FRAME: PathFrame = (math.nan, math.nan, math.nan, math.nan, math.nan)


def _hermite_basis(u: float, h: float) -> tuple[float, float, float, float]:
    """Cubic Hermite weights ``(h00, h10, h01, h11)`` at ``u`` in [0, 1] of an interval ``h`` long.

    A value interpolates as ``h00 v0 + h10 d0 + h01 v1 + h11 d1`` (``d`` the arc-length
    derivatives; ``h`` is folded into ``h10`` and ``h11``).

    >>> _hermite_basis(0.0, 2.0), _hermite_basis(1.0, 2.0)
    ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))
    >>> _hermite_basis(0.5, 2.0)
    (0.5, 0.25, 0.5, -0.25)
    """
    u2 = u * u
    u3 = u2 * u
    return 2 * u3 - 3 * u2 + 1, (u3 - 2 * u2 + u) * h, -2 * u3 + 3 * u2, (u3 - u2) * h


# Over 300 lines on purpose: this is the whole path contract of docs/architecture.md (point,
# tangent, curvature, project, lookahead, ...) over one set of arc-length tables; every method
# reads the same tables, and the laws rely on finding the contract in one object.
class Path:
    """A C^2 planar path parameterised by arc length ``s_m`` in ``[0, length_m]``.

    Build one with :func:`function_path`, :func:`parametric_path` or :func:`waypoint_path`
    rather than directly.

    Attributes
    ----------
    length_m : total arc length.
    closed : True for a loop; every query then wraps ``s`` modulo ``length_m``.
    start_xy_m : the point at ``s = 0``.
    start_heading_rad : the tangent direction at ``s = 0`` (anticlockwise from +x).
    s_table_m, x_table_m, y_table_m, tx_table, ty_table, k_table_1_m : the arc-length table
        (numpy arrays, read-only), also convenient for plotting.
    """

    def __init__(self, s_m: npt.ArrayLike, x_m: npt.ArrayLike, y_m: npt.ArrayLike, tx: npt.ArrayLike,
                 ty: npt.ArrayLike, k_1_m: npt.ArrayLike, closed: bool):
        s = np.asarray(s_m, dtype=float)
        if s.ndim != 1 or s.size < 3:
            raise ValueError("path table: expected at least 3 nodes")
        self.length_m = float(s[-1])
        if not (math.isfinite(self.length_m) and self.length_m > 0):
            raise ValueError(f"path length: expected a finite length > 0, got {self.length_m!r}")
        self.closed = bool(closed)
        self._n = s.size - 1  # number of intervals
        self._h = self.length_m / self._n
        self._inv_h = 1.0 / self._h
        arrays = {}
        for name, values in (("s", s), ("x", x_m), ("y", y_m), ("tx", tx), ("ty", ty), ("k", k_1_m)):
            arr = np.array(values, dtype=float)
            if arr.shape != s.shape or not np.all(np.isfinite(arr)):
                raise ValueError(f"path table {name}: expected {s.size} finite values")
            arr.setflags(write=False)
            arrays[name] = arr
        self.s_table_m = arrays["s"]
        self.x_table_m = arrays["x"]
        self.y_table_m = arrays["y"]
        self.tx_table = arrays["tx"]
        self.ty_table = arrays["ty"]
        self.k_table_1_m = arrays["k"]
        # Python lists: scalar indexing of a list is several times cheaper than of an ndarray.
        self._x: list[float] = self.x_table_m.tolist()
        self._y: list[float] = self.y_table_m.tolist()
        self._tx: list[float] = self.tx_table.tolist()
        self._ty: list[float] = self.ty_table.tolist()
        self._k: list[float] = self.k_table_1_m.tolist()
        # Interval table for the vectorised queries: row i holds, for interval i, the cubic
        # polynomials in u of the point (x, y), of the unnormalised tangent (ax, ay) and of the
        # curvature, as Horner coefficients ``coef[i, p, :]`` of ``u**p``: the Hermite forms of
        # the scalar queries expanded once, so a vectorised query is one gather and three
        # multiply-adds instead of some forty array operations.
        self._coef = _hermite_coefficients(self.x_table_m, self.y_table_m, self.tx_table,
                                           self.ty_table, self.k_table_1_m, self._h)
        # The last two frames evaluated, as (s, frame, s, frame): a tick asks for the frames of the
        # projection and of the look-ahead point, which the searches that found them have just
        # evaluated, and the next tick starts its searches from the same two points.
        # A NaN arc length never compares equal, so the empty slots are never returned.
        self._memo: tuple[float, PathFrame, float, PathFrame] = (math.nan, _NO_FRAME, math.nan, _NO_FRAME)
        self.start_xy_m = (self._x[0], self._y[0])
        self.start_heading_rad = math.atan2(self._ty[0], self._tx[0])
        self.end_xy_m = (self._x[-1], self._y[-1])
        self.end_heading_rad = math.atan2(self._ty[-1], self._tx[-1])

    def __repr__(self) -> str:
        kind = "closed" if self.closed else "open"
        return f"Path({kind}, length_m={self.length_m:.3f}, nodes={self._n + 1})"

    # ------------------------------------------------------------------ scalar queries
    def _locate(self, s_m: float) -> tuple[int, float]:
        """Interval index ``i`` and local coordinate ``u`` in [0, 1] of arc length ``s_m``."""
        if self.closed:
            s_m = s_m % self.length_m
        elif s_m <= 0.0:
            return 0, 0.0
        elif s_m >= self.length_m:
            return self._n - 1, 1.0
        q = s_m * self._inv_h
        i = int(q)
        if i >= self._n:
            return self._n - 1, 1.0
        return i, q - i

    def wrap(self, s_m: float) -> float:
        """``s_m`` brought into ``[0, length_m]``: modulo the length if closed, clamped if open."""
        if self.closed:
            return s_m % self.length_m
        return min(max(s_m, 0.0), self.length_m)

    def point(self, s_m: float) -> tuple[float, float]:
        """The point ``(x_m, y_m)`` at arc length ``s_m`` (clamped to the ends of an open path)."""
        i, u = self._locate(s_m)
        h00, h10, h01, h11 = _hermite_basis(u, self._h)
        x, y, tx, ty = self._x, self._y, self._tx, self._ty
        return (h00 * x[i] + h10 * tx[i] + h01 * x[i + 1] + h11 * tx[i + 1],
                h00 * y[i] + h10 * ty[i] + h01 * y[i + 1] + h11 * ty[i + 1])

    def tangent(self, s_m: float) -> tuple[float, float]:
        """The unit tangent ``(tx, ty)`` at ``s_m`` (direction of increasing arc length)."""
        i, u = self._locate(s_m)
        return self._tangent_iu(i, u)

    def _tangent_iu(self, i: int, u: float) -> tuple[float, float]:
        h00, h10, h01, h11 = _hermite_basis(u, self._h)
        tx, ty, k = self._tx, self._ty, self._k
        # d(tx)/ds = -k ty, d(ty)/ds = k tx (Frenet).
        ax = h00 * tx[i] - h10 * k[i] * ty[i] + h01 * tx[i + 1] - h11 * k[i + 1] * ty[i + 1]
        ay = h00 * ty[i] + h10 * k[i] * tx[i] + h01 * ty[i + 1] + h11 * k[i + 1] * tx[i + 1]
        norm = math.hypot(ax, ay)
        return ax / norm, ay / norm

    def curvature(self, s_m: float) -> float:
        """Signed curvature at ``s_m`` in 1/m: positive for a left (anticlockwise) turn."""
        i, u = self._locate(s_m)
        return self._k[i] + u * (self._k[i + 1] - self._k[i])

    def max_abs_curvature(self, s_from_m: float, s_to_m: float) -> float:
        """Largest ``|curvature|`` (1/m) on ``[s_from_m, s_to_m]`` (wrapping on a closed path).

        Exact for the interpolant: the curvature is linear between nodes, so the largest value is
        at one of the nodes that bracket the interval.
        """
        if s_to_m < s_from_m:
            s_from_m, s_to_m = s_to_m, s_from_m
        n = self._n
        if self.closed:
            if s_to_m - s_from_m >= self.length_m:
                return float(np.max(np.abs(self.k_table_1_m)))
            i0 = int(math.floor((s_from_m % self.length_m) * self._inv_h))
            i1 = i0 + int(math.ceil((s_to_m - s_from_m) * self._inv_h)) + 1
            k = self.k_table_1_m
            idx = np.arange(i0, i1 + 1) % n
            return float(np.max(np.abs(k[idx])))
        i0 = min(max(int(math.floor(s_from_m * self._inv_h)), 0), n)
        i1 = min(max(int(math.ceil(s_to_m * self._inv_h)), 0), n)
        return float(np.max(np.abs(self.k_table_1_m[i0:i1 + 1])))

    def radius_of_curvature_m(self, s_m: float) -> float:
        """``1 / |curvature|`` at ``s_m`` (``inf`` on a straight stretch)."""
        k = abs(self.curvature(s_m))
        return math.inf if k < 1e-12 else 1.0 / k

    def heading_rad(self, s_m: float) -> float:
        """Direction of the tangent at ``s_m``, anticlockwise from +x, in (-pi, pi]."""
        tx, ty = self.tangent(s_m)
        return math.atan2(ty, tx)

    def frame(self, s_m: float) -> PathFrame:
        """``(x_m, y_m, tx, ty, curvature_1_m)`` at ``s_m`` in one call (saves work on the hot path).

        The last two frames are remembered: asking again for either costs a comparison.
        """
        memo = self._memo
        if s_m == memo[0]:
            return memo[1]
        if s_m == memo[2]:
            return memo[3]
        i, u = self._locate(s_m)
        h00, h10, h01, h11 = _hermite_basis(u, self._h)
        x, y, tx, ty, k = self._x, self._y, self._tx, self._ty, self._k
        px = h00 * x[i] + h10 * tx[i] + h01 * x[i + 1] + h11 * tx[i + 1]
        py = h00 * y[i] + h10 * ty[i] + h01 * y[i + 1] + h11 * ty[i + 1]
        ax = h00 * tx[i] - h10 * k[i] * ty[i] + h01 * tx[i + 1] - h11 * k[i + 1] * ty[i + 1]
        ay = h00 * ty[i] + h10 * k[i] * tx[i] + h01 * ty[i + 1] + h11 * k[i + 1] * tx[i + 1]
        norm = math.hypot(ax, ay)
        result = (px, py, ax / norm, ay / norm, k[i] + u * (k[i + 1] - k[i]))
        self._memo = (s_m, result, memo[0], memo[1])
        return result

    def crosstrack_m(self, x_m: float, y_m: float, s_m: float) -> float:
        """Signed distance of ``(x_m, y_m)`` from the path point at ``s_m``: positive left of the path.

        Equal to the cross-track error when ``s_m`` is the projection of the point.
        """
        px, py = self.point(s_m)
        tx, ty = self.tangent(s_m)
        dx, dy = x_m - px, y_m - py
        side = tx * dy - ty * dx
        dist = math.hypot(dx, dy)
        return dist if side >= 0.0 else -dist

    # ------------------------------------------------------------------ projection
    def project(self, x_m: float, y_m: float, s_hint: float | None = None) -> float:
        """Arc length of the closest path point to ``(x_m, y_m)``.

        Parameters
        ----------
        x_m, y_m : the query point (local ENU).
        s_hint : the previous projection, if any. With a hint only arc lengths within
            ``2 * |q - point(s_hint)| + 2 m`` of the hint are searched, so the result stays on the
            hinted branch of a path that comes back near itself. Without a hint the search is
            global on a closed path; on an open path it is the first local minimum of the
            distance from ``s = 0`` forward within ``2 d_min + 2 m`` (open paths are followed
            from their start).

        Returns
        -------
        float in ``[0, length_m]`` (``[0, length_m)`` for a closed path).
        """
        n = self._n
        if s_hint is None:
            if not self.closed:
                return self._refine_projection(x_m, y_m, self._first_local_minimum(x_m, y_m))
            lo, hi = 0, n
        else:
            # The hinted point is also Newton's first frame: evaluate it once.
            first = self.frame(self.wrap(s_hint))
            window_m = PROJECT_WINDOW_FACTOR * math.hypot(x_m - first[0], y_m - first[1]) + PROJECT_WINDOW_MIN_M
            s_newton = self._newton_projection(x_m, y_m, s_hint, window_m, first)
            if s_newton is not None:
                return s_newton
            # Newton did not settle: scan the window around the hint.
            c = self.wrap(s_hint) * self._inv_h
            w = int(window_m * self._inv_h) + 2
            lo, hi = int(c) - w, int(c) + w + 1
            if self.closed and hi - lo >= n:
                lo, hi = 0, n
            elif not self.closed:
                lo, hi = max(lo, 0), min(hi, n)
        if self.closed and (lo < 0 or hi > n):
            idx = np.arange(lo, hi + 1) % n
            dx = self.x_table_m[idx] - x_m
            dy = self.y_table_m[idx] - y_m
            j = int(idx[int(np.argmin(dx * dx + dy * dy))])
        else:
            dx = self.x_table_m[lo:hi + 1] - x_m
            dy = self.y_table_m[lo:hi + 1] - y_m
            j = lo + int(np.argmin(dx * dx + dy * dy))
        return self._refine_projection(x_m, y_m, j)

    def _first_local_minimum(self, x_m: float, y_m: float) -> int:
        """The first table node, from ``s = 0`` forward, where the distance to ``(x_m, y_m)`` has
        a local minimum no larger than the hint window of the nearest one allows
        (``PROJECT_WINDOW_FACTOR * d_min + PROJECT_WINDOW_MIN_M``): the first branch that passes
        about as near as the nearest (module docstring, "Projection and look-ahead")."""
        dx = self.x_table_m - x_m
        dy = self.y_table_m - y_m
        d2 = dx * dx + dy * dy
        d_near = PROJECT_WINDOW_FACTOR * math.sqrt(float(np.min(d2))) + PROJECT_WINDOW_MIN_M
        # A local minimum: strictly below the node before (the first of a plateau, as argmin),
        # not above the node after; the path's ends count when the distance rises from them.
        falls = np.concatenate(([True], d2[1:] < d2[:-1]))
        stops = np.concatenate((d2[:-1] <= d2[1:], [True]))
        found = np.flatnonzero(falls & stops & (d2 <= d_near * d_near))
        return int(found[0])

    def _newton_projection(self, x_m: float, y_m: float, s_hint: float, window_m: float,
                           first: PathFrame | None = None) -> float | None:
        """Closest point by Newton from the hint: the local minimum of the distance the hint is in.

        ``first`` is ``frame(wrap(s_hint))`` when the caller has it. Returns None (the caller
        then scans the window) when Newton does not settle within a few steps on a minimum
        inside the window, or leaves an open path's ends.
        """
        s = self.wrap(s_hint)
        s0 = s
        for it in range(6):
            px, py, tx, ty, k = first if (it == 0 and first is not None) else self.frame(s)
            dx, dy = px - x_m, py - y_m
            g = dx * tx + dy * ty
            dg = 1.0 + k * (dx * -ty + dy * tx)
            if dg <= 0.05:
                return None
            step = g / dg
            if abs(step) < 1e-7:
                # Settled: the point just evaluated is within 1e-7 m of the root (the distance
                # to the path is then exact to ~1e-14 m), and its frame is remembered.
                return self.wrap(s)
            s -= step
            if abs(s - s0) > window_m or (not self.closed and not 0.0 <= s <= self.length_m):
                return None
        return None

    def _refine_projection(self, x_m: float, y_m: float, j: int) -> float:
        """Closest point near node ``j``: Newton on ``(p(s) - q) . t(s) = 0`` within one node spacing."""
        h = self._h
        s = j * h
        s_lo, s_hi = s - h, s + h
        if not self.closed:
            s_lo, s_hi = max(s_lo, 0.0), min(s_hi, self.length_m)
        for _ in range(3):
            px, py, tx, ty, k = self.frame(s)
            dx, dy = px - x_m, py - y_m
            g = dx * tx + dy * ty  # derivative of |p - q|^2 / 2
            dg = 1.0 + k * (dx * -ty + dy * tx)  # 1 + k (p - q) . n
            if dg <= 1e-9:  # at or beyond the centre of curvature: keep the node
                break
            step = g / dg
            s = min(max(s - step, s_lo), s_hi)
            if abs(step) < 1e-9:
                break
        return self.wrap(s)

    # ------------------------------------------------------------------ look-ahead
    def _dist2_node(self, j: int, x_m: float, y_m: float) -> float:
        if self.closed:
            j %= self._n
        dx = self._x[j] - x_m
        dy = self._y[j] - y_m
        return dx * dx + dy * dy

    def lookahead(self, x_m: float, y_m: float, l1_m: float, s_from: float) -> float | None:
        """First arc length forward of ``s_from`` where the path leaves the circle of radius ``l1_m``.

        The point ``point(s)`` returned is at Euclidean distance ``l1_m`` (to about a micrometre)
        from ``(x_m, y_m)`` and the path is inside the circle just before it: this is the Park
        (2007) L1 reference point. For a closed path the search covers one lap and the result
        may exceed ``length_m`` (it is ``s_from`` plus the distance travelled along the path;
        every query wraps it).

        The path is scanned forward at a stride of about ``LOOKAHEAD_STRIDE_M``, then the
        crossing is solved inside the bracketing stride, so an excursion out of the circle and
        back in shorter than the stride would be missed: far below anything a vehicle can follow.

        Returns ``None`` when the path ends (open path) or a lap is completed before leaving the
        circle, or when the path never enters the circle (the vehicle is more than ``l1_m`` from
        every point ahead).
        """
        r2 = l1_m * l1_m
        n = self._n
        if self.closed:
            s_from = s_from % self.length_m
        elif s_from >= self.length_m:
            return None
        j0 = max(int(s_from * self._inv_h), 0)
        j_end = j0 + n if self.closed else n
        stride = max(1, int(round(LOOKAHEAD_STRIDE_M * self._inv_h)))
        X, Y = self._x, self._y
        closed = self.closed
        # Coarse march: first node pair (a, b) with a inside the circle and b outside.
        a = j0
        px, py = self.frame(s_from)[:2]  # s_from is usually the projection: remembered
        d2_from = (px - x_m) ** 2 + (py - y_m) ** 2
        a_inside = d2_from <= r2  # at s_from itself
        if a_inside:
            # |p(s) - q| <= (s - s_from) + |p(s_from) - q|: every point up to L1 - d further on
            # is inside the circle, so the march can start there.
            skip_nodes = int((l1_m - math.sqrt(d2_from)) * self._inv_h)
            a = max(j0, min(j0 + skip_nodes, j_end - 1))
        while a < j_end:
            b = min(a + stride, j_end)
            jb = b % n if closed else b
            dx = X[jb] - x_m
            dy = Y[jb] - y_m
            b_inside = dx * dx + dy * dy <= r2
            if a_inside and not b_inside:
                break
            a, a_inside = b, b_inside
        else:
            return None
        # f = |p - q|^2 - r2 at the bracket's ends, from what the march already has.
        if a * self._h > s_from:
            ja = a % n if closed else a
            fa = (X[ja] - x_m) ** 2 + (Y[ja] - y_m) ** 2 - r2
            s_a = a * self._h
        else:
            fa, s_a = d2_from - r2, s_from
        return self._refine_lookahead(x_m, y_m, r2, s_a, b * self._h, fa, dx * dx + dy * dy - r2)

    def _refine_lookahead(self, x_m: float, y_m: float, r2: float, a: float, b: float,
                          fa: float, fb: float) -> float:
        """Root of ``f(s) = |p(s) - q|^2 - r2`` in ``[a, b]`` (inside at a, outside at b), given
        ``fa = f(a)`` and ``fb = f(b)``.

        Newton (``f' = 2 (p - q) . t``) from the secant of the bracket, kept inside the bracket
        (bisection when a step leaves it). The bracket is one stride, so two or three steps
        settle it: stops when ``|f| < 1e-10`` or the bracket is narrower than 1e-9 m, and
        returns the last point evaluated (whose frame is then remembered).
        """
        if fa > 0.0:  # the bracket's start is already outside (rounding at s_from)
            return a
        m = a - fa * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not (a < m < b):
            m = 0.5 * (a + b)
        frame = self.frame
        for _ in range(60):
            px, py, tx, ty, _ = frame(m)
            dx, dy = px - x_m, py - y_m
            fm = dx * dx + dy * dy - r2
            if abs(fm) < 1e-10:
                return m
            if fm <= 0.0:
                a = m
            else:
                b = m
            if b - a < 1e-9:
                return m
            df = 2.0 * (dx * tx + dy * ty)
            nxt = m - fm / df if df != 0.0 else a
            m = nxt if a < nxt < b else 0.5 * (a + b)
        return 0.5 * (a + b)

    # ------------------------------------------------------------------ vectorised queries
    def _locate_array(self, s_m: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        s = np.asarray(s_m, dtype=float)
        if self.closed:
            s = np.mod(s, self.length_m)
        else:
            s = np.minimum(np.maximum(s, 0.0), self.length_m)
        q = s * self._inv_h
        i = np.minimum(q.astype(np.intp), self._n - 1)
        return i, q - i

    def point_array(self, s_m: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`point`: arrays ``x_m, y_m`` for an array of arc lengths."""
        x, y, _, _, _ = self.frame_array(s_m)
        return x, y

    def tangent_array(self, s_m: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`tangent`."""
        _, _, tx, ty, _ = self.frame_array(s_m)
        return tx, ty

    def frame_array(self, s_m: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised :meth:`frame`: arrays ``(x_m, y_m, tx, ty, curvature_1_m)``.

        The same cubic Hermite interpolants as :meth:`frame`, evaluated from the per-interval
        polynomial coefficients (equal to float rounding).
        """
        i, u = self._locate_array(s_m)
        c = self._coef[i]  # (..., 4, 5): powers of u x (x, y, ax, ay, k)
        u = u[..., None]
        r = c[..., 3, :] * u
        r += c[..., 2, :]
        r *= u
        r += c[..., 1, :]
        r *= u
        r += c[..., 0, :]
        ax, ay = r[..., 2], r[..., 3]
        norm = np.hypot(ax, ay)
        return r[..., 0], r[..., 1], ax / norm, ay / norm, r[..., 4]

    def curvature_array(self, s_m: npt.ArrayLike) -> np.ndarray:
        """Vectorised :meth:`curvature`."""
        return self.frame_array(s_m)[4]

    def sample(self, n: int = 500) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``n`` evenly spaced points for plotting: arrays ``(s_m, x_m, y_m)``."""
        if n < 2:
            raise ValueError(f"sample: expected n >= 2, got {n}")
        s = np.linspace(0.0, self.length_m, int(n))
        x, y = self.point_array(s)
        return s, x, y


def _hermite_coefficients(x: np.ndarray, y: np.ndarray, tx: np.ndarray, ty: np.ndarray, k: np.ndarray,
                          h: float) -> np.ndarray:
    """Per-interval monomial coefficients of the table's cubic Hermite interpolants.

    For interval ``i`` (nodes ``i`` and ``i + 1``, local coordinate ``u`` in [0, 1]) a value
    ``v0, v1`` with arc-length derivatives ``d0, d1`` interpolates as
    ``v0 + (h d0) u + (3 (v1 - v0) - h (2 d0 + d1)) u^2 + (2 (v0 - v1) + h (d0 + d1)) u^3``.
    Columns: x and y (derivative the tangent), the unnormalised tangent ax, ay (derivatives
    ``-k ty`` and ``k tx``, Frenet) and the curvature (linear). Shape ``(n, 4, 5)``.
    """
    def cubic(v: np.ndarray, d: np.ndarray) -> np.ndarray:
        v0, v1, d0, d1 = v[:-1], v[1:], d[:-1] * h, d[1:] * h
        return np.stack([v0, d0, 3.0 * (v1 - v0) - 2.0 * d0 - d1, 2.0 * (v0 - v1) + d0 + d1], axis=1)

    kx, ky = -k * ty, k * tx
    zero = np.zeros(k.size - 1)
    lin = np.stack([k[:-1], k[1:] - k[:-1], zero, zero], axis=1)
    coef = np.stack([cubic(x, tx), cubic(y, ty), cubic(tx, kx), cubic(ty, ky), lin], axis=2)
    coef = np.ascontiguousarray(coef)
    coef.setflags(write=False)
    return coef


# ---------------------------------------------------------------------------- construction
def _table_from_splines(sx: CubicSpline, sy: CubicSpline, u0: float, u1: float, closed: bool,
                        what: str) -> Path:
    """Resample the spline curve ``(sx(u), sy(u))`` on a uniform arc-length table."""
    dsx, dsy = sx.derivative(1), sy.derivative(1)
    ddsx, ddsy = sx.derivative(2), sy.derivative(2)
    # Arc length s(u): integrate |r'(u)| with 4-point Gauss-Legendre on each source interval.
    knots = sx.x
    gauss_u, gauss_w = np.polynomial.legendre.leggauss(4)
    a, b = knots[:-1], knots[1:]
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    uq = mid[:, None] + half[:, None] * gauss_u[None, :]
    speed_q = np.hypot(dsx(uq), dsy(uq))
    seg = (speed_q * gauss_w[None, :]).sum(axis=1) * half
    s_knots = np.concatenate(([0.0], np.cumsum(seg)))
    speed_knots = np.hypot(dsx(knots), dsy(knots))
    if not np.all(np.isfinite(s_knots)):
        raise ValueError(f"{what}: the curve is not finite everywhere on its range")
    if np.min(speed_knots) <= 1e-9 * max(1.0, float(np.max(speed_knots))):
        raise ValueError(f"{what}: the curve stops (zero speed) somewhere: it has no tangent there")
    length = float(s_knots[-1])
    if not length > 1e-6:
        raise ValueError(f"{what}: expected a path longer than 1e-6 m, got {length!r} m")
    n = int(min(max(math.ceil(length / TARGET_SPACING_M), MIN_NODES), MAX_NODES))
    s_table = np.linspace(0.0, length, n + 1)
    # Invert s(u): piecewise-cubic Hermite of u(s) (exact derivative 1/|r'|) then Newton polish.
    u_of_s = np.interp(s_table, s_knots, knots)
    for _ in range(4):
        k = np.clip(np.searchsorted(knots, u_of_s, side="right") - 1, 0, knots.size - 2)
        # s(u) inside the interval by 4-point Gauss on [knots[k], u].
        lo = knots[k]
        half_u = 0.5 * (u_of_s - lo)
        uq = (lo + half_u)[:, None] + half_u[:, None] * gauss_u[None, :]
        s_u = s_knots[k] + (np.hypot(dsx(uq), dsy(uq)) * gauss_w[None, :]).sum(axis=1) * half_u
        sp = np.hypot(dsx(u_of_s), dsy(u_of_s))
        u_of_s = np.clip(u_of_s - (s_u - s_table) / sp, u0, u1)
    u_of_s[0], u_of_s[-1] = u0, u1
    vx, vy = dsx(u_of_s), dsy(u_of_s)
    ax, ay = ddsx(u_of_s), ddsy(u_of_s)
    sp = np.hypot(vx, vy)
    k = (vx * ay - vy * ax) / sp**3
    return Path(s_table, sx(u_of_s), sy(u_of_s), vx / sp, vy / sp, k, closed)


def _evaluate(fn: ArrayFn, u: np.ndarray, what: str) -> np.ndarray:
    try:
        values = np.asarray(fn(u), dtype=float)
    except Exception as err:  # a user-supplied callable: report what failed, keep the cause
        raise ValueError(f"{what}: evaluating the curve failed: {err}") from err
    if values.shape == ():
        values = np.full_like(u, float(values))
    if values.shape != u.shape:
        raise ValueError(f"{what}: expected an array of shape {u.shape}, got {values.shape}")
    if not np.all(np.isfinite(values)):
        bad = float(u[np.flatnonzero(~np.isfinite(values))[0]])
        raise ValueError(f"{what}: the curve is not finite at parameter {bad:.6g}")
    return values


def _check_range(range_: tuple[float, float], what: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in range_)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{what}: expected two numbers [start, end], got {range_!r}") from err
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ValueError(f"{what}: expected finite start < end, got [{lo}, {hi}]")
    return lo, hi


def function_path(y_of_x: ArrayFn, x_range_m: tuple[float, float]) -> Path:
    """The graph ``y = f(x)`` for x in ``x_range_m``, travelled towards increasing x.

    Parameters
    ----------
    y_of_x : numpy-vectorised callable, ``f(np.ndarray) -> np.ndarray`` (metres to metres).
    x_range_m : ``(x_start_m, x_end_m)`` with ``x_start_m < x_end_m``.

    Examples
    --------
    >>> import numpy as np
    >>> p = function_path(lambda x: 0.5 * x, (0.0, 10.0))
    >>> round(p.length_m, 6), round(p.heading_rad(3.0), 6)
    (11.18034, 0.463648)
    """
    x0, x1 = _check_range(x_range_m, "x_range_m")
    u = np.linspace(x0, x1, SOURCE_SAMPLES)
    y = _evaluate(y_of_x, u, "y_of_x")
    return _table_from_splines(CubicSpline(u, u), CubicSpline(u, y), x0, x1, False, "y_of_x")


def parametric_path(x_of_u: ArrayFn, y_of_u: ArrayFn, u_range: tuple[float, float],
                    closed: bool = False) -> Path:
    """The curve ``(x(u), y(u))`` for u in ``u_range``, travelled towards increasing u.

    ``u`` need not be arc length: the path is reparameterised. With ``closed=True`` the curve
    must end where it starts (within 1 mm) and is treated as a loop (periodic spline; queries
    wrap modulo the length). The callables are numpy-vectorised.

    Examples
    --------
    >>> import numpy as np
    >>> c = parametric_path(lambda u: 20 * np.cos(u), lambda u: 20 * np.sin(u), (0, 2 * np.pi), closed=True)
    >>> round(c.length_m, 4), round(c.curvature(7.0), 6)
    (125.6637, 0.05)
    """
    u0, u1 = _check_range(u_range, "u_range")
    u = np.linspace(u0, u1, SOURCE_SAMPLES)
    x = _evaluate(x_of_u, u, "x_of_u")
    y = _evaluate(y_of_u, u, "y_of_u")
    bc = "not-a-knot"
    if closed:
        gap = math.hypot(x[-1] - x[0], y[-1] - y[0])
        if gap > 1e-3:
            raise ValueError(f"closed path: expected the curve to end where it starts, gap {gap:.4g} m")
        x[-1], y[-1] = x[0], y[0]
        bc = "periodic"
    return _table_from_splines(CubicSpline(u, x, bc_type=bc), CubicSpline(u, y, bc_type=bc),
                               u0, u1, closed, "parametric path")


def waypoint_path(points_xy_m: npt.ArrayLike, closed: bool = False) -> Path:
    """A C^2 cubic spline through waypoints, parameterised by chord length, then by arc length.

    Parameters
    ----------
    points_xy_m : sequence of ``(x_m, y_m)``, at least 3 (2 for a straight segment), with no two
        consecutive points equal.
    closed : join the last point back to the first with a periodic spline (the first point must
        not be repeated at the end; if it is, it is dropped).
    """
    pts = np.asarray(points_xy_m, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points_m: expected a list of [x, y] pairs, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points_m: expected finite coordinates")
    if closed and pts.shape[0] > 1 and np.hypot(*(pts[-1] - pts[0])) < 1e-9:
        pts = pts[:-1]
    need = 3 if closed else 2
    if pts.shape[0] < need:
        raise ValueError(f"points_m: expected at least {need} points, got {pts.shape[0]}")
    if closed:
        pts = np.vstack([pts, pts[:1]])
    chords = np.hypot(*np.diff(pts, axis=0).T)
    if np.any(chords < 1e-6):
        i = int(np.flatnonzero(chords < 1e-6)[0])
        raise ValueError(f"points_m: points {i} and {i + 1} coincide")
    u = np.concatenate(([0.0], np.cumsum(chords)))
    if closed:
        bc = "periodic"
    elif pts.shape[0] == 2:
        bc = "natural"  # a straight segment
    else:
        bc = "not-a-knot" if pts.shape[0] > 3 else "natural"
    sx = CubicSpline(u, pts[:, 0], bc_type=bc)
    sy = CubicSpline(u, pts[:, 1], bc_type=bc)
    # Resample densely so arc length and curvature are integrated on a fine grid of the spline.
    uu = np.linspace(0.0, u[-1], SOURCE_SAMPLES)
    bc_dense = "periodic" if closed else "not-a-knot"
    xs, ys = sx(uu), sy(uu)
    if closed:
        xs[-1], ys[-1] = xs[0], ys[0]
    return _table_from_splines(CubicSpline(uu, xs, bc_type=bc_dense), CubicSpline(uu, ys, bc_type=bc_dense),
                               0.0, float(u[-1]), closed, "waypoint path")
