"""ArduPilot's L1 controller (``AP_L1_Control``), applied to a curved path.

Source: ArduPilot ``libraries/AP_L1_Control/AP_L1_Control.cpp`` (``update_waypoint``), itself
after S. Park, J. Deyst and J. P. How, "A New Nonlinear Guidance Logic for Trajectory Tracking",
AIAA GNC 2004 (Park 2007 in the paper), "modified to enable period and damping of guidance loop
to be set explicitly" and "to provide explicit control over capture angle".

The equations, with ground speed V, period T (``NAVL1_PERIOD``, default 17 s) and damping zeta
(``NAVL1_DAMPING``, default 0.75)::

    K   = 4 zeta^2                      (gain for the requested damping)
    L1  = zeta T V / pi                 (look-ahead distance for the requested period)
    Nu  = Nu1 + Nu2,   |Nu1| <= 45 deg  (capture-angle limit), |Nu| <= 90 deg
    a   = K V^2 sin(Nu) / L1

On a straight leg ``Nu2`` is the angle from the ground velocity to the track and
``Nu1 = asin(d / L1)`` the angle from the track to the line of sight to the L1 point, so that
``Nu`` is the angle from the velocity to the line of sight (Park's eta). With zeta = 1/sqrt(2),
K = 2 and the law is exactly Park's constant-L1 law with L1 tied to speed.

Applying it to a curved path (our choice, documented in ``docs/benchmarks.md``): the L1 point is
the first path point forward of the closest point at Euclidean distance L1 (as in Park). ``Nu1``
is split into a capture part (line of sight relative to the chord from the closest point to the
L1 point) and a curvature part (chord relative to the tangent at the closest point). The 45 deg
capture limit and the cross-track integrator act on the capture part only; on a straight line
the chord is the tangent and this is ArduPilot's ``update_waypoint`` term for term. When the
vehicle is farther than L1 from the path there is no L1 point; ArduPilot then flies the clamped
capture angle (``sin Nu1 = +-0.7071``), and so do we. Past the end of an open path the path is
continued straight along its end tangent (``companion.guidance.path_frame.goal_point``).

Cross-track integrator (``NAVL1_XTRACK_I``, default 0.02): while the capture angle is within
5 deg, ``I += Nu1 * XTRACK_I * dt`` with I clamped to +-0.1 rad, and ``Nu1 += I``. The time step
is the difference of successive ``t_s`` clamped to 0.1 s; a gap over 1 s resets I (as ArduPilot
does when it has not been called for a second).

Left out (not path-following maths): the anti-indecision latch for flying away from a waypoint,
the loiter PD law, the waypoint-A/B "fly to point" branches, reverse flight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.geometry.checks import require_positive_finite
from companion.guidance.path_frame import frame_output, PathLike, goal_point, path_frame, wrap_pi
from companion.guidance.types import GuidanceOutput, VehicleState

CAPTURE_LIMIT_RAD = math.pi / 4.0  # ArduPilot: sine_Nu1 constrained to +-0.7071
NU_LIMIT_RAD = math.pi / 2.0
XTRACK_I_WINDOW_RAD = math.radians(5.0)
XTRACK_I_LIMIT_RAD = 0.1
MIN_GROUND_SPEED_M_S = 0.1


@dataclass(frozen=True)
class ApL1Params:
    """Tuning of :class:`ApL1Guidance` (ArduPilot parameter names in brackets).

    Attributes
    ----------
    period_s : L1 tracking-loop period T [NAVL1_PERIOD], > 0.
    damping : damping ratio zeta [NAVL1_DAMPING], > 0.
    xtrack_i_gain : cross-track integrator gain [NAVL1_XTRACK_I], >= 0 (0 disables it).
    """

    period_s: float = 17.0
    damping: float = 0.75
    xtrack_i_gain: float = 0.02

    def __post_init__(self) -> None:
        require_positive_finite(self, ("period_s", "damping"))
        g = self.xtrack_i_gain
        if not (isinstance(g, (int, float)) and math.isfinite(g) and g >= 0):
            raise ValueError(f"xtrack_i_gain: expected a finite number >= 0, got {g!r}")

    def l1_m(self, ground_speed_m_s: float) -> float:
        """L1 = zeta T V / pi."""
        return self.damping * self.period_s * ground_speed_m_s / math.pi

    @property
    def gain(self) -> float:
        """K = 4 zeta^2."""
        return 4.0 * self.damping * self.damping


class ApL1Guidance:
    """ArduPilot's L1 law on a :class:`~companion.geometry.paths.Path`; see the module docstring.

    Examples
    --------
    ``ApL1Guidance(path, ApL1Params(period_s=10.0)).step(0.0, VehicleState(0, 0, 0, 5))``
    """

    method = "ap_l1"

    def __init__(self, path: PathLike, params: ApL1Params | None = None) -> None:
        self.path = path
        self.params = params if params is not None else ApL1Params()
        self._s_hint: float | None = None
        self._xtrack_i_rad = 0.0
        self._last_t_s: float | None = None

    def _integrator_dt_s(self, t_s: float) -> float:
        if self._last_t_s is None:
            dt = 0.0
        else:
            dt = t_s - self._last_t_s
            if dt > 1.0:
                self._xtrack_i_rad = 0.0
            dt = min(max(dt, 0.0), 0.1)
        self._last_t_s = t_s
        return dt

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        p = self.params
        v = max(state.speed_m_s, MIN_GROUND_SPEED_M_S)
        l1 = p.l1_m(v)
        dt = self._integrator_dt_s(t_s)
        f = path_frame(self.path, state.x_m, state.y_m, self._s_hint, state.course_rad)
        self._s_hint = f.s_m

        nu2 = wrap_pi(f.tangent_rad - state.course_rad)  # velocity -> tangent at the closest point
        l1_xy = goal_point(self.path, state.x_m, state.y_m, l1, f.s_m)
        if l1_xy is None:
            curve_part = 0.0
            capture = -math.copysign(CAPTURE_LIMIT_RAD, f.crosstrack_m) if f.crosstrack_m else 0.0
        else:
            lx, ly = l1_xy
            chord_len = math.hypot(lx - f.px_m, ly - f.py_m)
            chord = math.atan2(ly - f.py_m, lx - f.px_m) if chord_len > 1e-9 else f.tangent_rad
            curve_part = wrap_pi(chord - f.tangent_rad)
            capture = wrap_pi(math.atan2(ly - state.y_m, lx - state.x_m) - chord)
        capture = min(max(capture, -CAPTURE_LIMIT_RAD), CAPTURE_LIMIT_RAD)

        if p.xtrack_i_gain <= 0.0:
            self._xtrack_i_rad = 0.0
        elif abs(capture) < XTRACK_I_WINDOW_RAD:
            self._xtrack_i_rad += capture * p.xtrack_i_gain * dt
            self._xtrack_i_rad = min(max(self._xtrack_i_rad, -XTRACK_I_LIMIT_RAD), XTRACK_I_LIMIT_RAD)

        nu = capture + self._xtrack_i_rad + curve_part + nu2
        nu = min(max(nu, -NU_LIMIT_RAD), NU_LIMIT_RAD)
        a_cmd = p.gain * v * v / l1 * math.sin(nu)
        return frame_output(self.path, f, a_cmd, l1_xy,
                            {"l1_m": l1, "nu_rad": nu, "xtrack_i_rad": self._xtrack_i_rad})
