"""The compiled loops of :mod:`companion.guidance.rollout_kernel` (imports numba: loaded only by
:func:`companion.guidance.rollout_kernel.load`, so that a flight that never builds a
``predictive`` law never imports numba and its LLVM, about 100 MB of memory).

The same operations on the same numbers in the same order as the numpy rollouts of
:mod:`companion.guidance.predictive` (each block names the numpy function it stands for).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np
from numba import njit


def _compiled(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` compiled, and cached on disk beside this file."""
    return njit(cache=True)(fn)  # type: ignore[no-any-return]


@_compiled
def _band_limits(centre: int, back: int, ahead: int, whole: bool, n: int) -> tuple[int, int]:
    """The first and last window sample of a band (:class:`companion.guidance.predictive._Band`)
    around ``centre``: ``back`` samples behind to ``ahead`` ahead, or the whole window."""
    if whole:
        return 0, n - 1
    return max(centre - back, 0), min(centre + ahead, n - 1)


@_compiled
def _nearest(wx: np.ndarray, wy: np.ndarray, x: float, y: float, lo_j: int, hi_j: int) -> int:
    """``_project``'s search: the first nearest window sample among ``lo_j .. hi_j`` (the band).
    Only the band is measured: the samples outside it cannot be chosen (the goal search measures
    its own, from the nearest sample on)."""
    best = math.inf
    i0 = lo_j
    for j in range(lo_j, hi_j + 1):
        dx = wx[j] - x
        dy = wy[j] - y
        r2 = dx * dx + dy * dy
        if r2 < best:
            best = r2
            i0 = j
    return i0


@_compiled
def _offset(wx: np.ndarray, wy: np.ndarray, wtx: np.ndarray, wty: np.ndarray, wk: np.ndarray, spacing: float,
            x: float, y: float, i0: int) -> tuple[float, float]:
    """``_project`` from the nearest sample ``i0`` on: the signed cross-track error of ``(x, y)``
    to the osculating circle there and its distance along the tangent (not clipped)."""
    ex = x - wx[i0]
    ey = y - wy[i0]
    tx, ty = wtx[i0], wty[i0]
    along = tx * ex + ty * ey
    along_c = min(max(along, -spacing), spacing)
    return tx * ey - ty * ex - 0.5 * wk[i0] * along_c * along_c, along


@_compiled
def _pursue(wx: np.ndarray, wy: np.ndarray, wtx: np.ndarray, wty: np.ndarray, wk: np.ndarray, spacing: float,
            x: float, y: float, course: float, v: float, look: float, cff: float, lead: float, i0: int,
            ) -> tuple[float, float, float, float, float]:
    """``_project`` from the nearest sample ``i0`` on, and ``_pursue``: the command, the
    cross-track error, L_eff and the goal of one row."""
    n = wx.shape[0]
    tx, ty = wtx[i0], wty[i0]
    d, along = _offset(wx, wy, wtx, wty, wk, spacing, x, y, i0)
    # the goal: the first sample from i0 on at L_eff or more, interpolated from the one before
    l_eff = max(look, math.sqrt(2.0) * abs(d))
    # (the distances measured as far as the goal only, in the numpy rollouts' arithmetic)
    jg = -1
    r_j = r_jm = 0.0
    for j in range(i0, n):
        dx = wx[j] - x
        dy = wy[j] - y
        r_jm, r_j = r_j, math.sqrt(dx * dx + dy * dy)
        if r_j >= l_eff:
            jg = j
            break
    frac = 1.0
    if jg > i0:
        frac = (l_eff - r_jm) / max(r_j - r_jm, 1e-12)
    idx = jg if jg >= 0 else n - 1
    b = max(idx - 1, 0)
    goal_x = wx[b] + frac * (wx[idx] - wx[b])
    goal_y = wy[b] + frac * (wy[idx] - wy[b])
    tgx, tgy = goal_x - x, goal_y - y
    eta = (math.atan2(tgy, tgx) - course + math.pi) % (2.0 * math.pi) - math.pi
    vv = v * v
    w2 = vv * 2.0
    a = w2 * math.sin(eta) / max(math.hypot(tgx, tgy), 1e-6)
    if cff != 0.0:  # the curvature feed-forward at the closest point, read lead seconds ahead
        along_c = min(max(along, -spacing), spacing)
        bow = 0.5 * wk[i0] * along_c * along_c  # P on the osculating circle, its tangent turned by kappa along
        cx = goal_x - (wx[i0] + along * tx) + bow * ty
        cy = goal_y - (wy[i0] + along * ty) - bow * tx
        pos = min(max(i0 + (along + v * lead) / spacing, 0.0), n - 1.0)
        lo = min(int(pos), n - 2) if n > 1 else 0
        kappa = wk[lo] + (pos - lo) * (wk[min(lo + 1, n - 1)] - wk[lo])
        length = max(math.hypot(cx, cy), 1e-6)
        turn = wk[i0] * along_c
        sin_eta_p = (tx * cy - ty * cx - turn * (tx * cx + ty * cy)) / length
        a = a - cff * (w2 * sin_eta_p / length - vv * kappa)
    return a, d, l_eff, goal_x, goal_y


@_compiled
def _rollout(wx: np.ndarray, wy: np.ndarray, wtx: np.ndarray, wty: np.ndarray, wk: np.ndarray, spacing: float,
             x0: float, y0: float, h0: float, a0: float, look: np.ndarray, step_plans: np.ndarray, speed: float,
             wind_x: float, wind_y: float, alpha: float, dt: float, cff: float, lead: float, limit: float,
             centre0: int, back: int, ahead: int, whole: bool, d_ref: np.ndarray, w_d: float, w_u: float,
             min_speed: float, terminal: np.ndarray) -> np.ndarray:
    """Residuals ``(rows, 2 * steps + 3)`` of the rollouts; the arguments as
    :meth:`PredictiveGuidance.rollout` has them (window samples ``wx .. wk``; the band
    ``centre0, back, ahead, whole`` of :class:`companion.guidance.predictive._Band`; the
    cost-to-go factor ``terminal``, :func:`companion.guidance.predictive.cost_to_go_factor`)."""
    rows, steps, n = look.shape[0], step_plans.shape[0], wx.shape[0]
    res = np.empty((rows, 2 * steps + 3))
    windy = wind_x != 0.0 or wind_y != 0.0
    for row in range(rows):
        x, y, h, a_act, centre = x0, y0, h0, a0, centre0
        for step in range(steps):
            gx, gy = speed * math.cos(h), speed * math.sin(h)  # the ground velocity
            if windy:
                gx, gy = gx + wind_x, gy + wind_y
            lo_j, hi_j = _band_limits(centre, back, ahead, whole, n)
            centre = _nearest(wx, wy, x, y, lo_j, hi_j)
            a, d, _, _, _ = _pursue(wx, wy, wtx, wty, wk, spacing, x, y, math.atan2(gy, gx),
                                    max(math.hypot(gx, gy), min_speed), look[row], cff, lead, centre)
            u = a + step_plans[step, row]
            if limit < math.inf:
                u = min(max(u, -limit), limit)
            res[row, 2 * step] = (d - d_ref[step]) * w_d
            res[row, 2 * step + 1] = u * w_u
            # the lag, the turn, the position from the midpoint heading
            a_act = a_act + (u - a_act) * alpha
            dh = a_act / speed * dt
            mid = h + 0.5 * dh
            mx, my = speed * math.cos(mid), speed * math.sin(mid)
            if windy:
                mx, my = mx + wind_x, my + wind_y
            x, y, h = x + mx * dt, y + my * dt, h + dh
        # the cost to go from where the row ends: its deviation (d, d', a - V^2 kappa)
        gx, gy = speed * math.cos(h), speed * math.sin(h)
        if windy:
            gx, gy = gx + wind_x, gy + wind_y
        lo_j, hi_j = _band_limits(centre, back, ahead, whole, n)
        i0 = _nearest(wx, wy, x, y, lo_j, hi_j)
        dev0 = _offset(wx, wy, wtx, wty, wk, spacing, x, y, i0)[0]
        dev1 = wtx[i0] * gy - wty[i0] * gx
        dev2 = a_act - (gx * gx + gy * gy) * 2.0 * (0.5 * wk[i0])
        for r in range(3):
            res[row, 2 * steps + r] = terminal[r, 0] * dev0 + terminal[r, 1] * dev1 + terminal[r, 2] * dev2
    return res


@_compiled
def _pursuit(wx: np.ndarray, wy: np.ndarray, wtx: np.ndarray, wty: np.ndarray, wk: np.ndarray, spacing: float,
             x: float, y: float, course: float, v: float, look: float, cff: float, lead: float, centre: int,
             back: int, ahead: int, whole: bool) -> tuple[float, float, float, float, float]:
    """:func:`companion.guidance.predictive.pursuit_command` for one vehicle (not clipped), its
    nearest sample searched in its band: the command, the cross-track error, L_eff and the goal.
    The tick's own command, where the numpy one costs some ninety calls."""
    lo_j, hi_j = _band_limits(centre, back, ahead, whole, wx.shape[0])
    i0 = _nearest(wx, wy, x, y, lo_j, hi_j)
    out: tuple[float, float, float, float, float] = _pursue(wx, wy, wtx, wty, wk, spacing, x, y, course, v, look,
                                                            cff, lead, i0)
    return out


@_compiled
def _project(wx: np.ndarray, wy: np.ndarray, wtx: np.ndarray, wty: np.ndarray, wk: np.ndarray, spacing: float,
             x: float, y: float, centre: int, back: int, ahead: int, whole: bool) -> tuple[int, float]:
    """:func:`companion.guidance.predictive._nearest` for one point: its nearest sample in its
    band and its signed cross-track error there."""
    lo_j, hi_j = _band_limits(centre, back, ahead, whole, wx.shape[0])
    i0 = _nearest(wx, wy, x, y, lo_j, hi_j)
    return i0, _offset(wx, wy, wtx, wty, wk, spacing, x, y, i0)[0]
