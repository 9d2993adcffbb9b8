"""Identify a multicopter's response to velocity + yaw-rate setpoints from a flown log.

    samples = resample(t_cmd_s=..., vel_cmd_ne_m_s=..., ...)       # uniform grid, pure arrays
    result = identify(samples)                                    # IdentifyResult
    result.model.a_max_m_s2, result.quality["vaf_one_step"], result.unidentified

The model (docs/vehicle_model.md) is the one the mock flies and the guidance plans with: the
horizontal velocity ``v`` follows the commanded velocity ``c`` seen ``delay_s`` late, reduced in
magnitude in turns by ``speed_sag_s * |a_lat|`` (the speed sag), through a first-order lag of
time constant ``lag_s`` whose acceleration is limited to ``a_max_m_s2`` (norm of the horizontal
acceleration; in a turn at constant speed, the lateral acceleration)::

    c_d(t) = c(t - delay_s) * max(0, 1 - speed_sag_s |a_lat(t)| / |c(t - delay_s)|)
    e      = c_d - v,   f += (e - f) (1 - exp(-dt / tail_tc_s))                 (the slow tail)
    dv     = (e - tail_share f) (1 - exp(-dt / lag_s)),   |dv| <= a_max_m_s2 dt  (one step dt)

and the yaw rate follows its command clipped to ``yaw_rate_max_rad_s``. Apart from the response,
the velocity estimate's errors are measured from how the reported position leaves the integral
of the reported velocity: the position's delay (:func:`position_delay`), a constant offset
(``vel_offset_m_s``, :func:`velocity_offset`) and the bias that wanders beside it
(``vel_bias_m_s``, ``vel_bias_tc_s``, :func:`velocity_bias`), more while the vehicle manoeuvres
where the log says so (``vel_bias_jerk_s2``, ``vel_bias_jerk_max_m_s3``, ``companion.sim.wander``).

How it is fitted
----------------
The measured velocity is smoothed (zero-phase Savitzky-Golay, :data:`SMOOTH_S`) and differenced.
The parameters minimise the **free-run** error of the horizontal acceleration vector: the model
driven by the commands alone (:func:`simulate`, restarted from the measurement after each gap in
the setpoint stream), its output passed through the same smoother, against the measurement; a
nonlinear least-squares problem solved by :func:`scipy.optimize.least_squares`, first for the
first-order model, then with the second lag ``accel_lag_s`` free, then instead with the slow tail
(``tail_share``, ``tail_tc_s``) free. Either extension is kept only if it cuts the residual by
:data:`SECOND_ORDER_GAIN` of itself and by :data:`SECOND_ORDER_GAIN_ABS` of the lateral
acceleration's RMS (the better of the two if both do). The fit quality is the variance of the
measured lateral acceleration the model explains (``1 - var(residual) / var(measured)``) one
step ahead (each step from the measured velocity, and acceleration for the second-order model,
where the figure is therefore close to 1 by construction; the slow tail's low-passed error is
computed from the measured velocities, as a predictor would) and in the free run, and the
residual RMS of each.

A parameter is *identified* when its 1-sigma standard error (from the Jacobian at the optimum)
is under :data:`MAX_RELATIVE_SE` of its value and the log excites it: the acceleration limit
needs the model to be saturated for at least :data:`MIN_SATURATED_S`; delay and lag need
:data:`MIN_TURNING_S` of changing lateral-acceleration command; the speed sag needs turning at
steady commanded speed; the yaw-rate limit needs the command to exceed what is flown for at
least :data:`MIN_SATURATED_S`. Otherwise :attr:`IdentifyResult.unidentified` names it and why.

Pure numpy/scipy: no files, no MAVLink (the tlog is read by ``companion.io``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.signal import lfilter, savgol_filter

from companion.guidance.types import ACCEL_FF_KEYS, VehicleModel
from companion.sim.wander import BiasSmoothing, JerkWander, fit_jerk_wander, fit_smoothing, manoeuvre_jerk_m_s3, usable_pairs

GRID_DT_S = 0.02  # resampling step (50 Hz, the rate the setpoints and positions are streamed at)
MAX_COMMAND_GAP_S = 0.2  # a setpoint older than this: no command stream, the sample is not used
SMOOTH_S = 0.3  # window of the smoother applied to the measured velocity before differencing
MIN_SPEED_M_S = 1.0  # below it the lateral direction is ill-defined
MAX_RELATIVE_SE = 0.1  # a parameter whose standard error exceeds this share of it is unidentified
MIN_SATURATED_S = 1.0
MIN_TURNING_S = 5.0
MIN_SAG_TURNING_S = 5.0
YAW_HOLD_S = 1.0  # a yaw-rate command held this long has had time to be flown
YAW_SATURATION_MARGIN = 1.2  # command at least 20 % above the flown rate counts as saturating it
BIAS_LAGS_S = (0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0)  # lags at which the velocity bias's drift is measured
BIAS_BOOTSTRAP_RUNS = 40  # drifts drawn from the fitted bias for its standard errors
BIAS_BOOTSTRAP_SEED = 0
NO_BIAS_TC_S = VehicleModel().vel_bias_tc_s  # the time constant written where there is no bias
ACROSS_MIN_SPEED_M_S = 2.0  # the bias across the track is measured where the vehicle flies at least this fast
POSITION_DELAY_LAG_S = 1.0  # the lag over which the drift's change is regressed on the velocity's
MAX_POSITION_DELAY_S = 0.5  # a fitted position delay beyond this (either way) is not one
DELAY_SCALE_S = 0.01  # a delay's standard error is judged against at least this (a delay of 0 is one too)
BIAS_NEGLIGIBLE_M_S = 0.01  # a velocity bias below this: none to speak of (its time constant is not judged)
OFFSET_NEGLIGIBLE_M_S = 0.001  # a constant velocity offset below this: none (a millimetre a second)
# The bias's correlation time shows only in how the drift bends over seconds, and a few minutes
# of flight hold a few dozen independent samples of that: it is accepted to this share.
MAX_RELATIVE_SE_BIAS_TC = 0.5
#: The bias's growth with the jerk is kept when it stands this many standard errors clear of zero.
JERK_WANDER_SIGNIFICANCE = 4.0

PARAMS = ("delay_s", "lag_s", "a_max_m_s2", "speed_sag_s", "accel_lag_s", "tail_share", "tail_tc_s",
          "accel_ff_gain", "accel_ff_lag_s")
_LOWER = np.array([0.0, 0.02, 0.2, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0])
_UPPER = np.array([1.5, 3.0, 30.0, 2.0, 2.0, 0.95, 20.0, 3.0, 1.5])
_SCALE = np.array([0.1, 0.1, 1.0, 0.1, 0.1, 0.1, 0.5, 0.1, 0.05])  # least-squares x_scale of each parameter
# The parameters each model structure fits (indices into PARAMS); the others stay at their
# neutral values (no second lag, no tail).
FIRST_ORDER = (0, 1, 2, 3)
SECOND_ORDER = (0, 1, 2, 3, 4)
SLOW_TAIL = (0, 1, 2, 3, 5, 6)
_NEUTRAL = np.array([0.0, 0.3, 3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
#: The acceleration target's gain and lag: fitted beside each structure's own when the log has one.
ACCEL_FF = tuple(PARAMS.index(name) for name in ACCEL_FF_KEYS)
#: Seconds of acceleration target (above ACCEL_FF_MIN_M_S2) a log needs to identify its gain and lag.
MIN_ACCEL_FF_S = 5.0
ACCEL_FF_MIN_M_S2 = 0.3
# The second-order model is kept when it cuts the free-run residual RMS by this share of it and
# by this share of the lateral acceleration's RMS (a cut of a tiny residual is no evidence).
SECOND_ORDER_GAIN = 0.1
SECOND_ORDER_GAIN_ABS = 0.02


class IdentifyError(ValueError):
    """The samples cannot be used at all (too short, no command stream, nothing moving)."""


@dataclass(frozen=True)
class Samples:
    """Commands and measurements on one uniform time grid (NE horizontal components).

    ``valid[k]`` is true where a command was being streamed and the measurement exists at both
    ``k`` and ``k + 1``; ``vel_cmd_ne_m_s`` is the command as sent (no delay applied): the model
    reads it at ``t - delay_s`` by linear interpolation in ``t_cmd_s`` / ``vel_cmd_raw``.
    """

    t_s: np.ndarray
    vel_ne_m_s: np.ndarray  # (N, 2) measured
    valid: np.ndarray  # (N,) bool
    t_cmd_s: np.ndarray  # raw command times
    vel_cmd_raw_ne_m_s: np.ndarray  # (M, 2) raw commands
    yaw_rate_cmd_raw_rad_s: np.ndarray  # (M,)
    t_yaw_s: np.ndarray  # measured yaw-rate times
    yaw_rate_rad_s: np.ndarray  # measured yaw rate
    pos_ne_m: np.ndarray | None = None  # (N, 2) measured position (None: the log has none)
    # (N,) the autopilot's own clock at each grid time (None: the grid's): the velocity is
    # integrated over it, as the vehicle moved in the autopilot's seconds
    t_autopilot_s: np.ndarray | None = None
    # (M, 2) the acceleration target sent with each command (None: the log's setpoints had none)
    acc_ff_raw_ne_m_s2: np.ndarray | None = None

    def has_accel_target(self) -> bool:
        return self.acc_ff_raw_ne_m_s2 is not None and bool(np.any(self.acc_ff_raw_ne_m_s2 != 0.0))


def resample(*, t_cmd_s: ArrayLike, vel_cmd_ne_m_s: ArrayLike, yaw_rate_cmd_rad_s: ArrayLike,
             t_meas_s: ArrayLike, vel_meas_ne_m_s: ArrayLike, t_yaw_s: ArrayLike = (),
             yaw_rate_meas_rad_s: ArrayLike = (), pos_meas_ne_m: ArrayLike | None = None,
             t_meas_autopilot_s: ArrayLike | None = None, acc_ff_ne_m_s2: ArrayLike | None = None,
             dt_s: float = GRID_DT_S) -> Samples:
    """Put the log's commands and measurements on one grid of step ``dt_s``.

    Times are seconds on one clock (the log's). Measured velocities (and positions, when given)
    are interpolated linearly onto the grid; a grid point is valid when the newest command is at
    most :data:`MAX_COMMAND_GAP_S` old and the measurement brackets it closely.
    ``t_meas_autopilot_s``, the measurements' own time stamps (the autopilot's clock), is carried
    onto the grid the same way (:attr:`Samples.t_autopilot_s`). ``acc_ff_ne_m_s2``, the
    acceleration target sent with each command (zero where a setpoint carried none), is kept with
    the commands.
    """
    t_cmd = np.asarray(t_cmd_s, float)
    vc = np.asarray(vel_cmd_ne_m_s, float).reshape(-1, 2)
    yc = np.asarray(yaw_rate_cmd_rad_s, float)
    tm = np.asarray(t_meas_s, float)
    vm = np.asarray(vel_meas_ne_m_s, float).reshape(-1, 2)
    if len(t_cmd) < 10:
        raise IdentifyError(f"only {len(t_cmd)} velocity setpoints: expected a flight streaming them")
    if len(tm) < 10:
        raise IdentifyError(f"only {len(tm)} velocity measurements: expected LOCAL_POSITION_NED throughout")
    order = np.argsort(t_cmd, kind="stable")
    t_cmd, vc, yc = t_cmd[order], vc[order], yc[order]
    ff = None if acc_ff_ne_m_s2 is None else np.asarray(acc_ff_ne_m_s2, float).reshape(-1, 2)[order]
    order = np.argsort(tm, kind="stable")
    tm, vm = tm[order], vm[order]
    pm = None if pos_meas_ne_m is None else np.asarray(pos_meas_ne_m, float).reshape(-1, 2)[order]
    t0 = max(t_cmd[0], tm[0])
    t1 = min(t_cmd[-1], tm[-1])
    if t1 - t0 < 10 * dt_s:
        raise IdentifyError("the setpoints and the measurements do not overlap in time")
    t = np.arange(t0, t1, dt_s)
    v = np.column_stack([np.interp(t, tm, vm[:, 0]), np.interp(t, tm, vm[:, 1])])
    idx = np.searchsorted(t_cmd, t, side="right") - 1
    cmd_age = t - t_cmd[np.clip(idx, 0, None)]
    jdx = np.clip(np.searchsorted(tm, t), 1, len(tm) - 1)
    meas_gap = tm[jdx] - tm[jdx - 1]
    ok = (idx >= 0) & (cmd_age <= MAX_COMMAND_GAP_S) & (meas_gap <= 0.25)
    valid = ok.copy()
    valid[:-1] &= ok[1:]
    valid[-1] = False
    finite = np.isfinite(v).all(axis=1)
    valid &= finite & np.roll(finite, -1)
    pos = None if pm is None else np.column_stack([np.interp(t, tm, pm[:, 0]), np.interp(t, tm, pm[:, 1])])
    t_ap = None if t_meas_autopilot_s is None else np.interp(t, tm, np.asarray(t_meas_autopilot_s, float)[order])
    return Samples(t, v, valid, t_cmd, vc, yc, np.asarray(t_yaw_s, float), np.asarray(yaw_rate_meas_rad_s, float),
                   pos, t_ap, ff)


def velocity_bias(t_s: np.ndarray, pos_ne_m: np.ndarray, vel_ne_m_s: np.ndarray, valid: np.ndarray,
                  t_autopilot_s: np.ndarray | None = None,
                  pos_delay_s: float = 0.0) -> tuple[float, float, float, float, dict[float, float]]:
    """The velocity estimate's bias: ``(sigma_m_s, tc_s, se_sigma_m_s, se_tc_s, structure)``.

    On a uniform grid, ``e(t) = p(t) - integral of v`` (reported position minus the integral of
    the reported velocity) moves only by what the velocity estimate misses. For a bias that is a
    first-order Gauss-Markov process (standard deviation sigma, correlation time tau) on each
    axis, the change of ``e`` over a lag ``T`` has the mean square::

        D^2(T) = 2 sigma^2 tau^2 (T / tau - 1 + exp(-T / tau))

    (``sigma T`` for ``T << tau``; a random walk ``2 sigma^2 tau T`` for ``T >> tau``). ``D`` is
    measured at the lags :data:`BIAS_LAGS_S` (up to a quarter of the valid span), over pairs of
    samples with every sample between them valid, both axes pooled, and ``(sigma, tau)`` fitted
    in log space, each lag weighted by its number of independent pairs (one per ``max(T, tau)``).
    The lags share their samples, so the standard errors are a parametric bootstrap's: the spread
    of the same fit on :data:`BIAS_BOOTSTRAP_RUNS` drifts drawn from the fitted process over the
    same samples (seeded: the same log gives the same errors). ``structure``
    maps each lag ``T`` (s) to the measured ``D`` (m). Pure: arrays in, numbers out.

    The velocity is integrated over ``t_autopilot_s`` when given (the autopilot's clock at each
    grid time): a simulator's clock can run slower than the log's, and integrating over the log's
    seconds would then add ``v`` times the difference in rates to the drift (0.07 m/s at 5 m/s
    for PX4 SIH's steady 1.3 %; far more where its clock slips unevenly). With ``pos_delay_s``
    (:func:`position_delay`) the drift is measured against the integral that much earlier, so
    that a position reported late is not counted as a bias.
    """
    e, ok, dt = _drift_ne(t_s, pos_ne_m, vel_ne_m_s, valid, t_autopilot_s, pos_delay_s)
    return _fit_bias_with_errors([(e, ok)], dt)


def across_track_velocity_bias(t_s: np.ndarray, pos_ne_m: np.ndarray, vel_ne_m_s: np.ndarray, valid: np.ndarray,
                               t_autopilot_s: np.ndarray | None = None,
                               min_speed_m_s: float = ACROSS_MIN_SPEED_M_S,
                               pos_delay_s: float = 0.0) -> tuple[float, float, float, float, dict[float, float]]:
    """The velocity bias across the track only: as :func:`velocity_bias`, on the component of the
    drift ``e`` perpendicular to the reported velocity, over the samples flown at
    ``min_speed_m_s`` or more.

    A track moves by the bias across it; along it the bias only changes the speed. PX4 SIH's
    is larger across the track than along it (docs/vehicle_model.md), so this is the figure that
    predicts how far a track wanders. Each step of ``e`` is projected on the left normal of that
    step's velocity and summed: for a bias of ``sigma`` across the track, its structure is that of
    :func:`velocity_bias` with that ``sigma``.
    """
    across, ok, dt = _across_drift(t_s, pos_ne_m, vel_ne_m_s, valid, t_autopilot_s, min_speed_m_s, pos_delay_s)
    return _fit_bias_with_errors([(across, ok)], dt)


def pooled_across_track_bias(flights: list[Samples], min_speed_m_s: float = ACROSS_MIN_SPEED_M_S,
                             pos_delay_s: float = 0.0,
                             past_offset: bool = False) -> tuple[float, float, float, float, dict[float, float]]:
    """One bias process fitted to several flights at once: as :func:`across_track_velocity_bias`,
    with every flight's pairs of samples pooled at each lag (no pair spans two flights).

    This is the estimate of the process the flights share, the one a simulator should fly: each
    flight of a minute holds few independent samples of a correlation time of seconds, and the
    fits of single flights scatter along a ridge (a larger ``sigma`` with a shorter ``tau`` drifts
    alike). The median of their ``sigma`` and the median of their ``tau``, taken apart, come from
    different flights and can describe a process none of them flew: one flight of a slow bias
    among six is dropped by both medians, though it drifts furthest. Pooled, it counts for its
    share of the seconds. With ``past_offset`` each flight's drift is taken without its constant
    offset and turn (:func:`velocity_offset`'s ``rest``): the bias that wanders beside the offset.
    ValueError when there are no flights, when they are not on one time step or when one has no
    positions.
    """
    segments = []
    for f, pos in _with_positions(flights, "pooled bias"):
        if past_offset:
            _, _, across, ok, dt = velocity_offset(f.t_s, pos, f.vel_ne_m_s, f.valid, f.t_autopilot_s,
                                                   min_speed_m_s, pos_delay_s)
        else:
            across, ok, dt = _across_drift(f.t_s, pos, f.vel_ne_m_s, f.valid, f.t_autopilot_s, min_speed_m_s,
                                           pos_delay_s)
        segments.append((across, ok))
    return _fit_bias_with_errors(segments, dt)


def pooled_jerk_wander(flights: list[Samples], tc_s: float, min_speed_m_s: float = ACROSS_MIN_SPEED_M_S,
                       pos_delay_s: float = 0.0) -> JerkWander | None:
    """The wander that grows with the manoeuvre (``companion.sim.wander``), fitted to several
    flights at once across the track, past each flight's offset (as :func:`pooled_across_track_bias`
    with ``past_offset``), at the correlation time ``tc_s``. None when too few windows can be used;
    ValueError as :func:`pooled_across_track_bias`."""
    segments, dt = _wander_segments(flights, "pooled jerk wander", min_speed_m_s, pos_delay_s)
    return fit_jerk_wander(segments, dt, tc_s)


def pooled_bias_smoothing(flights: list[Samples], wander: JerkWander, min_speed_m_s: float = ACROSS_MIN_SPEED_M_S,
                          pos_delay_s: float = 0.0) -> BiasSmoothing | None:
    """The smoothing of a wander's bias (``companion.sim.wander.fit_smoothing``) that gives back the
    fast part of several flights' drifts across the track, past each flight's offset (the samples
    of :func:`pooled_jerk_wander`). None as ``fit_smoothing``; ValueError as
    :func:`pooled_across_track_bias`."""
    segments, dt = _wander_segments(flights, "pooled bias smoothing", min_speed_m_s, pos_delay_s)
    return fit_smoothing(segments, dt, wander)


def _wander_segments(flights: list[Samples], what: str, min_speed_m_s: float,
                     pos_delay_s: float) -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray]], float]:
    """Each flight's drift across the track past its offset and turn, its valid samples and its
    manoeuvre jerk; and the grid's step."""
    segments, dt = [], 0.0
    for f, pos in _with_positions(flights, what):
        _, _, rest, ok, dt = velocity_offset(f.t_s, pos, f.vel_ne_m_s, f.valid, f.t_autopilot_s, min_speed_m_s,
                                             pos_delay_s)
        _, acc, *_ = _measured(f)
        segments.append((rest, ok, manoeuvre_jerk_m_s3(acc, dt)))
    return segments, dt


def pooled_velocity_offset(flights: list[Samples], min_speed_m_s: float = ACROSS_MIN_SPEED_M_S,
                           pos_delay_s: float = 0.0) -> tuple[float, float]:
    """The standard deviation of the constant offset that flights draw, per axis: ``(sigma, se)``.

    Each flight's offset (:func:`velocity_offset`) is one draw on each axis, measured with an error
    ``s``: its square is ``sigma^2 + s^2`` on average, so ``sigma^2`` is the mean of ``c^2 - s^2``
    over the flights' components (0 if that is negative). ``se`` is the spread of that mean by
    the delta method. A flight whose track keeps one direction adds its large error to both
    sides and counts for little. ValueError when there are no flights or one has no positions.
    """
    parts = []
    for f, pos in _with_positions(flights, "pooled offset"):
        c, s, *_ = velocity_offset(f.t_s, pos, f.vel_ne_m_s, f.valid, f.t_autopilot_s, min_speed_m_s, pos_delay_s)
        parts.append(_offset_terms(c, s))
    values = np.concatenate(parts)
    if not values.size:
        return 0.0, math.inf
    sigma = _offset_sigma(values)
    spread = float(np.std(values, ddof=1)) / math.sqrt(values.size) if values.size > 1 else math.inf
    return sigma, (spread / (2.0 * sigma) if sigma > 0.0 else math.inf)


def _with_positions(flights: list[Samples], what: str) -> list[tuple[Samples, np.ndarray]]:
    """Each flight with its positions, checked to be some flights, on one time step, each with
    positions (ValueError)."""
    if not flights:
        raise ValueError(f"{what}: expected at least one flight, got none")
    steps = {float(f.t_s[1] - f.t_s[0]) for f in flights if f.t_s.size > 1}
    if len(steps) != 1:
        raise ValueError(f"{what}: expected flights on one time step, got steps {sorted(steps)}")
    out = [(f, f.pos_ne_m) for f in flights if f.pos_ne_m is not None]
    if len(out) < len(flights):
        raise ValueError(f"{what}: a flight has no positions")
    return out


def velocity_offset(t_s: np.ndarray, pos_ne_m: np.ndarray, vel_ne_m_s: np.ndarray, valid: np.ndarray,
                    t_autopilot_s: np.ndarray | None = None, min_speed_m_s: float = ACROSS_MIN_SPEED_M_S,
                    pos_delay_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The velocity estimate's constant offset: ``(offset_ne_m_s, se_ne_m_s, rest, valid, dt)``.

    ArduCopter SITL's estimate misses a velocity that stays put in the north-east frame for a
    whole flight (about 1 cm/s; docs/vehicle_model.md). On a straight leg it moves the track by a
    steady rate, which the autopilot's position loop takes up; only where the track turns does its
    share across the track change. So it is told apart from the bias that wanders
    (:func:`velocity_bias`) by the track's turns: the drift across the track
    (:func:`across_track_velocity_bias`) moves by ``c . left`` per second for an offset ``c``
    (``left`` the unit normal of the velocity), and by ``rho |v|`` for a velocity turned by a small
    angle ``rho`` (a drift across the track that never changes: no track moves by it, but it must
    not be taken for ``c``). ``c`` and ``rho`` are the least squares of the drift's changes over
    :data:`POSITION_DELAY_LAG_S` on those of ``integral(left)`` and ``integral(|v|)``; the
    standard errors count one independent pair per lag or per correlation time of what is left
    (:func:`velocity_bias`'s ``tau``), whichever is longer: a bias that wanders slowly holds
    still for a while, and looks like an offset over that while. A log
    whose track keeps one direction cannot tell ``c`` from ``rho``: its errors come out large
    (infinite if it never turns).

    ``rest`` is the drift across the track without the fitted offset and turn (one column, on
    :func:`across_track_velocity_bias`'s samples ``valid``): what the wandering bias must explain.
    ``(0, inf)`` errors when fewer than ten pairs can be used.

    Examples
    --------
    A circle flown at 5 m/s with the velocity estimate missing 0.02 m/s north:

    >>> t = np.arange(0.0, 60.0, 0.02)
    >>> w = 5.0 / 20.0
    >>> vel = np.column_stack([-5.0 * np.sin(w * t), 5.0 * np.cos(w * t)])
    >>> pos = np.column_stack([20.0 * np.cos(w * t) + 0.02 * t, 20.0 * np.sin(w * t)])
    >>> offset, se, rest, ok, dt = velocity_offset(t, pos, vel, np.ones(t.size, bool))
    >>> [round(float(x), 4) + 0.0 for x in offset]
    [0.02, 0.0]
    """
    across, ok, dt = _across_drift(t_s, pos_ne_m, vel_ne_m_s, valid, t_autopilot_s, min_speed_m_s, pos_delay_s)
    left, speed = _unit_lateral(np.asarray(vel_ne_m_s, float))
    w = np.where(ok, dt, 0.0)[:, None]
    x = np.cumsum(np.column_stack([left, speed]) * w, axis=0)  # integral(left_n), integral(left_e), integral(|v|)
    k = max(1, int(round(POSITION_DELAY_LAG_S / dt)))
    none = (np.zeros(2), np.full(2, math.inf), across, ok, dt)
    if ok.size <= k:
        return none
    use = usable_pairs(ok, k)
    dx, dy = (x[k:] - x[:-k])[use], (across[k:, 0] - across[:-k, 0])[use]
    if dy.size < 10:
        return none
    coef, *_ = np.linalg.lstsq(dx, dy, rcond=None)
    residual = dy - dx @ coef
    rest = across - (x @ coef)[:, None]
    # one independent pair per lag, or per correlation time of what is left if that is longer
    fit = _fit_bias([(rest, ok)], dt)
    independent = max(1.0, float(use.sum()) / max(k, fit[1] / dt if fit is not None else 0.0))
    scale = float(residual @ residual) / max(1, dy.size - 3) * dy.size / independent
    gram = dx.T @ dx
    if np.linalg.cond(gram) > 1e12:  # a track that never turns: nothing tells c from rho
        return coef[:2], np.full(2, math.inf), rest, ok, dt
    se = np.sqrt(np.maximum(np.diag(np.linalg.inv(gram))[:2] * scale, 0.0))
    return coef[:2], se, rest, ok, dt


def _across_drift(t_s: np.ndarray, pos_ne_m: np.ndarray, vel_ne_m_s: np.ndarray, valid: np.ndarray,
                  t_autopilot_s: np.ndarray | None, min_speed_m_s: float,
                  pos_delay_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """``(across, valid, dt)``: the drift's component across the track, summed step by step, as a
    one-column array, valid where the vehicle flies at ``min_speed_m_s`` or more."""
    e, ok, dt = _drift_ne(t_s, pos_ne_m, vel_ne_m_s, valid, t_autopilot_s, pos_delay_s)
    left, speed = _unit_lateral(np.asarray(vel_ne_m_s, float))
    ok = ok & (speed >= min_speed_m_s)
    de = np.zeros_like(e)
    de[1:] = np.diff(e, axis=0)
    return np.cumsum(np.where(ok, np.sum(de * left, axis=1), 0.0))[:, None], ok, dt


def _drift_ne(t_s: np.ndarray, pos_ne_m: np.ndarray, vel_ne_m_s: np.ndarray, valid: np.ndarray,
              t_autopilot_s: np.ndarray | None, pos_delay_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """``(e, valid, dt)``: the reported position minus the integral of the reported velocity up
    to ``pos_delay_s`` earlier (the position's own delay, :func:`position_delay`)."""
    t = np.asarray(t_s, float)
    dt = float(t[1] - t[0])
    ok = np.asarray(valid, bool)
    integral = velocity_integral(t, vel_ne_m_s, t_autopilot_s)
    if pos_delay_s != 0.0:
        integral = np.column_stack([np.interp(t - pos_delay_s, t, integral[:, i]) for i in range(2)])
    return np.asarray(pos_ne_m, float) - integral, ok, dt


def velocity_integral(t_s: np.ndarray, vel_ne_m_s: np.ndarray, t_autopilot_s: np.ndarray | None = None) -> np.ndarray:
    """The track the reported velocity alone gives, from 0 at the first sample (trapezoids over
    the autopilot's clock ``t_autopilot_s`` when given, else over the grid's step)."""
    v = np.asarray(vel_ne_m_s, float)
    step = np.zeros_like(v)
    t = np.asarray(t_s, float)
    step_s = float(t[1] - t[0]) if t_autopilot_s is None else np.diff(np.asarray(t_autopilot_s, float))[:, None]
    step[1:] = 0.5 * (v[1:] + v[:-1]) * step_s
    return np.cumsum(step, axis=0)


def gauss_markov_drift(rng: np.random.Generator, shape: tuple[int, int], sigma: float, tau_s: float,
                       dt_s: float) -> np.ndarray:
    """The drift (m) of a first-order Gauss-Markov bias (``sigma`` m/s, ``tau_s``, started in its
    stationary distribution) on each of ``shape[1]`` axes over ``shape[0]`` samples ``dt_s``
    apart: the bias summed times ``dt_s``."""
    phi = math.exp(-dt_s / tau_s)
    kicks = rng.standard_normal(shape) * sigma * math.sqrt(1.0 - phi * phi)
    kicks[0] = rng.standard_normal(shape[1]) * sigma
    return np.asarray(np.cumsum(lfilter([1.0], [1.0, -phi], kicks, axis=0), axis=0) * dt_s, float)


def position_delay(t_s: np.ndarray, pos_ne_m: np.ndarray, vel_ne_m_s: np.ndarray, valid: np.ndarray,
                   t_autopilot_s: np.ndarray | None = None,
                   lag_s: float = POSITION_DELAY_LAG_S) -> tuple[float, float]:
    """How much older the reported position is than the reported velocity: ``(delay_s, se_s)``.

    A position reported ``delta`` late is ``P(t - delta)``, ``P`` the integral of the velocity, so
    the drift ``e = p - P`` holds ``-delta v(t)`` besides the velocity bias's own drift ``b``. Over
    a lag ``T`` its change is ``De = Db - delta Dv``: the least-squares ``delta`` of ``De`` on
    ``-Dv`` over every pair of valid samples ``T`` apart (both axes pooled). A bias that does not
    follow the velocity's changes leaves it unbiased; the standard error counts one independent
    pair per ``T`` and axis (it understates the scatter between flights about twofold: a bias
    that by chance follows one flight's velocity changes moves the fit). ArduCopter SITL's comes
    out 13-24 ms (docs/vehicle_model.md), PX4 SIH's about 0. ``(0, inf)`` when the velocity hardly changes over the log.

    Examples
    --------
    A position reported 0.05 s late on a circle flown at 5 m/s:

    >>> t = np.arange(0.0, 60.0, 0.02)
    >>> w = 5.0 / 20.0
    >>> vel = np.column_stack([-5.0 * np.sin(w * t), 5.0 * np.cos(w * t)])
    >>> pos = np.column_stack([20.0 * np.cos(w * (t - 0.05)), 20.0 * np.sin(w * (t - 0.05))])
    >>> delay, se = position_delay(t, pos, vel, np.ones(t.size, bool))
    >>> round(delay, 4)
    0.05
    """
    e, ok, dt = _drift_ne(t_s, pos_ne_m, vel_ne_m_s, valid, t_autopilot_s)
    v = np.asarray(vel_ne_m_s, float)
    k = max(1, int(round(lag_s / dt)))
    if ok.size <= k:
        return 0.0, math.inf
    use = usable_pairs(ok, k)
    x = -(v[k:] - v[:-k])[use].ravel()
    y = (e[k:] - e[:-k])[use].ravel()
    sxx = float(x @ x)
    if x.size < 10 or sxx <= 1e-9 * x.size:
        return 0.0, math.inf
    delay = float(x @ y) / sxx
    residual = y - delay * x
    independent = max(1.0, 2.0 * float(use.sum()) / k)  # pairs T apart, two axes
    se = math.sqrt(float(residual @ residual) / max(1, x.size - 1) / sxx * x.size / independent)
    return delay, se


def _fit_bias_with_errors(segments: list[tuple[np.ndarray, np.ndarray]], dt: float,
                          ) -> tuple[float, float, float, float, dict[float, float]]:
    """:func:`_fit_bias` with the parametric bootstrap's standard errors (see :func:`velocity_bias`)."""
    full = _fit_bias(segments, dt)
    if full is None:
        return 0.0, NO_BIAS_TC_S, math.inf, math.inf, {}
    sigma, tau, structure = full
    # Parametric bootstrap: the same fit on drifts drawn from the fitted process over the same
    # samples (an AR(1) bias on each axis, integrated); the spread of those fits is the error.
    rng = np.random.default_rng(BIAS_BOOTSTRAP_SEED)
    estimates = []
    for _ in range(BIAS_BOOTSTRAP_RUNS):
        drawn = [(gauss_markov_drift(rng, e.shape, sigma, tau, dt), ok) for e, ok in segments]
        part = _fit_bias(drawn, dt)
        if part is not None:
            estimates.append(part[:2])
    if len(estimates) < BIAS_BOOTSTRAP_RUNS // 2:
        return sigma, tau, math.inf, math.inf, structure
    se = np.std(np.array(estimates), axis=0, ddof=1)
    return sigma, tau, float(se[0]), float(se[1]), structure


def _fit_bias(segments: list[tuple[np.ndarray, np.ndarray]], dt: float) -> tuple[float, float, dict[float, float]] | None:
    """``(sigma, tau, D by lag)`` fitted to the drifts ``e`` over their samples ``ok``, one
    ``(e, ok)`` per flight (see :func:`velocity_bias`); None when fewer than three lags can be
    measured. A flight adds its pairs at a lag up to a quarter of its own valid span."""
    # Per flight: its valid span, and where a pair is usable (no invalid sample between its ends).
    flights = [(e, ok, float(ok.sum()) * dt) for e, ok in segments]
    lags, meas, pairs = [], [], []
    for lag in BIAS_LAGS_S:
        k = int(round(lag / dt))
        squares, count, used = 0.0, 0, 0
        for e, ok, span in flights:
            if k < 1 or lag > span / 4.0:
                continue
            use = usable_pairs(ok, k)
            d = e[k:][use] - e[:-k][use]
            squares += float(np.sum(d * d))
            count += d.size
            used += int(use.sum())
        if used < 10:
            continue
        lags.append(lag)
        meas.append(math.sqrt(squares / count))
        pairs.append(float(used) * dt)  # seconds of usable pairs (per axis)
    if len(lags) < 3 or min(meas) <= 0.0:
        return None
    lag_a, log_meas, pair_s = np.array(lags), np.log(meas), np.array(pairs)

    def log_d(x: np.ndarray) -> np.ndarray:
        sigma, tau = np.exp(np.clip(x, -30.0, 30.0))
        r = lag_a / tau
        return np.asarray(np.log(np.sqrt(2.0) * sigma * tau) + 0.5 * np.log(np.maximum(r - 1.0 + np.exp(-r), 1e-300)))

    x = np.log([meas[0] / lags[0], 3.0])
    for _ in range(2):  # the weights depend on tau: fit, then fit again with the fitted tau's
        # log D from n independent pairs (both axes) has a variance of about 1 / (2 n)
        w = np.sqrt(2.0 * 2.0 * pair_s / np.maximum(lag_a, math.exp(x[1])))
        x = least_squares(lambda z, w=w: (log_d(z) - log_meas) * w, x, method="lm").x
    sigma, tau = (float(v) for v in np.exp(x))
    return sigma, tau, dict(zip(lags, meas))


def _offset_terms(offset_ne: np.ndarray, se_ne: np.ndarray) -> np.ndarray:
    """``c^2 - s^2`` for each offset component measured (finite error ``s``): on average ``sigma^2``."""
    return np.asarray((offset_ne * offset_ne - se_ne * se_ne)[np.isfinite(se_ne)], float)


def _offset_sigma(terms: np.ndarray) -> float:
    """The offset's standard deviation from :func:`_offset_terms` (0 where they say none)."""
    return math.sqrt(max(0.0, float(np.mean(terms)))) if terms.size else 0.0


def _unit_lateral(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vector to the left of the velocity (NE frame: north, east; left of north is west)."""
    speed = np.hypot(v[..., 0], v[..., 1])
    safe = np.maximum(speed, 1e-9)
    return np.stack([v[..., 1] / safe, -v[..., 0] / safe], axis=-1), speed


def lateral_m_s2(vel_ne_m_s: np.ndarray, acc_ne_m_s2: np.ndarray) -> np.ndarray:
    """Lateral acceleration, ``(v x a) / |v|`` with NE components, positive to the left of the
    velocity (a left turn: anticlockwise seen from above)."""
    lat, _ = _unit_lateral(vel_ne_m_s)
    return np.asarray(np.sum(lat * acc_ne_m_s2, axis=-1), dtype=float)


def _delayed_command(s: Samples, delay_s: float) -> np.ndarray:
    tq = s.t_s - delay_s
    return np.column_stack([np.interp(tq, s.t_cmd_s, s.vel_cmd_raw_ne_m_s[:, 0]),
                            np.interp(tq, s.t_cmd_s, s.vel_cmd_raw_ne_m_s[:, 1])])


def _delayed_accel_target(s: Samples, delay_s: float) -> np.ndarray:
    """The acceleration target at ``t - delay_s`` (held from each command, as the vehicle holds it)."""
    if s.acc_ff_raw_ne_m_s2 is None:
        return np.zeros((len(s.t_s), 2))
    idx = np.clip(np.searchsorted(s.t_cmd_s, s.t_s - delay_s, side="right") - 1, 0, None)
    return np.asarray(s.acc_ff_raw_ne_m_s2[idx], dtype=float)


def smoothed(s: Samples) -> np.ndarray:
    """The measured velocity through a zero-phase Savitzky-Golay smoother (quadratic, window
    :data:`SMOOTH_S`): differencing 50 Hz estimator output amplifies its sample noise (PX4's by
    metres per second squared), far above the dynamics being fitted."""
    dt = float(s.t_s[1] - s.t_s[0])
    window = max(5, int(round(SMOOTH_S / dt)) | 1)
    if len(s.t_s) <= window:
        return np.array(s.vel_ne_m_s, dtype=float)
    return np.asarray(savgol_filter(s.vel_ne_m_s, window, 2, axis=0, mode="interp"), dtype=float)


def _smooth_like_measured(s: Samples, acc: np.ndarray) -> np.ndarray:
    """The same smoother applied to a model's acceleration, so a free run is compared with the
    measurement like with like (both linear filters commute with differencing)."""
    dt = float(s.t_s[1] - s.t_s[0])
    window = max(5, int(round(SMOOTH_S / dt)) | 1)
    if len(s.t_s) <= window:
        return acc
    return np.asarray(savgol_filter(acc, window, 2, axis=0, mode="interp"), dtype=float)


def _measured(s: Samples) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    dt = float(s.t_s[1] - s.t_s[0])
    v = smoothed(s)
    acc = np.zeros_like(v)
    acc[:-1] = (v[1:] - v[:-1]) / dt
    # lateral acceleration of the step, about the mean velocity over it
    v_mid = v.copy()
    v_mid[:-1] = 0.5 * (v[1:] + v[:-1])
    return dt, acc, lateral_m_s2(v_mid, acc), v_mid, v


def _used(s: Samples, v_mid: np.ndarray, delay_s: float) -> np.ndarray:
    return np.asarray(s.valid & (np.hypot(v_mid[:, 0], v_mid[:, 1]) > MIN_SPEED_M_S)
                      & (s.t_s - delay_s >= s.t_cmd_s[0]), dtype=bool)


def simulate(s: Samples, theta: ArrayLike, *, one_step: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Run the model over the samples; returns ``(acc (N, 2), saturated (N,))``: the model's
    acceleration over each step ``k -> k + 1``.

    ``theta`` = ``(delay_s, lag_s, a_max_m_s2, speed_sag_s, accel_lag_s, tail_share, tail_tc_s,
    accel_ff_gain, accel_ff_lag_s)`` (the tail's two and the target's two may be left out: none, and
    a target added as sent). The acceleration target, times its gain through its lag, joins the
    demand as the velocity error that would ask for it, before the tail (docs/vehicle_model.md).
    In a free run (default) the state is the model's own, restarted from the (smoothed)
    measurement after each gap in the command stream (the tail's low-pass from the error there,
    the target's lag from the target); with ``one_step`` every step starts from the measured
    velocity (and acceleration, for the second-order model; the tail's low-pass runs on the
    measured error), so the result is the one-step prediction.
    The speed sag always reads the model's own lateral acceleration: the measured one, a
    difference of a noisy estimate, would feed its noise straight into the prediction.
    """
    dt, acc_m, a_lat_m, _, v_m = _measured(s)
    theta = np.asarray(theta, dtype=float)
    delay, lag, a_max, sag, acc_lag = (float(x) for x in theta[:5])
    share, tail_tc = (float(theta[5]), float(theta[6])) if theta.size > 5 else (0.0, 1.0)
    ff_gain, ff_lag = (float(theta[7]), float(theta[8])) if theta.size > 7 else (1.0, 0.0)
    c = _delayed_command(s, delay)
    target = _delayed_accel_target(s, delay) * ff_gain
    k_ff = 1.0 - math.exp(-dt / ff_lag) if ff_lag > 0 else 1.0
    k_v = (1.0 - math.exp(-dt / lag)) / dt if lag > 0 else 1.0 / dt
    k_a = 1.0 - math.exp(-dt / acc_lag) if acc_lag > 0 else 1.0
    k_f = 1.0 - math.exp(-dt / tail_tc)
    fn = fe = 0.0
    restart = True
    n = len(s.t_s)
    out = np.zeros((n, 2))
    sat = np.zeros(n, dtype=bool)
    valid = s.valid
    vn, ve = v_m[0]
    an, ae = 0.0, 0.0
    gn, ge = target[0]
    lat_abs = 0.0
    for i in range(n - 1):
        if one_step or not valid[i]:
            vn, ve = v_m[i]
            if i > 0:
                an, ae = acc_m[i - 1]
            if not valid[i]:
                lat_abs = abs(a_lat_m[i - 1]) if i > 0 else 0.0
                restart = True
                continue
        cn, ce = c[i]
        cs = math.hypot(cn, ce)
        scale = min(1.0, max(0.0, 1.0 - sag * lat_abs / cs)) if cs > 1e-9 else 1.0
        if restart:  # the target lag's state is unknown here: as if the target had lasted
            gn, ge = target[i]
        else:
            gn += (target[i, 0] - gn) * k_ff
            ge += (target[i, 1] - ge) * k_ff
        en, ee = cn * scale - vn + gn / k_v, ce * scale - ve + ge / k_v
        if restart:  # and the tail's: as if this error had lasted
            fn, fe, restart = en, ee, False
        tn = (en - share * fn) * k_v
        te = (ee - share * fe) * k_v
        fn += (en - fn) * k_f
        fe += (ee - fe) * k_f
        norm = math.hypot(tn, te)
        if norm > a_max:
            tn *= a_max / norm
            te *= a_max / norm
            sat[i] = True
        an += (tn - an) * k_a
        ae += (te - ae) * k_a
        out[i] = (an, ae)
        mn, me = vn + 0.5 * an * dt, ve + 0.5 * ae * dt
        sp = math.hypot(mn, me)
        lat_abs = abs(me * an - mn * ae) / sp if sp > 1e-9 else 0.0
        vn += an * dt
        ve += ae * dt
    return out, sat


@dataclass(frozen=True)
class IdentifyResult:
    """What :func:`identify` found.

    ``model`` carries every fitted value (also those not identified, as the fit left them);
    ``unidentified`` maps a parameter name to the reason the log cannot pin it down;
    ``std_errors`` the 1-sigma standard errors; ``quality`` the fit figures.
    """

    model: VehicleModel
    std_errors: dict[str, float]
    quality: dict[str, float | str]
    excitation: dict[str, float]
    unidentified: dict[str, str] = field(default_factory=dict)


def _vaf(measured: np.ndarray, predicted: np.ndarray) -> float:
    var = float(np.var(measured))
    return float("nan") if var <= 0 else 1.0 - float(np.var(measured - predicted)) / var


def _fit(s: Samples, free: tuple[int, ...], start: ArrayLike,
         max_nfev: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares of the free-run acceleration error over the parameters ``free`` (indices
    into :data:`PARAMS`), the others held at ``start``; returns (theta, std errors, rms)."""
    _, acc_m, _, v_mid, _ = _measured(s)
    idx = np.array(free)
    base = np.asarray(start, float).copy()

    def full(x: np.ndarray) -> np.ndarray:
        theta = np.array(base, dtype=float)
        theta[idx] = x
        return theta

    # One set of samples for every trial delay (the least squares needs a fixed number of
    # residuals): those with a command at least the longest delay old (a log that starts in
    # flight would otherwise gain or lose samples as the delay moves).
    u = _used(s, v_mid, float(_UPPER[0]))

    def residual(x: np.ndarray) -> np.ndarray:
        acc = _smooth_like_measured(s, simulate(s, full(x))[0])
        return np.asarray(acc[u] - acc_m[u], dtype=float).ravel()

    lower, upper = _LOWER[idx], _UPPER[idx]
    x0 = np.clip(base[idx], lower + 1e-6, upper - 1e-6)
    best = least_squares(residual, x0, bounds=(lower, upper), x_scale=_SCALE[idx], diff_step=1e-3,
                         max_nfev=max_nfev)
    n = best.fun.size
    sigma2 = 2.0 * best.cost / max(n - len(idx), 1)
    # Neighbouring samples' errors are correlated (the free run carries its error along): count
    # one independent sample per lag time, which widens the standard errors accordingly.
    lag_samples = max(1.0, float(full(best.x)[1]) / float(s.t_s[1] - s.t_s[0]))
    cov = np.linalg.pinv(best.jac.T @ best.jac) * sigma2 * lag_samples
    se = np.zeros(len(PARAMS))
    se[idx] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return full(best.x), se, float(np.sqrt(2.0 * best.cost / max(n, 1)))


def _yaw_rate_limit(s: Samples, delay_s: float, dt: float) -> tuple[float | None, float, float]:
    """(limit_rad_s, saturated_s, max_flown_rad_s): the yaw-rate limit from the samples where the
    command exceeds the flown rate by :data:`YAW_SATURATION_MARGIN`."""
    if len(s.t_yaw_s) < 10:
        return None, 0.0, 0.0
    cmd = np.interp(s.t_yaw_s - delay_s, s.t_cmd_s, s.yaw_rate_cmd_raw_rad_s)
    idx = np.searchsorted(s.t_cmd_s, s.t_yaw_s - delay_s, side="right") - 1
    streamed = (idx >= 0) & ((s.t_yaw_s - delay_s) - s.t_cmd_s[np.clip(idx, 0, None)] <= MAX_COMMAND_GAP_S)
    flown = np.abs(s.yaw_rate_rad_s)
    max_flown = float(np.max(flown[streamed])) if streamed.any() else 0.0
    # held: the command has not changed over the last YAW_HOLD_S (the response has settled)
    held = np.abs(cmd - np.interp(s.t_yaw_s - delay_s - YAW_HOLD_S, s.t_cmd_s, s.yaw_rate_cmd_raw_rad_s)) < 0.02
    sat = streamed & held & (np.abs(cmd) > YAW_SATURATION_MARGIN * flown) & (np.abs(cmd) > 0.2)
    # each yaw sample stands for the median spacing of the yaw stream
    spacing = float(np.median(np.diff(s.t_yaw_s)))
    sat_s = float(sat.sum()) * spacing
    if sat.sum() < 5:
        return None, sat_s, max_flown
    # the flown rate while held at the limit: the upper decile of the saturated samples; a
    # limit must also be about the most the vehicle ever flew (else the command was only lagging)
    limit = float(np.percentile(flown[sat], 90))
    if limit < 0.8 * float(np.percentile(flown[streamed], 99.5)):
        return None, sat_s, max_flown
    return limit, sat_s, max_flown


def _fit_structures(s: Samples, a_lat_rms: float) -> tuple[str, np.ndarray, np.ndarray, tuple[float, float, float]]:
    """Fit the first-order model, then each extension (second lag, slow tail) from it; an
    extension is chosen only if it cuts the residual clearly. With an acceleration target in the
    log, its gain and lag are fitted beside every structure's own parameters.
    Returns ``(structure, theta, std errors, (rms first, second, tail))``."""
    extra = ACCEL_FF if s.has_accel_target() else ()
    start = _NEUTRAL.copy()
    start[list(FIRST_ORDER)] = (0.15, 0.3, 3.0, 0.05)
    if extra:
        start[list(extra)] = (1.0, 0.05)
    theta1, se1, rms1 = _fit(s, FIRST_ORDER + extra, start, 40)
    start2 = theta1.copy()
    start2[4] = 0.05
    theta2, se2, rms2 = _fit(s, SECOND_ORDER + extra, start2, 20)
    start3 = theta1.copy()
    start3[5:7] = (0.5, 1.0)
    theta3, se3, rms3 = _fit(s, SLOW_TAIL + extra, start3, 30)

    def better(rms: float) -> bool:
        return rms < (1.0 - SECOND_ORDER_GAIN) * rms1 and rms1 - rms > SECOND_ORDER_GAIN_ABS * a_lat_rms

    structures = [("first order", theta1, se1, rms1)]
    structures += [c for c in (("second order", theta2, se2, rms2), ("slow tail", theta3, se3, rms3)) if better(c[3])]
    structure, theta, se, _ = min(structures, key=lambda c: c[3])
    return structure, theta, se, (rms1, rms2, rms3)


def identify(s: Samples) -> IdentifyResult:
    """Fit the model to the samples; see the module docstring."""
    dt = float(s.t_s[1] - s.t_s[0])
    _, acc_m, a_lat_m, v_mid, _ = _measured(s)
    u0 = _used(s, v_mid, 0.0)
    if u0.sum() * dt < 10.0:
        raise IdentifyError(f"only {u0.sum() * dt:.1f} s of flight above {MIN_SPEED_M_S} m/s under "
                            "velocity setpoints: expected at least 10 s")
    structure, theta, se, (rms1, rms2, rms3) = _fit_structures(s, float(np.sqrt(np.mean(a_lat_m[u0] ** 2))))
    u = _used(s, v_mid, theta[0])
    a_lat = a_lat_m[u]
    one, sat = simulate(s, theta, one_step=True)
    free = _smooth_like_measured(s, simulate(s, theta)[0])
    a_lat_one = lateral_m_s2(v_mid, one)[u]
    a_lat_free = lateral_m_s2(v_mid, free)[u]
    quality = {
        "samples": int(u.sum()),
        "duration_s": float(u.sum() * dt),
        "model_order": 2 if structure == "second order" else 1,
        "model_structure": structure,
        "vaf_one_step": _vaf(a_lat, a_lat_one),
        "residual_rms_one_step_m_s2": float(np.sqrt(np.mean((a_lat - a_lat_one) ** 2))),
        "vaf_free_run": _vaf(a_lat, a_lat_free),
        "residual_rms_free_run_m_s2": float(np.sqrt(np.mean((a_lat - a_lat_free) ** 2))),
        "acc_residual_rms_first_order_m_s2": rms1,
        "acc_residual_rms_second_order_m_s2": rms2,
        "acc_residual_rms_slow_tail_m_s2": rms3,
        "a_lat_rms_m_s2": float(np.sqrt(np.mean(a_lat ** 2))),
    }
    r = {"saturated": sat, "c": _delayed_command(s, theta[0])}
    # Excitation of each parameter
    c = r["c"]
    c_speed = np.hypot(c[:, 0], c[:, 1])
    c_turn = np.zeros(len(c))
    c_turn[:-1] = lateral_m_s2(0.5 * (c[1:] + c[:-1]), (c[1:] - c[:-1]) / dt)
    changing = u & (np.abs(np.gradient(c_turn, dt)) > 0.2)
    turning = u & (np.abs(c_turn) > 0.3)
    steady_speed = np.abs(np.gradient(c_speed, dt)) < 0.1
    excitation = {
        "saturated_s": float((r["saturated"] & u).sum() * dt),
        "turn_changing_s": float(changing.sum() * dt),
        "turning_steady_speed_s": float((turning & steady_speed).sum() * dt),
        "a_lat_cmd_max_m_s2": float(np.max(np.abs(c_turn[u]))) if u.any() else 0.0,
        # 0: no acceleration target in the log (its gain and lag are not fitted, nor written)
        "accel_target_s": float((u & (np.hypot(*_delayed_accel_target(s, theta[0]).T) >= ACCEL_FF_MIN_M_S2)).sum()
                                * dt) if s.has_accel_target() else 0.0,
    }
    yaw_limit, yaw_sat_s, yaw_flown = _yaw_rate_limit(s, theta[0], dt)
    excitation["yaw_saturated_s"] = yaw_sat_s
    excitation["yaw_rate_max_flown_rad_s"] = yaw_flown

    unidentified = _unidentified(excitation, theta, se, yaw_limit, yaw_flown, len(s.t_yaw_s))
    yaw_value = yaw_limit if yaw_limit is not None else max(yaw_flown, math.radians(1.0))
    drift_values, drift_errors = _identify_bias(s, quality, unidentified)
    model = VehicleModel(a_max_m_s2=float(theta[2]), delay_s=float(theta[0]), lag_s=float(theta[1]),
                         speed_sag_s=float(theta[3]), accel_lag_s=float(theta[4]),
                         tail_share=float(theta[5]), tail_tc_s=float(theta[6]),
                         accel_ff_gain=float(theta[7]), accel_ff_lag_s=float(theta[8]),
                         yaw_rate_max_deg_s=math.degrees(yaw_value), **drift_values)
    std = {name: float(se[i]) for i, name in enumerate(PARAMS)}
    std.update(drift_errors)
    return IdentifyResult(model=model, std_errors=std, quality=quality, excitation=excitation,
                          unidentified=unidentified)


def _identify_bias(s: Samples, quality: dict[str, float | str],
                   unidentified: dict[str, str]) -> tuple[dict[str, float], dict[str, float]]:
    """The estimate's errors that :func:`identify` measures, besides the response: the position's
    delay (:func:`position_delay`), the velocity's constant offset (:func:`velocity_offset`) and
    its bias (:func:`velocity_bias`, on the drift that the delay and the offset do not explain);
    ``(values, standard errors)``, both keyed by the ``vehicle:`` block's names. Adds the measured
    drift to ``quality`` and what the log cannot pin down to ``unidentified``."""
    keys = ("vel_bias_m_s", "vel_bias_tc_s", "vel_offset_m_s", "pos_delay_s")
    if s.pos_ne_m is None:
        unidentified.update(dict.fromkeys(keys, "no positions in the log"))
        return ({"vel_bias_m_s": 0.0, "vel_bias_tc_s": NO_BIAS_TC_S, "vel_offset_m_s": 0.0, "pos_delay_s": 0.0},
                dict.fromkeys(keys, math.inf))
    delay, delay_se = position_delay(s.t_s, s.pos_ne_m, s.vel_ne_m_s, s.valid, s.t_autopilot_s)
    quality["pos_delay_fitted_s"] = delay
    if math.isfinite(delay_se) and abs(delay) <= 2.0 * delay_se:
        delay = 0.0  # none to tell from zero (PX4 SIH's: -9 +- 13 ms): no delay, identified as such
    elif not (abs(delay) <= MAX_POSITION_DELAY_S and delay_se <= MAX_RELATIVE_SE * max(abs(delay), DELAY_SCALE_S)):
        unidentified["pos_delay_s"] = (f"{delay:.3g} +- {delay_se:.2g} s: the velocity changes too little in "
                                       "the log to tell the position's delay from its drift")
        delay = 0.0
    delay = max(0.0, delay)  # a position ahead of the velocity is not modelled
    offset_ne, offset, offset_se = _identify_offset(s, s.pos_ne_m, delay, unidentified)
    # the bias is what wanders beside the offset: the offset's own drift is taken out first
    past_offset = s.pos_ne_m - np.outer(s.t_s - s.t_s[0], offset_ne)
    bias, tc, se, tc_se, drift = velocity_bias(s.t_s, past_offset, s.vel_ne_m_s, s.valid, s.t_autopilot_s, delay)
    quality.update({f"position_drift_{lag:g}s_m": d for lag, d in drift.items()})
    if drift.get(1.0, math.inf) < BIAS_NEGLIGIBLE_M_S * 1.0:
        # Under a centimetre over a second: no bias to speak of. What drift there is, the rounding
        # of the reported numbers, fits as white noise (a huge sigma over a vanishing tau).
        bias, tc, se, tc_se = 0.0, NO_BIAS_TC_S, 0.0, 0.0
    across, across_tc, across_se, across_tc_se, measured = across_track_velocity_bias(
        s.t_s, s.pos_ne_m, s.vel_ne_m_s, s.valid, s.t_autopilot_s, pos_delay_s=delay)
    if measured:  # a diagnostic: the mock flies the missions' across-track figure (docs/vehicle_model.md)
        quality.update({"vel_bias_across_m_s": across, "vel_bias_across_se_m_s": across_se,
                        "vel_bias_across_tc_s": across_tc, "vel_bias_across_tc_se_s": across_tc_se})
    unidentified.update(_bias_unidentified(bias, tc, se, tc_se, bool(drift)))
    if bias < BIAS_NEGLIGIBLE_M_S:
        tc = NO_BIAS_TC_S  # no bias to speak of: its time constant means nothing
    values = {"vel_bias_m_s": bias, "vel_bias_tc_s": tc, "vel_bias_jerk_s2": 0.0, "vel_bias_jerk_max_m_s3": 1.0,
              "vel_bias_smooth_s": 0.0, "vel_offset_m_s": offset, "pos_delay_s": delay}
    errors = {"vel_bias_m_s": se, "vel_bias_tc_s": tc_se, "vel_bias_jerk_s2": math.inf,
              "vel_bias_jerk_max_m_s3": math.inf, "vel_bias_smooth_s": math.inf, "vel_offset_m_s": offset_se,
              "pos_delay_s": delay_se}
    if bias >= BIAS_NEGLIGIBLE_M_S and "vel_bias_m_s" not in unidentified:
        _identify_jerk_wander(s, past_offset, delay, values, errors, quality)
    return values, errors


def _identify_jerk_wander(s: Samples, pos_ne_m: np.ndarray, delay_s: float, values: dict[str, float],
                          errors: dict[str, float], quality: dict[str, float | str]) -> None:
    """Whether the bias wanders more while the vehicle manoeuvres (``companion.sim.wander``), at the
    bias's fitted correlation time: where the jerk's share stands :data:`JERK_WANDER_SIGNIFICANCE`
    standard errors clear of zero, the bias's level and that share replace the single level in
    ``values`` and ``errors``, with the smoothing that gives back the drift's fast part
    (``companion.sim.wander.fit_smoothing``; the levels scaled by its factor). The fit goes to
    ``quality`` either way."""
    e, ok, dt = _drift_ne(s.t_s, pos_ne_m, s.vel_ne_m_s, s.valid, s.t_autopilot_s, delay_s)
    _, acc, *_ = _measured(s)
    segments = [(e, ok, manoeuvre_jerk_m_s3(acc, dt))]
    fit = fit_jerk_wander(segments, dt, values["vel_bias_tc_s"])
    if fit is None:
        return
    errors["vel_bias_jerk_s2"] = fit.se_jerk_gain_s2
    quality.update({"vel_bias_still_m_s": fit.sigma_m_s, "vel_bias_jerk_fitted_s2": fit.jerk_gain_s2,
                    "vel_bias_jerk_se_s2": fit.se_jerk_gain_s2, "vel_bias_jerk_max_fitted_m_s3": fit.jerk_max_m_s3})
    if fit.jerk_gain_s2 > JERK_WANDER_SIGNIFICANCE * fit.se_jerk_gain_s2:
        smooth = fit_smoothing(segments, dt, fit)
        scale = 1.0 if smooth is None else smooth.level_scale
        values.update(vel_bias_m_s=scale * fit.sigma_m_s, vel_bias_jerk_s2=scale * fit.jerk_gain_s2,
                      vel_bias_jerk_max_m_s3=fit.jerk_max_m_s3,
                      vel_bias_smooth_s=0.0 if smooth is None else smooth.smooth_s)
        errors.update(vel_bias_m_s=scale * fit.se_sigma_m_s, vel_bias_jerk_s2=scale * fit.se_jerk_gain_s2)
        if smooth is not None:
            quality.update({"vel_bias_fast_ratio": smooth.ratio_measured,
                            "vel_bias_fast_ratio_model": smooth.ratio_model})


def _identify_offset(s: Samples, pos_ne_m: np.ndarray, delay_s: float,
                     unidentified: dict[str, str]) -> tuple[np.ndarray, float, float]:
    """The velocity's constant offset in this log (:func:`velocity_offset`): ``(offset_ne_m_s,
    sigma, se)``, ``sigma`` the standard deviation per axis that this one draw stands for (the
    RMS of its components past their errors, as :func:`pooled_velocity_offset` takes it over
    several flights). An offset under a millimetre a second, or one the log's turns cannot tell
    from a turned velocity, is none (the latter named in ``unidentified``)."""
    offset_ne, offset_se, *_ = velocity_offset(s.t_s, pos_ne_m, s.vel_ne_m_s, s.valid, s.t_autopilot_s,
                                               pos_delay_s=delay_s)
    se = float(np.sqrt(np.mean(offset_se ** 2)))
    sigma = _offset_sigma(_offset_terms(offset_ne, offset_se))
    if not se <= MAX_RELATIVE_SE_BIAS_TC * max(sigma, BIAS_NEGLIGIBLE_M_S):
        unidentified["vel_offset_m_s"] = (f"standard error {se:.2g} m/s: the track turns too little in the log to "
                                          "tell a constant velocity offset from a turned velocity")
        return np.zeros(2), 0.0, se
    if sigma < OFFSET_NEGLIGIBLE_M_S:
        return np.zeros(2), 0.0, se
    return offset_ne, sigma, se


def _bias_unidentified(bias: float, tc: float, se: float, tc_se: float, measured: bool) -> dict[str, str]:
    """The velocity bias's parameters the log cannot pin down (see :func:`velocity_bias`)."""
    if not measured:
        why = "too little flight under velocity setpoints to measure the position's drift (expected 1 s at least)"
        return {"vel_bias_m_s": why, "vel_bias_tc_s": why}
    out = {}
    if not se <= MAX_RELATIVE_SE * max(bias, BIAS_NEGLIGIBLE_M_S):
        out["vel_bias_m_s"] = (f"standard error {se:.3g} is more than {MAX_RELATIVE_SE:.0%} of the value "
                               f"{bias:.3g}: the log does not pin it down")
    if bias >= BIAS_NEGLIGIBLE_M_S and not tc_se <= MAX_RELATIVE_SE_BIAS_TC * tc:
        out["vel_bias_tc_s"] = (f"standard error {tc_se:.3g} is more than {MAX_RELATIVE_SE_BIAS_TC:.0%} of the "
                                f"value {tc:.3g}: fly longer (minutes) to pin it down")
    return out


def _unidentified(excitation: dict[str, float], theta: np.ndarray, se: np.ndarray, yaw_limit: float | None,
                  yaw_flown: float, n_yaw_samples: int) -> dict[str, str]:
    """Each parameter the log cannot pin down, with the reason (too little excitation of it, or
    a standard error over :data:`MAX_RELATIVE_SE` of its value)."""
    unidentified: dict[str, str] = {}
    if excitation["turn_changing_s"] < MIN_TURNING_S:
        for name in ("delay_s", "lag_s"):
            unidentified[name] = (f"only {excitation['turn_changing_s']:.1f} s of changing turn command "
                                  f"(expected {MIN_TURNING_S:.0f} s): fly course-rate steps or a chirp")
    if excitation["saturated_s"] < MIN_SATURATED_S:
        unidentified["a_max_m_s2"] = (f"the vehicle reached its acceleration limit for only "
                                      f"{excitation['saturated_s']:.1f} s (expected {MIN_SATURATED_S:.0f} s; "
                                      f"largest turn commanded {excitation['a_lat_cmd_max_m_s2']:.1f} m/s^2): "
                                      "fly harder turns")
    if excitation["turning_steady_speed_s"] < MIN_SAG_TURNING_S:
        unidentified["speed_sag_s"] = (f"only {excitation['turning_steady_speed_s']:.1f} s of turning at a "
                                       f"steady commanded speed (expected {MIN_SAG_TURNING_S:.0f} s)")
    if 0.0 < excitation["accel_target_s"] < MIN_ACCEL_FF_S:
        for name in ACCEL_FF_KEYS:
            unidentified[name] = (f"only {excitation['accel_target_s']:.1f} s of acceleration target above "
                                  f"{ACCEL_FF_MIN_M_S2} m/s^2 (expected {MIN_ACCEL_FF_S:.0f} s)")
    # The sag is zero for a vehicle without it: judge its standard error in absolute terms.
    scales = {"delay_s": max(theta[0], 0.1), "lag_s": theta[1], "a_max_m_s2": theta[2],
              "speed_sag_s": max(theta[3], 0.2), "accel_lag_s": max(theta[4], 0.05),
              "tail_share": max(theta[5], 0.1), "tail_tc_s": theta[6],
              "accel_ff_gain": max(theta[7], 0.1), "accel_ff_lag_s": max(theta[8], 0.05)}
    for i, name in enumerate(PARAMS):
        if name not in unidentified and not se[i] <= MAX_RELATIVE_SE * scales[name]:
            unidentified[name] = (f"standard error {se[i]:.3g} is more than {MAX_RELATIVE_SE:.0%} of the "
                                  f"value {theta[i]:.3g}: the log does not pin it down")
    if yaw_limit is None:
        if n_yaw_samples < 10:
            unidentified["yaw_rate_max_deg_s"] = "no ATTITUDE messages (yaw rate) in the log"
        else:
            unidentified["yaw_rate_max_deg_s"] = (
                f"the yaw rate never saturated (flown up to {math.degrees(yaw_flown):.0f} deg/s as commanded): "
                f"the limit is at least that; command faster yaw rates to find it")
    return unidentified
