"""One guidance tick, as a pure function shared by the live loop and replay.

``compute_tick`` takes the newest ``LOCAL_POSITION_NED`` sample (NED), its age, the tick time
and the guidance object, and returns everything that tick decided: the vehicle state handed to
the guidance (ENU), the guidance output, the setpoint fields to send, and the row recorded in the
tlog as ``DEBUG_FLOAT_ARRAY "guidance"`` (layout: ``DEBUG_FIELDS``, documented in
``docs/recording.md``).

Rules applied here (and therefore identically in flight and in replay):

* no sample, or a sample older than ``stale_s`` -> **hold** (zero velocity, zero yaw rate, zero
  vertical velocity: nothing is computed from the old sample; wings level for the attitude
  output), the guidance is not stepped;
* the course handed to the guidance is the direction of the measured ground velocity; below
  ``min_course_speed_m_s`` it falls back to the attitude yaw, then to the previous course. A
  vehicle with velocity output still gathering speed (slower than ``gathering_fraction`` of
  the mission speed) is handed its commanded course instead (on the first tick, its yaw: the
  copter faced its start course, docs/flying.md): its velocity loop is driving it that way, and
  the direction of a slow velocity is mostly the loop's transient and the estimate's bias (a
  lateral error of 0.1 m/s is 6 deg at 1 m/s; every law reads it as if flown at V; a hovering
  PX4 SIH reported 0.5-0.65 m/s while its position moved by centimetres). On the mock's
  ArduCopter, taking off along the racetrack, ``predictive`` answered those swings with
  +-1.8 m/s^2 for 5 s (docs/flying.md). Such a vehicle is sent the acceleration target scaled by
  its ground speed over V: its velocity turns with the setpoint on ``|v| a_cmd / V``;
* the speed handed to the guidance is the mission's ``speed_m_s`` (the commanded ground speed V);
  a mission with a profile (``TickConfig.profile``) commands ``V(s)`` and the altitude hold on
  ``h(s)`` with the feed-forward climb ``V(s) dh/ds`` at the tick's projection ``s``
  (:func:`companion.io.setpoints.profile_targets`; the guidance gets ``V(s)`` through
  :class:`companion.guidance.profiled.ProfiledGuidance`);
* the velocity setpoint's direction is the **commanded course**, integrated tick by tick
  (``course_cmd += a_cmd / V * dt``), not re-derived from the measured course every tick. A vehicle
  whose velocity loop lags (time constant tau) trails the command by about ``omega * tau`` in a
  steady turn; re-basing on the measured course each tick would cut the achieved turn rate by
  ``dt / tau`` (a 0.02 s tick on a 0.3 s velocity loop turns 15 times too slowly). The commanded
  course is kept within ``max_course_lead_rad`` of the measured one (no wind-up when the vehicle
  cannot follow) and restarts from the measured course after a hold. Carry
  ``TickResult.course_cmd_rad`` into the next call as ``prev_course_cmd_rad``;
* with ``TickConfig.drift_tc_s`` > 0 (velocity output), every fresh sample feeds the flight's
  :class:`~companion.guidance.drift.DriftEstimator`: the course handed to the guidance is that of
  the reported velocity plus the estimate, and the velocity setpoint is sent less the estimate
  (the vehicle flies its setpoint plus its estimate's drift; ``docs/flying.md``);
* with ``TickConfig.speed_hold_tc_s`` > 0 (velocity output), the flight's
  :class:`~companion.guidance.speed_hold.SpeedHold` integrates the ground-speed error and the
  velocity setpoint's *length* is the speed plus that correction; it still turns at ``a / V``;
* with ``TickConfig.tail_share`` > 0 (velocity output), the flight's
  :class:`~companion.guidance.tail_comp.TailCompensator` runs the velocity loop's slow tail beside
  it and adds it to the horizontal setpoint, so that the loop answers the setpoint as a first-order
  lag; a hold starts it again from zero.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from functools import cached_property

from companion.geometry import frames
from companion.guidance.drift import DriftEstimator
from companion.guidance.speed_hold import SpeedHold
from companion.guidance.tail_comp import TailCompensator
from companion.guidance.types import MAX_TAIL_SHARE, GuidanceOutput, VehicleState, frozen_maker
from companion.io.setpoints import (
    AltitudeHold,
    AttitudeSetpoint,
    VelocitySetpoint,
    attitude_setpoint,
    hold_setpoint,
    position_hold_setpoint,
    profile_targets,
    velocity_setpoint,
)
from companion.io.state import PositionSample

#: Position older than this (s) -> hold: ``companion fly --stale-s``'s default, replay's assumption.
DEFAULT_STALE_S = 0.3
#: ``companion fly --drift-tc-s``'s default: the velocity estimate's drift, low-passed over this
#: long (s), is compensated (:mod:`companion.guidance.drift`); 0 turns it off.
DEFAULT_DRIFT_TC_S = 0.3

PHASE_CODES = {"midcourse": 0, "close_range": 1, "finished": 2, "hold": 3}
PHASE_NAMES = {code: name for name, code in PHASE_CODES.items()}
HOLD_REASON_CODES = {"": 0, "stale": 1, "no_position": 2}

#: Layout of the ``data`` array of the per-tick ``DEBUG_FLOAT_ARRAY "guidance"`` record.
DEBUG_FIELDS = (
    "tick",                  # 0  tick counter (ticks actually run, from 0)
    "t_s",                   # 1  tick time since the first tick (loop clock), s
    "phase_code",            # 2  0 midcourse, 1 close_range, 2 finished, 3 hold
    "a_cmd_m_s2",            # 3  lateral acceleration command, ENU, left positive
    "crosstrack_m",          # 4  signed cross-track error, left of path positive
    "s_proj_m",              # 5  arc length of the closest path point
    "k1",                    # 6  corrector weight k1 (NaN when not used)
    "k2",                    # 7  corrector weight k2 (NaN when not used)
    "x_enu_m",               # 8  vehicle position east
    "y_enu_m",               # 9  vehicle position north
    "course_enu_rad",        # 10 course handed to the guidance
    "speed_m_s",             # 11 speed handed to the guidance (mission speed V)
    "yaw_rate_cmd_rad_s",    # 12 yaw-rate command, ENU (left positive)
    "vn_cmd_m_s",            # 13 commanded velocity north (NED vx)
    "ve_cmd_m_s",            # 14 commanded velocity east (NED vy)
    "vd_cmd_m_s",            # 15 commanded velocity down (NED vz)
    "reoptimised",           # 16 1 on ticks where k1, k2 were re-optimised
    "sample_age_s",          # 17 age of the position sample used
    "ground_speed_m_s",      # 18 measured horizontal ground speed
    "hold_reason",           # 19 0 none, 1 stale, 2 no position yet
    "roll_cmd_rad",          # 20 fixed-wing roll command (NED, right wing down +), NaN otherwise
    "alt_m",                 # 21 measured altitude (up)
    "course_cmd_enu_rad",    # 22 commanded course (velocity setpoint direction), NaN when none
    "prev_course_cmd_rad",   # 23 the prev_course_cmd_rad this tick was given (NaN for None)
    "prev_course_rad",       # 24 the prev_course_rad this tick was given
    "t_s_residual",          # 25 t_s - float32(t_s): field 1 + field 25 restores the float64 t_s
    "setpoint_sent",         # 26 1 if this tick's setpoint went on the wire, 0 if it came too late
    "debug_layout",          # 27 DEBUG_LAYOUT (NaN padding in logs written before this field)
    "yaw_ned_rad",           # 28 the ATTITUDE yaw this tick was given (NaN for None)
    "rate_hz",               # 29 the loop rate the tick was computed for (its dt is 1 / rate), Hz
    "drift_n_m_s",           # 30 the velocity estimate's drift the tick compensated, north (NaN: off)
    "drift_e_m_s",           # 31 ... east
    "drift_tc_s",            # 32 the drift estimate's time constant (TickConfig.drift_tc_s; 0: off)
    "speed_hold_m_s",        # 33 the speed hold's correction added to the setpoint's magnitude (NaN: off)
    "speed_hold_tc_s",       # 34 the speed hold's integral time (TickConfig.speed_hold_tc_s; 0: off)
    "tail_comp_n_m_s",       # 35 the slow tail's compensation added to the setpoint, north (NaN: off)
    "tail_comp_e_m_s",       # 36 ... east
    "tail_share",            # 37 the tail's share compensated (TickConfig.tail_share; 0: off)
    "tail_tc_s",             # 38 the tail's time (TickConfig.tail_tc_s)
)
#: Value of the ``debug_layout`` field of the layout written now; a log's value says which of the
#: later fields it holds (older logs: NaN padding there).
DEBUG_LAYOUT = 6
LAYOUT_WITH_YAW = 2  # from this layout on, field 28 holds the tick's yaw
LAYOUT_WITH_RATE = 3  # from this layout on, field 29 holds the loop rate
LAYOUT_WITH_DRIFT = 4  # from this layout on, fields 30-32 hold the drift compensation
LAYOUT_WITH_SPEED_HOLD = 5  # from this layout on, fields 33-34 hold the speed hold
LAYOUT_WITH_TAIL_COMP = 6  # from this layout on, fields 35-38 hold the tail compensation


@dataclass(frozen=True)
class TickConfig:
    """The per-tick settings of a flight (everything ``compute_tick`` needs besides its inputs)."""

    speed_m_s: float
    rate_hz: float
    altitude_m: float
    stale_s: float = DEFAULT_STALE_S
    output: str = "velocity"  # "velocity" (copter, rover) or "attitude" (plane)
    max_bank_deg: float = 35.0
    min_course_speed_m_s: float = 0.5
    alt_gain_1_s: float = 1.0
    max_climb_m_s: float = 2.0
    thrust: float = 0.5
    max_course_lead_rad: float = math.pi / 4
    gathering_fraction: float = 0.5
    profile: object = None  # the mission's PathProfile (altitude and speed along the path), or None
    drift_tc_s: float = 0.0  # time constant of the velocity estimate's drift compensation (s); 0: off
    # the lateral command sent as acceleration feed-forward, limited to this (m/s^2); 0: not sent
    # (companion.io.setpoints; companion.loop.limits.accel_feedforward_max)
    accel_ff_max_m_s2: float = 0.0
    speed_hold_tc_s: float = 0.0  # integral time of the ground-speed hold (s); 0: off (companion.guidance.speed_hold)
    # the velocity loop's slow tail compensated (companion.guidance.tail_comp): its share (0: off) and time (s)
    tail_share: float = 0.0
    tail_tc_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("speed_m_s", "rate_hz", "stale_s", "max_bank_deg", "alt_gain_1_s", "max_climb_m_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
        if self.output not in ("velocity", "attitude"):
            raise ValueError(f"output: expected 'velocity' or 'attitude', got {self.output!r}")
        if not (0 < self.max_bank_deg < 90):
            raise ValueError(f"max_bank_deg: expected 0 < value < 90, got {self.max_bank_deg!r}")
        for name in ("drift_tc_s", "accel_ff_max_m_s2", "speed_hold_tc_s", "tail_share", "tail_tc_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
        if self.tail_share > 0 and not (self.tail_share <= MAX_TAIL_SHARE and self.tail_tc_s > 0):
            raise ValueError(f"tail_share, tail_tc_s: expected a share <= {MAX_TAIL_SHARE} and a time > 0, "
                             f"got {self.tail_share!r}, {self.tail_tc_s!r}")

    @property
    def compensates_drift(self) -> bool:
        """Velocity output with a drift time constant: the ticks estimate and compensate the
        velocity estimate's drift (:mod:`companion.guidance.drift`)."""
        return self.output == "velocity" and self.drift_tc_s > 0

    @property
    def holds_speed(self) -> bool:
        """Velocity output with a speed-hold integral time: the setpoint's magnitude is corrected
        until the vehicle flies the mission's speed (:mod:`companion.guidance.speed_hold`)."""
        return self.output == "velocity" and self.speed_hold_tc_s > 0

    @property
    def compensates_tail(self) -> bool:
        """Velocity output with a tail share: the velocity loop's slow tail is compensated
        (:mod:`companion.guidance.tail_comp`)."""
        return self.output == "velocity" and self.tail_share > 0

    def gathering(self, sample: PositionSample) -> bool:
        """Velocity output and slower than ``gathering_fraction`` of the mission speed: hovering or
        still gathering speed, so the direction of the measured velocity is not yet a course."""
        return (self.output == "velocity"
                and math.hypot(sample.vx_ned_m_s, sample.vy_ned_m_s) < self.gathering_fraction * self.speed_m_s)

    @cached_property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    @cached_property
    def altitude_hold(self) -> AltitudeHold:
        return AltitudeHold(self.altitude_m, self.alt_gain_1_s, self.max_climb_m_s)


@dataclass(frozen=True)
class TickResult:
    """What one tick decided.

    ``debug`` is the tick's ``DEBUG_FIELDS`` row, built on first use (the flight loop records
    it; replay, which only compares setpoints, never pays for it).
    """

    tick: int
    t_s: float
    phase: str  # a guidance phase, or "hold"
    hold_reason: str  # "" when not holding
    state: VehicleState | None
    output: GuidanceOutput | None
    setpoint: VelocitySetpoint | AttitudeSetpoint
    sample: PositionSample | None
    sample_age_s: float
    course_rad: float  # the course used (carry it into the next tick as ``prev_course_rad``)
    course_cmd_rad: float = math.nan  # commanded course (carry as ``prev_course_cmd_rad``)
    prev_course_cmd_rad: float = math.nan  # the inputs carried from the previous tick (NaN: none)
    prev_course_rad: float = math.nan
    yaw_ned_rad: float = math.nan  # the attitude yaw the tick was given (NaN: none)
    rate_hz: float = math.nan  # the loop rate the tick was computed for (TickConfig.rate_hz)
    drift_n_m_s: float = math.nan  # the drift compensated (NED north, east; NaN: not compensating)
    drift_e_m_s: float = math.nan
    drift_tc_s: float = math.nan  # the drift estimate's time constant (TickConfig.drift_tc_s)
    speed_hold_m_s: float = math.nan  # the speed hold's correction to the setpoint's magnitude (NaN: none)
    speed_hold_tc_s: float = math.nan  # its integral time (TickConfig.speed_hold_tc_s)
    tail_comp_n_m_s: float = math.nan  # the slow tail's compensation in the setpoint (NED; NaN: none)
    tail_comp_e_m_s: float = math.nan
    tail_share: float = math.nan  # the tail compensated (TickConfig.tail_share, tail_tc_s)
    tail_tc_s: float = math.nan

    @property
    def phase_code(self) -> int:
        return PHASE_CODES[self.phase]

    @property
    def is_hold(self) -> bool:
        return self.phase == "hold"

    @cached_property
    def debug(self) -> list[float]:
        return debug_row(self)


#: Every field by name, filled at once (``frozen_maker``: one tick builds these 50 times a second).
_tick_result = frozen_maker(TickResult)
_vehicle_state = frozen_maker(VehicleState)


def _gathering_course(gathering: bool, yaw_ned_rad: float | None, prev_course_cmd_rad: float | None) -> float | None:
    """The course of a vehicle still gathering speed (:meth:`TickConfig.gathering`): the commanded
    one, else (the first tick) the yaw; None when it is not gathering speed, or neither is known."""
    if not gathering:
        return None
    if prev_course_cmd_rad is not None and math.isfinite(prev_course_cmd_rad):
        return prev_course_cmd_rad
    if yaw_ned_rad is not None and math.isfinite(yaw_ned_rad):
        return frames.course_enu_from_ned(yaw_ned_rad)
    return None


def course_from_sample(sample: PositionSample | None, yaw_ned_rad: float | None, prev_course_rad: float,
                       min_speed_m_s: float, drift_ned_m_s: tuple[float, float] = (0.0, 0.0)) -> float:
    """Course (ENU) from the ground velocity; yaw, then the previous course, when slow (or no sample).

    The ground velocity is the reported one plus ``drift_ned_m_s``, the velocity estimate's drift
    (north, east) where the tick compensates it.

    The one definition of this rule: the ticks, the course before the first tick and the holds
    streamed before the path starts all use it.
    """
    if sample is not None:
        vn, ve = sample.vx_ned_m_s + drift_ned_m_s[0], sample.vy_ned_m_s + drift_ned_m_s[1]
        if math.hypot(vn, ve) >= min_speed_m_s:
            return frames.course_enu_from_vel_ned(vn, ve)
    if yaw_ned_rad is not None and math.isfinite(yaw_ned_rad):
        return frames.course_enu_from_ned(yaw_ned_rad)
    return prev_course_rad


def compute_tick(
    guidance,
    tick: int,
    t_s: float,
    sample: PositionSample | None,
    sample_age_s: float,
    config: TickConfig,
    yaw_ned_rad: float | None = None,
    prev_course_rad: float = 0.0,
    prev_course_cmd_rad: float | None = None,
    drift: DriftEstimator | None = None,
    speed_hold: SpeedHold | None = None,
    tail: TailCompensator | None = None,
) -> TickResult:
    """Run one tick: newest position sample -> VehicleState -> guidance.step -> setpoint.

    Parameters
    ----------
    guidance : object with ``step(t_s, VehicleState) -> GuidanceOutput`` (``TwoPhaseGuidance``).
    tick : the tick counter (0 for the first tick run).
    t_s : tick time since the first tick, in the loop's clock (passed to ``guidance.step``).
    sample : newest valid LOCAL_POSITION_NED sample, or None if none has arrived yet.
    sample_age_s : age of ``sample`` at this tick (loop clock); > ``config.stale_s`` -> hold.
    config : the flight's tick settings.
    yaw_ned_rad : newest ATTITUDE yaw (fallback for the course when slow), or None.
    prev_course_rad : course used on the previous tick (last fallback).
    prev_course_cmd_rad : commanded course of the previous tick (``TickResult.course_cmd_rad``),
        None/NaN to start from the measured course.
    drift : the flight's drift estimator (``TickDriver.drift``), fed with every sample a tick
        uses, when ``config.compensates_drift``; None otherwise.
    speed_hold, tail : the flight's speed hold and tail compensator (``TickDriver.speed_hold``,
        ``TickDriver.tail``) when ``config.holds_speed``, ``config.compensates_tail``.
    """
    alt_m = -sample.z_ned_m if sample is not None else math.nan
    hold_reason = _hold_reason(sample, sample_age_s, config)
    state = None
    output = None
    course = prev_course_rad
    course_cmd = boost = math.nan
    drift_ned = comp_ned = (math.nan, math.nan)
    if hold_reason:  # stale or missing data: not even the altitude term uses it (vz = 0)
        setpoint = hold_for(config, alt_m, False, prev_course_rad)
        phase = "hold"
    else:
        if drift is not None and config.compensates_drift:
            drift_ned = drift.update(sample.time_s, sample.x_ned_m, sample.y_ned_m,
                                     sample.vx_ned_m_s, sample.vy_ned_m_s)
        gathering = config.gathering(sample)
        course = _gathering_course(gathering, yaw_ned_rad, prev_course_cmd_rad)
        if course is None:
            course = course_from_sample(sample, yaw_ned_rad, prev_course_rad, config.min_course_speed_m_s,
                                        _compensated(drift_ned))
        x_enu, y_enu, _ = frames.enu_from_ned(sample.x_ned_m, sample.y_ned_m, sample.z_ned_m)
        state = _vehicle_state(x_m=x_enu, y_m=y_enu, course_rad=course, speed_m_s=config.speed_m_s)
        output = guidance.step(t_s, state)
        phase = output.phase
        a_cmd = float(output.a_cmd_m_s2)
        if phase == "finished" or not math.isfinite(a_cmd):
            setpoint = hold_for(config, alt_m, True, course, output.s_proj_m)
            drift_ned = (math.nan, math.nan)  # a hold compensates nothing
        elif config.output == "attitude":
            setpoint = _attitude(config, a_cmd, course, alt_m, output.s_proj_m)
        else:
            setpoint, boost, comp_ned = _velocity(config, a_cmd, _led_course(config, course, prev_course_cmd_rad),
                                                  output.s_proj_m, alt_m, gathering, sample, _compensated(drift_ned),
                                                  speed_hold, tail)
            course_cmd = setpoint.course_cmd_enu_rad
    if tail is not None and not math.isfinite(comp_ned[0]):
        tail.reset()  # a hold, or the end: the setpoint is no longer ours to compensate

    prev_cmd = math.nan if prev_course_cmd_rad is None else float(prev_course_cmd_rad)
    return _tick_result(tick=tick, t_s=t_s, phase=phase, hold_reason=hold_reason, state=state, output=output,
                        setpoint=setpoint, sample=sample, sample_age_s=sample_age_s, course_rad=course,
                        course_cmd_rad=course_cmd, prev_course_cmd_rad=prev_cmd, prev_course_rad=prev_course_rad,
                        yaw_ned_rad=math.nan if yaw_ned_rad is None else float(yaw_ned_rad),
                        rate_hz=float(config.rate_hz), drift_n_m_s=drift_ned[0], drift_e_m_s=drift_ned[1],
                        drift_tc_s=float(config.drift_tc_s), speed_hold_m_s=boost,
                        speed_hold_tc_s=float(config.speed_hold_tc_s), tail_comp_n_m_s=comp_ned[0],
                        tail_comp_e_m_s=comp_ned[1], tail_share=float(config.tail_share),
                        tail_tc_s=float(config.tail_tc_s))


def _hold_reason(sample: PositionSample | None, sample_age_s: float, config: TickConfig) -> str:
    """Why a tick holds: no sample yet, or one older than ``stale_s`` (NaN ages too); "" if not."""
    if sample is None:
        return "no_position"
    return "" if sample_age_s <= config.stale_s else "stale"


def _led_course(config: TickConfig, course_rad: float, prev_course_cmd_rad: float | None) -> float:
    """The course the setpoint turns from: the commanded course carried from the previous tick,
    kept within ``max_course_lead_rad`` of the measured one (module docstring); the measured one
    when there is none (the first tick, after a hold)."""
    if prev_course_cmd_rad is None or not math.isfinite(prev_course_cmd_rad):
        return course_rad
    lead = frames.angle_diff_rad(prev_course_cmd_rad, course_rad)
    lead = max(-config.max_course_lead_rad, min(config.max_course_lead_rad, lead))
    return frames.wrap_pi(course_rad + lead)


def _feed_forward_share(gathering: bool, sample: PositionSample, speed_m_s: float) -> float:
    """The share of the command sent as the acceleration target (``velocity_setpoint``, which
    keeps it within [0, 1]): the measured ground speed over ``speed_m_s`` while the vehicle gathers
    speed (``gathering``: :meth:`TickConfig.gathering`), else 1. A copter leaving the hover turns its velocity with the
    setpoint on ``|v| a_cmd / V``; ArduCopter adds the whole target to a trajectory it starts from
    the hover's velocity, and the real one slid 7-10 cm sideways in its first 1.5 s (docs/flying.md)."""
    if not gathering:
        return 1.0
    return math.hypot(sample.vx_ned_m_s, sample.vy_ned_m_s) / speed_m_s


def _velocity(config: TickConfig, a_cmd: float, base: float, s_m: float, alt_m: float, gathering: bool,
              sample: PositionSample, drift_ned: tuple[float, float],
              speed_hold: SpeedHold | None,
              tail: TailCompensator | None) -> tuple[VelocitySetpoint, float, tuple[float, float]]:
    """A tick's velocity setpoint from the commanded course ``base``, the speed hold's
    correction in it (NaN when off) and the tail compensation in it (NED; NaN when off)."""
    speed, hold = _targets(config, s_m)
    boost = _speed_hold(speed_hold, config, gathering, sample, speed, drift_ned)
    comp = _tail_correction(tail, config, gathering, sample, speed)
    sp = velocity_setpoint(a_cmd, base, speed, config.dt_s, alt_m, hold, drift_ned, config.accel_ff_max_m_s2,
                           _feed_forward_share(gathering, sample, speed), _finite_or_zero(boost),
                           _compensated(comp))
    if tail is not None and config.compensates_tail:
        tail.sent(sp.vx_ned_m_s, sp.vy_ned_m_s)
    return sp, boost, comp


def _speed_hold(hold: SpeedHold | None, config: TickConfig, gathering: bool, sample: PositionSample,
                speed_m_s: float, drift_ned: tuple[float, float]) -> float:
    """The speed hold's correction for this tick (NaN when off): fed the ground speed the
    position moves at (the reported velocity plus the compensated drift), paused while the
    vehicle gathers speed (the take-off is not a speed error to integrate)."""
    if hold is None or not config.holds_speed:
        return math.nan
    if gathering:
        return hold.pause()
    return hold.update(sample.time_s, speed_m_s, sample.vx_ned_m_s + drift_ned[0], sample.vy_ned_m_s + drift_ned[1])


def _tail_correction(tail: TailCompensator | None, config: TickConfig, gathering: bool, sample: PositionSample,
                     speed_m_s: float) -> tuple[float, float]:
    """The tail compensation for this tick (NED; NaN when off): none while the vehicle gathers
    speed. From the hover the loop's error is the whole speed and its acceleration saturates:
    the identified linear tail does not hold there, and run through a take-off the compensation
    overshot the speed by 12 % and swung the real PX4 0.7 m across the path (docs/flying.md)."""
    if tail is None or not config.compensates_tail:
        return math.nan, math.nan
    if gathering:
        tail.reset()
        return 0.0, 0.0
    return tail.correction(sample.time_s, speed_m_s, sample.vx_ned_m_s, sample.vy_ned_m_s)


def _finite_or_zero(x: float) -> float:
    return x if math.isfinite(x) else 0.0


def _compensated(pair_ned: tuple[float, float]) -> tuple[float, float]:
    """The drift (or tail) a tick compensates: its estimate, or none (NaN: not compensating)."""
    return pair_ned if math.isfinite(pair_ned[0]) else (0.0, 0.0)


def _targets(config: TickConfig, s_m: float) -> tuple[float, object]:
    """Speed and altitude hold at arc length ``s_m``: the mission's constants, or its profile's."""
    if config.profile is None:
        return config.speed_m_s, config.altitude_hold
    return profile_targets(config.profile, s_m)


def _attitude(config: TickConfig, a_cmd: float, course: float, alt_m: float, s_m: float) -> AttitudeSetpoint:
    """The plane's setpoint; with an altitude profile it pitches to the flight-path angle of the
    climb the altitude hold asks for (``atan(climb / V)``)."""
    if config.profile is None:
        return attitude_setpoint(a_cmd, course, config.max_bank_deg, config.thrust)
    speed, hold = _targets(config, s_m)
    pitch = math.atan2(hold.climb_m_s(alt_m), speed)
    return attitude_setpoint(a_cmd, course, config.max_bank_deg, config.thrust, pitch)


def hold_for(config: TickConfig, alt_m: float, have_sample: bool,
             course_enu_rad: float, s_m: float = 0.0,
             position_ne_m: tuple[float, float] | None = None,
             anchor_ne_m: tuple[float, float] | None = None) -> VelocitySetpoint | AttitudeSetpoint:
    """The hold of this output: zero velocity and yaw rate (copter, rover; altitude held when a
    sample exists, at the profile's height at ``s_m`` for a mission with an altitude profile), or
    wings level on the last course (plane: it cannot stop; the autopilot's own setpoint-loss
    failsafe takes over if the hold lasts). With a fresh sample's ``position_ne_m`` and an
    ``anchor_ne_m`` (NED north, east), the copter's hold keeps that horizontal position
    (:func:`position_hold_setpoint`) instead of zero velocity."""
    if config.output == "attitude":
        return attitude_setpoint(0.0, course_enu_rad, config.max_bank_deg, config.thrust)
    hold = None
    if have_sample:
        hold = (profile_targets(config.profile, s_m, feed_forward=False)[1] if config.profile is not None
                else config.altitude_hold)
    if have_sample and position_ne_m is not None and anchor_ne_m is not None:
        return position_hold_setpoint(*position_ne_m, *anchor_ne_m, alt_m, hold)
    return hold_setpoint(alt_m, hold)


def coast_setpoint(last: TickResult | None, sample: PositionSample | None, sample_age_s: float,
                   config: TickConfig, course_cmd_rad: float,
                   turning: bool = True) -> VelocitySetpoint | AttitudeSetpoint:
    """The setpoint for a tick whose guidance step has not finished yet (a slow re-optimisation).

    Keeps turning at the last commanded acceleration from the commanded course (the zero-order hold
    of ``a_cmd`` the offline simulator assumes), so a slow step never freezes the velocity vector.
    With ``turning=False`` (the runner's choice once a coast has lasted ``max_coast_turn_s``) it
    flies straight on the commanded course instead: a long stall must not become a full circle.
    Stale or missing data, or a last tick that was a hold or the end, give a hold.
    """
    alt_m = -sample.z_ned_m if sample is not None else math.nan
    if (sample is None or not (sample_age_s <= config.stale_s) or last is None or last.output is None
            or last.phase in ("finished", "hold") or not math.isfinite(last.output.a_cmd_m_s2)):
        fresh = sample is not None and sample_age_s <= config.stale_s
        s_m = last.output.s_proj_m if last is not None and last.output is not None else 0.0
        return hold_for(config, alt_m, fresh, last.course_rad if last is not None else 0.0, s_m)
    a_cmd = float(last.output.a_cmd_m_s2) if turning else 0.0
    if config.output == "attitude":
        return _attitude(config, a_cmd, last.course_rad, alt_m, last.output.s_proj_m)
    base = course_cmd_rad if math.isfinite(course_cmd_rad) else last.course_rad
    speed, hold = _targets(config, last.output.s_proj_m)
    return velocity_setpoint(a_cmd, base, speed, config.dt_s, alt_m, hold,
                             _compensated((last.drift_n_m_s, last.drift_e_m_s)), config.accel_ff_max_m_s2,
                             _feed_forward_share(config.gathering(sample), sample, speed),
                             _finite_or_zero(last.speed_hold_m_s), _compensated((last.tail_comp_n_m_s,
                                                                                last.tail_comp_e_m_s)))


def _float32(x: float) -> float:
    """``x`` rounded to the nearest float32 (what DEBUG_FLOAT_ARRAY stores)."""
    return struct.unpack("<f", struct.pack("<f", x))[0] if math.isfinite(x) else x


def debug_row(result: TickResult) -> list[float]:
    """The ``DEBUG_FIELDS`` row of a tick (NaN where a field does not apply)."""
    nan = math.nan
    out = result.output
    sp = result.setpoint
    sample = result.sample
    if sample is not None:
        ground_speed_m_s = math.hypot(sample.vx_ned_m_s, sample.vy_ned_m_s)
        alt_m = -sample.z_ned_m
    else:
        ground_speed_m_s = alt_m = nan
    if isinstance(sp, VelocitySetpoint):
        vn, ve, vd = sp.vx_ned_m_s, sp.vy_ned_m_s, sp.vz_ned_m_s
        yaw_rate_enu = frames.yaw_rate_enu_from_ned(sp.yaw_rate_ned_rad_s)
        roll = nan
    else:
        vn = ve = vd = nan
        a = out.a_cmd_m_s2 if out is not None else 0.0
        yaw_rate_enu = a / result.state.speed_m_s if result.state is not None else 0.0
        roll = sp.roll_ned_rad
    state = result.state
    values = {  # by name: DEBUG_FIELDS gives the order
        "tick": float(result.tick),
        "t_s": float(result.t_s),
        "phase_code": float(result.phase_code),
        "a_cmd_m_s2": float(out.a_cmd_m_s2) if out is not None else 0.0,
        "crosstrack_m": float(out.crosstrack_m) if out is not None else nan,
        "s_proj_m": float(out.s_proj_m) if out is not None else nan,
        "k1": float(out.k1) if out is not None else nan,
        "k2": float(out.k2) if out is not None else nan,
        "x_enu_m": float(state.x_m) if state is not None else nan,
        "y_enu_m": float(state.y_m) if state is not None else nan,
        "course_enu_rad": float(result.course_rad),
        "speed_m_s": float(state.speed_m_s) if state is not None else nan,
        "yaw_rate_cmd_rad_s": float(yaw_rate_enu),
        "vn_cmd_m_s": float(vn),
        "ve_cmd_m_s": float(ve),
        "vd_cmd_m_s": float(vd),
        "reoptimised": 1.0 if (out is not None and out.reoptimised) else 0.0,
        "sample_age_s": float(result.sample_age_s),
        "ground_speed_m_s": float(ground_speed_m_s),
        "hold_reason": float(HOLD_REASON_CODES[result.hold_reason]),
        "roll_cmd_rad": float(roll),
        "alt_m": float(alt_m),
        "course_cmd_enu_rad": float(result.course_cmd_rad),
        "prev_course_cmd_rad": float(result.prev_course_cmd_rad),
        "prev_course_rad": float(result.prev_course_rad),
        "t_s_residual": float(result.t_s) - _float32(result.t_s),
        "setpoint_sent": 1.0,
        "debug_layout": float(DEBUG_LAYOUT),
        "yaw_ned_rad": float(result.yaw_ned_rad),
        "rate_hz": float(result.rate_hz),
        "drift_n_m_s": float(result.drift_n_m_s),
        "drift_e_m_s": float(result.drift_e_m_s),
        "drift_tc_s": float(result.drift_tc_s),
        "speed_hold_m_s": float(result.speed_hold_m_s),
        "speed_hold_tc_s": float(result.speed_hold_tc_s),
        "tail_comp_n_m_s": float(result.tail_comp_n_m_s),
        "tail_comp_e_m_s": float(result.tail_comp_e_m_s),
        "tail_share": float(result.tail_share),
        "tail_tc_s": float(result.tail_tc_s),
    }
    if len(values) != len(DEBUG_FIELDS):
        raise AssertionError(f"debug_row: {sorted(set(values) ^ set(DEBUG_FIELDS))}")
    return [values[name] for name in DEBUG_FIELDS]
