"""Hand-made reference paths for the bench tests: a straight line and a circle.

They implement the documented Path contract (``point``, ``tangent``, ``curvature``,
``heading_rad``, ``project``, ``length_m``, ``closed``, ``start_xy_m``,
``start_heading_rad``) with closed-form geometry, so the laws' commands can be checked against
hand arithmetic independently of ``companion.geometry.paths``. They have no ``lookahead``,
so the laws' own forward search (``companion.guidance.path_frame.lookahead_s``) is exercised too.
"""

from __future__ import annotations

import math

import numpy as np
from companion.guidance.types import VehicleState


class LinePath:
    """Straight segment from (x0, y0) along heading, of a given length."""

    closed = False

    def __init__(self, x0=0.0, y0=0.0, heading_rad=0.0, length_m=1000.0):
        self.x0, self.y0, self.h, self.length_m = x0, y0, heading_rad, length_m
        self.c, self.s = math.cos(heading_rad), math.sin(heading_rad)
        self.start_xy_m = (x0, y0)
        self.start_heading_rad = heading_rad

    def point(self, s):
        return np.array([self.x0 + s * self.c, self.y0 + s * self.s])

    def tangent(self, s):
        return np.array([self.c, self.s])

    def curvature(self, s):
        return 0.0

    def heading_rad(self, s):
        return self.h

    def project(self, x, y, s_hint=None):
        s = (x - self.x0) * self.c + (y - self.y0) * self.s
        return min(max(s, 0.0), self.length_m)


class CirclePath:
    """Circle of radius R about (cx, cy), starting at angle phi0, anticlockwise if ccw else clockwise."""

    closed = True

    def __init__(self, radius_m=30.0, cx=0.0, cy=0.0, phi0_rad=0.0, ccw=True):
        self.r, self.cx, self.cy, self.phi0 = radius_m, cx, cy, phi0_rad
        self.dir = 1.0 if ccw else -1.0
        self.length_m = 2.0 * math.pi * radius_m
        self.start_xy_m = tuple(self.point(0.0))
        self.start_heading_rad = self.heading_rad(0.0)

    def _phi(self, s):
        return self.phi0 + self.dir * s / self.r

    def point(self, s):
        phi = self._phi(s)
        return np.array([self.cx + self.r * math.cos(phi), self.cy + self.r * math.sin(phi)])

    def tangent(self, s):
        phi = self._phi(s)
        return self.dir * np.array([-math.sin(phi), math.cos(phi)])

    def curvature(self, s):
        return self.dir / self.r

    def heading_rad(self, s):
        t = self.tangent(s)
        return math.atan2(t[1], t[0])

    def project(self, x, y, s_hint=None):
        phi = math.atan2(y - self.cy, x - self.cx)
        return ((phi - self.phi0) * self.dir % (2.0 * math.pi)) * self.r


def mirror_path(path):
    """The same path reflected across the x axis (y -> -y): left turns become right turns."""
    if isinstance(path, LinePath):
        return LinePath(path.x0, -path.y0, -path.h, path.length_m)
    return CirclePath(path.r, path.cx, -path.cy, -path.phi0, ccw=path.dir < 0)


def mirror_state(state: VehicleState) -> VehicleState:
    return VehicleState(state.x_m, -state.y_m, -state.course_rad, state.speed_m_s)


def fly(law, state: VehicleState, t_end_s: float, dt_s: float = 0.02, wind=(0.0, 0.0)):
    """Ideal unicycle (constant airspeed, course-rate = a / V, steady wind), Euler steps.

    Returns the time series of (t, crosstrack, a_cmd). Kept here, independent of the project's
    simulator, so the laws' tests do not depend on it.
    """
    v_air = state.speed_m_s
    x, y = state.x_m, state.y_m
    psi = state.course_rad  # air heading (equals course in zero wind)
    out = []
    t = 0.0
    while t <= t_end_s:
        gx, gy = v_air * math.cos(psi) + wind[0], v_air * math.sin(psi) + wind[1]
        st = VehicleState(x, y, math.atan2(gy, gx), math.hypot(gx, gy))
        o = law.step(t, st)
        out.append((t, o.crosstrack_m, o.a_cmd_m_s2))
        psi += o.a_cmd_m_s2 / v_air * dt_s
        x += gx * dt_s
        y += gy * dt_s
        t += dt_s
    return np.array(out)
