"""Pure pursuit of a goal point at a look-ahead distance (Coulter 1992).

Source: R. C. Coulter, "Implementation of the Pure Pursuit Path Tracking Algorithm",
CMU-RI-TR-92-01, 1992; the goal-point search follows PythonRobotics
(``PathTracking/pure_pursuit``): walk forward from the closest path point to the first point at
least the look-ahead distance ``L_d`` away, with ``L_d = lookahead_m + speed_gain_s * V``.

The pursuit arc through the vehicle and the goal point, tangent to the velocity, has curvature
``gamma = 2 x_lat / L_d^2`` (``x_lat`` the goal's lateral offset in the velocity frame), i.e.
``2 sin(alpha) / L_d`` with alpha the angle from the velocity to the goal. At constant speed the
command is ``a = V^2 gamma = 2 V^2 sin(alpha) / L_d``.

Honest note: this is the same expression as Park's constant-L1 law (Park 2007 presents L1
guidance as a relative of pure pursuit). The two differ only when the vehicle is farther than
``L_d`` from the path: pure pursuit then aims at the closest path point (the goal search never
leaves it), whereas the two-phase law runs its mid-course phase. The benchmark keeps it as the
law a mobile-robotics user would pick, swept over ``L_d``. Our addition, as for the paper's laws
(:mod:`companion.guidance.capture`): while the closest point lies behind the beam, the command
is the bounded turn ``2 V^2 / L_d`` towards it, so a vehicle pointing away from the path comes
back (Coulter's ``2 V^2 sin(alpha) / d`` is 0 with the goal dead astern). Past the end of an open path the goal
is taken on the straight continuation of the end tangent (``companion.guidance.path_frame.goal_point``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.guidance.capture import capture_command_m_s2, capture_side
from companion.guidance.path_frame import frame_output, PathLike, goal_point, path_frame, wrap_pi
from companion.guidance.types import GuidanceOutput, VehicleState


@dataclass(frozen=True)
class PurePursuitParams:
    """Tuning of :class:`PurePursuitGuidance`.

    Attributes
    ----------
    lookahead_m : constant part of the look-ahead distance L_d, > 0.
    speed_gain_s : speed-proportional part (L_d = lookahead_m + speed_gain_s * V), >= 0.
    """

    lookahead_m: float = 10.0
    speed_gain_s: float = 0.0

    def __post_init__(self) -> None:
        if not (isinstance(self.lookahead_m, (int, float)) and math.isfinite(self.lookahead_m)
                and self.lookahead_m > 0):
            raise ValueError(f"lookahead_m: expected a finite number > 0, got {self.lookahead_m!r}")
        if not (isinstance(self.speed_gain_s, (int, float)) and math.isfinite(self.speed_gain_s)
                and self.speed_gain_s >= 0):
            raise ValueError(f"speed_gain_s: expected a finite number >= 0, got {self.speed_gain_s!r}")


class PurePursuitGuidance:
    """Pure pursuit on a :class:`~companion.geometry.paths.Path`; see the module docstring."""

    method = "pure_pursuit"

    def __init__(self, path: PathLike, params: PurePursuitParams | None = None) -> None:
        self.path = path
        self.params = params if params is not None else PurePursuitParams()
        self._s_hint: float | None = None
        self._capture_side = 0  # the side of the bounded capture turn (companion.guidance.capture)

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        p = self.params
        v = state.speed_m_s
        ld = p.lookahead_m + p.speed_gain_s * v
        f = path_frame(self.path, state.x_m, state.y_m, self._s_hint, state.course_rad)
        self._s_hint = f.s_m
        goal = goal_point(self.path, state.x_m, state.y_m, ld, f.s_m)
        if goal is None:  # far from the path: the goal search stays at the closest point
            gx, gy = f.px_m, f.py_m
            self._capture_side = capture_side(state.x_m, state.y_m, state.course_rad, gx, gy, f.tx, f.ty,
                                              self._capture_side)
        else:
            gx, gy = goal
            self._capture_side = 0
        dx, dy = gx - state.x_m, gy - state.y_m
        dist = math.hypot(dx, dy)
        if self._capture_side:  # the closest point behind the beam: our bounded capture turn
            a_cmd = capture_command_m_s2(self._capture_side, v, ld)
        elif dist < 1e-9:
            a_cmd = 0.0
        else:
            alpha = wrap_pi(math.atan2(dy, dx) - state.course_rad)
            # gamma = 2 x_lat / L^2 with x_lat = dist sin(alpha), over the actual goal distance.
            a_cmd = v * v * 2.0 * math.sin(alpha) / dist
        return frame_output(self.path, f, a_cmd, (gx, gy), {"lookahead_m": ld})
