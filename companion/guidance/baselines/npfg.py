"""An NPFG-style law: PX4's nonlinear path following guidance, written in ENU.

Sources: T. Stastny and R. Siegwart, "On Flying Backwards: Preventing Run-away of Small,
Low-speed, Fixed-wing UAVs in Strong Winds", IROS 2019, and its implementation in PX4
``src/lib/npfg/npfg.cpp`` (``NPFG::evaluate``), whose step names this file keeps. With ground
velocity ``v_g``, wind ``w``, air velocity ``v_a = v_g - w`` (airspeed ``V_a``), unit path tangent
``t`` at the closest point, signed track error ``e`` (positive left of the path), curvature
``kappa``, period T (``NPFG_PERIOD``, default 10 s) and damping zeta (``NPFG_DAMPING``, 0.7)::

    time constant      tau  = T zeta
    track-error bound  e_b  = |v_g| tau            (0.5 tau (|v_g|^2 + 1) below 1 m/s)
    normalised error   n    = min(|e| / e_b, 1)
    look-ahead angle   th   = pi/2 (n - 1)^2
    bearing            b    = cos(th) u_e + sin(th) t        (u_e the unit vector towards the path)
    air velocity ref   v_ar = wind-triangle solution flying ground track along b at airspeed V_a
    P gain             k_p  = 4 pi zeta / T
    feedback           a_fb = k_p (v_a x v_ar) / |v_ar|      (k_p V_a sign(...) beyond 90 deg)
    feed-forward       a_ff = V_a (1 + w.t / sqrt(V_a^2 - (w x t)^2)) * kappa_e * max(v_g.t, 0),
                       kappa_e = kappa / max(1 - kappa e, |kappa| r_min)
    track proximity    p    = sin(th)^2
    command            a    = a_fb + f p a_ff

``f`` is the bearing feasibility (product of the feasibility of the bearing and of the track
direction at the closest point): ``sin^2(pi/2 clamp((V_a - |w x b|) / V_buf, 0, 1))`` with
``|w x b|`` replaced by ``|w|`` when the wind has a head component along the bearing (w.b < 0).
When the bearing is infeasible (the wind is stronger than the airspeed across it) the air
velocity reference follows PX4's mitigation law ``normalize(sqrt(|w|^2 - V_a^2) b - w) V_a``.

Left out (PX4 features a constant-airspeed point-mass does not exercise): period adaptation to
the roll time constant (``NPFG_LB_PERIOD``/``NPFG_UB_PERIOD``, off here), airspeed increments for
minimum ground speed and track keeping, the waypoint-A "fly to point" branch, roll slew limits.
The wind is the known steady wind of the scenario (PX4 takes the EKF's wind estimate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.geometry.checks import require_positive_finite
from companion.guidance.path_frame import PathLike, is_finished, path_frame
from companion.guidance.types import GuidanceOutput, VehicleState

EPSILON = 1.0e-4  # as PX4's NPFG::EPSILON


def _cross(ax: float, ay: float, bx: float, by: float) -> float:
    """z-component of a x b (positive when b is anticlockwise of a)."""
    return ax * by - ay * bx


@dataclass(frozen=True)
class NpfgParams:
    """Tuning of :class:`NpfgGuidance` (PX4 parameter names in brackets).

    Attributes
    ----------
    period_s : guidance period T [NPFG_PERIOD], > 0.
    damping : damping ratio zeta [NPFG_DAMPING], > 0.
    airspeed_buffer_m_s : bearing-feasibility buffer [NPFG_ASPD_BUF], > 0.
    min_radius_m : smallest path-frame radius in the feed-forward (PX4 ``MIN_RADIUS``), > 0.
    wind_x_m_s, wind_y_m_s : known steady wind, ENU (east, north), m/s.
    """

    period_s: float = 10.0
    damping: float = 0.7
    airspeed_buffer_m_s: float = 1.5
    min_radius_m: float = 0.5
    wind_x_m_s: float = 0.0
    wind_y_m_s: float = 0.0

    def __post_init__(self) -> None:
        require_positive_finite(self, ("period_s", "damping", "airspeed_buffer_m_s", "min_radius_m"))
        for name in ("wind_x_m_s", "wind_y_m_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"{name}: expected a finite number, got {value!r}")

    @property
    def p_gain_1_s(self) -> float:
        """k_p = 4 pi zeta / T."""
        return 4.0 * math.pi * self.damping / self.period_s

    @property
    def time_const_s(self) -> float:
        """tau = T zeta."""
        return self.period_s * self.damping


def track_error_bound_m(ground_speed_m_s: float, time_const_s: float) -> float:
    """e_b = |v_g| tau, smoothed below 1 m/s to avoid a zero bound (PX4 ``trackErrorBound``)."""
    if ground_speed_m_s > 1.0:
        return ground_speed_m_s * time_const_s
    return 0.5 * time_const_s * (ground_speed_m_s * ground_speed_m_s + 1.0)


def look_ahead_angle_rad(normalized_track_error: float) -> float:
    """th = pi/2 (n - 1)^2: pi/2 (along the path) on track, 0 (straight at it) at the bound."""
    return 0.5 * math.pi * (normalized_track_error - 1.0) ** 2


def bearing_feasibility(wind_cross_bearing: float, wind_dot_bearing: float, airspeed_m_s: float,
                        wind_speed_m_s: float, buffer_m_s: float) -> float:
    """Continuous feasibility in [0, 1] of holding a ground track along a bearing in wind."""
    cross = wind_speed_m_s if wind_dot_bearing < 0.0 else abs(wind_cross_bearing)
    arg = min(max((airspeed_m_s - cross) / buffer_m_s, 0.0), 1.0)
    return math.sin(0.5 * math.pi * arg) ** 2


def air_velocity_ref(bx: float, by: float, wx: float, wy: float, airspeed_m_s: float) -> tuple[float, float]:
    """Air velocity of magnitude V_a whose ground velocity points along the bearing b (if possible)."""
    w_cross_b = _cross(wx, wy, bx, by)
    w_dot_b = wx * bx + wy * by
    wind_speed = math.hypot(wx, wy)
    feasible = abs(w_cross_b) < airspeed_m_s and (w_dot_b > 0.0 or wind_speed < airspeed_m_s)
    if feasible:
        along = math.sqrt(max(airspeed_m_s * airspeed_m_s - w_cross_b * w_cross_b, 0.0))
        # along * b + w_cross_b * (left normal of b): the cross component cancels the wind's.
        return along * bx - w_cross_b * by, w_cross_b * bx + along * by
    k = math.sqrt(max(wind_speed * wind_speed - airspeed_m_s * airspeed_m_s, 0.0))
    rx, ry = k * bx - wx, k * by - wy
    n = math.hypot(rx, ry) or 1.0
    return rx / n * airspeed_m_s, ry / n * airspeed_m_s


class NpfgGuidance:
    """PX4-NPFG-style law on a :class:`~companion.geometry.paths.Path`; see the module docstring."""

    method = "npfg"

    def __init__(self, path: PathLike, params: NpfgParams | None = None) -> None:
        self.path = path
        self.params = params if params is not None else NpfgParams()
        self._s_hint: float | None = None

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        p = self.params
        wx, wy = p.wind_x_m_s, p.wind_y_m_s
        gx = state.speed_m_s * math.cos(state.course_rad)
        gy = state.speed_m_s * math.sin(state.course_rad)
        ax, ay = gx - wx, gy - wy
        airspeed = math.hypot(ax, ay)
        wind_speed = math.hypot(wx, wy)
        f = path_frame(self.path, state.x_m, state.y_m, self._s_hint, state.course_rad)
        self._s_hint = f.s_m
        e = f.crosstrack_m
        tx, ty = f.tx, f.ty

        e_b = track_error_bound_m(state.speed_m_s, p.time_const_s)
        n = min(abs(e) / e_b, 1.0)
        theta = look_ahead_angle_rad(n)
        # Unit vector from the vehicle towards the path: minus the left normal when left of it.
        sign_e = 1.0 if e >= 0.0 else -1.0
        ux, uy = sign_e * ty, -sign_e * tx
        bx = math.cos(theta) * ux + math.sin(theta) * tx
        by = math.cos(theta) * uy + math.sin(theta) * ty

        feas_track = bearing_feasibility(_cross(wx, wy, tx, ty), wx * tx + wy * ty, airspeed,
                                         wind_speed, p.airspeed_buffer_m_s)
        feas_bearing = bearing_feasibility(_cross(wx, wy, bx, by), wx * bx + wy * by, airspeed,
                                           wind_speed, p.airspeed_buffer_m_s)
        rx, ry = air_velocity_ref(bx, by, wx, wy, airspeed)
        ref_speed = math.hypot(rx, ry)

        k_p = p.p_gain_1_s
        cross_err = _cross(ax, ay, rx, ry)
        if ax * rx + ay * ry < 0.0:  # more than 90 deg off: hold the largest feedback command
            a_fb = k_p * (airspeed if cross_err >= 0.0 else -airspeed)
        else:
            a_fb = k_p * cross_err / max(ref_speed, EPSILON)

        kappa = f.curvature_1_m
        kappa_e = kappa / max(1.0 - kappa * e, abs(kappa) * p.min_radius_m, EPSILON)
        tangent_ground_speed = max(gx * tx + gy * ty, 0.0)
        w_cross_t = _cross(wx, wy, tx, ty)
        along_air = math.sqrt(max(airspeed * airspeed - w_cross_t * w_cross_t, 0.0))
        speed_ratio = 1.0 + (wx * tx + wy * ty) / max(along_air, EPSILON)
        a_ff = airspeed * speed_ratio * kappa_e * tangent_ground_speed

        proximity = math.sin(theta) ** 2
        a_cmd = a_fb + feas_track * feas_bearing * proximity * a_ff
        phase = "finished" if is_finished(self.path, f.s_m) else "close_range"
        return GuidanceOutput(
            a_cmd_m_s2=a_cmd,
            phase=phase,
            crosstrack_m=e,
            s_proj_m=f.s_m,
            extra={"track_error_bound_m": e_b, "look_ahead_angle_rad": theta,
                   "a_ff_m_s2": a_ff, "feasibility": feas_track * feas_bearing},
        )
