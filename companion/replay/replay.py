"""Re-run the guidance on a logged flight and report where it differs from what was commanded.

The question replay answers: *given what the vehicle reported, did the companion command what
the guidance law says it should have?* It rebuilds the guidance from the mission, feeds it the
logged ``LOCAL_POSITION_NED`` samples in the order and at the ticks the flight used (see
:mod:`companion.replay.flightlog`), and runs each tick through
:func:`companion.loop.tick.compute_tick`, the same function the live loop calls, so replay
and flight cannot drift apart through a copied formula.

Comparison, per tick
--------------------
- yaw rate: ``|yaw_rate_logged - yaw_rate_replayed|`` (rad/s, NED, as sent);
- velocity: ``|v_logged - v_replayed|``, the Euclidean norm of the difference of the commanded
  (vx, vy, vz) vectors (m/s, NED);
- on companion logs also the recorded internals: phase, a_cmd, k1, k2 (reported; a phase
  mismatch counts as a divergence, the others follow from the yaw rate ``= a_cmd / V``).

A tick is *within tolerance* when both differences are at most the tolerances and (companion logs)
the phase is the same. The flight is within tolerance when every compared tick is. Per-phase
figures are grouped by the logged phase (companion logs) or by the replayed phase (other logs,
which record none).

The flight's own tracking figures use :func:`companion.sim.metrics.tracking_metrics` on the
logged cross-track error and lateral acceleration: the recorded internals on companion logs; on
other logs the cross-track error of the logged positions from the mission path and
``a = -yaw_rate_ned * |v_horizontal|`` of the logged setpoint (the lateral acceleration of a
vehicle turning at the commanded yaw rate at the commanded speed, left positive).
"""

from __future__ import annotations

import contextlib
import gc
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from companion.errors import LogError
from companion.guidance.types import GuidanceLaw
from companion.io.logread import LogWarning
from companion.io.tlog import MISSION_SUFFIX, mission_path_beside
from companion.io.setpoints import AttitudeSetpoint, VelocitySetpoint, uses_accel_target
from companion.loop.driver import TickDriver, make_guidance
from companion.loop.limits import (
    accel_feedforward_limit_m_s2,
    limit_from_params,
    mission_for_tail,
    mission_with_limit,
)
from companion.loop.tick import DEFAULT_STALE_S, TickConfig
from companion.mission import Mission, load_mission
from companion.mission.placement import onto_autopilot_origin
from companion.replay.flightlog import (
    DEBUG_INDEX,
    LoggedAttitude,
    LoggedFlight,
    LoggedSetpoint,
    LoggedTick,
    phase_name,
    read_flight,
    recorded_drift_tc_s,
    recorded_speed_hold_tc_s,
    recorded_tail,
    recorded_rate_hz,
)
from companion.replay.progress import ByteProgress
from companion.sim.metrics import PROFILE_METRIC_KEYS, profile_errors, tracking_metrics



@dataclass(frozen=True)
class Tolerance:
    """Largest accepted difference between a logged and a replayed setpoint."""

    yaw_rate_rad_s: float = 0.01
    vel_m_s: float = 0.05
    attitude_rad: float = 0.01  # fixed-wing output: rotation between logged and replayed attitude

    def __post_init__(self) -> None:
        for name in ("yaw_rate_rad_s", "vel_m_s", "attitude_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")


@dataclass
class ReplayResult:
    """The outcome of a replay: verdict, per-phase differences, per-tick series."""

    flight: LoggedFlight
    mission_name: str
    tolerance: Tolerance
    series: dict[str, np.ndarray]
    first_divergence: dict | None
    per_phase: dict[str, dict]
    phase_switches: dict[str, list[dict]]
    tracking: dict
    timing_s: dict = field(default_factory=dict)
    mission_path: object = None  # the mission's reference path (for plots)
    rate_hz: float = math.nan  # the loop rate replayed at
    mission_profile: object = None  # the mission's altitude / speed profile, or None (for plots)

    @property
    def steps_compared(self) -> int:
        return int(np.count_nonzero(self.series["compared"]))

    @property
    def within_tolerance(self) -> bool:
        return self.first_divergence is None

    @property
    def exit_code(self) -> int:
        return 0 if self.within_tolerance else 1

    def to_json(self) -> dict:
        """One JSON-ready object (metric names of :mod:`companion.sim.metrics`; NaN as null)."""
        from companion.replay.report import json_safe

        return json_safe({
            "file": str(self.flight.path),
            "kind": self.flight.kind,
            "mission": self.mission_name,
            "rate_hz": self.rate_hz,
            "steps_compared": self.steps_compared,
            "ticks": int(self.series["t_s"].size),
            "within_tolerance": self.within_tolerance,
            "tolerance": {"yaw_rate_rad_s": self.tolerance.yaw_rate_rad_s, "vel_m_s": self.tolerance.vel_m_s,
                          "attitude_rad": self.tolerance.attitude_rad},
            "first_divergence": self.first_divergence,
            "per_phase": self.per_phase,
            "phase_switches": self.phase_switches,
            "d_rms_m": self.tracking["d_rms_m"],
            "d_max_m": self.tracking["d_max_m"],
            "a_rms_m_s2": self.tracking["a_rms_m_s2"],
            "a_max_m_s2": self.tracking["a_max_m_s2"],
            "duration_s": self.tracking["duration_s"],
            **{k: self.tracking[k] for k in PROFILE_METRIC_KEYS if k in self.tracking},
            "phases": self.tracking["phases"],
            "warnings": [w.as_dict() for w in self.flight.warnings],
            "notes": list(self.flight.notes),
            "timing_s": dict(self.timing_s),
        })


# ------------------------------------------------------------------------------ set-up

def find_mission(tlog: str | Path, mission: str | Path | None) -> Path:
    """The mission file: ``mission`` if given, else ``<tlog>.mission.yaml`` recorded beside the log,
    else ``<tlog stem>.yaml`` beside it. Raises :class:`LogError` when there is none."""
    if mission is not None:
        return Path(mission)
    tlog = Path(tlog)
    for candidate in (mission_path_beside(tlog), tlog.with_suffix(".yaml")):
        if candidate.is_file():
            return candidate
    raise LogError(f"{tlog}: no mission recorded beside the log (expected {tlog.name}{MISSION_SUFFIX}); "
                   "pass --mission M.yaml")


def tick_config_for(mission: Mission, rate_hz: float, output: str = "velocity",
                    stale_s: float = DEFAULT_STALE_S, drift_tc_s: float = 0.0,
                    accel_ff: bool = False, speed_hold_tc_s: float = 0.0,
                    tail: tuple[float, float] = (0.0, 0.0)) -> TickConfig:
    """The per-tick settings of a flight of this mission at ``rate_hz`` with ``output``
    (``"velocity"`` or ``"attitude"``), the stale-position limit ``stale_s``, the drift
    compensation's time constant ``drift_tc_s`` (0: off) and, with ``accel_ff``, the acceleration
    target up to the mission's limit (:func:`companion.loop.limits.accel_feedforward_limit_m_s2`)
    the ground-speed hold's integral time ``speed_hold_tc_s`` (0: off) and the velocity loop's
    slow ``tail`` compensated (share and time; share 0: off).

    ``--max-bank-deg`` is not recorded in the log; replay uses its default (35 deg).
    """
    return TickConfig(speed_m_s=mission.speed_m_s, rate_hz=rate_hz, altitude_m=mission.altitude_m,
                      output=output, stale_s=stale_s, profile=mission.profile, drift_tc_s=drift_tc_s,
                      accel_ff_max_m_s2=accel_feedforward_limit_m_s2(mission) if accel_ff else 0.0,
                      speed_hold_tc_s=speed_hold_tc_s, tail_share=tail[0], tail_tc_s=tail[1])


def flight_sent_accel(flight: LoggedFlight) -> bool:
    """Whether the flight's velocity setpoints carried the acceleration target (their mask uses it):
    the log, not the mission (whose default may have changed since), says what was sent."""
    return any(type(tk.setpoint) is LoggedSetpoint and uses_accel_target(tk.setpoint.type_mask)
               for tk in flight.ticks)


def flight_stale_s(flight: LoggedFlight) -> float:
    """A stale-position limit that reproduces the flight's hold decisions.

    The runner's ``--stale-s`` is not recorded, but every tick records its sample age and whether
    it held for a stale sample: the limit lies in ``[largest age that did not hold, smallest age
    that did)``. The default 0.3 s is used when it lies in that interval (or nothing is known),
    else the lower end.
    """
    flown, held = [], []
    for tk in flight.ticks:
        age = tk.debug_value("sample_age_s")
        if not math.isfinite(age):
            continue
        if tk.debug_value("hold_reason") == 1.0:
            held.append(age)
        elif tk.debug_value("phase_code") != 3.0 and tk.sample is not None:
            flown.append(age)
    low = max(flown, default=0.0)
    high = min(held, default=math.inf)
    if low <= DEFAULT_STALE_S < high or low >= high:
        return DEFAULT_STALE_S
    return low if low > 0 else DEFAULT_STALE_S


def flight_output(flight: LoggedFlight) -> str:
    """``"attitude"`` when the flight's paired setpoints are mostly SET_ATTITUDE_TARGET, else
    ``"velocity"`` (the runner picks it from the vehicle type; the log shows what was sent)."""
    attitude = sum(isinstance(tk.setpoint, LoggedAttitude) for tk in flight.ticks)
    velocity = sum(isinstance(tk.setpoint, LoggedSetpoint) for tk in flight.ticks)
    return "attitude" if attitude > velocity else "velocity"


def default_guidance(mission: Mission, rate_hz: float) -> GuidanceLaw:
    """A fresh guidance for the mission, built exactly as the live runner builds it."""
    return make_guidance(mission, rate_hz)


def in_flight_frame(flight: LoggedFlight, mission: Mission) -> Mission:
    """The mission in the logged flight's local frame.

    A geodetic mission is flown translated onto the autopilot's EKF origin (see
    :func:`companion.mission.placement.onto_autopilot_origin`); replay applies the same translation from
    the GPS_GLOBAL_ORIGIN recorded in the log. The acceleration limit the flight read from the
    autopilot's parameters (:mod:`companion.loop.limits`) is applied from the PARAM_VALUEs in the log.
    """
    if flight.kind == "companion" and flight.params:  # the limit the flight read from the autopilot
        mission = mission_with_limit(mission, limit_from_params(flight.params))[0]
    if mission.frame != "geodetic":
        return mission
    if flight.origin is None:
        raise LogError(f"{flight.path}: the mission is geodetic but the log holds no GPS_GLOBAL_ORIGIN "
                       "from the autopilot; cannot place the path in the flight's local frame")
    return onto_autopilot_origin(mission, flight.origin)[0]


def flight_rate_hz(flight: LoggedFlight, mission: Mission) -> float:
    """The loop rate the flight ran at: the one its ticks record; in logs from before that field,
    from the recorded tick times (median spacing, rounded to a whole number of hertz when within
    1 %: right on an unloaded machine, not where many ticks were skipped); else the mission's
    ``guidance.rate_hz``."""
    recorded = recorded_rate_hz(flight.ticks) if flight.kind == "companion" else None
    if recorded is not None:
        return recorded
    if flight.kind == "companion" and len(flight.ticks) > 2:
        t = np.array([tk.t_s for tk in flight.ticks])
        steps = np.diff(t)
        steps = steps[steps > 0]
        if steps.size:
            rate = 1.0 / float(np.median(steps))
            if abs(rate - round(rate)) <= 0.01 * rate:
                rate = float(round(rate))
            return rate
    return float(mission.guidance.rate_hz)


# ------------------------------------------------------------------------------ replay

_SERIES = ("t_s", "tick", "x_enu_m", "y_enu_m", "crosstrack_m", "a_logged_m_s2", "a_replayed_m_s2",
           "yaw_rate_logged_rad_s", "yaw_rate_replayed_rad_s", "vx_logged_m_s", "vy_logged_m_s",
           "vz_logged_m_s", "vx_replayed_m_s", "vy_replayed_m_s", "vz_replayed_m_s",
           "k1_logged", "k2_logged", "k1_replayed", "k2_replayed", "yaw_rate_diff_rad_s", "vel_diff_m_s",
           "roll_logged_rad", "roll_replayed_rad", "attitude_diff_rad",
           "alt_m", "s_proj_m", "ground_speed_m_s")  # the last three: profile errors


def _absdiff(a: float, b: float) -> float:
    """|a - b|, 0 when both are NaN (the same "not applicable"), inf when only one is."""
    if math.isnan(a) or math.isnan(b):
        return 0.0 if (math.isnan(a) and math.isnan(b)) else math.inf
    return abs(a - b)


def replay_flight(
    flight: LoggedFlight,
    mission: Mission,
    tolerance: Tolerance = Tolerance(),
    config: TickConfig | None = None,
    guidance_factory: Callable[[Mission, float], GuidanceLaw] = default_guidance,
    progress: bool | None = None,
) -> ReplayResult:
    """Replay the ticks of ``flight`` through a fresh guidance built from ``mission``.

    ``config`` defaults to :func:`tick_config_for` at :func:`flight_rate_hz`;
    ``guidance_factory(mission, rate_hz)`` builds the guidance (default: the live runner's).
    """
    started = time.perf_counter()
    mission = in_flight_frame(flight, mission)
    rate_hz = config.rate_hz if config is not None else flight_rate_hz(flight, mission)
    if config is None and flight.kind == "companion":
        config = tick_config_for(mission, rate_hz, flight_output(flight), flight_stale_s(flight),
                                 recorded_drift_tc_s(flight.ticks), flight_sent_accel(flight),
                                 recorded_speed_hold_tc_s(flight.ticks), recorded_tail(flight.ticks))
    config = config or tick_config_for(mission, rate_hz, flight_output(flight))
    mission = mission_for_tail(mission, config.compensates_tail)[0]  # as the flight chose its lambda
    guidance = guidance_factory(mission, rate_hz)
    replay = _Replay(flight, mission, tolerance, config, guidance)
    replay.run(progress)
    return replay.result(mission, tolerance, rate_hz, time.perf_counter() - started)


class _Replay:
    """One replay's state: the tick driver, the series (Python lists while stepping: an item
    store is several times cheaper than into an ndarray), the phases and the first divergence."""

    def __init__(self, flight: LoggedFlight, mission: Mission, tolerance: Tolerance, config: TickConfig,
                 guidance: GuidanceLaw):
        self.flight = flight
        self.tolerance = tolerance
        self.path = mission.path
        self.profile = mission.profile
        self.companion_log = flight.kind == "companion"
        n = len(flight.ticks)
        self.cols: dict[str, list[float]] = {name: [math.nan] * n for name in _SERIES}
        self.compared = [False] * n
        self.phase_logged: list[str] = []
        self.phase_replayed: list[str] = []
        self.first_divergence: dict | None = None
        # The state the live loop carries from tick to tick, with the loop's rules.
        self.driver = TickDriver(guidance, config, self.path.start_heading_rad)
        self.s_hint: float | None = None
        self.coasts = flight.coasts if self.companion_log else []
        self.coast_next = 0
        self.coast_diffs: list[dict] = []

    def coasts_before(self, row: int) -> None:
        """Replay the coasting setpoints sent after the previous row and before ``row``."""
        coasts, flight = self.coasts, self.flight
        while self.coast_next < len(coasts) and coasts[self.coast_next].after_tick < row:
            c = coasts[self.coast_next]
            self.coast_next += 1
            sp = self.driver.coast(c.sample, c.sample_age_s)
            diff, reasons = _compare_setpoints(c.setpoint, sp, self.tolerance)
            self.coast_diffs.append(diff)
            if reasons and self.first_divergence is None:
                prev = flight.ticks[c.after_tick]
                self.first_divergence = {
                    "time_s": float(prev.t_s + (c.time_unix_s - prev.time_unix_s)),
                    "tick": int(prev.tick), "coast": True, "reasons": reasons,
                    **{k: _json_float(v) for k, v in diff.items()},
                    "logged": {k: _json_float(v) for k, v in _setpoint_fields(c.setpoint).items()},
                    "replayed": {k: _json_float(v) for k, v in _setpoint_fields(sp).items()},
                }

    def run(self, progress: bool | None) -> None:
        """Every tick in order (and the coasts between them)."""
        ticks, coasts = self.flight.ticks, self.coasts
        n, n_coasts = len(ticks), len(coasts)
        tick = self.tick
        with ByteProgress(n, "replaying", enabled=progress, unit=" ticks") as bar:
            for i, tk in enumerate(ticks):
                if i % 1024 == 0:
                    bar.update_to(i)
                if self.coast_next < n_coasts and coasts[self.coast_next].after_tick < i:
                    self.coasts_before(i)
                tick(i, tk)
            self.coasts_before(n)
            bar.update_to(n)

    def tick(self, i: int, tk: LoggedTick) -> None:
        """Replay one logged tick and store both sides (runs once per tick of an hour-long log)."""
        cols, driver, companion_log = self.cols, self.driver, self.companion_log
        row = tk.debug
        if row is not None and math.isfinite(row[_I_PREV]):
            # The loop records the course state each tick was given (it differs from the
            # carried state when the step was late): use it as the input.
            prev_course = row[_I_PREV]
            cmd = row[_I_PREV_CMD]
            prev_course_cmd = cmd if math.isfinite(cmd) else None
        else:
            prev_course, prev_course_cmd = driver.prev_course_rad, driver.prev_course_cmd_rad
        t_s = _tick_time(tk) if companion_log else tk.t_s
        res = driver.step(tk.tick, t_s, tk.sample, tk.sample_age_s, tk.yaw_ned_rad, prev_course, prev_course_cmd)
        # A companion tick without its setpoint is a late one (recorded, not sent).
        driver.accept(res, sent=tk.setpoint is not None or not companion_log)
        sp = res.setpoint
        out = res.output
        cols["t_s"][i] = tk.t_s
        cols["tick"][i] = tk.tick
        sample = tk.sample
        if sample is not None:
            cols["x_enu_m"][i] = sample.y_ned_m
            cols["y_enu_m"][i] = sample.x_ned_m
            if self.profile is not None:
                cols["alt_m"][i] = -sample.z_ned_m
                cols["ground_speed_m_s"][i] = math.hypot(sample.vx_ned_m_s, sample.vy_ned_m_s)
        if out is not None:
            cols["s_proj_m"][i] = out.s_proj_m
            cols["a_replayed_m_s2"][i], cols["k1_replayed"][i], cols["k2_replayed"][i] = out.a_cmd_m_s2, out.k1, out.k2
        else:
            cols["a_replayed_m_s2"][i] = 0.0
        if type(sp) is VelocitySetpoint:
            cols["yaw_rate_replayed_rad_s"][i], cols["vx_replayed_m_s"][i] = sp.yaw_rate_ned_rad_s, sp.vx_ned_m_s
            cols["vy_replayed_m_s"][i], cols["vz_replayed_m_s"][i] = sp.vy_ned_m_s, sp.vz_ned_m_s
        self.phase_replayed.append(res.phase)
        if companion_log:
            self.phase_logged.append(phase_name(row[_I_PHASE]))
            cols["crosstrack_m"][i], cols["a_logged_m_s2"][i] = row[_I_XTRACK], row[_I_A]
            cols["k1_logged"][i], cols["k2_logged"][i] = row[_I_K1], row[_I_K2]
        else:
            self._other_log_tick(i, tk, res.phase)
        if tk.setpoint is None:
            return
        reasons = self._compare(i, tk.setpoint, sp)
        self.compared[i] = True
        if companion_log and self.phase_logged[-1] != res.phase:
            reasons.append("phase")
        if reasons and self.first_divergence is None:
            self.first_divergence = _divergence(tk, i, cols, self.phase_logged[-1], res.phase, reasons,
                                                companion_log)

    def _other_log_tick(self, i: int, tk: LoggedTick, phase: str) -> None:
        """A log the companion did not write: the flight's own cross-track and acceleration."""
        cols = self.cols
        self.phase_logged.append(phase)
        sample, logged = tk.sample, tk.setpoint
        if sample is not None:
            x, y = sample.y_ned_m, sample.x_ned_m
            self.s_hint = self.path.project(x, y, self.s_hint)
            cols["crosstrack_m"][i] = self.path.crosstrack_m(x, y, self.s_hint)
        if logged is not None:
            speed_h = math.hypot(logged.vx_ned_m_s, logged.vy_ned_m_s)
            cols["a_logged_m_s2"][i] = -logged.yaw_rate_ned_rad_s * speed_h

    def _compare(self, i: int, logged: LoggedSetpoint | LoggedAttitude,
                 sp: VelocitySetpoint | AttitudeSetpoint) -> list[str]:
        """Store the logged setpoint and the differences; the tolerances broken."""
        cols, tolerance = self.cols, self.tolerance
        if type(sp) is VelocitySetpoint and type(logged) is LoggedSetpoint:
            # The common case, written out (_compare_setpoints is the general one).
            cols["yaw_rate_logged_rad_s"][i], cols["vx_logged_m_s"][i] = logged.yaw_rate_ned_rad_s, logged.vx_ned_m_s
            cols["vy_logged_m_s"][i], cols["vz_logged_m_s"][i] = logged.vy_ned_m_s, logged.vz_ned_m_s
            d_yaw = abs(logged.yaw_rate_ned_rad_s - sp.yaw_rate_ned_rad_s)
            dx = logged.vx_ned_m_s - sp.vx_ned_m_s
            dy = logged.vy_ned_m_s - sp.vy_ned_m_s
            dz = logged.vz_ned_m_s - sp.vz_ned_m_s
            d_vel = math.sqrt(dx * dx + dy * dy + dz * dz)
            if d_yaw != d_yaw or d_vel != d_vel:  # NaN on a side: _absdiff's rule
                diff, _ = _compare_setpoints(logged, sp, tolerance)
                d_yaw, d_vel = diff["yaw_rate_diff_rad_s"], diff["vel_diff_m_s"]
            cols["yaw_rate_diff_rad_s"][i], cols["vel_diff_m_s"][i] = d_yaw, d_vel
            reasons = []
            if not d_yaw <= tolerance.yaw_rate_rad_s:
                reasons.append("yaw_rate")
            if not d_vel <= tolerance.vel_m_s:
                reasons.append("velocity")
            if logged.type_mask != sp.type_mask:  # e.g. the acceleration target sent on one side only
                reasons.append("type_mask")
            return reasons
        fields = _setpoint_fields(logged)
        cols["yaw_rate_logged_rad_s"][i], cols["vx_logged_m_s"][i] = fields["yaw_rate_rad_s"], fields["vx_m_s"]
        cols["vy_logged_m_s"][i], cols["vz_logged_m_s"][i] = fields["vy_m_s"], fields["vz_m_s"]
        cols["roll_logged_rad"][i] = fields["roll_rad"]
        if isinstance(sp, AttitudeSetpoint):
            cols["roll_replayed_rad"][i] = sp.roll_ned_rad
        diff, reasons = _compare_setpoints(logged, sp, tolerance)
        cols["yaw_rate_diff_rad_s"][i], cols["vel_diff_m_s"][i], cols["attitude_diff_rad"][i] = (
            diff["yaw_rate_diff_rad_s"], diff["vel_diff_m_s"], diff["attitude_diff_rad"])
        return reasons

    def result(self, mission: Mission, tolerance: Tolerance, rate_hz: float, replay_s: float) -> ReplayResult:
        """The series as arrays, the per-phase figures, the phase switches and the flight's tracking."""
        phase_logged, phase_replayed, coast_diffs = self.phase_logged, self.phase_replayed, self.coast_diffs
        cols: dict[str, np.ndarray] = {name: np.array(values, dtype=float) for name, values in self.cols.items()}
        cols["compared"] = np.array(self.compared, dtype=bool)
        per_phase = _per_phase(cols, phase_logged if self.companion_log else phase_replayed)
        if coast_diffs:
            per_phase["coast"] = _per_phase(
                {**{k: np.array([d[k] for d in coast_diffs]) for k in coast_diffs[0]},
                 "compared": np.ones(len(coast_diffs), dtype=bool)}, ["coast"] * len(coast_diffs))["coast"]
        switches = {"logged": _switches(cols["t_s"], phase_logged) if self.companion_log else [],
                    "replayed": _switches(cols["t_s"], phase_replayed)}
        tracking = _tracking(cols, phase_logged, mission.profile)
        cols["phase_logged"] = np.asarray(phase_logged, dtype=object)
        cols["phase_replayed"] = np.asarray(phase_replayed, dtype=object)
        return ReplayResult(self.flight, mission.name, tolerance, cols, self.first_divergence, per_phase, switches,
                            tracking, {"replay_s": replay_s}, mission.path, rate_hz,
                            mission.profile)


_I_PREV, _I_PREV_CMD = DEBUG_INDEX["prev_course_rad"], DEBUG_INDEX["prev_course_cmd_rad"]
_I_PHASE, _I_XTRACK, _I_A = DEBUG_INDEX["phase_code"], DEBUG_INDEX["crosstrack_m"], DEBUG_INDEX["a_cmd_m_s2"]
_I_K1, _I_K2 = DEBUG_INDEX["k1"], DEBUG_INDEX["k2"]


def _compare_setpoints(logged, sp, tolerance: Tolerance) -> tuple[dict, list[str]]:
    """Differences between a logged and a replayed setpoint, and the tolerances they break."""
    reasons = []
    diff = {"yaw_rate_diff_rad_s": math.nan, "vel_diff_m_s": math.nan, "attitude_diff_rad": math.nan}
    if isinstance(logged, LoggedSetpoint) and isinstance(sp, VelocitySetpoint):
        diff["yaw_rate_diff_rad_s"] = d_yaw = _absdiff(logged.yaw_rate_ned_rad_s, sp.yaw_rate_ned_rad_s)
        diff["vel_diff_m_s"] = d_vel = math.sqrt(_absdiff(logged.vx_ned_m_s, sp.vx_ned_m_s) ** 2
                                                 + _absdiff(logged.vy_ned_m_s, sp.vy_ned_m_s) ** 2
                                                 + _absdiff(logged.vz_ned_m_s, sp.vz_ned_m_s) ** 2)
        if not d_yaw <= tolerance.yaw_rate_rad_s:
            reasons.append("yaw_rate")
        if not d_vel <= tolerance.vel_m_s:
            reasons.append("velocity")
        if logged.type_mask != sp.type_mask:
            reasons.append("type_mask")
    elif isinstance(logged, LoggedAttitude) and isinstance(sp, AttitudeSetpoint):
        diff["attitude_diff_rad"] = d_att = rotation_between_rad(logged.q, sp.q)
        if not d_att <= tolerance.attitude_rad:
            reasons.append("attitude")
    else:
        reasons.append("setpoint_type")  # e.g. velocity logged, attitude replayed
    return diff, reasons


def _setpoint_fields(sp) -> dict:
    """The comparable fields of a logged or replayed setpoint (NaN where not applicable)."""
    nan = math.nan
    if isinstance(sp, LoggedSetpoint):
        return {"vx_m_s": sp.vx_ned_m_s, "vy_m_s": sp.vy_ned_m_s, "vz_m_s": sp.vz_ned_m_s,
                "yaw_rate_rad_s": sp.yaw_rate_ned_rad_s, "roll_rad": nan}
    if isinstance(sp, VelocitySetpoint):
        return {"vx_m_s": sp.vx_ned_m_s, "vy_m_s": sp.vy_ned_m_s, "vz_m_s": sp.vz_ned_m_s,
                "yaw_rate_rad_s": sp.yaw_rate_ned_rad_s, "roll_rad": nan}
    if isinstance(sp, LoggedAttitude):
        return {"vx_m_s": nan, "vy_m_s": nan, "vz_m_s": nan, "yaw_rate_rad_s": nan,
                "roll_rad": roll_from_quaternion(sp.q)}
    return {"vx_m_s": nan, "vy_m_s": nan, "vz_m_s": nan, "yaw_rate_rad_s": nan, "roll_rad": sp.roll_ned_rad}


def _tick_time(tk: LoggedTick) -> float:
    """The float64 tick time the loop stepped the guidance with (``docs/recording.md``).

    The record holds ``t_s`` as float32 (0.24 ms resolution at one hour, enough to move a
    re-optimisation by a tick) plus the float32 residual ``t_s - float32(t_s)``: their sum
    restores the flown time to about 1e-11 s. Logs without the residual use the float32 time.
    """
    residual = tk.debug[_I_RESIDUAL] if tk.debug is not None else math.nan
    return tk.t_s + residual if math.isfinite(residual) else tk.t_s


_I_RESIDUAL = DEBUG_INDEX["t_s_residual"]


def _divergence(tk: LoggedTick, i: int, cols: dict, phase_logged: str, phase_replayed: str,
                reasons: list[str], companion_log: bool) -> dict:
    def side(which: str, phase: str) -> dict:
        out = {
            "vx_m_s": cols[f"vx_{which}_m_s"][i],
            "vy_m_s": cols[f"vy_{which}_m_s"][i],
            "vz_m_s": cols[f"vz_{which}_m_s"][i],
            "yaw_rate_rad_s": cols[f"yaw_rate_{which}_rad_s"][i],
            "a_cmd_m_s2": cols[f"a_{which}_m_s2"][i],
            "roll_rad": cols[f"roll_{which}_rad"][i],
        }
        if companion_log or which == "replayed":
            out.update(phase=phase, k1=cols[f"k1_{which}"][i], k2=cols[f"k2_{which}"][i])
        return {k: (_json_float(v) if isinstance(v, float) else v) for k, v in out.items()}

    return {
        "time_s": float(tk.t_s),
        "tick": int(tk.tick),
        "reasons": reasons,
        "yaw_rate_diff_rad_s": _json_float(cols["yaw_rate_diff_rad_s"][i]),
        "vel_diff_m_s": _json_float(cols["vel_diff_m_s"][i]),
        "attitude_diff_rad": _json_float(cols["attitude_diff_rad"][i]),
        "logged": side("logged", phase_logged),
        "replayed": side("replayed", phase_replayed),
    }


def roll_from_quaternion(q) -> float:
    """Roll (NED, right wing down positive) of an attitude quaternion ``(w, x, y, z)``."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))


def rotation_between_rad(q1, q2) -> float:
    """Angle of the rotation between two attitude quaternions, in ``[0, pi]`` (sign-insensitive).

    The unit quaternions of a rotation by ``theta`` lie ``theta / 2`` apart on the 4-sphere, and
    ``atan2(|q1 - s q2|, |q1 + s q2|)`` (``s`` the sign of their dot product) is half of that
    separation, so the rotation is ``4 atan2(...)``: well conditioned for small angles, unlike
    ``2 acos(|q1 . q2|)``.

    >>> round(rotation_between_rad((1, 0, 0, 0), (math.cos(0.05), math.sin(0.05), 0, 0)), 12)
    0.1
    """
    a = np.asarray(q1, dtype=float)
    b = np.asarray(q2, dtype=float)
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    if float(np.dot(a, b)) < 0.0:
        b = -b
    return float(4.0 * math.atan2(np.linalg.norm(a - b), np.linalg.norm(a + b)))


def _json_float(value) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _per_phase(cols: dict, phases: list[str]) -> dict[str, dict]:
    names = np.asarray(phases, dtype=object)
    out: dict[str, dict] = {}
    for name in dict.fromkeys(phases):
        mask = (names == name) & cols["compared"]
        entry = {"steps": int(np.count_nonzero(mask))}
        for column, key in (("yaw_rate_diff_rad_s", "yaw_rate"), ("vel_diff_m_s", "vel"),
                            ("attitude_diff_rad", "attitude")):
            unit = column[column.index("_diff") + 5:]
            values = cols[column][mask]
            values = values[np.isfinite(values) | np.isinf(values)]
            if key == "attitude" and values.size == 0:
                continue  # velocity output: no attitude columns
            entry[f"{key}_max{unit}"] = _json_float(np.max(values)) if values.size else None
            entry[f"{key}_rms{unit}"] = _json_float(np.sqrt(np.mean(values * values))) if values.size else None
        out[str(name)] = entry
    return out


def _switches(t_s: np.ndarray, phases: list[str]) -> list[dict]:
    out = []
    for i in range(1, len(phases)):
        if phases[i] != phases[i - 1]:
            out.append({"time_s": float(t_s[i]), "from": phases[i - 1], "to": phases[i]})
    return out


def _tracking(cols: dict, phases: list[str], profile=None) -> dict:
    """Tracking figures of the flight itself, over the ticks with a cross-track value (and, for a
    mission with a profile, the vertical and speed errors)."""
    d = cols["crosstrack_m"]
    a = cols["a_logged_m_s2"]
    keep = np.isfinite(d) & np.isfinite(a)
    names = [p for p, k in zip(phases, keep) if k]
    m = tracking_metrics(cols["t_s"][keep], d[keep], a[keep], names,
                         **profile_errors(profile, cols["s_proj_m"][keep], cols["alt_m"][keep],
                                          cols["ground_speed_m_s"][keep]))
    return {k: (_json_float(v) if isinstance(v, float) else v) for k, v in m.items()}


# ------------------------------------------------------------------------------ one call

@contextlib.contextmanager
def _collector_paused():
    """Pause the cyclic garbage collector for the block (if it was running); resume after."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def replay_log(
    tlog: str | Path,
    mission: str | Path | Mission | None = None,
    tolerance: Tolerance = Tolerance(),
    on_warning: Callable[[LogWarning], None] | None = None,
    progress: bool | None = None,
    guidance_factory: Callable[[Mission, float], GuidanceLaw] = default_guidance,
    config: TickConfig | None = None,
) -> ReplayResult:
    """Read ``tlog``, load its mission, replay it. Raises :class:`LogError` / ``MissionError``.

    The cyclic garbage collector is paused while the log is read and replayed: a long log keeps
    millions of small objects alive (records, ticks, samples; none in reference cycles), and each
    full collection would walk all of them again, about a tenth of the time of an hour's log.
    The collector resumes (if it was running) when the call returns.
    """
    with _collector_paused():
        started = time.perf_counter()
        flight = read_flight(tlog, on_warning=on_warning, progress=progress)
        read_s = time.perf_counter() - started
        if not isinstance(mission, Mission):
            mission = load_mission(find_mission(tlog, mission))
        result = replay_flight(flight, mission, tolerance, config=config, guidance_factory=guidance_factory,
                               progress=progress)
    result.timing_s["read_s"] = read_s
    result.timing_s["total_s"] = time.perf_counter() - started
    if result.steps_compared == 0:
        raise LogError(f"{tlog}: none of the {len(flight.ticks)} ticks has a logged setpoint to compare "
                       "with")
    return result
