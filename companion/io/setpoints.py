"""Lateral acceleration -> MAVLink setpoint fields (pure conversion, no pymavlink).

The guidance produces one number per tick, the lateral acceleration ``a_cmd`` (ENU, positive =
turn left). Two output adapters turn it into what an autopilot flies:

**Velocity + yaw rate** (copter, rover): ``SET_POSITION_TARGET_LOCAL_NED`` in
``MAV_FRAME_LOCAL_NED`` with

* the horizontal velocity vector of magnitude V pointing along the course the vehicle reaches
  *one tick ahead* when it turns at ``a_cmd``: ``course_cmd = course + (a_cmd / V) * dt``.
  A unicycle at constant speed turns at ``omega = a / V``; a vehicle that holds this velocity for
  the tick ends the tick on exactly the course an ideal unicycle would have at ``t + dt``. The
  command therefore realises the commanded turn within one tick (the first-order effect of the
  turn appears in the very next sample; no extra lag is introduced by the conversion). The position
  difference to the ideal arc is the chord/arc difference, at most ``V dt * |omega| dt / 2`` per
  tick (tested in ``tests/io/test_setpoints.py``).
* ``yaw_rate = a_cmd / V`` (sign flipped for NED: clockwise positive) so that the nose follows
  the turn;
* altitude held by a **vertical velocity** ``vz = -k (alt_target - alt)`` clamped to
  ``max_climb_m_s``, not by a z position. A mission with an altitude profile adds the profile's
  climb rate ``V(s) dh/ds`` as feed-forward and clamps to its climb and sink limits
  (:func:`profile_targets`). ArduCopter reads the three position bits of
  ``type_mask`` as one group, ignored when any of them is set: a z position beside ignored x, y
  would not be flown at all. Using ``vz`` keeps one mask, ``0x05C7`` (1479: position, acceleration
  and yaw ignored; vx, vy, vz, yaw_rate used), which PX4 and ArduPilot both accept.
* for a copter with ``guidance.accel_feedforward`` (by default on ArduPilot;
  companion.loop.limits.accel_feedforward_max), the lateral command
  itself as the **acceleration target** ``(afx, afy)``: ``a_cmd`` (limited to the flight's
  acceleration limit) along the left normal of the commanded course, ``afz = 0``; mask ``0x0407``
  (1031: position and yaw ignored). ArduCopter GUIDED adds it to its velocity correction
  (``shape_vel_accel_xy``, after that correction's ``WPNAV_ACCEL`` limit) and moves its velocity
  target on by it until the next setpoint; PX4 adds it to its velocity loop's output as
  feed-forward. Either way the autopilot turns with the command instead of after its velocity
  error has grown (docs/real_firmware.md, "The command as acceleration feed-forward"). ArduCopter
  reads the three acceleration bits as one group too (any set: none used), so all three are used.

**Attitude** (fixed wing): ``SET_ATTITUDE_TARGET`` with the coordinated-turn bank angle
``phi = atan(a_cmd / g)`` limited to ``max_bank_deg``. In NED a positive roll is right wing down,
a right (clockwise) turn, so a left turn command (a_cmd > 0) gives a negative roll. Body rates
are ignored; the speed is set separately by a speed command (see ``companion.io.link``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from companion.geometry import frames

G_M_S2 = 9.80665

# SET_POSITION_TARGET_LOCAL_NED type_mask bits (a set bit means "ignore this field").
IGNORE_X = 1
IGNORE_Y = 2
IGNORE_Z = 4
IGNORE_VX = 8
IGNORE_VY = 16
IGNORE_VZ = 32
IGNORE_AX = 64
IGNORE_AY = 128
IGNORE_AZ = 256
FORCE_SET = 512
IGNORE_YAW = 1024
IGNORE_YAW_RATE = 2048

#: velocity (vx, vy, vz) + yaw rate; position, acceleration and yaw ignored. 1479 = 0x05C7.
TYPE_MASK_VELOCITY_YAW_RATE = (
    IGNORE_X | IGNORE_Y | IGNORE_Z | IGNORE_AX | IGNORE_AY | IGNORE_AZ | IGNORE_YAW
)
#: velocity + acceleration (feed-forward) + yaw rate; position and yaw ignored. 1031 = 0x0407.
TYPE_MASK_VELOCITY_ACCEL_YAW_RATE = IGNORE_X | IGNORE_Y | IGNORE_Z | IGNORE_YAW
MAV_FRAME_LOCAL_NED = 1


def uses_accel_target(type_mask: int) -> bool:
    """Whether a SET_POSITION_TARGET_LOCAL_NED with this mask carries an acceleration target as
    ArduCopter reads it: all three acceleration bits clear (any one set ignores the group).

    >>> uses_accel_target(TYPE_MASK_VELOCITY_ACCEL_YAW_RATE), uses_accel_target(TYPE_MASK_VELOCITY_YAW_RATE)
    (True, False)
    >>> uses_accel_target(TYPE_MASK_VELOCITY_ACCEL_YAW_RATE | IGNORE_AZ)
    False
    """
    return not type_mask & (IGNORE_AX | IGNORE_AY | IGNORE_AZ)

# SET_ATTITUDE_TARGET type_mask bits.
ATT_IGNORE_ROLL_RATE = 1
ATT_IGNORE_PITCH_RATE = 2
ATT_IGNORE_YAW_RATE = 4
ATT_IGNORE_THRUST = 64
ATT_IGNORE_ATTITUDE = 128
#: attitude (quaternion) + thrust, body rates ignored.
TYPE_MASK_ATTITUDE_THRUST = ATT_IGNORE_ROLL_RATE | ATT_IGNORE_PITCH_RATE | ATT_IGNORE_YAW_RATE


@dataclass(frozen=True)
class AltitudeHold:
    """Vertical-velocity altitude hold:
    ``vz_up = clamp(climb_ff + gain * (alt_target - alt), -max_sink, +max_climb)``.

    ``climb_ff_m_s`` is the feed-forward climb rate of an altitude profile (``V dh/ds`` where the
    vehicle is on the path; 0 for a constant altitude). ``max_sink_m_s`` defaults to
    ``max_climb_m_s`` (a symmetric clamp, the constant-altitude hold).
    """

    altitude_m: float  # target altitude above the local origin (up positive)
    gain_1_s: float = 1.0
    max_climb_m_s: float = 2.0
    max_sink_m_s: float | None = None
    climb_ff_m_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("altitude_m", "climb_ff_m_s"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: expected a finite number, got {getattr(self, name)!r}")
        for name in ("gain_1_s", "max_climb_m_s", "max_sink_m_s"):
            value = getattr(self, name)
            if name == "max_sink_m_s" and value is None:
                continue
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")

    def climb_m_s(self, alt_m: float) -> float:
        """Upward velocity that drives the altitude to the target (0 when alt is not finite)."""
        if not math.isfinite(alt_m):
            return 0.0
        sink = self.max_climb_m_s if self.max_sink_m_s is None else self.max_sink_m_s
        climb = self.climb_ff_m_s + self.gain_1_s * (self.altitude_m - alt_m)
        return max(-sink, min(self.max_climb_m_s, climb))

    def vz_ned_m_s(self, alt_m: float) -> float:
        """Downward velocity that drives the altitude to the target (0 when alt is not finite)."""
        return -self.climb_m_s(alt_m)


def profile_targets(profile, s_m: float, feed_forward: bool = True) -> tuple[float, AltitudeHold]:
    """Speed and altitude hold at arc length ``s_m`` of a
    :class:`companion.geometry.profile.PathProfile`: the local speed ``V(s)``, and the hold on
    ``h(s)`` with the feed-forward climb ``V(s) dh/ds`` (without it for ``feed_forward=False``,
    a hold at one point), clamped to the profile's climb and sink limits.

    >>> from companion.geometry.profile import ProfileLimits, build_profile
    >>> p = build_profile(100.0, False, ProfileLimits(), alt_target=lambda s: 10 + 0.1 * s,
    ...                   speed_target=5.0)
    >>> v, hold = profile_targets(p, 50.0)
    >>> v, round(hold.altitude_m, 6), round(hold.climb_ff_m_s, 6)   # V dh/ds = 5 * 0.1
    (5.0, 15.0, 0.5)
    """
    limits = profile.limits
    v = profile.speed_m_s(s_m)
    ff = v * profile.slope(s_m) if feed_forward else 0.0
    return v, AltitudeHold(profile.altitude_m(s_m), limits.alt_gain_1_s, limits.climb_max_m_s,
                           limits.sink_max_m_s, ff)


@dataclass(frozen=True)
class VelocitySetpoint:
    """Fields of one SET_POSITION_TARGET_LOCAL_NED (velocity + yaw rate, and the horizontal
    acceleration feed-forward when ``type_mask`` uses it; MAV_FRAME_LOCAL_NED)."""

    vx_ned_m_s: float
    vy_ned_m_s: float
    vz_ned_m_s: float
    yaw_rate_ned_rad_s: float
    type_mask: int = TYPE_MASK_VELOCITY_YAW_RATE
    coordinate_frame: int = MAV_FRAME_LOCAL_NED
    course_cmd_enu_rad: float = math.nan  # the course the velocity vector points along (ENU)
    afx_ned_m_s2: float = 0.0  # acceleration feed-forward north (sent when type_mask uses it)
    afy_ned_m_s2: float = 0.0  # acceleration feed-forward east

    @property
    def is_hold(self) -> bool:
        return self.vx_ned_m_s == 0.0 and self.vy_ned_m_s == 0.0 and self.yaw_rate_ned_rad_s == 0.0


@dataclass(frozen=True)
class AttitudeSetpoint:
    """Fields of one SET_ATTITUDE_TARGET (fixed wing): quaternion w, x, y, z (NED body) + thrust."""

    q: tuple[float, float, float, float]
    roll_ned_rad: float
    thrust: float
    type_mask: int = TYPE_MASK_ATTITUDE_THRUST
    pitch_ned_rad: float = 0.0


def velocity_setpoint(
    a_cmd_m_s2: float,
    course_enu_rad: float,
    speed_m_s: float,
    dt_s: float,
    alt_m: float,
    hold: AltitudeHold,
    drift_ned_m_s: tuple[float, float] = (0.0, 0.0),
    accel_ff_max_m_s2: float = 0.0,
    accel_ff_share: float = 1.0,
    speed_boost_m_s: float = 0.0,
    tail_comp_ned_m_s: tuple[float, float] = (0.0, 0.0),
) -> VelocitySetpoint:
    """Velocity + yaw-rate setpoint for a lateral acceleration command.

    Parameters
    ----------
    a_cmd_m_s2 : lateral acceleration, ENU, positive = turn left.
    course_enu_rad : current course (direction of the ground velocity), ENU.
    speed_m_s : commanded ground speed V (the mission speed), > 0.
    dt_s : tick period; the velocity vector points along the course reached one tick ahead.
    alt_m : current altitude (up, metres above the local origin).
    hold : the altitude hold.
    drift_ned_m_s : the velocity estimate's drift (north, east; :mod:`companion.guidance.drift`),
        subtracted from the horizontal velocity so that the vehicle, which flies the setpoint plus
        the drift, moves along the commanded course at the commanded speed.
    accel_ff_max_m_s2 : > 0: send the command, limited to this, as the acceleration target along
        the left normal of the commanded course (mask ``TYPE_MASK_VELOCITY_ACCEL_YAW_RATE``);
        0: no acceleration target (mask ``TYPE_MASK_VELOCITY_YAW_RATE``).
    accel_ff_share : the share of the command sent as the acceleration target, in [0, 1]: 1 for a
        vehicle flying at ``speed_m_s``; its ground speed over ``speed_m_s`` while it gathers speed
        (``companion.loop.tick``). The setpoint turns at ``omega = a_cmd / V``; a vehicle moving at
        ``v`` turns with it on ``v * omega``, and an autopilot that adds the target to its own
        trajectory (ArduCopter) pushes a hovering copter sideways with the rest.
    speed_boost_m_s : added to the setpoint's length, not to the ``V`` it turns with (the ground-
        speed hold, :mod:`companion.guidance.speed_hold`); the length stays >= 0.
    tail_comp_ned_m_s : added to the horizontal velocity (north, east) after all the rest: the
        velocity loop's slow tail compensated (:mod:`companion.guidance.tail_comp`).

    Examples
    --------
    Flying east at 5 m/s, no turn: velocity is pure east (NED y), yaw rate zero.

    >>> sp = velocity_setpoint(0.0, 0.0, 5.0, 0.02, 10.0, AltitudeHold(10.0))
    >>> round(sp.vx_ned_m_s, 9), round(sp.vy_ned_m_s, 9), sp.yaw_rate_ned_rad_s
    (0.0, 5.0, -0.0)

    Turning left at 3 m/s^2 while flying east, feed-forward limited to 2.5: it points north.

    >>> sp = velocity_setpoint(3.0, 0.0, 5.0, 0.0, 10.0, AltitudeHold(10.0), accel_ff_max_m_s2=2.5)
    >>> round(sp.afx_ned_m_s2, 9), round(sp.afy_ned_m_s2, 9), sp.type_mask == TYPE_MASK_VELOCITY_ACCEL_YAW_RATE
    (2.5, -0.0, True)
    """
    if not (speed_m_s > 0 and math.isfinite(speed_m_s)):
        raise ValueError(f"speed_m_s: expected a finite number > 0, got {speed_m_s!r}")
    if not math.isfinite(speed_boost_m_s):
        raise ValueError(f"speed_boost_m_s: expected a finite number, got {speed_boost_m_s!r}")
    omega_enu_rad_s = a_cmd_m_s2 / speed_m_s
    course_cmd = frames.wrap_pi(course_enu_rad + omega_enu_rad_s * dt_s)
    length = max(0.0, speed_m_s + speed_boost_m_s)
    ve = length * math.cos(course_cmd)
    vn = length * math.sin(course_cmd)
    vx_ned, vy_ned, _ = frames.vel_ned_from_enu(ve, vn, 0.0)
    return VelocitySetpoint(
        vx_ned_m_s=vx_ned - drift_ned_m_s[0] + tail_comp_ned_m_s[0],
        vy_ned_m_s=vy_ned - drift_ned_m_s[1] + tail_comp_ned_m_s[1],
        vz_ned_m_s=hold.vz_ned_m_s(alt_m),
        yaw_rate_ned_rad_s=frames.yaw_rate_ned_from_enu(omega_enu_rad_s),
        course_cmd_enu_rad=course_cmd,
        **_feed_forward(a_cmd_m_s2 * min(1.0, max(0.0, accel_ff_share)), course_cmd, accel_ff_max_m_s2),
    )


def _feed_forward(a_cmd_m_s2: float, course_cmd_enu_rad: float, a_max_m_s2: float) -> dict:
    """The acceleration target's fields for :class:`VelocitySetpoint` (none for ``a_max <= 0``):
    the command limited to ``a_max`` along the left normal ``(-sin c, cos c)`` (ENU) of the
    commanded course ``c``, in NED."""
    if not a_max_m_s2 > 0.0:
        return {}
    a = max(-a_max_m_s2, min(a_max_m_s2, a_cmd_m_s2))
    north, east = a * math.cos(course_cmd_enu_rad), -a * math.sin(course_cmd_enu_rad)
    return {"afx_ned_m_s2": north, "afy_ned_m_s2": east, "type_mask": TYPE_MASK_VELOCITY_ACCEL_YAW_RATE}


def hold_setpoint(alt_m: float, hold: AltitudeHold | None) -> VelocitySetpoint:
    """The hold: zero horizontal velocity and yaw rate.

    ``vz`` holds the altitude when ``hold`` is given, and is 0 otherwise (stale or no data).
    """
    vz = hold.vz_ned_m_s(alt_m) if hold is not None else 0.0
    return VelocitySetpoint(0.0, 0.0, vz, 0.0)


POSITION_HOLD_GAIN_1_S = 1.0  # horizontal position hold: velocity per metre off the anchor (PX4's MPC_XY_P is 0.95)
POSITION_HOLD_MAX_M_S = 1.0  # and at most this fast back to it


def position_hold_setpoint(north_m: float, east_m: float, anchor_north_m: float, anchor_east_m: float,
                           alt_m: float, hold: AltitudeHold | None,
                           gain_1_s: float = POSITION_HOLD_GAIN_1_S,
                           max_speed_m_s: float = POSITION_HOLD_MAX_M_S) -> VelocitySetpoint:
    """A hold that keeps the horizontal position: velocity ``-gain (p - anchor)`` (NED), at most
    ``max_speed_m_s``, zero yaw rate, ``vz`` as :func:`hold_setpoint`.

    An autopilot's velocity loop holds its velocity *estimate* at zero, and the vehicle drifts by
    whatever that estimate misses; this closes the loop on the reported position instead. A
    non-finite position gives the plain hold (zero velocity), never a NaN.

    >>> sp = position_hold_setpoint(2.0, -0.5, 0.0, 0.0, 10.0, None)
    >>> round(sp.vx_ned_m_s, 6), round(sp.vy_ned_m_s, 6), sp.vz_ned_m_s
    (-0.970143, 0.242536, 0.0)
    """
    plain = hold_setpoint(alt_m, hold)
    dn, de = north_m - anchor_north_m, east_m - anchor_east_m
    if not (math.isfinite(dn) and math.isfinite(de)):
        return plain
    vn, ve = -gain_1_s * dn, -gain_1_s * de
    speed = math.hypot(vn, ve)
    if speed > max_speed_m_s:
        vn, ve = vn * max_speed_m_s / speed, ve * max_speed_m_s / speed
    return replace(plain, vx_ned_m_s=vn, vy_ned_m_s=ve)


FACE_GAIN_1_S = 1.5  # turning to face a course: yaw rate per radian of yaw error
FACE_MAX_RATE_RAD_S = math.radians(45.0)  # and at most this (PX4's MPC_YAWRAUTO_MAX default)


def facing_yaw_rate_ned_rad_s(yaw_ned_rad: float, course_enu_rad: float, gain_1_s: float = FACE_GAIN_1_S,
                              max_rate_rad_s: float = FACE_MAX_RATE_RAD_S) -> float:
    """Yaw rate (NED, positive clockwise) that turns a nose at ``yaw_ned_rad`` to face the ENU
    course ``course_enu_rad`` the short way: ``gain`` times the error, at most ``max_rate_rad_s``;
    0 for a non-finite yaw.

    >>> round(facing_yaw_rate_ned_rad_s(0.0, 0.0), 6)  # nose north, to face east: clockwise, capped
    0.785398
    >>> round(facing_yaw_rate_ned_rad_s(math.radians(80.0), 0.0), 6)  # 10 deg short of east
    0.261799
    """
    if not (math.isfinite(yaw_ned_rad) and math.isfinite(course_enu_rad)):
        return 0.0
    err = frames.angle_diff_rad(frames.yaw_ned_from_enu(course_enu_rad), yaw_ned_rad)
    return max(-max_rate_rad_s, min(max_rate_rad_s, gain_1_s * err))


def bank_angle_rad(a_cmd_m_s2: float, max_bank_deg: float) -> float:
    """Coordinated-turn bank ``atan(a / g)`` (ENU sense: left turn positive), limited."""
    limit = math.radians(max_bank_deg)
    phi = math.atan(a_cmd_m_s2 / G_M_S2)
    return max(-limit, min(limit, phi))


def quaternion_from_euler_ned(roll_rad: float, pitch_rad: float, yaw_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of the aerospace 3-2-1 (yaw, pitch, roll) rotation, NED body."""
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def attitude_setpoint(
    a_cmd_m_s2: float,
    course_enu_rad: float,
    max_bank_deg: float,
    thrust: float = 0.5,
    pitch_rad: float = 0.0,
) -> AttitudeSetpoint:
    """Fixed-wing setpoint: roll = -bank (NED, right wing down positive), pitch (0: level; an
    altitude profile gives the flight-path angle ``atan(climb / V)``, nose up positive), yaw = course.

    >>> sp = attitude_setpoint(9.80665, math.pi / 2, 60.0)   # 1 g left turn, flying north
    >>> round(math.degrees(sp.roll_ned_rad), 6)
    -45.0
    """
    roll_ned = -bank_angle_rad(a_cmd_m_s2, max_bank_deg)
    yaw_ned = frames.yaw_ned_from_enu(course_enu_rad)
    return AttitudeSetpoint(
        q=quaternion_from_euler_ned(roll_ned, pitch_rad, yaw_ned),
        roll_ned_rad=roll_ned,
        thrust=float(min(1.0, max(0.0, thrust))),
        pitch_ned_rad=pitch_rad,
    )
