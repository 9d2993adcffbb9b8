"""Paths made of straight lines and circular arcs, blended so that they are C^2.

Lines and arcs joined tangentially give a path whose heading is continuous but whose curvature
jumps at every joint (0 on a line, 1/R on an arc): only C^1. A vehicle cannot change its lateral
acceleration instantly, and the guidance's curvature-based terms would see steps. So the
curvature profile is smoothed:

    kappa_b(s) = (1 / b) * integral of kappa(t) dt over t in [s - b/2, s + b/2]

a moving average of width ``b = blend_m``. The piecewise-constant curvature becomes piecewise
linear (a clothoid ramp of length ``b`` centred on each joint), so the curvature is continuous and
the path is C^2. The moving average preserves the total turn of each stretch away from the ends;
the heading is its exact integral (closed form) and the position is integrated numerically on a
fine grid.
Near each joint the blended path departs from the line-and-arc geometry by O(b^2 / R) (about
``b^2 / (48 R)`` at the joint itself).

Open paths extend the first and last curvature beyond the ends, so the start point and heading
are exactly those given. Closed paths use the periodic (circular) moving average; the unblended
lines and arcs must close (end point and heading) and the tiny closure error the blend leaves is
spread linearly along the loop.

:func:`filleted_waypoint_path` builds such a path from waypoints: straight legs with each corner
rounded by an arc of radius ``corner_radius_m``, blended with ``b = corner_radius_m / 2``
(capped by the shortest piece). The path passes through the first and last waypoints (open paths:
the small lateral shift each ramp causes, about b^2 / (24 R) per corner, is spread linearly along
the path) but cuts every corner.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.interpolate import CubicSpline

from companion.geometry.paths import Path, parametric_path

#: Spacing of the integration grid (finer grids for short paths).
GRID_SPACING_M = 0.02
MAX_GRID_POINTS = 400_001
#: The unblended loop must close to within this fraction of its length (plus 1 cm).
CLOSURE_TOLERANCE = 1e-6

Problem = Callable[[str, str], None]


def _turn_integrals(boundaries: np.ndarray, kappa: np.ndarray, closed: bool):
    """K(s) = integral of the piecewise-constant curvature from 0 to s, and KK(s) = integral of K.

    Both are exact closed forms for any real s: beyond the ends an open path continues with its
    first / last curvature; a closed path repeats (K grows by the total turn T every lap).
    """
    total_len = float(boundaries[-1])
    widths = np.diff(boundaries)
    k_at = np.concatenate(([0.0], np.cumsum(kappa * widths)))  # K at the boundaries
    kk_at = np.concatenate(([0.0], np.cumsum(k_at[:-1] * widths + 0.5 * kappa * widths**2)))
    total_turn = float(k_at[-1])
    kk_total = float(kk_at[-1])
    last = kappa.size - 1

    def inside(r: np.ndarray):
        i = np.clip(np.searchsorted(boundaries, r, side="right") - 1, 0, last)
        u = r - boundaries[i]
        return k_at[i] + kappa[i] * u, kk_at[i] + k_at[i] * u + 0.5 * kappa[i] * u * u

    def integrals(s: np.ndarray):
        s = np.asarray(s, dtype=float)
        if closed:
            laps = np.floor(s / total_len)
            r = s - laps * total_len
            k_r, kk_r = inside(r)
            big_k = k_r + laps * total_turn
            big_kk = (laps * kk_total + total_turn * total_len * laps * (laps - 1) / 2.0
                      + kk_r + laps * total_turn * r)
            return big_k, big_kk
        k_in, kk_in = inside(np.clip(s, 0.0, total_len))
        before = s < 0
        after = s > total_len
        d = s - total_len
        big_k = np.where(before, kappa[0] * s,
                         np.where(after, total_turn + kappa[-1] * d, k_in))
        big_kk = np.where(before, 0.5 * kappa[0] * s * s,
                          np.where(after, kk_total + total_turn * d + 0.5 * kappa[-1] * d * d, kk_in))
        return big_k, big_kk

    return integrals


def segments_path(start_xy_m, start_heading_rad: float, segments, blend_m: float, *, closed: bool,
                  where: str = "path", problem: Problem | None = None,
                  pin_end: bool = False) -> Path | None:
    """A C^2 path from tangent lines and arcs.

    Parameters
    ----------
    start_xy_m, start_heading_rad : the first point and heading (ENU, anticlockwise from east).
    segments : sequence of ``("line", length_m, 0.0)`` or ``("arc", radius_m, turn_rad)``
        (turn positive = left).
    blend_m : width of the curvature ramps (> 0 for C^2; 0 keeps the curvature jumps).
    closed : the segments form a loop.
    where, problem : where to report problems: ``problem(key_path, message)``; when None, a
        problem raises ``ValueError``.
    pin_end : (open paths) spread the end-point shift the blends cause linearly along the path,
        so the path ends exactly where the unblended lines and arcs end.

    Returns
    -------
    Path or None (after reporting a problem).
    """
    def report(key: str, message: str) -> None:
        if problem is None:
            raise ValueError(f"{key}: {message}")
        problem(key, message)

    lengths_a, kappa_a = _lengths_and_curvatures(segments)
    boundaries = np.concatenate(([0.0], np.cumsum(lengths_a)))
    total = float(boundaries[-1])
    end_x, end_y, end_heading = _unblended_end(start_xy_m, start_heading_rad, lengths_a, kappa_a)
    if closed and not _loop_closes(start_xy_m, start_heading_rad, (end_x, end_y, end_heading), total,
                                   where, report):
        return None
    n = int(min(max(math.ceil(total / GRID_SPACING_M), 2000), MAX_GRID_POINTS - 1))
    s = np.linspace(0.0, total, n + 1)
    theta = _blended_heading(s, start_heading_rad, _turn_integrals(boundaries, kappa_a, closed), blend_m)
    xs, ys = _integrate_position(s, theta, start_xy_m)
    bc = "not-a-knot"
    if pin_end and not closed:
        xs = xs + (end_x - xs[-1]) * s / total
        ys = ys + (end_y - ys[-1]) * s / total
    if closed:
        gx, gy = xs[-1] - xs[0], ys[-1] - ys[0]
        xs = xs - gx * s / total
        ys = ys - gy * s / total
        xs[-1], ys[-1] = xs[0], ys[0]
        bc = "periodic"
    sx = CubicSpline(s, xs, bc_type=bc)
    sy = CubicSpline(s, ys, bc_type=bc)
    return parametric_path(sx, sy, (0.0, total), closed=closed)


def _lengths_and_curvatures(segments) -> tuple[np.ndarray, np.ndarray]:
    """Arc length and (constant) signed curvature of each line or arc."""
    lengths, kappas = [], []
    for kind, size, turn in segments:
        if kind == "line":
            lengths.append(float(size))
            kappas.append(0.0)
        else:
            lengths.append(float(size) * abs(turn))
            kappas.append(math.copysign(1.0 / float(size), turn))
    return np.asarray(lengths), np.asarray(kappas)


def _unblended_end(start_xy_m, start_heading_rad: float, lengths_a: np.ndarray,
                   kappa_a: np.ndarray) -> tuple[float, float, float]:
    """End point and heading of the unblended lines and arcs (exact), for the closure check."""
    x, y, h = float(start_xy_m[0]), float(start_xy_m[1]), float(start_heading_rad)
    for length, k in zip(lengths_a, kappa_a):
        if k == 0.0:
            x += length * math.cos(h)
            y += length * math.sin(h)
        else:
            r = 1.0 / k
            h_new = h + k * length
            x += r * (math.sin(h_new) - math.sin(h))
            y -= r * (math.cos(h_new) - math.cos(h))
            h = h_new
    return x, y, h


def _loop_closes(start_xy_m, start_heading_rad: float, end: tuple[float, float, float], total: float,
                 where: str, report: Problem) -> bool:
    """A loop turns a whole number of turns and ends where it starts (else reported)."""
    x, y, h = end
    turn_deg = math.degrees(h - start_heading_rad)
    laps = round(turn_deg / 360.0)
    gap = math.hypot(x - start_xy_m[0], y - start_xy_m[1])
    if abs(turn_deg - 360.0 * laps) > 1e-6:
        report(f"{where}.closed", f"expected segments turning a whole number of turns for a loop, "
               f"got {turn_deg:.6g} deg")
        return False
    if gap > CLOSURE_TOLERANCE * total + 0.01:
        report(f"{where}.closed", f"expected the segments to end where they start, got a gap of "
               f"{gap:.4g} m")
        return False
    return True


def _blended_heading(s: np.ndarray, start_heading_rad: float, integrals, blend_m: float) -> np.ndarray:
    """Heading on the grid ``s``: the integral of the moving-average curvature (width ``blend_m``)."""
    if blend_m <= 0:
        return start_heading_rad + integrals(s)[0]
    # Heading = integral of the moving-average curvature = moving average of K (box kernel):
    # theta(s) = theta0 + (KK(s + b/2) - KK(s - b/2)) / b, exact. Away from the joints (K linear
    # over the window) this is exactly the unblended heading theta0 + K(s); a closed loop whose
    # start lies inside a ramp starts with the blended heading there.
    half = 0.5 * blend_m
    _, kk_hi = integrals(s + half)
    _, kk_lo = integrals(s - half)
    return start_heading_rad + (kk_hi - kk_lo) / blend_m


def _integrate_position(s: np.ndarray, theta: np.ndarray, start_xy_m) -> tuple[np.ndarray, np.ndarray]:
    """Position: trapezoid rule on the fine grid (error per metre about h^2 k^2 / 12: negligible)."""
    ds = np.diff(s)
    c, sn = np.cos(theta), np.sin(theta)
    xs = start_xy_m[0] + np.concatenate(([0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * ds)))
    ys = start_xy_m[1] + np.concatenate(([0.0], np.cumsum(0.5 * (sn[1:] + sn[:-1]) * ds)))
    return xs, ys


def filleted_waypoint_path(points_xy_m, corner_radius_m: float, *, closed: bool, where: str = "path",
                           problem: Problem | None = None) -> Path | None:
    """Straight legs between waypoints, each corner rounded with an arc, blended to C^2.

    The arc at a corner turning by ``alpha`` starts ``corner_radius_m * tan(|alpha| / 2)`` before
    the waypoint; two neighbouring corners must fit on their common leg. Closed loops start at the
    middle of the first leg.
    """
    def report(key: str, message: str) -> None:
        if problem is None:
            raise ValueError(f"{key}: {message}")
        problem(key, message)

    pts = np.asarray(points_xy_m, dtype=float)
    if closed and np.hypot(*(pts[-1] - pts[0])) < 1e-9:
        pts = pts[:-1]
    m = len(pts)
    legs = [(pts[(i + 1) % m] - pts[i]) for i in range(m if closed else m - 1)]
    leg_len = [float(np.hypot(*d)) for d in legs]
    dirs = [d / L for d, L in zip(legs, leg_len)]
    r = float(corner_radius_m)
    n_legs = len(legs)

    # Corner turn angles: corner i sits between leg i-1 and leg i.
    def turn_at(i: int) -> float:
        a, b = dirs[(i - 1) % n_legs], dirs[i % n_legs]
        return math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1])

    corners = range(m) if closed else range(1, m - 1)
    turn = {i: turn_at(i) for i in corners}
    for i, t in turn.items():
        if abs(abs(t) - math.pi) < 1e-6:
            report(f"{where}.points_m[{i}]", "expected a corner of less than 180 deg, got a reversal")
            return None
    cut = {i: r * math.tan(abs(t) / 2.0) for i, t in turn.items()}
    ok = True
    for j in range(n_legs):
        before = cut.get(j, 0.0)  # corner at the leg's first point
        after = cut.get((j + 1) % m if closed else j + 1, 0.0)
        if before + after > leg_len[j] + 1e-9:
            report(f"{where}.corner_radius_m", f"expected corners that fit on their legs: leg {j} "
                   f"(points {j} to {(j + 1) % m}) is {leg_len[j]:.3g} m but its rounded corners need "
                   f"{before + after:.3g} m; use a smaller radius")
            ok = False
    if not ok:
        return None

    segs: list[tuple[str, float, float]] = []

    def add_line(length: float) -> None:
        if length > 1e-9:
            segs.append(("line", length, 0.0))

    def add_corner(i: int) -> None:
        if abs(turn[i]) > 1e-9:
            segs.append(("arc", r, turn[i]))

    if closed:
        start = pts[0] + 0.5 * legs[0]
        heading = math.atan2(dirs[0][1], dirs[0][0])
        add_line(0.5 * leg_len[0] - cut[1 % m])
        for j in range(1, n_legs):
            add_corner(j)
            add_line(leg_len[j] - cut[j] - cut[(j + 1) % m])
        add_corner(0)
        add_line(0.5 * leg_len[0] - cut[0])
    else:
        start = pts[0]
        heading = math.atan2(dirs[0][1], dirs[0][0])
        add_line(leg_len[0] - cut.get(1, 0.0))
        for j in range(1, n_legs):
            add_corner(j)
            add_line(leg_len[j] - cut[j] - cut.get(j + 1, 0.0))
    shortest = min(size * (abs(t) if kind == "arc" else 1.0) for kind, size, t in segs)
    blend = min(0.5 * r, shortest)
    return segments_path((float(start[0]), float(start[1])), heading, segs, blend, closed=closed,
                         where=where, problem=problem, pin_end=True)
