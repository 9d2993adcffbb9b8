"""Flight-health failsafes: notice that a flight is not working, say why, and say what to do.

Pure and clock-injected: :class:`HealthMonitor` is fed one :class:`HealthSample` per guidance
tick (the loop's own time, the vehicle's position, the guidance's along-path progress and
cross-track error, the autopilot's time from its messages) and returns a :class:`HealthVerdict`.
No I/O, no MAVLink, no clock read here: the flight loop owns those and acts on the verdict.

Checks (defaults in :class:`HealthOptions`; the operator's view and exit codes in
``docs/failsafes.md``):

* **no progress** (``--no-progress-s``, 5 s): over the last ``no_progress_s`` of non-hold ticks
  the vehicle advanced along the path *and* moved in a straight line less than
  ``min_progress_fraction`` (0.2) of the distance the mission speed covers in that time (5 m at
  5 m/s). A vehicle that does not move (a plane on the ground, a copter that did not take off, a
  vehicle orbiting on the spot) -> ``warn`` after half the window, ``stop`` after the whole window.
  Progress is ``max(s_now - s_then, |p_now - p_then|)``: during the mid-course phase the vehicle
  flies towards the path and its projection ``s`` stays at the path start, but it moves.
* **cross-track runaway** (``--max-xtrack-m``, 25 m; ``--xtrack-hold-s``, 3 s): the distance to
  the path grew more than ``max_xtrack_m`` beyond its smallest value so far in the flight (on the
  path: beyond 25 m; approaching from 80 m away: beyond 25 m more than the closest approach, so an
  approach from far is not a failure). Half the bound -> ``warn``; the bound -> ``hold`` (the loop
  sends holds, the vehicle stops where it is); still beyond it ``xtrack_hold_s`` later -> ``stop``.
  Back within the bound during the hold -> the flight resumes. In the mid-course phase, and in
  any phase until the vehicle has first come within half the bound of the path, the bound is
  widened by one turn's diameter (:func:`turn_allowance_m`): the vehicle swings round an
  initiation circle onto the path start, and a vehicle that starts pointing away (a plane that
  loitered before the flight began) turns round at its tightest radius towards the path, moving
  up to that diameter farther from it first.
Feeding it (the flight loop, once per guidance tick, after ``compute_tick``)::

    verdict = monitor.update(sample_from_tick(result, t_s, link.state.autopilot_time_s))
    if verdict.changed and verdict.level != "ok":
        status.event(verdict.reason); link.record_event(verdict.reason, severity)
    if verdict.level == "hold": send a hold setpoint instead of result.setpoint
    if verdict.level == "stop": send a hold, ask for the autopilot's hold mode, raise verdict.error()

* **clock mismatch** (``--clock-tolerance``, 0.25): the autopilot's ``time_boot_ms`` advanced
  at a rate outside ``1 +- clock_tolerance`` of the loop's clock over the last
  ``clock_window_s`` (2 s). A simulator running 5x real time with ``--clock wall`` -> ``warn`` at
  2 s into the flight, suggesting ``--clock autopilot``. With ``--clock autopilot`` the loop's
  clock *is* the autopilot's, so the check is off.

A value of 0 turns a check off. Ticks that are holds on stale data (``hold=True``) expect no
progress: they restart the progress window and are not counted in the cross-track minimum.

Examples
--------
A vehicle that never moves, mission speed 5 m/s, ticks at 10 Hz:

>>> mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
>>> levels = [mon.update(HealthSample(t_s=k / 10, x_enu_m=0.0, y_enu_m=0.0, s_m=0.0,
...                                   crosstrack_m=0.0)).level for k in range(51)]
>>> levels.index("warn") / 10, levels.index("stop") / 10
(2.5, 5.0)
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from companion.errors import CompanionError, FlightUnhealthy

#: Process exit code of a flight stopped by a health failsafe (docs/failsafes.md).
EXIT_HEALTH_STOP = FlightUnhealthy.exit_code

#: Verdict levels, mildest first.
LEVELS = ("ok", "warn", "hold", "stop")


@dataclass(frozen=True)
class HealthOptions:
    """Thresholds of the flight-health checks (``companion fly`` flags in brackets); 0 = off.

    Attributes
    ----------
    no_progress_s : window of the no-progress check, seconds [--no-progress-s, 5].
    min_progress_fraction : progress expected over the window, as a fraction of
        ``speed_m_s * no_progress_s`` (0.2: 5 m in 5 s at 5 m/s).
    max_xtrack_m : growth of the distance to the path beyond its closest approach that holds
        the vehicle, metres [--max-xtrack-m, 25].
    xtrack_hold_s : how long the vehicle is held beyond that bound before the flight stops,
        seconds [--xtrack-hold-s, 3].
    clock_tolerance : accepted |autopilot time rate / loop clock rate - 1| [--clock-tolerance, 0.25].
    clock_window_s : window over which the clock rate is measured, seconds (2).
    """

    no_progress_s: float = 5.0
    min_progress_fraction: float = 0.2
    max_xtrack_m: float = 25.0
    xtrack_hold_s: float = 3.0
    clock_tolerance: float = 0.25
    clock_window_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("no_progress_s", "min_progress_fraction", "max_xtrack_m", "xtrack_hold_s",
                     "clock_tolerance", "clock_window_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise CompanionError(f"--{name.replace('_', '-')}: expected a number >= 0, got {value!r}")
        if self.clock_window_s <= 0:
            raise CompanionError(f"clock_window_s: expected a number > 0, got {self.clock_window_s!r}")
        if self.min_progress_fraction >= 1:
            raise CompanionError("min_progress_fraction: expected a number below 1, got "
                                 f"{self.min_progress_fraction!r}")


@dataclass(frozen=True)
class HealthSample:
    """What one guidance tick knows, for the health checks.

    ``t_s`` is the loop's clock (wall, or the autopilot's with ``--clock autopilot``);
    ``autopilot_time_s`` the newest ``time_boot_ms`` / 1000 heard from the autopilot (NaN:
    none yet). ``s_m`` and ``crosstrack_m`` come from the guidance output (NaN on a hold).
    ``hold`` is True on a tick that held on stale data (no progress expected).
    """

    t_s: float
    x_enu_m: float
    y_enu_m: float
    s_m: float
    crosstrack_m: float
    autopilot_time_s: float = math.nan
    ground_speed_m_s: float = math.nan
    phase: str = "close_range"
    hold: bool = False


@dataclass(frozen=True)
class HealthVerdict:
    """The monitor's answer for one tick.

    ``level`` is one of :data:`LEVELS`; ``check`` names the check behind it (``progress``,
    ``crosstrack``, ``clock``; ``""`` when ok); ``reason`` is the one line for the operator
    (status line, event, STATUSTEXT); ``exit_code`` is :data:`EXIT_HEALTH_STOP` for ``stop``, else
    0; ``changed`` is True on the tick the level or check differs from the previous tick's
    (print an event and record a STATUSTEXT only then).
    """

    level: str = "ok"
    check: str = ""
    reason: str = ""
    exit_code: int = 0
    changed: bool = False

    @property
    def ok(self) -> bool:
        return self.level == "ok"

    def error(self) -> FlightUnhealthy:
        """The exception the flight loop raises on a ``stop`` (exit code 3, this reason)."""
        return FlightUnhealthy(f"flight-health failsafe: {self.reason}")


_OK = HealthVerdict()


def turn_allowance_m(circle_radius_m: float, speed_m_s: float,
                     lat_accel_max_m_s2: float = math.inf) -> float:
    """Cross-track growth expected while the vehicle turns onto the path (the mid-course phase,
    or a start pointing away): the diameter of the larger of the initiation circle and the
    vehicle's tightest turn, ``2 max(R, v^2 / a_max)``.

    >>> turn_allowance_m(10.0, 5.0)  # a copter on the paper's 10 m circle
    20.0
    >>> round(turn_allowance_m(10.0, 18.0, 9.80665 * math.tan(math.radians(35.0))), 1)
    94.4
    """
    turn_m = speed_m_s ** 2 / lat_accel_max_m_s2 if lat_accel_max_m_s2 > 0 else math.inf
    return 2.0 * max(float(circle_radius_m), turn_m)


def sample_from_tick(result, t_s: float, autopilot_time_s: float = math.nan) -> HealthSample:
    """The health sample of one :class:`companion.loop.tick.TickResult` (what the loop feeds).

    Position from the tick's vehicle state (ENU), else from its LOCAL_POSITION_NED sample; ground
    speed from the sample's velocity; ``s`` and cross-track error from the guidance output (NaN
    on a hold); ``hold`` from the tick; ``t_s`` the loop's clock at the tick and
    ``autopilot_time_s`` the newest autopilot time the link holds.
    """
    state, out, pos = result.state, result.output, result.sample
    if state is not None:
        x, y = state.x_m, state.y_m
    elif pos is not None:
        x, y = pos.y_ned_m, pos.x_ned_m  # ENU east = NED y, north = NED x
    else:
        x = y = math.nan
    speed = math.hypot(pos.vx_ned_m_s, pos.vy_ned_m_s) if pos is not None else math.nan
    return HealthSample(
        t_s=t_s, x_enu_m=x, y_enu_m=y,
        s_m=out.s_proj_m if out is not None else math.nan,
        crosstrack_m=out.crosstrack_m if out is not None else math.nan,
        autopilot_time_s=autopilot_time_s, ground_speed_m_s=speed,
        phase=result.phase, hold=result.is_hold)


class HealthMonitor:
    """Per-flight state of the health checks. Call :meth:`update` once per guidance tick.

    Parameters
    ----------
    options : thresholds.
    speed_m_s : the mission speed (sets the progress expected).
    clock : ``"wall"`` or ``"autopilot"`` (the loop's clock; ``autopilot`` turns the clock check off).
    turn_allowance_m : extra cross-track growth accepted while the vehicle turns onto the path:
        in the mid-course phase (it swings round an initiation circle onto the path start) and,
        in any phase, until it has first come within half the bound of the path (it may start
        pointing away and turn round first); the flight loop passes :func:`turn_allowance_m` of
        the mission and the vehicle.
    """

    def __init__(self, options: HealthOptions, speed_m_s: float, *, clock: str = "wall",
                 turn_allowance_m: float = 0.0):
        if not (math.isfinite(speed_m_s) and speed_m_s > 0):
            raise ValueError(f"speed_m_s: expected a number > 0, got {speed_m_s!r}")
        self.opt = options
        self.speed_m_s = float(speed_m_s)
        self.clock = clock
        self.turn_allowance_m = float(turn_allowance_m)
        self._track: deque = deque()  # (t_s, x, y, s) of non-hold ticks since the last reset
        self._clock_track: deque = deque()  # (t_s, autopilot_time_s)
        self._best_xtrack_m = math.inf
        self._xtrack_since_s: float | None = None
        self._previous = _OK

    # ------------------------------------------------------------------ the checks

    def _progress(self, s: HealthSample) -> HealthVerdict:
        window = self.opt.no_progress_s
        if window <= 0:
            return _OK
        if s.hold or not (math.isfinite(s.x_enu_m) and math.isfinite(s.y_enu_m)):
            self._track.clear()
            return _OK
        track = self._track
        track.append((s.t_s, s.x_enu_m, s.y_enu_m, s.s_m))
        # Keep exactly one sample at least a full window old (the reference).
        while len(track) >= 2 and track[1][0] <= s.t_s - window:
            track.popleft()
        for span_s, level in ((window, "stop"), (0.5 * window, "warn")):
            ref = self._sample_before(s.t_s - span_s)
            if ref is None:
                continue
            moved_m = math.hypot(s.x_enu_m - ref[1], s.y_enu_m - ref[2])
            along_m = s.s_m - ref[3] if math.isfinite(s.s_m) and math.isfinite(ref[3]) else 0.0
            progress_m = max(moved_m, along_m)
            expected_m = self.opt.min_progress_fraction * self.speed_m_s * span_s
            if progress_m < expected_m:
                speed = (f", ground speed {s.ground_speed_m_s:.1f} m/s"
                         if math.isfinite(s.ground_speed_m_s) else "")
                what = ("stopping" if level == "stop" else
                        f"stopping if it lasts --no-progress-s {window:g}")
                return HealthVerdict(
                    level, "progress",
                    f"no progress: {progress_m:.1f} m in {span_s:g} s (expected >= {expected_m:.1f} m "
                    f"at {self.speed_m_s:g} m/s{speed}): vehicle not moving (on the ground? "
                    f"not flying?); {what}",
                    EXIT_HEALTH_STOP if level == "stop" else 0)
            return _OK
        return _OK

    def _sample_before(self, t_s: float):
        """The newest tracked sample at or before ``t_s`` (None: the track is younger)."""
        ref = None
        for item in self._track:
            if item[0] <= t_s + 1e-9:
                ref = item
            else:
                break
        return ref

    def _crosstrack(self, s: HealthSample) -> HealthVerdict:
        bound = self.opt.max_xtrack_m
        if bound <= 0 or s.hold or not math.isfinite(s.crosstrack_m):
            return _OK
        d = abs(s.crosstrack_m)
        self._best_xtrack_m = min(self._best_xtrack_m, d)
        turning_on = s.phase == "midcourse" or self._best_xtrack_m > 0.5 * bound  # not yet on the path
        allowed = bound + (self.turn_allowance_m if turning_on else 0.0)
        excess = d - self._best_xtrack_m
        if excess <= allowed:
            self._xtrack_since_s = None
            if excess > 0.5 * allowed:
                return HealthVerdict("warn", "crosstrack",
                                     f"cross-track {d:.1f} m, {excess:.1f} m beyond the closest approach "
                                     f"(holds at --max-xtrack-m {bound:g})")
            return _OK
        if self._xtrack_since_s is None:
            self._xtrack_since_s = s.t_s
        held_s = s.t_s - self._xtrack_since_s
        what = (f"{d:.1f} m from the path, {excess:.1f} m beyond its closest approach "
                f"(--max-xtrack-m {bound:g})")
        if held_s >= self.opt.xtrack_hold_s:
            return HealthVerdict("stop", "crosstrack",
                                 f"runaway: {what} for {held_s:.1f} s; stopping",
                                 EXIT_HEALTH_STOP)
        return HealthVerdict("hold", "crosstrack",
                             f"runaway: {what}; holding, stopping after --xtrack-hold-s "
                             f"{self.opt.xtrack_hold_s:g}")

    def _clock(self, s: HealthSample) -> HealthVerdict:
        tol = self.opt.clock_tolerance
        if tol <= 0 or self.clock == "autopilot" or not math.isfinite(s.autopilot_time_s):
            return _OK
        track = self._clock_track
        if track and s.autopilot_time_s < track[-1][1]:
            track.clear()  # the autopilot restarted: a new series
        track.append((s.t_s, s.autopilot_time_s))
        window = self.opt.clock_window_s
        while len(track) >= 2 and track[1][0] <= s.t_s - window:
            track.popleft()
        t0, ap0 = track[0]
        if s.t_s - t0 < window - 1e-9:
            return _OK
        ratio = (s.autopilot_time_s - ap0) / (s.t_s - t0)
        if abs(ratio - 1.0) <= tol:
            return _OK
        pace = "faster" if ratio > 1 else "slower"
        return HealthVerdict(
            "warn", "clock",
            f"autopilot time runs {ratio:.2f}x the {self.clock} clock over {window:g} s (a simulator "
            f"{pace} than real time?): fly with --clock autopilot")

    # ------------------------------------------------------------------ entry point

    def update(self, sample: HealthSample) -> HealthVerdict:
        """One tick: the most severe verdict of the checks (a stop beats a hold beats a warning)."""
        xtrack = self._crosstrack(sample)
        if xtrack.level in ("hold", "stop"):
            self._track.clear()  # the vehicle is being held: no progress expected meanwhile
            progress = _OK
        else:
            progress = self._progress(sample)
        verdicts = (xtrack, progress, self._clock(sample))
        worst = max(verdicts, key=lambda v: LEVELS.index(v.level))
        changed = (worst.level, worst.check) != (self._previous.level, self._previous.check)
        if changed:
            worst = HealthVerdict(worst.level, worst.check, worst.reason, worst.exit_code, True)
        self._previous = worst
        return worst
