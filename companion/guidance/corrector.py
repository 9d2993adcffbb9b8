"""The corrector point and the corrector-aided command (paper section III-B).

Points, as numbered in the paper (local ENU):

- ``P1 = (x1, y1)``: the vehicle; ``v`` its unit velocity (course) direction.
- ``P1'``: the closest point of the path to P1 (its projection), with unit tangent ``t1``.
- ``P2 = (x2, y2)``: the look-ahead point, on the path at distance L1 from P1.
- the *green line*: through P2, perpendicular to ``v``.
- ``P4 = (x4, y4)``: the corrector point, where the tangent line at P1' meets the green line.
- ``P3 = (x3, y3)``: not defined by the paper. Here it is the foot of the perpendicular from P1
  onto the green line, ``P3 = P1 + ((P2 - P1) . v) v``: the point straight ahead of the vehicle
  on the green line, i.e. where it would cross that line if it did not turn. Then ``l23`` and
  ``l43`` are the lateral offsets of the look-ahead and corrector points from the vehicle's
  straight-ahead line, which is what the paper's text says they stand for ("the lateral
  acceleration demand would be more for a look-ahead point at a larger distance" from P3).

The command (paper eqs. for ``a12``, ``a14``, ``w1``, ``w2`` and ``a_cmd``)::

    a12 = 2 V^2 sin(eta12) / L1          a14 = 2 V^2 sin(eta14) / Lc
    w1  = k1 R_L1 / (1 + l23)            w2  = k2 v_m / (R_L1 (1 + l43))
    a   = (w1 a12 + w2 a14) / (w1 + w2)

``R_L1`` is the radius of curvature at P2, ``v_l`` the speed of P2 along the path when L1 is
held constant (Park's ``V_T``), ``v_m = (V + v_l) / 2``.

Degenerate geometry (every rule gives a finite command):

- *Straight path at P2* (``R_L1`` infinite): both weights are multiplied by the curvature
  ``|k2|`` at P2 before use, ``w1' = k1 / (1 + l23)``, ``w2' = k2 v_m k^2 / (1 + l43)``; the
  ratio, hence the command, is unchanged where the curvature is not zero, and on a straight
  stretch ``w2' = 0`` so ``a = a12``.
- *Both weights zero* (``k1 = 0`` on a straight stretch, or ``k1 = k2 = 0``): ``a = a12``.
- *Tangent at P1' parallel to the green line* (``|t1 . v| < 1e-6``, the vehicle flies across
  the path): no corrector point exists; ``a = a12``. As ``t1 . v`` tends to 0 the corrector
  point runs off along the tangent, ``a14 -> 0`` and ``w2 -> 0``, so this rule is the limit.
- *Look-ahead point not ahead of the vehicle* (``(P2 - P1) . v <= 0``, ``|eta12| >= 90 deg``):
  the green line lies behind the vehicle and the corrector has no meaning; ``a = a12``.
- *Vehicle on the path*: ``P1' = P1``; nothing special is needed.
- *Look-ahead point speed*: ``v_l = V ((P2 - P1) . v) / ((P2 - P1) . t2)``; it is capped at
  ``V_L_MAX_FACTOR * V`` when the path at P2 runs nearly perpendicular to the line of sight.

The bound the corrector guarantees. P4 lies on the green line, whose distance ahead of the
vehicle is ``x = (P2 - P1) . v = L1 cos(eta12)``; with ``y`` the lateral offset of P4,
``a14 = 2 V^2 y / (x^2 + y^2)``, whose largest magnitude over ``y`` is ``V^2 / x``. So
``|a14| <= V^2 / (L1 cos eta12)``, which is at most ``2 V^2 / L1`` while ``|eta12| <= 60 deg``.
Beyond that ``a14`` is saturated at ``2 V^2 / L1``. The weighted average of two commands lies
between them, hence the corrector-aided command obeys the same bound as constant L1:
``|a| <= 2 V^2 / L1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from companion.guidance.types import frozen_maker

V_L_MAX_FACTOR = 10.0
PARALLEL_EPS = 1e-6


@dataclass(frozen=True)
class CorrectorTerms:
    """Everything the corrector-aided command is made of, for one tick (for logs and tests)."""

    a_cmd_m_s2: float
    a12_m_s2: float
    a14_m_s2: float  # nan when the corrector is not used
    eta12_rad: float
    corrector_xy_m: tuple[float, float] | None
    p3_xy_m: tuple[float, float]
    l_c_m: float
    l23_m: float
    l43_m: float
    v_l_m_s: float
    v_m_m_s: float
    radius_l1_m: float  # inf on a straight stretch
    w1: float  # the paper's weights (inf/0 on a straight stretch)
    w2: float
    corrector_used: bool


#: A scalar or an array of them (the vectorised commands broadcast their arguments).
Floats = float | NDArray[np.float64]

#: A :class:`CorrectorTerms` from its fifteen fields by name (``frozen_maker``).
_terms = frozen_maker(CorrectorTerms)


def corrector_point(x1_m: float, y1_m: float, vx: float, vy: float,
                    px_m: float, py_m: float, tx: float, ty: float,
                    x2_m: float, y2_m: float) -> tuple[float, float] | None:
    """Where the path tangent at the projection ``(px_m, py_m)`` (direction ``(tx, ty)``) meets
    the line through the look-ahead point ``(x2_m, y2_m)`` perpendicular to the velocity
    direction ``(vx, vy)``. ``None`` when the two lines are parallel."""
    denom = tx * vx + ty * vy
    if abs(denom) < PARALLEL_EPS:
        return None
    lam = ((x2_m - px_m) * vx + (y2_m - py_m) * vy) / denom
    return px_m + lam * tx, py_m + lam * ty


def lookahead_speed_m_s(speed_m_s: float, x1_m: float, y1_m: float, vx: float, vy: float,
                        x2_m: float, y2_m: float, t2x: float, t2y: float) -> float:
    """Speed of the look-ahead point along the path that keeps its distance to the vehicle constant.

    From ``d/dt |P2 - P1|^2 = 0``: ``v_l (P2 - P1) . t2 = V (P2 - P1) . v``. Clamped to
    ``[0, V_L_MAX_FACTOR * V]``.
    """
    lx, ly = x2_m - x1_m, y2_m - y1_m
    num = speed_m_s * (lx * vx + ly * vy)
    den = lx * t2x + ly * t2y
    cap = V_L_MAX_FACTOR * speed_m_s
    if num <= 0.0:
        return 0.0
    if den <= num / cap:
        return cap
    return num / den


def corrector_command(x1_m: float, y1_m: float, course_rad: float, speed_m_s: float, l1_m: float,
                      proj: tuple[float, float, float, float],
                      look: tuple[float, float, float, float, float],
                      k1: float, k2: float) -> CorrectorTerms:
    """The corrector-aided lateral acceleration and its internals.

    Parameters
    ----------
    x1_m, y1_m, course_rad, speed_m_s : vehicle position, course and ground speed V.
    l1_m : the look-ahead distance the look-ahead point was found with.
    proj : ``(x, y, tx, ty)`` of the projection P1' (point and unit tangent).
    look : ``(x, y, tx, ty, curvature_1_m)`` of the look-ahead point P2.
    k1, k2 : the non-negative weights' gains.
    """
    V = speed_m_s
    vx, vy = math.cos(course_rad), math.sin(course_rad)
    x2, y2, t2x, t2y, k_l1 = look
    dx2, dy2 = x2 - x1_m, y2 - y1_m
    fwd2 = dx2 * vx + dy2 * vy  # distance of the green line ahead of the vehicle
    lat2 = vx * dy2 - vy * dx2
    d2 = math.hypot(dx2, dy2)
    a12 = 2.0 * V * V * lat2 / (d2 * d2) if d2 > 1e-9 else 0.0  # = 2 V^2 sin(eta12) / |P1P2|
    eta12 = math.atan2(lat2, fwd2)
    p3 = (x1_m + fwd2 * vx, y1_m + fwd2 * vy)
    l23 = abs(lat2)
    radius = math.inf if k_l1 == 0.0 else 1.0 / abs(k_l1)
    a_max = 2.0 * V * V / l1_m
    p4 = None
    if fwd2 > 0.0:
        p4 = corrector_point(x1_m, y1_m, vx, vy, proj[0], proj[1], proj[2], proj[3], x2, y2)
    if p4 is None:
        return _terms(a_cmd_m_s2=a12, a12_m_s2=a12, a14_m_s2=math.nan, eta12_rad=eta12, corrector_xy_m=None,
                      p3_xy_m=p3, l_c_m=math.nan, l23_m=l23, l43_m=math.nan, v_l_m_s=math.nan,
                      v_m_m_s=math.nan, radius_l1_m=radius, w1=math.inf, w2=0.0, corrector_used=False)
    dx4, dy4 = p4[0] - x1_m, p4[1] - y1_m
    lat4 = vx * dy4 - vy * dx4
    l_c = math.hypot(dx4, dy4)
    a14 = 2.0 * V * V * lat4 / (l_c * l_c)  # = 2 V^2 sin(eta14) / Lc; Lc >= fwd2 > 0
    a14 = max(-a_max, min(a_max, a14))
    l43 = abs(lat4)
    v_l = lookahead_speed_m_s(V, x1_m, y1_m, vx, vy, x2, y2, t2x, t2y)
    v_m = 0.5 * (V + v_l)
    w1s = k1 / (1.0 + l23)  # w1 * |k|
    w2s = k2 * v_m * k_l1 * k_l1 / (1.0 + l43)  # w2 * |k|
    if w1s + w2s <= 0.0:
        a = a12
    else:
        # The weighted mean as a step from a12 towards a14 by the share w2 / (w1 + w2) in [0, 1]:
        # it stays between the two terms even when a weight underflows to a subnormal number.
        a = a12 + (a14 - a12) * (w2s / (w1s + w2s))
    if k_l1 == 0.0:
        w1, w2 = (math.inf if k1 > 0 else 0.0), 0.0
    else:
        w1, w2 = w1s * radius, w2s * radius
    return _terms(a_cmd_m_s2=a, a12_m_s2=a12, a14_m_s2=a14, eta12_rad=eta12, corrector_xy_m=p4, p3_xy_m=p3,
                  l_c_m=l_c, l23_m=l23, l43_m=l43, v_l_m_s=v_l, v_m_m_s=v_m, radius_l1_m=radius, w1=w1, w2=w2,
                  corrector_used=w2s > 0.0 and w1s + w2s > 0.0)


def corrector_command_array(x1_m: Floats, y1_m: Floats, course_rad: Floats, speed_m_s: float, l1_m: float,
                            px_m: Floats, py_m: Floats, tx: Floats, ty: Floats, x2_m: Floats, y2_m: Floats,
                            t2x: Floats, t2y: Floats, k_l1: Floats, k1: Floats, k2: Floats) -> NDArray[np.float64]:
    """Vectorised :func:`corrector_command` (command only), for the rollouts of many candidates.

    Every argument but ``speed_m_s`` and ``l1_m`` may be an array (broadcast together). With
    ``k2 = 0`` this is exactly constant-L1 guidance (``a12``).
    """
    return corrector_command_vxy(x1_m, y1_m, np.cos(course_rad), np.sin(course_rad), speed_m_s, l1_m,
                                 px_m, py_m, tx, ty, x2_m, y2_m, t2x, t2y, k_l1, k1, k2)


def corrector_command_vxy(x1_m: Floats, y1_m: Floats, vx: Floats, vy: Floats, speed_m_s: float, l1_m: float,
                          px_m: Floats, py_m: Floats, tx: Floats, ty: Floats, x2_m: Floats, y2_m: Floats,
                          t2x: Floats, t2y: Floats, k_l1: Floats, k1: Floats, k2: Floats) -> NDArray[np.float64]:
    """:func:`corrector_command_array` given the unit velocity ``(vx, vy) = (cos, sin)(course)``
    instead of the course: the rollouts already hold both from their unicycle step."""
    V = speed_m_s
    two_v2 = 2.0 * V * V
    dx2, dy2 = x2_m - x1_m, y2_m - y1_m
    fwd2 = dx2 * vx + dy2 * vy
    lat2 = vx * dy2 - vy * dx2
    d2sq = np.maximum(dx2 * dx2 + dy2 * dy2, 1e-18)
    a12 = two_v2 * lat2 / d2sq
    denom = tx * vx + ty * vy
    ok = (fwd2 > 0.0) & (np.abs(denom) >= PARALLEL_EPS)
    safe = np.where(ok, denom, 1.0)
    lam = ((x2_m - px_m) * vx + (y2_m - py_m) * vy) / safe
    dx4 = px_m + lam * tx - x1_m
    dy4 = py_m + lam * ty - y1_m
    lat4 = vx * dy4 - vy * dx4
    lc2 = np.maximum(dx4 * dx4 + dy4 * dy4, 1e-18)
    a_max = two_v2 / l1_m
    a14 = np.minimum(np.maximum(two_v2 * lat4 / lc2, -a_max), a_max)  # np.clip, cheaper on tiny arrays
    num = V * fwd2
    den = dx2 * t2x + dy2 * t2y
    cap = V_L_MAX_FACTOR * V
    v_l = np.where(num <= 0.0, 0.0, np.where(den <= num / cap, cap, num / np.maximum(den, 1e-18)))
    v_m = 0.5 * (V + v_l)
    w1s = k1 / (1.0 + np.abs(lat2))
    w2s = np.where(ok, k2 * v_m * k_l1 * k_l1 / (1.0 + np.abs(lat4)), 0.0)
    tot = w1s + w2s
    share = w2s / np.where(tot > 0.0, tot, 1.0)  # as corrector_command: a step from a12 towards a14
    out: NDArray[np.float64] = np.where(tot > 0.0, a12 + (a14 - a12) * share, a12)
    return out
