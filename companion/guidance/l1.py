"""Constant look-ahead distance (L1) guidance of Park, Deyst and How (2007).

The vehicle at ``(x, y)`` flying at ground speed ``V`` with course ``psi`` aims at a reference
point at distance ``L`` (the look-ahead point). With ``eta`` the angle from the velocity to the
line of sight, the lateral acceleration

    a = 2 V^2 sin(eta) / L

puts the vehicle on the circular arc through itself and the reference point that is tangent to
its velocity (a chord of length L subtends ``2 eta``, so the arc radius is ``L / (2 sin eta)``).
Hence ``|a| <= 2 V^2 / L`` always, and on a circle of radius R followed exactly, with the
reference point on the circle (``L <= 2 R``), ``a = V^2 / R``.

Sign convention: ``eta`` and ``a`` are positive to the left (anticlockwise), as every angle in
the local ENU frame.
"""

from __future__ import annotations

import math

from companion.geometry.frames import wrap_pi


def los_angle_rad(x_m: float, y_m: float, course_rad: float, tx_m: float, ty_m: float) -> float:
    """Angle ``eta`` from the velocity direction to the line of sight towards ``(tx_m, ty_m)``."""
    return wrap_pi(math.atan2(ty_m - y_m, tx_m - x_m) - course_rad)


def l1_command(x_m: float, y_m: float, course_rad: float, speed_m_s: float,
               tx_m: float, ty_m: float) -> tuple[float, float, float]:
    """Park's command towards the reference point ``(tx_m, ty_m)``.

    Returns
    -------
    (a_cmd_m_s2, eta_rad, distance_m) : the lateral acceleration (positive left), the
        line-of-sight angle and the distance to the reference point. A reference point within
        1 mm of the vehicle has no line of sight: the command is 0.
    """
    dx = tx_m - x_m
    dy = ty_m - y_m
    dist = math.hypot(dx, dy)
    if dist < 1e-3:
        return 0.0, 0.0, dist
    c = math.cos(course_rad)
    s = math.sin(course_rad)
    # sin(eta) = (v_hat x los_hat), computed without atan2: cross product over the distance.
    sin_eta = (c * dy - s * dx) / dist
    cos_eta = (c * dx + s * dy) / dist
    return 2.0 * speed_m_s * speed_m_s * sin_eta / dist, math.atan2(sin_eta, cos_eta), dist


def l1_bound_m_s2(speed_m_s: float, l1_m: float) -> float:
    """The largest command constant-L1 guidance can give: ``2 V^2 / L1``."""
    return 2.0 * speed_m_s * speed_m_s / l1_m
