"""The predictive law's batched rollouts as one compiled loop (numba), when numba is installed.

:meth:`companion.guidance.predictive.PredictiveGuidance.rollout` flies a few dozen candidate rows
through 25 steps of the pursuit and the vehicle model. In numpy each step is some ninety calls on
arrays of a few dozen numbers, and the interpreter's cost per call is most of a re-optimisation's
2-5 ms. Here the same arithmetic runs as scalar loops compiled by numba: the same operations on
the same numbers in the same order as the numpy code (each line below names the numpy line it
stands for), so the results agree with it to rounding, which the tests check
(``tests/guidance/test_rollout_kernel.py``).

Optional: ``pip install 'companion[fast]'``. Without numba (or with ``COMPANION_NO_JIT=1`` in the
environment) :data:`AVAILABLE` is False and the law uses its numpy rollouts. Compiled once per
machine (cached beside this file; about 5 s the first time) and loaded in a fraction of a second
after that; :func:`warm_up` does it before a flight's first tick.

Pure arithmetic on arrays, SI units, ENU: no I/O, no clocks.
"""

from __future__ import annotations

import math
import os
from typing import Any, Callable

import numpy as np

njit: Callable[..., Any] | None
try:  # pragma: no cover - which branch runs depends on the install
    if os.environ.get("COMPANION_NO_JIT"):
        raise ImportError("COMPANION_NO_JIT is set")
    from numba import njit
except ImportError:  # pragma: no cover
    njit = None

#: True when the compiled rollouts are used.
AVAILABLE = njit is not None


def _rollout(wx: np.ndarray, wy: np.ndarray, wtx: np.ndarray, wty: np.ndarray, wk: np.ndarray, spacing: float,
             x0: float, y0: float, h0: float, a0: float, look: np.ndarray, step_plans: np.ndarray, speed: float,
             wind_x: float, wind_y: float, alpha: float, dt: float, cff: float, lead: float, limit: float,
             centre0: int, back: int, ahead: int, whole: bool, d_ref: np.ndarray, w_d: float, w_u: float,
             min_speed: float) -> np.ndarray:
    """Residuals ``(rows, 2 * steps)`` of the rollouts; the arguments as
    :meth:`PredictiveGuidance.rollout` has them (window samples ``wx .. wk``; the band
    ``centre0, back, ahead, whole`` of :class:`companion.guidance.predictive._Band`)."""
    rows = look.shape[0]
    steps = step_plans.shape[0]
    n = wx.shape[0]
    res = np.empty((rows, 2 * steps))
    r2 = np.empty(n)
    for row in range(rows):
        x, y, h, a_act = x0, y0, h0, a0
        centre = centre0
        for step in range(steps):
            # ground = speed * (cos h, sin h) (+ wind); course and ground speed
            gx = speed * math.cos(h)
            gy = speed * math.sin(h)
            if wind_x != 0.0 or wind_y != 0.0:
                gx += wind_x
                gy += wind_y
            course = math.atan2(gy, gx)
            v = max(math.hypot(gx, gy), min_speed)
            # _project: squared distances, the nearest sample within the band
            lo_j, hi_j = 0, n - 1
            if not whole:
                lo_j, hi_j = max(centre - back, 0), min(centre + ahead, n - 1)
            i0 = -1
            best = math.inf
            for j in range(n):
                dx = wx[j] - x
                dy = wy[j] - y
                r2[j] = dx * dx + dy * dy
                if lo_j <= j <= hi_j and r2[j] < best:
                    best = r2[j]
                    i0 = j
            centre = i0
            ex = x - wx[i0]
            ey = y - wy[i0]
            tx, ty = wtx[i0], wty[i0]
            along = tx * ex + ty * ey
            along_c = min(max(along, -spacing), spacing)
            d = tx * ey - ty * ex - 0.5 * wk[i0] * along_c * along_c
            # _pursue: the goal, the first sample from i0 on at L_eff or more
            l_eff = max(look[row], math.sqrt(2.0) * abs(d))
            jg = -1
            for j in range(i0, n):
                if math.sqrt(r2[j]) >= l_eff:
                    jg = j
                    break
            if jg > i0:
                r_j, r_jm = math.sqrt(r2[jg]), math.sqrt(r2[jg - 1])
                frac = (l_eff - r_jm) / max(r_j - r_jm, 1e-12)
            else:
                frac = 1.0
            idx = jg if jg >= 0 else n - 1
            b = max(idx - 1, 0)
            goal_x = wx[b] + frac * (wx[idx] - wx[b])
            goal_y = wy[b] + frac * (wy[idx] - wy[b])
            tgx, tgy = goal_x - x, goal_y - y
            eta = (math.atan2(tgy, tgx) - course + math.pi) % (2.0 * math.pi) - math.pi
            vv = v * v
            w2 = vv * 2.0
            a = w2 * math.sin(eta) / max(math.hypot(tgx, tgy), 1e-6)
            if cff != 0.0:
                cx = goal_x - (wx[i0] + along * tx)
                cy = goal_y - (wy[i0] + along * ty)
                pos = i0 + (along + v * lead) / spacing
                pos = min(max(pos, 0.0), n - 1.0)
                lo = min(int(pos), n - 2) if n > 1 else 0
                kappa = wk[lo] + (pos - lo) * (wk[min(lo + 1, n - 1)] - wk[lo])
                length = max(math.hypot(cx, cy), 1e-6)
                sin_eta_p = (tx * cy - ty * cx) / length
                a = a - cff * (w2 * sin_eta_p / length - vv * kappa)
            u = a + step_plans[step, row]
            if limit < math.inf:
                u = min(max(u, -limit), limit)
            res[row, 2 * step] = (d - d_ref[step]) * w_d
            res[row, 2 * step + 1] = u * w_u
            # the lag, the turn, the midpoint heading for the position
            a_act = a_act + (u - a_act) * alpha
            dh = a_act / speed * dt
            mid = h + 0.5 * dh
            mx = speed * math.cos(mid)
            my = speed * math.sin(mid)
            if wind_x != 0.0 or wind_y != 0.0:
                mx += wind_x
                my += wind_y
            x = x + mx * dt
            y = y + my * dt
            h = h + dh
    return res


rollout: Callable[..., np.ndarray] | None = njit(cache=True)(_rollout) if njit is not None else None


def warm_up() -> None:
    """Compile (or load from the cache) before a flight's first tick; nothing without numba."""
    if rollout is None:
        return
    s = np.arange(5.0)
    z = np.zeros(5)
    rollout(s, z, np.ones(5), z, z, 1.0, 0.5, 0.5, 0.0, 0.0, np.array([3.0]), np.zeros((2, 1)), 5.0, 0.0, 0.0,
            0.5, 0.2, 1.0, 0.3, 5.0, 2, 3, 5, False, np.zeros(2), 0.4, 0.1, 0.1)
