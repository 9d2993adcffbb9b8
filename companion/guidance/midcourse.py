"""Mid-course phase: from far away to the path start along an initiation circle (paper section III-A).

Geometry (local ENU, angles anticlockwise):

- The path starts at S with heading ``theta0``. Two *initiation circles* of radius R touch the
  path there: the *left* one, centre ``S + R n0`` (``n0`` the left normal), flown anticlockwise
  (sense ``+1``), and the *right* one, centre ``S - R n0``, flown clockwise (sense ``-1``). Flying
  either in its sense brings the vehicle through S with heading ``theta0``.
- From the vehicle P with course direction ``v``, the circles through P tangent to ``v`` form a
  one-parameter family (signed curvature ``c``; the command that flies one is ``a = V^2 c``).
  Exactly two of them touch a given initiation circle C (centre O): the largest and smallest
  ``c``, which are the two extrema of Park's command over look-ahead points on C (lemma 1). Their
  contact points are lemma 1's W (the larger circle, smaller ``|a|``) and the *alternate* one.
- At a contact point the vehicle's velocity is tangent to C, but only one of the two touches
  arrives in C's sense. With ``D = P - O`` and ``a_n = D . n_v`` (``n_v`` the left normal of the
  velocity), the arriving-in-sense circle has, in closed form,

      c = -2 sigma (R + sigma a_n) / (|D|^2 - R^2)

  (external tangency when ``c`` has the sign opposite to ``sigma``, internal otherwise), and
  its contact point is ``W = O + R u`` with ``u`` the unit vector from O towards the touching
  circle's centre (external) or away from it (internal); on a straight approach (``c = 0``)
  ``W = O - sigma R n_v``.

Selection (the paper's Case 1 / Case 2 with their sectors): Case 1 when P is behind the start
(``(P - S) . t0 < 0``), Case 2 when it is in front. For each initiation circle, the arriving-in-
sense touch is either lemma 1's W ("primary": red / blue sectors) or the alternate circle
(green sector of Case 2). The paper's rule, applied to both cases: if exactly one initiation
circle is reached in sense through its primary W, fly that one; otherwise (green sectors) fly
the circle whose touch needs the smaller ``|a|``.

Flight: the arc's curvature c is held, commanding ``a = V^2 c`` at each tick's speed (at the
plan's speed, Park's ``2 V^2 sin(eta) / |PW|`` with W as a static look-ahead point; at the paper's
constant speed, a constant command), until the vehicle has flown the arc to W; then the initiation
circle is followed with constant-L1 guidance on the circle (look-ahead ``min(L1, sqrt(2) R)``,
which is the closed loop whose steady command is ``V^2 / R``) until the vehicle passes S, where
the close-range phase takes over.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.geometry.frames import wrap_pi
from companion.guidance.l1 import l1_command

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class InitiationCircle:
    """A circle of radius ``radius_m`` touching the path at its start, flown in ``sense``."""

    name: str  # "left" (anticlockwise) or "right" (clockwise)
    centre_xy_m: tuple[float, float]
    radius_m: float
    sense: int  # +1 anticlockwise, -1 clockwise

    def angle_rad(self, x_m: float, y_m: float) -> float:
        """Polar angle of ``(x_m, y_m)`` about the centre."""
        return math.atan2(y_m - self.centre_xy_m[1], x_m - self.centre_xy_m[0])


@dataclass(frozen=True)
class Approach:
    """The constant-curvature arc from the vehicle to a contact point on an initiation circle."""

    circle: InitiationCircle
    contact_xy_m: tuple[float, float]  # W
    a_cmd_m_s2: float  # V^2 c at the plan's speed (the flight holds c, not this command)
    curvature_1_m: float  # c, signed (0: straight approach)
    turn_rad: float  # course change from P to W, >= 0, in the direction of the turn
    arc_m: float  # distance flown from P to W
    circle_arc_rad: float  # angle flown on the initiation circle from W to S, in [0, 2 pi)
    primary: bool  # True: lemma 1's W (larger circle); False: the alternate circle
    tangency: str  # "external" or "internal"


@dataclass(frozen=True)
class MidcoursePlan:
    """The chosen approach, the alternative, and the paper's case."""

    chosen: Approach
    other: Approach | None  # None when the vehicle is inside the other circle
    case: int  # 1: vehicle behind the path start, 2: in front
    rule: str  # "only_primary" (red/blue sectors), "lower_acceleration" (green), "only_outside"


def initiation_circles(start_xy_m: tuple[float, float], start_heading_rad: float,
                       radius_m: float) -> tuple[InitiationCircle, InitiationCircle]:
    """The left (anticlockwise) and right (clockwise) circles touching the path at its start."""
    sx, sy = start_xy_m
    nx, ny = -math.sin(start_heading_rad), math.cos(start_heading_rad)
    left = InitiationCircle("left", (sx + radius_m * nx, sy + radius_m * ny), radius_m, +1)
    right = InitiationCircle("right", (sx - radius_m * nx, sy - radius_m * ny), radius_m, -1)
    return left, right


def _touching_curvatures(dsq: float, a_n: float, r: float) -> tuple[float, float]:
    """Signed curvatures of the two circles through P tangent to v that touch C.

    ``c_plus`` arrives in C's anticlockwise sense, ``c_minus`` in its clockwise sense.
    """
    den = dsq - r * r
    c_plus = -2.0 * (r + a_n) / den
    c_minus = 2.0 * (r - a_n) / den
    return c_plus, c_minus


def contact_approach(x_m: float, y_m: float, course_rad: float, speed_m_s: float,
                     circle: InitiationCircle, start_xy_m: tuple[float, float]) -> Approach:
    """The circle through the vehicle, tangent to its velocity, that touches ``circle`` in its sense.

    Requires the vehicle outside the circle (``|P - O| > R``).
    """
    ox, oy = circle.centre_xy_m
    r = circle.radius_m
    sigma = circle.sense
    vx, vy = math.cos(course_rad), math.sin(course_rad)
    nvx, nvy = -vy, vx
    dx, dy = x_m - ox, y_m - oy
    dsq = dx * dx + dy * dy
    if dsq <= r * r * (1.0 + 1e-9):
        raise ValueError("mid-course: the vehicle is on or inside the initiation circle")
    a_n = dx * nvx + dy * nvy
    c_plus, c_minus = _touching_curvatures(dsq, a_n, r)
    c, c_other = (c_plus, c_minus) if sigma > 0 else (c_minus, c_plus)
    primary = abs(c) <= abs(c_other)
    if abs(c) < 1e-12:
        c = 0.0
        wx, wy = ox - sigma * r * nvx, oy - sigma * r * nvy
        tangency = "external"
        arc = (wx - x_m) * vx + (wy - y_m) * vy
        # A straight approach only reaches a contact point ahead; one behind is out of reach
        # (the limit of ever larger circles): mark it as a full turn so that it is turned in to.
        turn = 0.0 if arc >= 0.0 else TWO_PI
        arc = arc if arc >= 0.0 else math.inf
    else:
        rho = 1.0 / c  # signed radius; centre Q = P + rho n_v
        qx, qy = x_m + rho * nvx, y_m + rho * nvy
        ux, uy = qx - ox, qy - oy
        norm = math.hypot(ux, uy)
        ux, uy = ux / norm, uy / norm
        external = (c > 0) != (sigma > 0)
        tangency = "external" if external else "internal"
        if not external:
            ux, uy = -ux, -uy
        wx, wy = ox + r * ux, oy + r * uy
        # Course change from P to W along the touching circle, in the turn direction.
        ang_p = math.atan2(y_m - qy, x_m - qx)
        ang_w = math.atan2(wy - qy, wx - qx)
        turn = ((ang_w - ang_p) * (1.0 if c > 0 else -1.0)) % TWO_PI
        arc = abs(rho) * turn
    sx, sy = start_xy_m
    circle_arc = (sigma * (math.atan2(sy - oy, sx - ox) - math.atan2(wy - oy, wx - ox))) % TWO_PI
    return Approach(circle, (wx, wy), speed_m_s * speed_m_s * c, c, turn, arc, circle_arc,
                    primary, tangency)


def plan_midcourse(x_m: float, y_m: float, course_rad: float, speed_m_s: float,
                   start_xy_m: tuple[float, float], start_heading_rad: float,
                   radius_m: float) -> MidcoursePlan:
    """Choose the initiation circle and contact point (Case 1 / Case 2 rules, module docstring).

    A vehicle inside one initiation circle (possible with the ``"paper"`` trigger when R0 < R)
    cannot reach it tangentially from outside: the other circle is flown (rule
    ``"only_outside"``, ``other`` is then None). The two circles only touch at S, so a vehicle
    away from S is always outside at least one of them.
    """
    left, right = initiation_circles(start_xy_m, start_heading_rad, radius_m)
    tx, ty = math.cos(start_heading_rad), math.sin(start_heading_rad)
    case = 1 if (x_m - start_xy_m[0]) * tx + (y_m - start_xy_m[1]) * ty < 0.0 else 2
    approaches: list[Approach | None] = []
    for circle in (left, right):
        try:
            approaches.append(contact_approach(x_m, y_m, course_rad, speed_m_s, circle, start_xy_m))
        except ValueError:  # on or inside this circle
            approaches.append(None)
    a_left, a_right = approaches
    if a_left is None or a_right is None:
        if a_left is None and a_right is None:
            raise ValueError("mid-course: the vehicle is at the path start, inside both circles")
        return MidcoursePlan(a_left if a_left is not None else a_right, None, case, "only_outside")  # type: ignore[arg-type]
    if a_left.primary != a_right.primary:
        chosen, other = (a_left, a_right) if a_left.primary else (a_right, a_left)
        rule = "only_primary"
    else:
        lower_left = (abs(a_left.a_cmd_m_s2), a_left.arc_m) <= (abs(a_right.a_cmd_m_s2), a_right.arc_m)
        chosen, other = (a_left, a_right) if lower_left else (a_right, a_left)
        rule = "lower_acceleration"
    return MidcoursePlan(chosen, other, case, rule)


def circle_lookahead(x_m: float, y_m: float, circle: InitiationCircle,
                     l1_m: float) -> tuple[float, float]:
    """The point of ``circle`` at distance ``l1_m`` from the vehicle, ahead in the circle's sense.

    When the circle of radius ``l1_m`` around the vehicle does not cut the initiation circle
    (the vehicle is more than ``l1_m`` off it), the point of the circle ``l1_m`` of arc ahead of
    the vehicle's radial projection is used instead.
    """
    ox, oy = circle.centre_xy_m
    r = circle.radius_m
    dx, dy = x_m - ox, y_m - oy
    d = math.hypot(dx, dy)
    theta = math.atan2(dy, dx)
    if d > 1e-9 and abs(d - r) < l1_m < d + r:
        # Law of cosines: angle at O between OP and the intersection point.
        cos_b = (d * d + r * r - l1_m * l1_m) / (2.0 * d * r)
        beta = math.acos(max(-1.0, min(1.0, cos_b)))
        phi = theta + circle.sense * beta
    else:
        phi = theta + circle.sense * (l1_m / r)
    return ox + r * math.cos(phi), oy + r * math.sin(phi)


class MidcourseGuidance:
    """Flies the mid-course phase: turn-in (if needed), the constant-curvature arc, the circle.

    The paper only considers vehicles heading towards the initiation circle (angle between the
    velocity and the line to the circle centre at most 90 deg). Outside that scope lemma 1's
    arc can be a huge loop (a kilometre for a vehicle flying away). So when the chosen approach
    needs a course change of more than ``TURN_IN_LIMIT_RAD`` on its arc, the vehicle first
    *turns in*: it turns towards the chosen circle's centre (the side is decided on the first
    tick and kept) at the circle's own command ``V^2 / R`` and re-plans every tick until the
    plan's arc turns less than that limit. The same happens when the arc would be tighter than
    the initiation circle itself (``|c| > 1 / R``: a start close to the circle, heading the wrong
    way); R being the feasible turn radius, the approach command never exceeds ``V^2 / R``.
    The caller may hold the turn-in for a tick (``keep_turning_in``): the two-phase guidance does
    while the closest point of the *path* lies behind the vehicle (our addition, docs/guidance.md,
    "Capture far from the path": from a start beside the path far from its start, heading away,
    lemma 1's arc to the start can bulge 100 m out; turning in first until the path is abeam
    keeps the vehicle near it).

    ``step`` returns ``(a_cmd_m_s2, stage, done)``; ``stage`` is ``"turn_in"``, ``"approach"``
    or ``"circle"`` and ``done`` turns True on the tick the vehicle passes the path start on the
    circle.
    """

    TURN_IN_LIMIT_RAD = math.pi

    def __init__(self, start_xy_m: tuple[float, float], start_heading_rad: float,
                 radius_m: float, l1_m: float):
        self.start_xy_m = start_xy_m
        self.start_heading_rad = start_heading_rad
        self.radius_m = radius_m
        self.l1_circle_m = min(l1_m, math.sqrt(2.0) * radius_m)
        self.plan: MidcoursePlan | None = None
        self.first_plan: MidcoursePlan | None = None
        self.stage = "turn_in"
        self._flown_m = 0.0
        self._t_prev: float | None = None
        self._remaining_prev: float | None = None
        self._turn_sign = 0
        self.lookahead_xy_m: tuple[float, float] | None = None

    @property
    def circle(self) -> InitiationCircle:
        assert self.plan is not None, "plan() first"
        return self.plan.chosen.circle

    def _remaining_rad(self, x_m: float, y_m: float) -> float:
        """Angle still to fly on the circle before the path start, in ``[0, 2 pi)``."""
        c = self.circle
        sx, sy = self.start_xy_m
        return (c.sense * (c.angle_rad(sx, sy) - c.angle_rad(x_m, y_m))) % TWO_PI

    def step(self, t_s: float, x_m: float, y_m: float, course_rad: float,
             speed_m_s: float, keep_turning_in: bool = False) -> tuple[float, str, bool]:
        """One tick; ``keep_turning_in`` holds the turn-in stage this tick whatever the plan (the
        caller's rule: the closest path point lies behind the vehicle, see the class docstring)."""
        dt = 0.0 if self._t_prev is None else max(t_s - self._t_prev, 0.0)
        self._t_prev = t_s
        if self.stage == "turn_in":
            plan = plan_midcourse(x_m, y_m, course_rad, speed_m_s, self.start_xy_m,
                                  self.start_heading_rad, self.radius_m)
            if self.first_plan is None:
                self.first_plan = plan
            self.plan = plan
            feasible = abs(plan.chosen.curvature_1_m) * self.radius_m <= 1.0 + 1e-9
            if plan.chosen.turn_rad <= self.TURN_IN_LIMIT_RAD and feasible and not keep_turning_in:
                self.stage = "approach"
                self._flown_m = 0.0
                dt = 0.0
            else:
                ox, oy = plan.chosen.circle.centre_xy_m
                if self._turn_sign == 0:  # chosen once, so that re-plans cannot make it dither
                    side = math.cos(course_rad) * (oy - y_m) - math.sin(course_rad) * (ox - x_m)
                    self._turn_sign = 1 if side >= 0.0 else -1
                self.lookahead_xy_m = (ox, oy)
                return self._turn_sign * speed_m_s * speed_m_s / self.radius_m, "turn_in", False
        if self.stage == "approach":
            assert self.plan is not None, "plan() first"
            self._flown_m += dt * speed_m_s
            # Switch on the tick closest to W (half a tick early).
            if self._flown_m + 0.5 * speed_m_s * dt >= self.plan.chosen.arc_m:
                self.stage = "circle"
            else:
                # The arc is held as a curvature, V^2 c at the speed now (the plan's a_cmd_m_s2 at
                # constant speed): a vehicle still gathering speed after take-off, or sagging in a
                # turn, flew another arc under a constant command and missed W.
                self.lookahead_xy_m = self.plan.chosen.contact_xy_m
                return self.plan.chosen.curvature_1_m * speed_m_s * speed_m_s, "approach", False
        remaining = self._remaining_rad(x_m, y_m)
        prev = self._remaining_prev
        self._remaining_prev = remaining
        # Passing S makes the remaining angle wrap from near 0 to near 2 pi.
        if prev is not None and prev < 0.5 * math.pi and remaining > 1.5 * math.pi:
            return 0.0, "circle", True
        lx, ly = circle_lookahead(x_m, y_m, self.circle, self.l1_circle_m)
        self.lookahead_xy_m = (lx, ly)
        a, _, _ = l1_command(x_m, y_m, course_rad, speed_m_s, lx, ly)
        return a, "circle", False


def circle_sense_course_error_rad(circle: InitiationCircle, x_m: float, y_m: float,
                                  course_rad: float) -> float:
    """Course minus the circle's tangent direction (in its sense) at the vehicle's angle."""
    theta = circle.angle_rad(x_m, y_m)
    tangent = theta + circle.sense * 0.5 * math.pi
    return wrap_pi(course_rad - tangent)
