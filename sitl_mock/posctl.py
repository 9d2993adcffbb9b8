"""ArduCopter's horizontal position controller, as GUIDED flies velocity targets.

A real ArduCopter does not pass a velocity target straight to its velocity loop. In GUIDED with
velocity targets (``ModeGuided::velaccel_control_run``, ArduPilot master) it

1. shapes the target into a kinematic trajectory (desired position, velocity, acceleration) whose
   acceleration changes at most at ``PSC_JERK_XY`` (``shape_vel_accel_xy`` in
   ``libraries/AP_Math/control.cpp``): the correction toward the target velocity is a square-root
   controller limited to ``WPNAV_ACCEL`` (when it points mostly along the target velocity, its
   cross part is held to 1/sqrt(2) of the limit: the "corner" rule), and a target acceleration,
   when the setpoint carries one, is added to it after that limit (GUIDED asks for no limit of the
   total); between two setpoints the target velocity itself moves on by the target acceleration
   (``update_vel_accel_xy`` on GUIDED's own target);
2. flies that trajectory with its position controller (``AC_PosControl::update_NE_controller``):
   a P loop on the desired position (``PSC_POSXY_P``) adds to the desired velocity, a PID on the
   velocity error (``PSC_VELXY_P/I/D``, error and derivative filtered at ``PSC_VELXY_FLTE/FLTD``)
   adds to the desired acceleration, and the sum is limited by the lean angle (``ANGLE_MAX``).

So the vehicle chases a trajectory that leaves at the limit and can pull more than ``WPNAV_ACCEL``
to catch up with it: from a hover the real SITL gathers speed faster than a first-order lag with
a 2.5 m/s^2 limit would (docs/real_firmware.md). :class:`NEPositionController` is that chain with
the firmware's default copter parameters, behind a short dead time, followed by the airframe: a
lag on the acceleration the controller asks for, and the air's drag, which the velocity loop's
integrator has to hold (ArduCopter SITL's copter leans about 11.5 deg to cruise at 5 m/s). It returns
the acceleration the vehicle flies. The mock's ArduPilot copter flies it in GUIDED velocity
control. The drag was measured from the shared ArduCopter identification flight's lean at steady
speeds, the dead time and the lag were then fitted to the same flight (docs/sitl_mock.md).

Frames: NE horizontal components, metres, m/s, m/s^2; plain floats (one step is a few
microseconds at the mock's 400 Hz).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from sitl_mock.vehicle import GRAVITY_M_S2

CORNER_ACCELERATION_RATIO = 1.0 / math.sqrt(2.0)  # AP_Math/control.h


@dataclass(frozen=True)
class PosControlParams:
    """ArduCopter's parameters of the chain, in SI units (defaults: the firmware's, copter).

    The last four are not parameters of the firmware but of the airframe it flies:
    ``input_delay_s`` is the dead time between a target leaving the companion and the controller
    acting on it (link, scheduler); ``airframe_lag_s`` a first-order lag on the acceleration the
    controller asks for (attitude loop and motors); the drag decelerates the vehicle by
    ``(drag_linear_1_s + drag_quadratic_1_m * |v|) v``. The drag is ArduCopter SITL's default
    copter's (momentum drag of the rotors, linear, and the body's, quadratic), measured from the
    shared identification flight's lean at 3, 5 and 8 m/s; the dead time (0.02 s) and the lag
    (0.18 s) were fitted to the same flight with that drag (docs/sitl_mock.md).
    """

    accel_max_m_s2: float = 2.5  # WPNAV_ACCEL 250 cm/s^2
    jerk_max_m_s3: float = 5.0  # PSC_JERK_XY
    pos_p_1_s: float = 1.0  # PSC_POSXY_P
    vel_p_1_s: float = 2.0  # PSC_VELXY_P
    vel_i_1_s2: float = 1.0  # PSC_VELXY_I
    vel_d: float = 0.25  # PSC_VELXY_D
    vel_imax_m_s2: float = 10.0  # PSC_VELXY_IMAX 1000 cm/s^2
    vel_filter_hz: float = 5.0  # PSC_VELXY_FLTE, PSC_VELXY_FLTD
    speed_max_m_s: float = 10.0  # WPNAV_SPEED 1000 cm/s: the position correction's speed limit
    lean_max_rad: float = math.radians(30.0)  # ANGLE_MAX 3000 cdeg
    input_delay_s: float = 0.02
    airframe_lag_s: float = 0.18
    drag_linear_1_s: float = 0.243
    drag_quadratic_1_m: float = 0.0316

    def __post_init__(self) -> None:
        for name in ("accel_max_m_s2", "jerk_max_m_s3", "vel_filter_hz", "speed_max_m_s", "lean_max_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: expected a positive finite number, got {value!r}")
        for name in ("pos_p_1_s", "vel_p_1_s", "vel_i_1_s2", "vel_d", "vel_imax_m_s2", "input_delay_s",
                     "airframe_lag_s", "drag_linear_1_s", "drag_quadratic_1_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")


def sqrt_controller(error: float, p: float, second_order_limit: float, dt_s: float) -> float:
    """ArduPilot's square-root controller: linear (gain ``p``) near zero, then the rate that stops
    at the limit ``second_order_limit``; never more than the error closes in one step."""
    if second_order_limit <= 0.0:
        rate = error * p
    elif p == 0.0:
        rate = math.copysign(math.sqrt(2.0 * second_order_limit * abs(error)), error)
    else:
        linear = second_order_limit / (p * p)
        if error > linear:
            rate = math.sqrt(2.0 * second_order_limit * (error - linear / 2.0))
        elif error < -linear:
            rate = -math.sqrt(2.0 * second_order_limit * (-error - linear / 2.0))
        else:
            rate = error * p
    if dt_s > 0.0:
        bound = abs(error) / dt_s
        rate = max(-bound, min(bound, rate))
    return rate


def _sqrt_controller_ne(en: float, ee: float, p: float, limit: float, dt_s: float) -> tuple[float, float]:
    norm = math.hypot(en, ee)
    if norm <= 0.0:
        return 0.0, 0.0
    scale = sqrt_controller(norm, p, limit, dt_s) / norm
    return en * scale, ee * scale


def _limit_length(x: float, y: float, limit: float) -> tuple[float, float]:
    norm = math.hypot(x, y)
    if norm > limit > 0.0:
        return x * limit / norm, y * limit / norm
    return x, y


def _split(an: float, ae: float, dn: float, de: float) -> tuple[float, float, float, float, float] | None:
    """An acceleration's part along the direction ``(dn, de)`` and its cross part (None: no direction)."""
    d = math.hypot(dn, de)
    if d <= 0.0:
        return None
    un, ue = dn / d, de / d
    along = an * un + ae * ue
    return un, ue, along, an - along * un, ae - along * ue


def _recombined(un: float, ue: float, along: float, cn: float, ce: float, limit: float,
                cross_limit: float) -> tuple[float, float]:
    """The cross part limited to ``cross_limit``, the along part to what remains of ``limit``."""
    cn, ce = _limit_length(cn, ce, cross_limit)
    along_max = math.sqrt(max(0.0, limit * limit - (cn * cn + ce * ce)))
    along = max(-along_max, min(along_max, along))
    return cn + along * un, ce + along * ue


def corner_limited(an: float, ae: float, dn: float, de: float, limit: float) -> tuple[float, float]:
    """An acceleration limited to ``limit`` the way ``shape_vel_accel_xy`` does about the direction
    ``(dn, de)``: when its part along the direction dominates, its cross part is held to
    1/sqrt(2) of the limit and the along part gets what remains; otherwise its length is limited."""
    parts = _split(an, ae, dn, de)
    if parts is None or parts[2] ** 2 <= parts[3] ** 2 + parts[4] ** 2:
        return _limit_length(an, ae, limit)
    return _recombined(*parts, limit, CORNER_ACCELERATION_RATIO * limit)


def cross_first_limited(an: float, ae: float, dn: float, de: float, limit: float) -> tuple[float, float]:
    """An acceleration limited to ``limit`` the way ``limit_accel_xy`` does about the direction of
    travel ``(dn, de)``: the cross part keeps up to the whole limit, the along part what remains."""
    if an * an + ae * ae <= limit * limit:
        return an, ae
    parts = _split(an, ae, dn, de)
    if parts is None:
        return _limit_length(an, ae, limit)
    return _recombined(*parts, limit, limit)


class NEPositionController:
    """ArduCopter GUIDED's horizontal chain from a velocity target to an acceleration command.

    Call :meth:`reset` when velocity control starts (the firmware starts its trajectory from the
    vehicle's own position, velocity and acceleration), then :meth:`update` every step.

    Examples
    --------
    >>> ctl = NEPositionController(PosControlParams(input_delay_s=0.0))
    >>> ctl.reset((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    >>> for _ in range(200):  # 0.5 s at 400 Hz: the trajectory's acceleration ramps at the jerk limit
    ...     _ = ctl.update(0.0025, (5.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    >>> round(ctl.desired_acc_ne_m_s2[0], 3)
    2.5
    """

    def __init__(self, params: PosControlParams) -> None:
        self.params = params
        self._queue: deque = deque()
        self.reset((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))

    def reset(self, pos_ne_m: tuple[float, float], vel_ne_m_s: tuple[float, float],
              acc_ne_m_s2: tuple[float, float]) -> None:
        """Start the trajectory at the vehicle's state, as ``init_NE_controller`` does: desired
        position and velocity the vehicle's, desired acceleration zero, and the velocity loop's
        integrator holding what the airframe pushes with (the acceleration it flies plus the drag
        at its velocity), so the command carries on from it."""
        self.desired_pos_ne_m = (float(pos_ne_m[0]), float(pos_ne_m[1]))
        self.desired_vel_ne_m_s = (float(vel_ne_m_s[0]), float(vel_ne_m_s[1]))
        self.desired_acc_ne_m_s2 = (0.0, 0.0)
        self.acc_ne_m_s2 = (float(acc_ne_m_s2[0]), float(acc_ne_m_s2[1]))  # what the airframe flies
        dn, de = self.drag_ne_m_s2(vel_ne_m_s)
        self._thrust = (self.acc_ne_m_s2[0] + dn, self.acc_ne_m_s2[1] + de)  # the lag's output, before drag
        self._integrator = _limit_length(self._thrust[0], self._thrust[1], self.params.vel_imax_m_s2)
        self._error = None  # the filtered velocity error (None: take the first one as it is)
        self._derivative = (0.0, 0.0)
        self._queue.clear()
        self._held = (float(vel_ne_m_s[0]), float(vel_ne_m_s[1]), 0.0, 0.0, -math.inf)
        self._vin = self._held[:2]
        self._target_key: tuple | None = None  # (received, vn, ve) of the setpoint held
        self._t_s = 0.0

    def _delayed(self, target: tuple) -> tuple:
        delay = self.params.input_delay_s
        if delay <= 0.0:
            return target
        queue = self._queue
        queue.append((self._t_s, target))
        due = self._t_s - delay + 1e-9
        while len(queue) > 1 and queue[1][0] <= due:
            queue.popleft()
        if queue[0][0] > due:  # nothing old enough yet: the trajectory carries on as it was
            return self._held
        self._held = queue[0][1]
        return self._held

    def _target(self, dt_s: float, target: tuple) -> tuple[float, float, float, float]:
        """GUIDED's own target (velocity, acceleration) this step: a new setpoint replaces it,
        and until the next one its velocity moves on by its acceleration (``update_vel_accel_xy``)."""
        vn, ve, an, ae, received = target
        if (received, vn, ve) != self._target_key:
            self._target_key = (received, vn, ve)
            self._vin = (vn, ve)
        else:
            self._vin = (self._vin[0] + an * dt_s, self._vin[1] + ae * dt_s)
        return self._vin[0], self._vin[1], an, ae

    def update(self, dt_s: float, vel_target_ne_m_s: tuple[float, float], pos_ne_m: tuple[float, float],
               vel_ne_m_s: tuple[float, float], acc_target_ne_m_s2: tuple[float, float] = (0.0, 0.0),
               received_s: float = 0.0) -> tuple[float, float]:
        """One step: the velocity and acceleration target given now (``received_s``: when that
        setpoint arrived, so that a new one is told from the one held), the vehicle's (estimated)
        position and velocity; returns the horizontal acceleration the vehicle flies (NE, m/s^2):
        the controller's command through the airframe's lag, less the drag at that velocity."""
        p = self.params
        self._t_s += dt_s
        target = (float(vel_target_ne_m_s[0]), float(vel_target_ne_m_s[1]),
                  float(acc_target_ne_m_s2[0]), float(acc_target_ne_m_s2[1]), received_s)
        vin_n, vin_e, ain_n, ain_e = self._target(dt_s, self._delayed(target))
        pn, pe = self.desired_pos_ne_m
        vn, ve = self.desired_vel_ne_m_s
        an, ae = self.desired_acc_ne_m_s2
        # The trajectory moves on (update_pos_vel_accel_xy) ...
        pn, pe = pn + vn * dt_s + 0.5 * an * dt_s * dt_s, pe + ve * dt_s + 0.5 * ae * dt_s * dt_s
        vn, ve = vn + an * dt_s, ve + ae * dt_s
        # ... and its acceleration turns toward the target velocity (shape_vel_accel_xy).
        k_pa = p.jerk_max_m_s3 / p.accel_max_m_s2
        tn, te = _sqrt_controller_ne(vin_n - vn, vin_e - ve, k_pa, p.jerk_max_m_s3, dt_s)
        tn, te = corner_limited(tn, te, vin_n, vin_e, p.accel_max_m_s2)
        tn, te = tn + ain_n, te + ain_e
        dn, de = _limit_length(tn - an, te - ae, p.jerk_max_m_s3 * dt_s)
        an, ae = an + dn, ae + de
        self.desired_pos_ne_m = (pn, pe)
        self.desired_vel_ne_m_s = (vn, ve)
        self.desired_acc_ne_m_s2 = (an, ae)
        # Position loop (a square-root P, its correction at most WPNAV_SPEED) ...
        cn, ce = _sqrt_controller_ne(pn - pos_ne_m[0], pe - pos_ne_m[1], p.pos_p_1_s, p.accel_max_m_s2, 0.0)
        cn, ce = _limit_length(cn, ce, p.speed_max_m_s)
        # ... velocity PID on the filtered error ...
        en, ee = vn + cn - vel_ne_m_s[0], ve + ce - vel_ne_m_s[1]
        alpha = dt_s / (dt_s + 1.0 / (2.0 * math.pi * p.vel_filter_hz))
        if self._error is None:
            fn, fe = en, ee
            self._derivative = (0.0, 0.0)
        else:
            old_n, old_e = self._error
            fn, fe = old_n + (en - old_n) * alpha, old_e + (ee - old_e) * alpha
            dn_, de_ = self._derivative
            self._derivative = (dn_ + ((fn - old_n) / dt_s - dn_) * alpha,
                                de_ + ((fe - old_e) / dt_s - de_) * alpha)
        self._error = (fn, fe)
        i_n, i_e = self._integrator
        self._integrator = _limit_length(i_n + fn * p.vel_i_1_s2 * dt_s, i_e + fe * p.vel_i_1_s2 * dt_s,
                                         p.vel_imax_m_s2)
        out_n = p.vel_p_1_s * fn + self._integrator[0] + p.vel_d * self._derivative[0] + an
        out_e = p.vel_p_1_s * fe + self._integrator[1] + p.vel_d * self._derivative[1] + ae
        # ... and the lean-angle limit (limit_accel_xy: the cross-track part first).
        cmd_n, cmd_e = cross_first_limited(out_n, out_e, vn, ve, GRAVITY_M_S2 * math.tan(p.lean_max_rad))
        # The attitude loop and the motors deliver it through a lag, and the air takes its drag.
        k = 1.0 if p.airframe_lag_s <= 0.0 else 1.0 - math.exp(-dt_s / p.airframe_lag_s)
        tn, te = self._thrust
        self._thrust = (tn + (cmd_n - tn) * k, te + (cmd_e - te) * k)
        dn, de = self.drag_ne_m_s2(vel_ne_m_s)
        self.acc_ne_m_s2 = (self._thrust[0] - dn, self._thrust[1] - de)
        return self.acc_ne_m_s2

    @property
    def thrust_ne_m_s2(self) -> tuple[float, float]:
        """The horizontal acceleration the thrust gives (the flown one plus the drag): the lean."""
        return self._thrust

    def drag_ne_m_s2(self, vel_ne_m_s: tuple[float, float]) -> tuple[float, float]:
        """The deceleration the air causes at a velocity: ``(linear + quadratic |v|) v`` (NE, m/s^2)."""
        p = self.params
        vn, ve = float(vel_ne_m_s[0]), float(vel_ne_m_s[1])
        c = p.drag_linear_1_s + p.drag_quadratic_1_m * math.hypot(vn, ve)
        return c * vn, c * ve
