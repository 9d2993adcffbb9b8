"""Point-mass vehicle model with a deliberately non-ideal inner loop.

The mock autopilot's flight logic (``sitl_mock.flight``) turns modes and setpoints into inner-loop
commands (a velocity in NED for copters and rovers; a bank angle, airspeed and climb rate for
planes); this module integrates the vehicle's response at a fixed physics step.

Model
-----
Copter
    The velocity follows the commanded velocity through a first-order lag of time constant
    ``tau_vel_s`` (exact discretisation, so a step reaches 63.2 % after one time constant), with
    the horizontal and the vertical acceleration each limited to ``a_max_m_s2``. The yaw rate follows
    the commanded yaw rate through a first-order lag ``tau_yaw_rate_s``; the command is clipped to
    ``yaw_rate_max_rad_s``. Optionally (docs/vehicle_model.md, the model ``companion identify``
    fits): every command acts ``delay_s`` late, the horizontal speed command shrinks in turns by
    ``speed_sag_s`` times the lateral acceleration, and the horizontal acceleration follows the one
    the velocity loop asks for through a second lag ``accel_lag_s``. A multicopter's velocity
    controller holds ground velocity, so a steady wind has no lasting effect on the track and is
    not modelled for copters. What is modelled is the autopilot's **velocity-estimate bias**
    (``vel_bias_m_s``, ``vel_bias_tc_s``): the velocity loop holds its estimate, which is off by a
    slowly varying bias (a Gauss-Markov process on each horizontal axis) and by a constant offset
    drawn once (``vel_offset_m_s``), so while airborne the copter flies the reported velocity plus
    that bias and offset, and its reported position (which the
    estimator ties to GPS) moves away from the integral of the reported velocity, as PX4's does
    in SIH (docs/vehicle_model.md). The reported position may also lag the vehicle's
    (``pos_delay_s``): ArduCopter SITL's estimator reports a position about 25 ms old beside a
    velocity about 10 ms old, so its position leaves the integral of its velocity by the velocity
    times the difference in the turns (docs/vehicle_model.md).
Plane
    Constant airspeed (never below ``airspeed_min_m_s``), heading turning at ``g tan(roll) / V``
    (coordinated turn, lateral acceleration ``g tan(roll)``), the roll angle following the command
    through a first-order lag ``tau_roll_s`` with ``|roll| <= roll_max_rad``. The ground velocity
    is the air velocity plus the steady wind.
Rover
    As the copter in the horizontal plane, always on the ground; the body points along the
    ground track while it moves faster than 0.3 m/s.

All state is plain floats so that one step costs a few microseconds; the model reads no clock
and owns its random generator (seeded), so the same commands give the same track.

Frames: positions and velocities are NED (x north, y east, z down) metres and m/s relative to the
local origin; yaw is clockwise from north in radians, wrapped to (-pi, pi].
"""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, field

GRAVITY_M_S2 = 9.80665
VEHICLE_KINDS = ("copter", "plane", "rover")
# Below this ground speed a rover turns on the spot from yaw-rate commands instead of following its track.
ROVER_TRACK_SPEED_M_S = 0.3
#: Time constant of the low-pass that turns ``|d a / dt|`` into the manoeuvre jerk that sizes the
#: velocity bias's kicks (s); ``companion identify`` measures the jerk with the same constant.
JERK_TC_S = 0.5
JERK_SAMPLE_S = 0.02  # the velocity's sampling for the jerk: the 50 Hz a log holds
JERK_SMOOTH_HALF = 7  # half-window of the velocity's smoother, in samples (0.3 s at 50 Hz)


def _jerk_kernel(m: int) -> tuple[float, ...]:
    """Weights of ``2 m + 3`` velocity samples (oldest first) giving the second difference of the
    velocity smoothed by a quadratic Savitzky-Golay filter of ``2 m + 1`` samples (divide by the
    step squared for the jerk): ``vs[c + 1] - 2 vs[c] + vs[c - 1]``."""
    norm = (2 * m - 1) * (2 * m + 1) * (2 * m + 3)
    h = {i: (3 * (3 * m * m + 3 * m - 1) - 15 * i * i) / norm for i in range(-m, m + 1)}
    return tuple(h.get(i - 1, 0.0) - 2.0 * h.get(i, 0.0) + h.get(i + 1, 0.0) for i in range(-m - 1, m + 2))


JERK_KERNEL = _jerk_kernel(JERK_SMOOTH_HALF)


class ManoeuvreJerk:
    """The manoeuvre jerk (m/s^3) as ``companion identify`` measures it from a log: the horizontal
    velocity sampled every :data:`JERK_SAMPLE_S`, smoothed (quadratic Savitzky-Golay over 0.3 s),
    differenced twice, its norm through a first-order low-pass of :data:`JERK_TC_S`. Causal, so
    it runs 0.16 s behind the log's zero-phase smoother; the low-pass is slower than that."""

    def __init__(self) -> None:
        self._samples: deque = deque(maxlen=len(JERK_KERNEL))
        self._since_s = JERK_SAMPLE_S  # sample at the first update
        self.value_m_s3 = 0.0

    def update(self, dt_s: float, vel_n_m_s: float, vel_e_m_s: float) -> float:
        """Advance by ``dt_s`` with the velocity now; the jerk."""
        self._since_s += dt_s
        if self._since_s < JERK_SAMPLE_S - 1e-9:
            return self.value_m_s3
        self._since_s -= JERK_SAMPLE_S
        self._samples.append((vel_n_m_s, vel_e_m_s))
        if len(self._samples) == len(JERK_KERNEL):
            jn = sum(k * v[0] for k, v in zip(JERK_KERNEL, self._samples))
            je = sum(k * v[1] for k, v in zip(JERK_KERNEL, self._samples))
            raw = math.hypot(jn, je) / (JERK_SAMPLE_S * JERK_SAMPLE_S)
            self.value_m_s3 += (raw - self.value_m_s3) * (1.0 - math.exp(-JERK_SAMPLE_S / JERK_TC_S))
        return self.value_m_s3


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle to the interval (-pi, pi]."""
    wrapped = math.fmod(angle_rad + math.pi, 2.0 * math.pi)
    if wrapped <= 0.0:
        wrapped += 2.0 * math.pi
    return wrapped - math.pi


def _lag_gain(dt_s: float, tau_s: float) -> float:
    """Fraction of the remaining error a first-order lag removes in one step (exact discretisation)."""
    return 1.0 if tau_s <= 0.0 else 1.0 - math.exp(-dt_s / tau_s)


def _lagged(state_ne: tuple[float, float], target_ne: tuple[float, float], gain: float) -> tuple[float, float]:
    """One step of a first-order lag on a north-east pair, ``gain`` from :func:`_lag_gain`."""
    return (state_ne[0] + gain * (target_ne[0] - state_ne[0]), state_ne[1] + gain * (target_ne[1] - state_ne[1]))


@dataclass(frozen=True)
class VehicleParams:
    """Physical and inner-loop parameters of the mock vehicle.

    Parameters
    ----------
    kind : str
        ``"copter"``, ``"plane"`` or ``"rover"``.
    tau_vel_s : float
        Time constant of the first-order velocity response (copter, rover; plane climb rate).
    tau_yaw_rate_s : float
        Time constant of the yaw-rate response (copter, rover).
    a_max_m_s2 : float
        Acceleration limit, horizontal and vertical separately.
    delay_s : float
        Copter, rover: dead time between a command and the inner loop acting on it.
    accel_lag_s : float
        Copter, rover: time constant of a second lag on the horizontal acceleration (0: none).
    tail_share, tail_tc_s : float
        Copter, rover: the slow tail of the velocity response: the loop asks for
        ``(e - tail_share * f) / tau_vel_s``, ``f`` the horizontal velocity error ``e`` through a
        low-pass of time constant ``tail_tc_s`` (0 <= share <= 0.95; 0: none).
    accel_ff_gain, accel_ff_lag_s : float
        Copter, rover: the acceleration feed-forward, after the command's dead time, times this gain
        through a first-order lag of this time constant, joins what the velocity loop asks for
        *before* the slow tail, which takes back its share of it too (PX4's; 1 and 0: added as sent).
    speed_sag_s : float
        Copter, rover: the horizontal speed command shrinks by this times the lateral acceleration
        (m/s per m/s^2), as real position controllers slow down in turns.
    yaw_rate_max_rad_s : float
        Largest yaw rate the inner loop will command.
    v_max_m_s : float
        Speed limit the flight logic applies to position control (copter, rover).
    climb_rate_m_s, descent_rate_m_s : float
        Vertical speeds used by takeoff, landing and altitude holds.
    airspeed_cruise_m_s, airspeed_min_m_s, airspeed_max_m_s : float
        Plane airspeed at start, and the band ``DO_CHANGE_SPEED`` may move it within.
    tau_roll_s, roll_max_rad : float
        Plane roll response time constant and bank-angle limit.
    wind_ned_m_s : tuple of float
        Steady horizontal wind (north, east) the plane drifts with.
    pos_noise_m : float
        Standard deviation of the Gaussian noise on each reported position axis.
    vel_bias_m_s, vel_bias_tc_s : float
        Copter: the velocity estimate's bias, a first-order Gauss-Markov process on each horizontal
        axis with this standard deviation (m/s, 0: none) and correlation time (s, > 0); airborne, the
        vehicle moves at the reported velocity plus the bias.
    vel_bias_jerk_s2, vel_bias_jerk_max_m_s3 : float
        Copter: the bias wanders more while the vehicle manoeuvres. Each step's kick is sized for
        the level ``sqrt(vel_bias_m_s^2 + (vel_bias_jerk_s2 * min(j, vel_bias_jerk_max_m_s3))^2)``,
        ``j`` the manoeuvre jerk: ``|d a / dt|`` of the horizontal acceleration, low-passed over
        :data:`JERK_TC_S` (s^2 and m/s^3; 0: a bias of one level; docs/vehicle_model.md).
    vel_bias_smooth_s : float
        Copter: the vehicle flies that bias through a first-order low-pass of this time constant
        (s, 0: as it is): a bias that wanders as smoothly as ArduCopter SITL's does within a second
        or two (docs/vehicle_model.md).
    vel_bias_loop_s : float
        Copter: the vehicle's velocity loop follows that (smoothed) bias only through a first-order
        lag of this time constant, and the reported velocity carries the rest with the opposite
        sign: an estimate that jitters quicker than the loop while the vehicle does not (s, 0: the
        whole bias flown, the reported velocity smooth; PX4 SIH, docs/real_firmware.md).
    vel_offset_m_s : float
        Copter: beside the bias, the velocity estimate misses a constant offset, drawn once (seeded)
        on each horizontal axis with this standard deviation (m/s, 0: none) and flown as the bias is.
    pos_delay_s : float
        How old the reported (estimated) position is behind the reported velocity (s, 0: none).
    seed : int
        Seed of the noise generators (position noise, velocity bias and offset).
    """

    kind: str = "copter"
    tau_vel_s: float = 0.3
    tau_yaw_rate_s: float = 0.3
    a_max_m_s2: float = 5.0
    delay_s: float = 0.0
    accel_lag_s: float = 0.0
    tail_share: float = 0.0
    tail_tc_s: float = 1.0
    accel_ff_gain: float = 1.0
    accel_ff_lag_s: float = 0.0
    speed_sag_s: float = 0.0
    yaw_rate_max_rad_s: float = math.radians(90.0)
    v_max_m_s: float = 12.0
    climb_rate_m_s: float = 2.5
    descent_rate_m_s: float = 1.0
    airspeed_cruise_m_s: float = 15.0
    airspeed_min_m_s: float = 10.0
    airspeed_max_m_s: float = 25.0
    tau_roll_s: float = 0.5
    roll_max_rad: float = math.radians(45.0)
    wind_ned_m_s: tuple[float, float] = (0.0, 0.0)
    pos_noise_m: float = 0.0
    vel_bias_m_s: float = 0.0
    vel_bias_tc_s: float = 3.0
    vel_bias_jerk_s2: float = 0.0
    vel_bias_jerk_max_m_s3: float = 1.0
    vel_bias_smooth_s: float = 0.0
    vel_bias_loop_s: float = 0.0
    vel_offset_m_s: float = 0.0
    pos_delay_s: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.kind not in VEHICLE_KINDS:
            raise ValueError(f"vehicle kind: expected one of {', '.join(VEHICLE_KINDS)}, got {self.kind!r}")
        positive = ("a_max_m_s2", "yaw_rate_max_rad_s", "v_max_m_s", "climb_rate_m_s", "descent_rate_m_s",
                    "airspeed_min_m_s", "roll_max_rad", "tail_tc_s", "vel_bias_tc_s", "vel_bias_jerk_max_m_s3")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: expected a positive finite number, got {value!r}")
        for name in ("tau_vel_s", "tau_yaw_rate_s", "tau_roll_s", "pos_noise_m", "delay_s", "accel_lag_s",
                     "speed_sag_s", "vel_bias_m_s", "vel_bias_jerk_s2", "vel_bias_smooth_s", "vel_bias_loop_s",
                     "vel_offset_m_s", "pos_delay_s", "accel_ff_gain", "accel_ff_lag_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
        if not 0.0 <= self.tail_share <= 0.95:
            raise ValueError(f"tail_share: expected a number in [0, 0.95], got {self.tail_share!r}")
        if not self.airspeed_min_m_s <= self.airspeed_cruise_m_s <= self.airspeed_max_m_s:
            raise ValueError("airspeed: expected airspeed_min_m_s <= airspeed_cruise_m_s <= airspeed_max_m_s")
        if self.roll_max_rad >= math.radians(80.0):
            raise ValueError(f"roll_max_rad: expected below 80 deg, got {math.degrees(self.roll_max_rad):.1f} deg")
        if len(self.wind_ned_m_s) != 2 or not all(math.isfinite(w) for w in self.wind_ned_m_s):
            raise ValueError(f"wind_ned_m_s: expected two finite numbers, got {self.wind_ned_m_s!r}")


@dataclass
class VehicleState:
    """Mutable true state of the vehicle (NED, metres, seconds, radians)."""

    t_s: float = 0.0
    pos_ned_m: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    vel_ned_m_s: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    acc_ned_m_s2: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    yaw_rad: float = 0.0
    yaw_rate_rad_s: float = 0.0
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    airspeed_m_s: float = 0.0
    on_ground: bool = True


class VehicleModel:
    """Integrates one vehicle at a fixed step from inner-loop commands.

    Parameters
    ----------
    params : VehicleParams
        Physical parameters.
    start_ned_m : tuple of float
        Initial (north, east, down) position; ``down`` < 0 is above the ground (the ground is z = 0).
    start_yaw_rad : float
        Initial heading, clockwise from north.
    airborne : bool
        Start in the air (a plane then starts at cruise airspeed).

    Examples
    --------
    >>> model = VehicleModel(VehicleParams(kind="copter"), (0.0, 0.0, -10.0), 0.0, airborne=True)
    >>> for _ in range(400):
    ...     model.step_multirotor(0.0025, (1.0, 0.0, 0.0), 0.0)
    >>> round(model.state.vel_ned_m_s[0], 3)  # 1 s of a 0.3 s velocity lag: 1 - exp(-1 / 0.3)
    0.964
    """

    def __init__(self, params: VehicleParams, start_ned_m: tuple[float, float, float], start_yaw_rad: float,
                 airborne: bool) -> None:
        self.params = params
        self.state = VehicleState(pos_ned_m=list(start_ned_m), yaw_rad=wrap_pi(start_yaw_rad), on_ground=not airborne)
        if params.kind == "rover":
            self.state.pos_ned_m[2] = 0.0
            self.state.on_ground = True
        if params.kind == "plane" and airborne:
            self.state.airspeed_m_s = params.airspeed_cruise_m_s
            self._set_plane_ground_velocity(0.0)
        self._rng = random.Random(params.seed)
        self._bias_rng = random.Random(f"vel-bias:{params.seed}")  # its own stream: the noise's stays as it was
        self._bias_ne_m_s = (0.0, 0.0)  # the velocity estimate's bias (what the vehicle flies beyond it)
        self._smooth_bias_ne_m_s = (0.0, 0.0)  # that bias through its low-pass (vel_bias_smooth_s)
        self._flown_bias_ne_m_s = (0.0, 0.0)  # what of it the velocity loop follows (vel_bias_loop_s)
        self._reported_rest_ne_m_s = (0.0, 0.0)  # what it does not, which the reported velocity shows
        self._jerk = ManoeuvreJerk()  # the manoeuvre jerk that sizes the bias's kicks
        offset_rng = random.Random(f"vel-offset:{params.seed}")  # its own stream: the bias's stays as it was
        self._offset_ne_m_s = (offset_rng.gauss(0.0, params.vel_offset_m_s), offset_rng.gauss(0.0, params.vel_offset_m_s))
        self._cmd_queue: deque = deque()
        self._tail_ne_m_s = (0.0, 0.0)  # the low-passed horizontal velocity error of the slow tail
        self._ff_ne_m_s2 = (0.0, 0.0)  # the acceleration feed-forward through its lag
        self._noise_ned_m = (0.0, 0.0, 0.0)
        self._pos_history: deque = deque()  # (t, position) over the last pos_delay_s, oldest first

    def _delayed(self, vel_cmd_ned_m_s, yaw_rate_cmd_rad_s, acc_ff_ned_m_s2=(0.0, 0.0, 0.0)):
        """The command (velocity, yaw rate, acceleration feed-forward) as the vehicle sees it
        ``delay_s`` after it was given (dead time)."""
        if self.params.delay_s <= 0.0:
            return vel_cmd_ned_m_s, yaw_rate_cmd_rad_s, acc_ff_ned_m_s2
        queue = self._cmd_queue
        queue.append((self.state.t_s, tuple(vel_cmd_ned_m_s), yaw_rate_cmd_rad_s, tuple(acc_ff_ned_m_s2)))
        due = self.state.t_s - self.params.delay_s + 1e-9
        while len(queue) > 1 and queue[1][0] <= due:
            queue.popleft()
        if queue[0][0] > due:  # no command old enough yet: carry on as now
            return tuple(self.state.vel_ned_m_s), self.state.yaw_rate_rad_s, (0.0, 0.0, 0.0)
        _, vel, yaw_rate, acc_ff = queue[0]
        return vel, yaw_rate, acc_ff

    def _draw_noise(self) -> None:
        """Draw this step's position noise, so a report depends on the step, not on how often it is read."""
        sigma = self.params.pos_noise_m
        if sigma > 0.0:
            g = self._rng.gauss
            self._noise_ned_m = (g(0.0, sigma), g(0.0, sigma), g(0.0, sigma))

    # ------------------------------------------------------------------ copter and rover
    def step_multirotor(self, dt_s: float, vel_cmd_ned_m_s: tuple[float, float, float], yaw_rate_cmd_rad_s: float,
                        acc_ff_ned_m_s2: tuple[float, float, float] = (0.0, 0.0, 0.0), grounded: bool = False,
                        acc_ne_m_s2: tuple[float, float] | None = None,
                        thrust_ne_m_s2: tuple[float, float] | None = None) -> None:
        """Advance a copter or rover by one step.

        Parameters
        ----------
        dt_s : float
            Physics step.
        vel_cmd_ned_m_s : tuple of float
            Commanded velocity (NED); a rover ignores the vertical component.
        yaw_rate_cmd_rad_s : float
            Commanded yaw rate (clipped to the limit).
        acc_ff_ned_m_s2 : tuple of float
            Acceleration feed-forward added to the lag response (then limited), after the same
            dead time as the command.
        grounded : bool
            Motors off (disarmed): the vehicle stays where it is if it is on the ground.
        acc_ne_m_s2 : tuple of float, optional
            The horizontal acceleration to fly, as an autopilot's own position controller produced
            it (``sitl_mock.posctl``): the horizontal velocity command and this model's horizontal
            response (lag, limit, sag, tail, second lag) are then not used.
        thrust_ne_m_s2 : tuple of float, optional
            The horizontal acceleration the thrust gives before the drag takes its share (the
            lean the attitude shows); default: the acceleration flown.
        """
        p = self.params
        s = self.state
        if grounded and s.on_ground:
            self._stay_on_ground(dt_s)
            return
        vel_cmd_ned_m_s, yaw_rate_cmd_rad_s, acc_ff_ned_m_s2 = self._delayed(vel_cmd_ned_m_s, yaw_rate_cmd_rad_s,
                                                                             acc_ff_ned_m_s2)
        k = _lag_gain(dt_s, p.tau_vel_s)
        v = s.vel_ned_m_s
        dv_max = p.a_max_m_s2 * dt_s
        if acc_ne_m_s2 is not None:  # the autopilot's own position controller chose it
            dvx, dvy = acc_ne_m_s2[0] * dt_s, acc_ne_m_s2[1] * dt_s
        else:
            dvx, dvy = self._horizontal_response(dt_s, vel_cmd_ned_m_s, acc_ff_ned_m_s2, k, dv_max)
        dvz = 0.0 if p.kind == "rover" else (vel_cmd_ned_m_s[2] - v[2]) * k + acc_ff_ned_m_s2[2] * dt_s
        dvz = max(-dv_max, min(dv_max, dvz))
        s.acc_ned_m_s2 = [dvx / dt_s, dvy / dt_s, dvz / dt_s]
        v_new = [v[0] + dvx, v[1] + dvy, 0.0 if p.kind == "rover" else v[2] + dvz]
        self._move(v, v_new, dt_s)
        if (p.vel_bias_m_s > 0.0 or p.vel_bias_jerk_s2 > 0.0 or p.vel_offset_m_s > 0.0) and p.kind == "copter":
            self._step_bias(dt_s)
        s.vel_ned_m_s = v_new
        if p.kind == "rover":
            s.pos_ned_m[2] = 0.0
        else:
            self._ground_contact(liftoff_m=0.05)
        if s.on_ground and p.kind == "copter":
            # A copter sitting on the ground does not slide about.
            s.vel_ned_m_s[0] = s.vel_ned_m_s[1] = 0.0
        r_cmd = max(-p.yaw_rate_max_rad_s, min(p.yaw_rate_max_rad_s, yaw_rate_cmd_rad_s))
        if p.kind == "rover" and math.hypot(v_new[0], v_new[1]) > ROVER_TRACK_SPEED_M_S:
            course = math.atan2(v_new[1], v_new[0])
            s.yaw_rate_rad_s = wrap_pi(course - s.yaw_rad) / dt_s if dt_s > 0 else 0.0
            s.yaw_rad = course
        else:
            s.yaw_rate_rad_s += (r_cmd - s.yaw_rate_rad_s) * _lag_gain(dt_s, p.tau_yaw_rate_s)
            s.yaw_rad = wrap_pi(s.yaw_rad + s.yaw_rate_rad_s * dt_s)
        # Attitude of a multicopter follows from the acceleration its thrust gives.
        if p.kind == "copter":
            tn, te = thrust_ne_m_s2 if thrust_ne_m_s2 is not None else s.acc_ned_m_s2[:2]
            cy, sy = math.cos(s.yaw_rad), math.sin(s.yaw_rad)
            a_fwd = cy * tn + sy * te
            a_right = -sy * tn + cy * te
            s.pitch_rad = -math.atan2(a_fwd, GRAVITY_M_S2)
            s.roll_rad = math.atan2(a_right, GRAVITY_M_S2)
        s.airspeed_m_s = math.hypot(v_new[0], v_new[1])
        s.t_s += dt_s
        self._record_position()
        self._draw_noise()

    def _horizontal_response(self, dt_s: float, vel_cmd_ned_m_s, acc_ff_ned_m_s2, k: float,
                             dv_max: float) -> tuple[float, float]:
        """This step's horizontal velocity change: speed sag, the feed-forward, slow tail, the lag
        ``k``, the limit ``dv_max`` and the second lag (the model's own velocity loop; module docstring)."""
        p = self.params
        s = self.state
        v = s.vel_ned_m_s
        cx, cy = vel_cmd_ned_m_s[0], vel_cmd_ned_m_s[1]
        if p.speed_sag_s > 0.0:
            # Speed sag: the horizontal command shrinks by speed_sag_s x |lateral acceleration|.
            c_h = math.hypot(cx, cy)
            speed = math.hypot(v[0], v[1])
            if c_h > 1e-9 and speed > 1e-9:
                a_lat = abs(v[0] * s.acc_ned_m_s2[1] - v[1] * s.acc_ned_m_s2[0]) / speed
                scale = max(0.0, 1.0 - p.speed_sag_s * a_lat / c_h)
                cx, cy = cx * scale, cy * scale
        ex, ey = cx - v[0], cy - v[1]
        # The feed-forward (gain, lag) joins the demand as the velocity error that would ask for it.
        ax_ff, ay_ff = self._ff_ne_m_s2
        kff = _lag_gain(dt_s, p.accel_ff_lag_s)
        ax_ff += (p.accel_ff_gain * acc_ff_ned_m_s2[0] - ax_ff) * kff
        ay_ff += (p.accel_ff_gain * acc_ff_ned_m_s2[1] - ay_ff) * kff
        self._ff_ne_m_s2 = (ax_ff, ay_ff)
        if k > 0.0:  # (a zero step changes nothing)
            ex, ey = ex + ax_ff * dt_s / k, ey + ay_ff * dt_s / k
        if p.tail_share > 0.0:
            # Slow tail: a low-passed share of the error is taken back from what the loop asks for.
            fx, fy = self._tail_ne_m_s
            kf = _lag_gain(dt_s, p.tail_tc_s)
            self._tail_ne_m_s = (fx + (ex - fx) * kf, fy + (ey - fy) * kf)
            ex, ey = ex - p.tail_share * fx, ey - p.tail_share * fy
        dvx = ex * k
        dvy = ey * k
        dv_h = math.hypot(dvx, dvy)
        if dv_h > dv_max:
            dvx *= dv_max / dv_h
            dvy *= dv_max / dv_h
        if p.accel_lag_s > 0.0:
            # Second order: the horizontal acceleration follows the one asked for through a lag.
            ka = _lag_gain(dt_s, p.accel_lag_s)
            ax, ay = s.acc_ned_m_s2[0], s.acc_ned_m_s2[1]
            dvx = (ax + (dvx / dt_s - ax) * ka) * dt_s
            dvy = (ay + (dvy / dt_s - ay) * ka) * dt_s
        return dvx, dvy

    # ------------------------------------------------------------------ plane
    def step_plane(self, dt_s: float, roll_cmd_rad: float, airspeed_cmd_m_s: float, climb_cmd_m_s: float,
                   grounded: bool = False) -> None:
        """Advance a plane by one step.

        Parameters
        ----------
        dt_s : float
            Physics step.
        roll_cmd_rad : float
            Commanded bank angle, positive right wing down (turns right, clockwise seen from above).
        airspeed_cmd_m_s : float
            Commanded airspeed; clipped to the airspeed band.
        climb_cmd_m_s : float
            Commanded climb rate (positive up).
        grounded : bool
            Engine off on the ground: the plane stays where it is.
        """
        p = self.params
        s = self.state
        if grounded and s.on_ground:
            s.airspeed_m_s = 0.0
            s.roll_rad = 0.0
            self._stay_on_ground(dt_s)
            return
        v_old = list(s.vel_ned_m_s)
        roll_cmd = max(-p.roll_max_rad, min(p.roll_max_rad, roll_cmd_rad))
        s.roll_rad += (roll_cmd - s.roll_rad) * _lag_gain(dt_s, p.tau_roll_s)
        target_as = max(p.airspeed_min_m_s, min(p.airspeed_max_m_s, airspeed_cmd_m_s))
        d_as = max(-p.a_max_m_s2 * dt_s, min(p.a_max_m_s2 * dt_s, target_as - s.airspeed_m_s))
        s.airspeed_m_s = max(s.airspeed_m_s + d_as, 0.0)
        if s.on_ground and s.airspeed_m_s < p.airspeed_min_m_s:
            # Take-off roll: no turning and no climbing below flying speed.
            s.roll_rad = 0.0
            s.yaw_rate_rad_s = 0.0
            climb_cmd_m_s = 0.0
        else:
            s.yaw_rate_rad_s = GRAVITY_M_S2 * math.tan(s.roll_rad) / max(s.airspeed_m_s, p.airspeed_min_m_s)
        s.yaw_rad = wrap_pi(s.yaw_rad + s.yaw_rate_rad_s * dt_s)
        vz_cmd = -climb_cmd_m_s
        vz = v_old[2] + (vz_cmd - v_old[2]) * _lag_gain(dt_s, p.tau_vel_s)
        self._set_plane_ground_velocity(vz)
        v_new = s.vel_ned_m_s
        self._move(v_old, v_new, dt_s)
        self._ground_contact(liftoff_m=0.5)
        s.acc_ned_m_s2 = [(v_new[i] - v_old[i]) / dt_s for i in range(3)]
        s.pitch_rad = math.atan2(-s.vel_ned_m_s[2], max(s.airspeed_m_s, 1e-6)) if s.airspeed_m_s > 0 else 0.0
        s.t_s += dt_s
        self._record_position()
        self._draw_noise()

    def _stay_on_ground(self, dt_s: float) -> None:
        """Motors off on the ground: no motion, no turning; time and the sensor noise go on."""
        s = self.state
        s.vel_ned_m_s = [0.0, 0.0, 0.0]
        s.acc_ned_m_s2 = [0.0, 0.0, 0.0]
        s.yaw_rate_rad_s = 0.0
        s.t_s += dt_s
        self._record_position()
        self._draw_noise()

    def _step_bias(self, dt_s: float) -> None:
        """Advance the velocity estimate's bias (exact discretisation of a first-order Gauss-Markov
        process), smooth it where the model says so, and, airborne, move the vehicle by it and by the
        offset: the loop holds the estimate."""
        p = self.params
        phi = math.exp(-dt_s / p.vel_bias_tc_s)
        level = p.vel_bias_m_s
        if p.vel_bias_jerk_s2 > 0.0:
            v = self.state.vel_ned_m_s
            jerk = p.vel_bias_jerk_s2 * min(self._jerk.update(dt_s, v[0], v[1]), p.vel_bias_jerk_max_m_s3)
            level = math.hypot(level, jerk)
        kick = level * math.sqrt(1.0 - phi * phi)
        g = self._bias_rng.gauss
        bn, be = self._bias_ne_m_s
        bn, be = phi * bn + kick * g(0.0, 1.0), phi * be + kick * g(0.0, 1.0)
        self._bias_ne_m_s = (bn, be)
        if p.vel_bias_smooth_s > 0.0:
            bn, be = self._smooth_bias_ne_m_s = _lagged(self._smooth_bias_ne_m_s, (bn, be),
                                                        _lag_gain(dt_s, p.vel_bias_smooth_s))
        if p.vel_bias_loop_s > 0.0:
            fn, fe = self._flown_bias_ne_m_s = _lagged(self._flown_bias_ne_m_s, (bn, be),
                                                       _lag_gain(dt_s, p.vel_bias_loop_s))
            self._reported_rest_ne_m_s = (fn - bn, fe - be)
            bn, be = fn, fe
        if not self.state.on_ground:
            self.state.pos_ned_m[0] += (bn + self._offset_ne_m_s[0]) * dt_s
            self.state.pos_ned_m[1] += (be + self._offset_ne_m_s[1]) * dt_s

    def reported_vel_ned_m_s(self) -> tuple[float, float, float]:
        """Velocity as the autopilot reports it: the loop's, plus, airborne, the part of the
        estimate's error quicker than the loop (``vel_bias_loop_s``; none without it). On the
        ground it reports standing still, as it stands."""
        v, (rn, re) = self.state.vel_ned_m_s, self._reported_rest_ne_m_s
        if self.state.on_ground:
            return (v[0], v[1], v[2])
        return (v[0] + rn, v[1] + re, v[2])

    def _move(self, v_old: list[float], v_new: list[float], dt_s: float) -> None:
        """Trapezoidal position update: exact for constant acceleration over the step."""
        pos = self.state.pos_ned_m
        for i in range(3):
            pos[i] += 0.5 * (v_old[i] + v_new[i]) * dt_s

    def _ground_contact(self, liftoff_m: float) -> None:
        """Touching the ground stops vertical motion there; ``liftoff_m`` above it counts as airborne."""
        s = self.state
        if s.pos_ned_m[2] >= 0.0 and s.vel_ned_m_s[2] >= 0.0:
            s.pos_ned_m[2] = 0.0
            s.vel_ned_m_s[2] = 0.0
            s.on_ground = True
        elif s.pos_ned_m[2] < -liftoff_m:
            s.on_ground = False

    def _set_plane_ground_velocity(self, vz_m_s: float) -> None:
        s = self.state
        wn, we = self.params.wind_ned_m_s
        if s.on_ground:
            wn = we = 0.0
        s.vel_ned_m_s = [s.airspeed_m_s * math.cos(s.yaw_rad) + wn, s.airspeed_m_s * math.sin(s.yaw_rad) + we, vz_m_s]

    # ------------------------------------------------------------------ measurements
    def _record_position(self) -> None:
        """Keep the true positions of the last ``pos_delay_s`` (one per physics step)."""
        delay = self.params.pos_delay_s
        if delay <= 0.0:
            return
        s = self.state
        history = self._pos_history
        history.append((s.t_s, (s.pos_ned_m[0], s.pos_ned_m[1], s.pos_ned_m[2])))
        while len(history) > 2 and history[1][0] <= s.t_s - delay:
            history.popleft()

    def estimated_pos_ned_m(self) -> tuple[float, float, float]:
        """The autopilot's estimate of the position: the true position ``pos_delay_s`` ago
        (interpolated between physics steps; the oldest kept while the history is shorter)."""
        pos = self.state.pos_ned_m
        history = self._pos_history
        if self.params.pos_delay_s <= 0.0 or not history:
            return (pos[0], pos[1], pos[2])
        due = self.state.t_s - self.params.pos_delay_s
        (t0, p0) = history[0]
        if len(history) == 1 or due <= t0:
            return p0
        t1, p1 = history[1]
        w = min(1.0, (due - t0) / (t1 - t0)) if t1 > t0 else 1.0
        return (p0[0] + (p1[0] - p0[0]) * w, p0[1] + (p1[1] - p0[1]) * w, p0[2] + (p1[2] - p0[2]) * w)

    def measured_pos_ned_m(self) -> tuple[float, float, float]:
        """Position as the autopilot reports it: its estimate plus this step's seeded Gaussian noise."""
        pos = self.estimated_pos_ned_m()
        n = self._noise_ned_m
        return (pos[0] + n[0], pos[1] + n[1], pos[2] + n[2])
