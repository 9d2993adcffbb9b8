"""Capture from far off the path: a bounded turn when the closest path point lies behind.

Our addition to the paper (and to pure pursuit), not part of either; ``docs/guidance.md``,
"Capture far from the path".

A law that aims at a look-ahead point on the path (constant L1, the corrector-aided law, pure
pursuit) has no such point when the vehicle is farther than its look-ahead distance ``L`` from
the path. It then aims at the closest path point P with Park's command
``2 V^2 sin(eta) / max(d, L)`` (``eta`` the angle from the velocity to the line of sight to P,
``d = |P - vehicle|``). While P lies ahead of the beam (``|eta| <= 90 deg``) that closes the
distance. Behind the beam it does not: ``sin(eta)`` is small near 180 deg and exactly 0 when P
lies dead astern, so a vehicle pointing away from the path flies on and never comes back.

The rule here: while P lies behind the beam (``cos(eta) < 0``), turn towards it at the law's
own bound ``2 V^2 / L`` (a circle of radius ``L / 2``): the vehicle strays at most ``L`` further
before it points back at the path, so it never gets farther than ``d0 + 2 L`` from a path it
started ``d0`` from, and the command stays within the law's bound ``|a| <= 2 V^2 / L``. The side
is chosen on the first tick behind the beam and kept until P is ahead again (so the command
cannot dither between sides when P is near dead astern): the side P lies on (the sign of
``sin(eta)``), or, when P is within ``SIDE_EPS`` of dead astern, the side the path's direction
at P lies on (so the vehicle joins it going its way), or left when both are undecided.

Once P is ahead of the beam the law's own command (towards P, then the look-ahead point as soon
as one exists) takes over again.

Which way the turn round goes near the path (``predictive`` only, :func:`join_side`): started
within two turn radii R = V^2 / a of the path, pointing away, a turn towards P sweeps across the
path at an angle and runs along it beyond; the turn the short way onto the path's direction
runs beside it instead.
"""

from __future__ import annotations

import math

from companion.geometry.paths import Path
from companion.guidance.path_frame import PathFrame
from companion.guidance.types import VehicleState

#: |sin| below which a direction counts as dead ahead or astern when choosing the side.
SIDE_EPS = 1e-3


def capture_side(x_m: float, y_m: float, course_rad: float, px_m: float, py_m: float,
                 tx: float, ty: float, side: int) -> int:
    """The side to turn at the law's bound, or 0 when the law's own command stands.

    Parameters
    ----------
    x_m, y_m, course_rad : the vehicle's position and course (local ENU, radians).
    px_m, py_m : the closest path point P.
    tx, ty : the unit path tangent at P (its direction of travel).
    side : the side returned on the previous tick (0 if none): kept while P stays behind.

    Returns
    -------
    +1 (turn left), -1 (turn right), or 0: P is ahead of the beam (``cos(eta) >= 0``), or within
    a millimetre of the vehicle.

    Examples
    --------
    >>> capture_side(0.0, 0.0, -math.pi / 2, 0.0, 15.0, 1.0, 0.0, 0)  # P dead astern, path going east
    1
    >>> capture_side(0.0, 0.0, math.pi / 2, 0.0, 15.0, 1.0, 0.0, 1)  # P ahead: the law's own command
    0
    """
    dx, dy = px_m - x_m, py_m - y_m
    dist = math.hypot(dx, dy)
    if dist < 1e-3:
        return 0
    c, s = math.cos(course_rad), math.sin(course_rad)
    if c * dx + s * dy >= 0.0:  # ahead of the beam (or on it)
        return 0
    if side:
        return side
    sin_eta = (c * dy - s * dx) / dist
    if abs(sin_eta) >= SIDE_EPS:
        return 1 if sin_eta > 0.0 else -1
    if abs(c * ty - s * tx) >= SIDE_EPS:  # the path's direction clear of dead ahead and astern
        return join_side(course_rad, tx, ty)
    return 1


#: Off the path by less than this, which side of it the vehicle is on is tracking noise: a
#: capture turn ignores the closest point's side (only the goal's), and ``predictive``'s rollouts
#: weigh both sides of the path alike (:func:`companion.guidance.predictive.weigh_overshoot`).
SIDE_MIN_OFFSET_M = 1.0


#: A new capture within this many turn radii of the path turns the way of the path's direction.
JOIN_SIDE_RADII = 2.0


def join_side(course_rad: float, tx: float, ty: float) -> int:
    """The side to turn onto the path's direction ``(tx, ty)`` the short way: +1 left, -1 right.

    >>> join_side(math.pi / 2, 1.0, 0.0)  # heading north, the path going east: right
    -1
    >>> join_side(math.radians(-100.0), 1.0, 0.0)  # heading south and a little west: left
    1
    """
    along = math.cos(course_rad) * ty - math.sin(course_rad) * tx  # velocity x path direction
    return 1 if along >= 0.0 else -1  # > 0: the path's direction lies to the left


def pursuit_capture_side(state: VehicleState, frame: PathFrame, gx_m: float, gy_m: float, side: int,
                         radius_m: float = 0.0) -> int:
    """:func:`capture_side` for a law that always has a goal ``(gx_m, gy_m)`` (``predictive``'s
    pursuit): the side to turn round, or 0. ``frame`` is the vehicle's path frame, ``side`` the
    previous tick's answer.

    A new capture off the path turns towards the closest point if that is behind too. On the path
    the goal decides: the closest point's side is there the sign of an error of centimetres (of
    noise, on a real vehicle), and following it turned a vehicle started on the path facing across
    it the long way round. Going the path's way with the closest point ahead, a goal behind the
    beam means the path bends back within the look-ahead distance (a tight loop, a hairpin): no
    turn round, the pursuit with its plan follows it (a turn round there left a loop of a
    self-crossing path on the held-out bench, ``random_1119``).

    Within ``JOIN_SIDE_RADII`` turn radii (``radius_m``, the turn's ``V^2 / a``) of the path, a
    new capture with the closest point behind turns the way that brings the course onto the
    path's direction the short way (:func:`join_side`), whichever side the closest point lies on:
    so near, the turn towards it swept across the path still turning and ran along it beyond,
    or came round against the path's direction and turned on through it.
    """
    x, y, course = state.x_m, state.y_m, state.course_rad
    behind = capture_side(x, y, course, gx_m, gy_m, frame.tx, frame.ty, side)
    if behind and not side:
        off_path = abs(frame.crosstrack_m) > SIDE_MIN_OFFSET_M
        p_behind = capture_side(x, y, course, frame.px_m, frame.py_m, frame.tx, frame.ty, 0) if off_path else 0
        going_its_way = math.cos(course) * frame.tx + math.sin(course) * frame.ty >= 0.0
        if going_its_way and not p_behind:
            behind = 0
        elif p_behind:
            behind = p_behind
            if abs(frame.crosstrack_m) < JOIN_SIDE_RADII * radius_m:
                behind = join_side(course, frame.tx, frame.ty)
    return behind


def capture_command_m_s2(side: int, speed_m_s: float, reach_m: float) -> float:
    """The bounded turn ``side * 2 V^2 / L`` (``L = reach_m``, the law's look-ahead distance)."""
    return side * 2.0 * speed_m_s * speed_m_s / reach_m


def start_course_rad(path: Path, x_m: float, y_m: float, l1_m: float) -> float:
    """The course a hovering copter should face before its path starts (local ENU, radians).

    A copter at rest has no course: its velocity loop flies any direction it is given. Started on
    whatever way its nose points, a law sees a vehicle already moving that way at the mission speed
    and commands a turn it does not need (a copter facing north on a path going east swings out by
    metres). Faced this way instead, every law starts with nothing to correct: the direction of
    Park's L1 point (the path's first exit from the circle of radius ``l1_m`` past the closest
    point, :meth:`~companion.geometry.paths.Path.lookahead`), or, farther than ``l1_m`` from the
    path (no such point), of the closest point itself. On the path that is the chord ``l1_m`` ahead.

    Examples
    --------
    >>> from companion.geometry.paths import waypoint_path
    >>> line = waypoint_path([[0.0, 0.0], [100.0, 0.0]])  # going east
    >>> round(math.degrees(start_course_rad(line, 10.0, 0.0, 10.0)), 6)  # on it: along it
    0.0
    >>> round(math.degrees(start_course_rad(line, 10.0, 6.0, 10.0)), 3)  # 6 m left: the L1 point 8 m ahead
    -36.87
    >>> round(math.degrees(start_course_rad(line, 10.0, 30.0, 10.0)), 6)  # beyond L1: straight at it
    -90.0
    """
    s = path.project(x_m, y_m)
    s_l1 = path.lookahead(x_m, y_m, l1_m, s)
    px, py = path.point(s if s_l1 is None else s_l1)
    if math.hypot(px - x_m, py - y_m) < 1e-6:  # on the path's end point: its direction
        return path.heading_rad(s)
    return math.atan2(py - y_m, px - x_m)
