"""Value types shared by the guidance laws, the simulator, the flight loop and replay.

Frames: every position and angle here is in the local ENU frame of the mission (x east, y north,
metres; angles anticlockwise from +x, radians), as in the paper. NED lives in ``companion.io``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Protocol, TypeVar

from companion.geometry.checks import require_positive_finite

#: The laws of the paper's two-phase object (:class:`companion.guidance.two_phase.TwoPhaseGuidance`).
TWO_PHASE_METHODS = ("fixed_l1", "corrector", "predictive")
#: The laws autopilots and textbooks fly (:mod:`companion.guidance.baselines`), flown as their
#: sources fly them: from any start, without a mid-course phase (docs/guidance.md).
BASELINE_METHODS = ("ap_l1", "npfg", "pure_pursuit")
#: Every mission ``guidance.method``; :func:`companion.guidance.factory.make_law` builds each.
METHODS = TWO_PHASE_METHODS + BASELINE_METHODS
#: The law of a mission that names none (the mission schema's default).
DEFAULT_METHOD = "predictive"
#: The law of ``GuidanceParams()`` built in code (``companion bench paper``, the simulator's tests):
#: the paper's corrector-aided law, which the paper's figures are about.
PAPER_METHOD = "corrector"
#: ``predictive``'s weight of the squared acceleration in its rollout cost (s^4): every default of it.
DEFAULT_LAMBDA_S4 = 0.03
#: ``predictive``'s lambda on a flight that compensates the velocity loop's slow tail, when the mission
#: states none (:func:`companion.loop.limits.mission_for_tail`). Chosen on the real PX4 on missions
#: outside the gallery (docs/real_firmware.md, "The tail compensated by default on PX4").
TAIL_COMPENSATED_LAMBDA_S4 = 0.3
PHASES = ("midcourse", "close_range", "finished")
MIDCOURSE_TRIGGERS = ("auto", "paper", "off")

#: Re-optimisations fall due this much before their scheduled time. Tick times often sit on an
#: exact millisecond grid (an autopilot's clock), so ``t >= t_last + window`` is frequently an
#: equality that float rounding decides; a tick time restored from a log (exact to ~1e-13 s, see
#: docs/recording.md) must fall on the same side as in flight. 1 ns is far below any tick.
SCHEDULE_TOLERANCE_S = 1e-9


@dataclass(frozen=True)
class GuidanceParams:
    """Tuning of the two-phase guidance. Validates on construction.

    Attributes
    ----------
    method : ``"fixed_l1"`` (Park 2007), ``"corrector"`` (the paper's corrector-aided law),
        ``"predictive"`` (:mod:`companion.guidance.predictive`: pursuit plus a receding-horizon plan
        over a model of the vehicle; the close-range phase only, mid-course is the same), or one
        of the baselines ``"ap_l1"`` (ArduPilot's L1), ``"npfg"`` (PX4's NPFG), ``"pure_pursuit"``
        (:mod:`companion.guidance.baselines`; no mid-course phase).
    l1_m : look-ahead distance L1 of the close-range phase.
    speed_m_s : the vehicle's constant ground speed V.
    rate_hz : guidance rate (the fixed tick).
    circle_radius_m : radius R of the mid-course initiation circle.
    midcourse_trigger : ``"auto"`` (documented in docs/guidance.md), ``"paper"`` (start at least
        2 R0 away, R0 the path's radius of curvature at its start) or ``"off"``.
    k1_max, k2_max : upper bounds of the online corrector-weight search (both >= 0).
    d_limit_factor : the re-optimisation window is ``min(d_limit_factor * L1, R_proj) / V``
        (the paper's d_limit = 2 L1).
    rollout_tau_s : time constant of the first-order inner loop the rollouts of ``corrector`` and
        ``predictive`` assume (0, the default, is the paper's ideal inner loop: achieved =
        commanded acceleration). The mock copter's is 0.3 s.
    lambda_s4 : ``predictive`` only: weight of the squared commanded acceleration against the
        squared cross-track error in its rollout cost (s^4), >= 0; smaller tracks tighter.
    a_max_m_s2 : ``predictive`` only: the vehicle's lateral-acceleration limit (> 0, ``math.inf``
        for none); every command is clipped to it and the rollouts know it.
    wind_x_m_s, wind_y_m_s : ``predictive`` only: known steady wind (ENU) its rollouts assume.
    period_s : ``ap_l1`` and ``npfg`` only: the tracking-loop period T (> 0; None: the autopilot's
        default, ArduPilot's NAVL1_PERIOD 17 s, PX4's NPFG_PERIOD 10 s).
    lookahead_m : ``pure_pursuit`` only: its look-ahead distance L_d (> 0; None: 10 m).
    adapt_model : ``predictive`` only: watch the flown lateral acceleration and re-plan with the
        model that explains it, or fall back to the feedback core (on when the mission has a
        ``vehicle:`` block; :class:`companion.guidance.predictive.ModelMonitor`).
    course_tc_s : ``predictive`` only: time constant of its course observer (s, >= 0; 0: the
        course as reported; :func:`companion.guidance.predictive.observe_course`). Off by default
        on every autopilot (docs/real_firmware.md, "The course observed through the model").
    """

    method: str = PAPER_METHOD
    l1_m: float = 10.0
    speed_m_s: float = 5.0
    rate_hz: float = 50.0
    circle_radius_m: float = 10.0
    midcourse_trigger: str = "auto"
    k1_max: float = 1.0
    k2_max: float = 1.0e4
    d_limit_factor: float = 2.0
    rollout_tau_s: float = 0.0
    lambda_s4: float = DEFAULT_LAMBDA_S4
    a_max_m_s2: float = math.inf
    wind_x_m_s: float = 0.0
    wind_y_m_s: float = 0.0
    adapt_model: bool = False
    period_s: float | None = None
    lookahead_m: float | None = None
    course_tc_s: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.adapt_model, bool):
            raise ValueError(f"adapt_model: expected true or false, got {self.adapt_model!r}")
        if self.method not in METHODS:
            raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {self.method!r}")
        if self.midcourse_trigger not in MIDCOURSE_TRIGGERS:
            raise ValueError(
                f"midcourse_trigger: expected one of {', '.join(MIDCOURSE_TRIGGERS)}, "
                f"got {self.midcourse_trigger!r}"
            )
        require_positive_finite(self, ("l1_m", "speed_m_s", "rate_hz", "circle_radius_m", "d_limit_factor"))
        for name in ("wind_x_m_s", "wind_y_m_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"{name}: expected a finite number, got {value!r}")
        for name in ("period_s", "lookahead_m"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not (
                    isinstance(value, (int, float)) and math.isfinite(value) and value > 0)):
                raise ValueError(f"{name}: expected a finite number > 0 (or none), got {value!r}")
        value = self.a_max_m_s2
        if isinstance(value, bool) or not (isinstance(value, (int, float)) and value > 0):
            raise ValueError(f"a_max_m_s2: expected a number > 0 (inf for no limit), got {value!r}")
        for name in ("k1_max", "k2_max", "rollout_tau_s", "lambda_s4", "course_tc_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")


#: Largest ``tail_share`` of a vehicle model (a share of 1 would leave no steady gain).
MAX_TAIL_SHARE = 0.95
#: The mission ``vehicle:`` block's keys, in the order files and ``companion identify`` write them.
VEHICLE_MODEL_KEYS = ("a_max_m_s2", "delay_s", "lag_s", "accel_lag_s", "tail_share", "tail_tc_s", "speed_sag_s",
                      "yaw_rate_max_deg_s", "vel_bias_m_s", "vel_bias_tc_s", "vel_bias_jerk_s2",
                      "vel_bias_jerk_max_m_s3", "vel_bias_smooth_s", "vel_bias_loop_s", "vel_offset_m_s", "pos_delay_s",
                      "accel_ff_gain", "accel_ff_lag_s")
#: The keys that describe the response to an acceleration target (``guidance.accel_feedforward``):
#: a log flown without one says nothing of them.
ACCEL_FF_KEYS = ("accel_ff_gain", "accel_ff_lag_s")


@dataclass(frozen=True)
class VehicleModel:
    """How the vehicle flies velocity + yaw-rate setpoints (docs/vehicle_model.md).

    The horizontal velocity follows the commanded one seen ``delay_s`` late, its speed reduced in
    turns by ``speed_sag_s`` times the lateral acceleration, through a first-order lag of time
    constant ``lag_s``, its acceleration limited to ``a_max_m_s2``; the yaw rate is limited to
    ``yaw_rate_max_deg_s``. The mission's ``vehicle:`` block, ``companion identify``'s output and
    the mock's ``--vehicle-model`` file share these keys. The defaults are the mock's historical
    copter (0.3 s lag, 5 m/s^2, no delay, no sag, 90 deg/s).

    Attributes
    ----------
    a_max_m_s2 : horizontal (in a turn at constant speed: lateral) acceleration limit, > 0.
    delay_s : dead time from a setpoint sent to the vehicle's response, >= 0.
    lag_s : time constant of the first-order velocity response, >= 0.
    accel_lag_s : time constant of a second lag, on the acceleration the velocity loop asks for
        (0: the first-order model), >= 0.
    tail_share, tail_tc_s : a slow tail of the velocity response: the velocity loop asks for
        ``(e - tail_share * f) / lag_s``, ``e`` the velocity error and ``f`` that error through a
        first-order low-pass of time constant ``tail_tc_s``. The error is first closed at
        ``1 / lag_s``, then at ``(1 - tail_share) / lag_s`` (PX4's velocity loop in OFFBOARD;
        0: no tail). ``0 <= tail_share <= 0.95``, ``tail_tc_s > 0``.
    speed_sag_s : speed lost per unit of lateral acceleration in a turn (m/s per m/s^2), >= 0.
    yaw_rate_max_deg_s : yaw-rate limit, > 0.
    vel_bias_m_s, vel_bias_tc_s : the autopilot's velocity estimate is off by a slowly varying
        bias, a first-order Gauss-Markov process on each horizontal axis with this standard
        deviation (>= 0; 0: none) and correlation time (> 0). The velocity loop holds the
        estimate, so the vehicle drifts by the bias, and the reported position leaves the integral
        of the reported velocity. The mock flies it; the guidance and the offline simulator do not
        use it (it is a disturbance, not a response to the command).
    vel_bias_jerk_s2, vel_bias_jerk_max_m_s3 : that bias wanders more while the vehicle
        manoeuvres: its level is ``sqrt(vel_bias_m_s^2 + (vel_bias_jerk_s2 * min(j,
        vel_bias_jerk_max_m_s3))^2)``, ``j`` the manoeuvre jerk (``|d a / dt|`` low-passed over
        0.5 s; ``companion.sim.wander``). ``vel_bias_jerk_s2 >= 0`` (0: one level throughout;
        ArduCopter SITL's: about 0.03), ``vel_bias_jerk_max_m_s3 > 0``. The mock flies it.
    vel_bias_smooth_s : the vehicle flies that bias through a first-order low-pass of this time
        constant, >= 0 (0: as it is; ArduCopter SITL's: about 0.7 s, its drift being smoother within
        a second or two than a first-order bias's; ``companion.sim.wander.fit_smoothing``).
    vel_bias_loop_s : where the estimate's error is quicker than the velocity loop, the vehicle
        does not fly it and the reported velocity shows it: the vehicle flies the bias through a
        first-order lag of this time constant and the reported velocity carries the rest (the
        bias less what is flown, with the opposite sign), >= 0 (0: the whole bias is flown and the
        reported velocity is smooth; PX4 SIH's estimate jitters above half a hertz while its
        vehicle does not, docs/real_firmware.md). The mock flies it.
    vel_offset_m_s : beside that bias, the estimate misses a velocity that stays put for a whole
        flight: an offset on each horizontal axis drawn once, with this standard deviation (>= 0;
        0: none; ArduCopter SITL's: about 1 cm/s). On a straight leg an autopilot's position loop
        takes it up; it moves a track only where the track turns. The mock flies it; the guidance
        does not use it.
    pos_delay_s : how much older the reported position is than the reported velocity, >= 0
        (ArduCopter SITL's estimator: about 19 ms). Its position then leaves the integral of its
        velocity by about ``-pos_delay_s * v``. The mock reports it so; the guidance does not use it.
    accel_ff_gain, accel_ff_lag_s : the response to an acceleration target sent beside the
        velocity (``guidance.accel_feedforward``): the target, seen ``delay_s`` late, times
        ``accel_ff_gain`` (>= 0) through a first-order lag ``accel_ff_lag_s`` (>= 0), joins what
        the velocity loop asks for *before* the slow tail, which takes back its share of it like
        the rest (PX4 SIH: gain 1.31, lag 0.17 s; docs/vehicle_model.md). 1 and 0: the target is
        added as sent. Flights without a target do not use them.
    """

    a_max_m_s2: float = 5.0
    delay_s: float = 0.0
    lag_s: float = 0.3
    accel_lag_s: float = 0.0
    tail_share: float = 0.0
    tail_tc_s: float = 1.0
    speed_sag_s: float = 0.0
    yaw_rate_max_deg_s: float = 90.0
    vel_bias_m_s: float = 0.0
    vel_bias_tc_s: float = 3.0
    vel_bias_jerk_s2: float = 0.0
    vel_bias_jerk_max_m_s3: float = 1.0
    vel_bias_smooth_s: float = 0.0
    vel_bias_loop_s: float = 0.0
    vel_offset_m_s: float = 0.0
    pos_delay_s: float = 0.0
    accel_ff_gain: float = 1.0
    accel_ff_lag_s: float = 0.0

    def __post_init__(self) -> None:
        for name in VEHICLE_MODEL_KEYS:
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"vehicle.{name}: expected a finite number, got {value!r}")
            strict = name in ("a_max_m_s2", "yaw_rate_max_deg_s", "tail_tc_s", "vel_bias_tc_s", "vel_bias_jerk_max_m_s3")
            if value < 0 or (strict and value == 0):
                raise ValueError(f"vehicle.{name}: expected a number {'>' if strict else '>='} 0, got {value!r}")
        if self.tail_share > MAX_TAIL_SHARE:
            raise ValueError(f"vehicle.tail_share: expected a number <= {MAX_TAIL_SHARE}, got {self.tail_share!r}")

    def rollout_tau_s(self) -> float:
        """The single first-order time constant that best stands for lag plus delay in the
        guidance's rollouts (a dead time d followed by lags tau_1, tau_2 has the mean delay d + tau_1 + tau_2).
        The slow tail is left out: it acts over seconds on what remains of an error, while the
        rollouts plan the first response to a turn (docs/vehicle_model.md)."""
        return self.lag_s + self.delay_s + self.accel_lag_s

    def as_dict(self) -> dict[str, float]:
        return {name: float(getattr(self, name)) for name in VEHICLE_MODEL_KEYS}


@dataclass(frozen=True)
class VehicleState:
    """What the guidance needs of the vehicle at one tick (local ENU)."""

    x_m: float
    y_m: float
    course_rad: float  # direction of the ground velocity, anticlockwise from +x (east)
    speed_m_s: float


@dataclass(frozen=True)
class GuidanceOutput:
    """One guidance tick: the command and the internals that explain it (for logs and replay)."""

    a_cmd_m_s2: float  # lateral acceleration, positive = turn left (anticlockwise)
    phase: str  # one of PHASES
    crosstrack_m: float  # signed distance to the closest path point, positive = left of path
    s_proj_m: float  # arc length of the closest path point
    k1: float = math.nan
    k2: float = math.nan
    lookahead_xy_m: tuple[float, float] | None = None
    corrector_xy_m: tuple[float, float] | None = None
    reoptimised: bool = False  # True on the ticks where k1, k2 were re-optimised
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def finished(self) -> bool:
        return self.phase == "finished"


class GuidanceLaw(Protocol):
    """What every law offers the simulator, the flight loop and replay: one ``step`` per tick.

    ``step(t_s, state)`` takes the tick time (s, the loop's clock) and the vehicle's state (ENU)
    and returns the tick's :class:`GuidanceOutput`. Deterministic: same inputs, same outputs.
    """

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        ...


_Record = TypeVar("_Record")


def frozen_maker(cls: type[_Record]) -> Callable[..., _Record]:
    """A constructor of the frozen dataclass ``cls`` for hot paths: it fills the instance's
    ``__dict__`` at once, where a frozen dataclass's ``__init__`` calls ``object.__setattr__`` once
    per field (a measurable share of a 50 Hz tick). It runs no ``__post_init__``, so it is only for
    classes without one; the instance is the same in every other respect.

    Give every field by name (the hot paths do): a missing or unknown name is a ``TypeError``, so
    two values of one type cannot swap places silently. Every field positionally, in declaration
    order, is also accepted (only the count is checked then).

    >>> make = frozen_maker(VehicleState)
    >>> make(x_m=1.0, y_m=2.0, course_rad=0.0, speed_m_s=5.0) == VehicleState(1.0, 2.0, 0.0, 5.0)
    True
    >>> make(x_m=1.0, y_m=2.0, course_rad=0.0, speed=5.0)
    Traceback (most recent call last):
    TypeError: VehicleState: missing speed_m_s; unknown speed
    """
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"frozen_maker: {cls.__name__} validates in __post_init__; use its constructor")
    order = tuple(f.name for f in fields(cls))  # type: ignore[arg-type]
    names = frozenset(order)
    new = object.__new__

    def make(*values: object, **named: object) -> _Record:
        if values:
            if named or len(values) != len(order):
                raise TypeError(f"{cls.__name__}: expected {len(order)} values in order, got {len(values)}")
            named = dict(zip(order, values))
        elif named.keys() != names:
            missing = ", ".join(sorted(names - named.keys())) or "nothing"
            unknown = ", ".join(sorted(named.keys() - names)) or "nothing"
            raise TypeError(f"{cls.__name__}: missing {missing}; unknown {unknown}")
        obj = new(cls)
        obj.__dict__.update(named)
        return obj

    return make

