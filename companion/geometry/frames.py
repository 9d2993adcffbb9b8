"""ENU <-> NED: the one place where the mission frame meets the autopilot frame.

Missions and guidance use a local **ENU** frame (x east, y north, z up; angles anticlockwise from
+x = east, as in the paper). MAVLink's ``LOCAL_POSITION_NED`` and ``SET_POSITION_TARGET_LOCAL_NED``
use **NED** (x north, y east, z down; yaw clockwise from north). Both frames share the autopilot's
local origin, so the conversion is a fixed reflection:

=====================  =====================
ENU                    NED
=====================  =====================
x_enu (east)           y_ned
y_enu (north)          x_ned
z_enu (up)             -z_ned
angle anticlockwise    yaw clockwise from
from east, theta       north, psi = pi/2 - theta
yaw rate (left +)      yaw rate (right +), r_ned = -r_enu
=====================  =====================

The reflection is its own inverse for positions and velocities (swap x/y, negate z) and for
angles (``pi/2 - (pi/2 - theta) = theta``); the functions are still named by direction so that a
call site says which way it converts. Angles are returned wrapped to ``(-pi, pi]``.

Examples
--------
>>> enu_from_ned(10.0, 3.0, -5.0)   # 10 m north, 3 m east, 5 m up
(3.0, 10.0, 5.0)
>>> round(course_enu_from_ned(0.0), 6)   # heading north in NED is +pi/2 in ENU
1.570796
"""

from __future__ import annotations

import math

TWO_PI = 2.0 * math.pi


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle to ``(-pi, pi]``.

    >>> round(wrap_pi(3.0 * math.pi / 2.0), 6)
    -1.570796
    >>> wrap_pi(-math.pi) == math.pi
    True
    """
    wrapped = math.fmod(angle_rad + math.pi, TWO_PI)
    if wrapped <= 0.0:
        wrapped += TWO_PI
    return wrapped - math.pi


def wrap_2pi(angle_rad: float) -> float:
    """Wrap an angle to ``[0, 2 pi)``.

    >>> round(wrap_2pi(-math.pi / 2.0), 6)
    4.712389
    """
    wrapped = math.fmod(angle_rad, TWO_PI)
    if wrapped < 0.0:
        wrapped += TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


def angle_diff_rad(a_rad: float, b_rad: float) -> float:
    """Smallest signed difference ``a - b`` wrapped to ``(-pi, pi]`` (continuous across +-pi)."""
    return wrap_pi(a_rad - b_rad)


def enu_from_ned(x_ned_m: float, y_ned_m: float, z_ned_m: float) -> tuple[float, float, float]:
    """Position (or any vector) NED -> ENU: ``(east, north, up) = (y_ned, x_ned, -z_ned)``."""
    return (float(y_ned_m), float(x_ned_m), -float(z_ned_m))


def ned_from_enu(x_enu_m: float, y_enu_m: float, z_enu_m: float) -> tuple[float, float, float]:
    """Position (or any vector) ENU -> NED: ``(north, east, down) = (y_enu, x_enu, -z_enu)``."""
    return (float(y_enu_m), float(x_enu_m), -float(z_enu_m))


def vel_enu_from_ned(vx_ned_m_s: float, vy_ned_m_s: float, vz_ned_m_s: float) -> tuple[float, float, float]:
    """Velocity NED -> ENU (same reflection as positions)."""
    return enu_from_ned(vx_ned_m_s, vy_ned_m_s, vz_ned_m_s)


def vel_ned_from_enu(vx_enu_m_s: float, vy_enu_m_s: float, vz_enu_m_s: float) -> tuple[float, float, float]:
    """Velocity ENU -> NED (same reflection as positions)."""
    return ned_from_enu(vx_enu_m_s, vy_enu_m_s, vz_enu_m_s)


def course_enu_from_ned(yaw_ned_rad: float) -> float:
    """A direction given NED-style (clockwise from north) -> ENU (anticlockwise from east).

    Applies equally to a course (direction of the ground velocity) and to a heading/yaw.
    Result in ``(-pi, pi]``.
    """
    return wrap_pi(math.pi / 2.0 - yaw_ned_rad)


def yaw_ned_from_enu(course_enu_rad: float) -> float:
    """A direction ENU (anticlockwise from east) -> NED yaw (clockwise from north), in ``(-pi, pi]``."""
    return wrap_pi(math.pi / 2.0 - course_enu_rad)


def yaw_rate_ned_from_enu(yaw_rate_enu_rad_s: float) -> float:
    """Yaw rate ENU (anticlockwise/left positive) -> NED (clockwise/right positive): sign flip."""
    return -float(yaw_rate_enu_rad_s)


def yaw_rate_enu_from_ned(yaw_rate_ned_rad_s: float) -> float:
    """Yaw rate NED (clockwise positive) -> ENU (anticlockwise positive): sign flip."""
    return -float(yaw_rate_ned_rad_s)


def course_enu_from_vel_ned(vx_ned_m_s: float, vy_ned_m_s: float) -> float:
    """Course (direction of ground velocity) in ENU from NED horizontal velocity components."""
    return math.atan2(vx_ned_m_s, vy_ned_m_s)
