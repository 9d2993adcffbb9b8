"""Offline simulator: fly any guidance law on the paper's kinematics (eq. 1).

    result = simulate(path, TwoPhaseGuidance(path, params), start, params)
    result.metrics["d_rms_m"], result.x_m, result.phase

The vehicle is a unicycle at constant airspeed V = ``start.speed_m_s``::

    x' = V cos(psi) + wind_x,   y' = V sin(psi) + wind_y,   psi' = a / V

stepped at the guidance rate (``params.rate_hz``). Each tick the law sees the state (position,
ground course, ground speed), returns a command, and the command is held for one tick. With no
wind and the ideal model the step is exact: a constant turn rate over the tick draws a circular
arc, integrated in closed form.

A guidance law is any object with ``step(t_s, VehicleState) -> GuidanceOutput``.

Models
------
- ideal (``model=None``): the achieved lateral acceleration equals the command (the paper).
- :class:`LagModel`: the achieved acceleration follows the command issued ``delay_s`` earlier
  (rounded to whole ticks), first saturated at ``a_max_m_s2``, with a first-order lag of time
  constant ``tau_s`` (exact discretisation over a tick; the turn rate used for the tick is the
  mean of the achieved acceleration over it), plus a constant wind.
  :meth:`LagModel.from_vehicle` builds it from a mission's ``vehicle:`` block.

Accounting (the same for every law)
-----------------------------------
The vehicle's limits act on every law's command before it is flown, whether the law clips its
own command or not. Three columns, one entry per tick ``i`` (time ``t_i``):

- ``a_cmd_m_s2``: the law's raw command issued at ``t_i``;
- ``a_sat_m_s2``: that command saturated at the vehicle's limit (``a_max_m_s2``), i.e. what the
  vehicle accepts; it acts ``delay_s`` later;
- ``a_achieved_m_s2``: the lateral acceleration the vehicle *flies* over the tick
  ``[t_i, t_i + dt]``: after dead time, saturation and lag, averaged over the tick. This is the
  turn rate ``a / V`` that moves the vehicle in the step, so it is what was flown. (The value in
  force at the start of the tick would lag the command by one tick in the ideal model, where the
  command is flown from ``t_i`` on; the tick mean equals the command there exactly.)

``metrics`` (``a_rms_m_s2``, ``a_max_m_s2``) measure ``a_achieved_m_s2``; in the ideal model it
equals ``a_cmd_m_s2`` to the bit, and in the lag model ``|a_achieved| <= a_max_m_s2`` for every
law.

End of a run: the law reports ``finished`` (for :class:`TwoPhaseGuidance` on an open path, the
look-ahead point reaching the path end), or ``t_max_s`` elapses (default: the time to fly three
times the path length plus the distance to its start, at V).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from companion.geometry.paths import Path
from companion.guidance.types import GuidanceLaw, GuidanceOutput, GuidanceParams, VehicleModel, VehicleState
from companion.sim.metrics import tracking_metrics

if TYPE_CHECKING:
    from companion.geometry.profile import PathProfile


@dataclass(frozen=True)
class LagModel:
    """First-order inner loop with saturation and a dead time, and a constant wind (local ENU)."""

    tau_s: float = 0.0
    a_max_m_s2: float = math.inf
    wind_enu_m_s: tuple[float, float] = (0.0, 0.0)
    delay_s: float = 0.0

    @classmethod
    def from_vehicle(cls, vehicle: VehicleModel, wind_enu_m_s: tuple[float, float] = (0.0, 0.0)) -> "LagModel":
        """The lateral part of a mission's ``vehicle:`` model: its lag, limit and dead time (a second
        acceleration lag is folded into the lag, the speed sag left out: the simulator flies at
        constant speed)."""
        return cls(tau_s=vehicle.lag_s + vehicle.accel_lag_s, a_max_m_s2=vehicle.a_max_m_s2,
                   wind_enu_m_s=wind_enu_m_s, delay_s=vehicle.delay_s)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.delay_s) and self.delay_s >= 0):
            raise ValueError(f"delay_s: expected a finite number >= 0, got {self.delay_s!r}")
        if not (math.isfinite(self.tau_s) and self.tau_s >= 0):
            raise ValueError(f"tau_s: expected a finite number >= 0, got {self.tau_s!r}")
        if not (self.a_max_m_s2 > 0):
            raise ValueError(f"a_max_m_s2: expected a number > 0, got {self.a_max_m_s2!r}")
        if len(self.wind_enu_m_s) != 2 or not all(math.isfinite(w) for w in self.wind_enu_m_s):
            raise ValueError(f"wind_enu_m_s: expected two finite numbers, got {self.wind_enu_m_s!r}")


@dataclass
class SimResult:
    """Per-tick arrays of one simulated flight and its metrics (:mod:`companion.sim.metrics`)."""

    t_s: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    course_rad: np.ndarray
    a_cmd_m_s2: np.ndarray  # the law's raw command
    a_achieved_m_s2: np.ndarray  # flown: mean over the tick after dead time, saturation and lag
    crosstrack_m: np.ndarray
    phase: list[str]
    k1: np.ndarray
    k2: np.ndarray
    finished: bool
    metrics: dict[str, Any] = field(default_factory=dict)
    outputs: list[GuidanceOutput] = field(default_factory=list)  # the GuidanceOutput of every tick
    a_sat_m_s2: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the command after the limit


#: The per-tick columns ``simulate`` records (``a``: the raw command, ``a_sat``: after the limit,
#: ``a_ach``: flown).
_COLUMNS = ("t", "x", "y", "course", "a", "a_sat", "a_ach", "d", "k1", "k2")


def unicycle_step(x_m: float, y_m: float, heading_rad: float, speed_m_s: float,
                  a_m_s2: float, dt_s: float) -> tuple[float, float, float]:
    """Exact step of eq. 1 for a constant lateral acceleration over ``dt_s`` (a circular arc)."""
    w = a_m_s2 / speed_m_s if speed_m_s > 0 else 0.0
    dpsi = w * dt_s
    psi1 = heading_rad + dpsi
    if abs(dpsi) < 1e-9:
        return (x_m + speed_m_s * dt_s * math.cos(heading_rad + 0.5 * dpsi),
                y_m + speed_m_s * dt_s * math.sin(heading_rad + 0.5 * dpsi), psi1)
    r = speed_m_s / w
    return (x_m + r * (math.sin(psi1) - math.sin(heading_rad)),
            y_m - r * (math.cos(psi1) - math.cos(heading_rad)), psi1)


def default_t_max_s(path: Path, start: VehicleState) -> float:
    sx, sy = path.start_xy_m
    dist = math.hypot(start.x_m - sx, start.y_m - sy)
    return 3.0 * (path.length_m + dist) / max(start.speed_m_s, 0.1) + 60.0


def simulate(path: Path, law: GuidanceLaw, start: VehicleState, params: GuidanceParams, *,
             model: LagModel | None = None, t_max_s: float | None = None,
             keep_outputs: bool = False, profile: PathProfile | None = None) -> SimResult:
    """Fly ``law`` from ``start`` until it reports ``finished`` or ``t_max_s`` elapses.

    Parameters
    ----------
    path : the reference path (used for the default ``t_max_s`` only; the law owns its path).
    law : any object with ``step(t_s, VehicleState) -> GuidanceOutput``.
    start : initial position, heading (= course without wind) and airspeed V.
    params : ``rate_hz`` sets the tick.
    model : None for the paper's ideal inner loop, or a :class:`LagModel`.
    t_max_s : time limit (default :func:`default_t_max_s`).
    keep_outputs : also keep every tick's :class:`GuidanceOutput` in ``result.outputs``.
    profile : a :class:`companion.geometry.profile.PathProfile` whose speed changes along the
        path: the vehicle then flies each tick at ``V(s)`` of the previous tick's projection (the
        start's speed first); None (default) flies at ``start.speed_m_s`` throughout.

    Returns
    -------
    SimResult. The ``finished`` tick itself is not recorded (its command is 0 by definition).
    Its ``metrics`` measure the flown acceleration ``a_achieved_m_s2`` (module docstring,
    "Accounting").
    """
    if t_max_s is None:
        t_max_s = default_t_max_s(path, start)
    dt = 1.0 / params.rate_hz
    V = start.speed_m_s
    if not V > 0:
        raise ValueError(f"start.speed_m_s: expected > 0, got {V!r}")
    wind = (0.0, 0.0) if model is None else model.wind_enu_m_s
    tau = 0.0 if model is None else model.tau_s
    a_lim = math.inf if model is None else model.a_max_m_s2
    lag = math.exp(-dt / tau) if tau > 0 else 0.0
    delay_ticks = 0 if model is None else int(round(model.delay_s / dt))
    pending = [0.0] * delay_ticks  # commands issued but not yet acting (dead time), oldest first
    x, y, psi = start.x_m, start.y_m, start.course_rad
    a_ach = 0.0
    cols: dict[str, list[float]] = {k: [] for k in _COLUMNS}
    phases: list[str] = []
    outputs = []
    finished = False
    n_max = int(math.floor(t_max_s / dt + 1e-9))
    for i in range(n_max + 1):
        t = i * dt
        gx = V * math.cos(psi) + wind[0]
        gy = V * math.sin(psi) + wind[1]
        course = math.atan2(gy, gx) if (wind[0] or wind[1]) else psi
        ground = math.hypot(gx, gy) if (wind[0] or wind[1]) else V
        out = law.step(t, VehicleState(x, y, course, ground))
        if out.phase == "finished":
            finished = True
            break
        a_cmd = out.a_cmd_m_s2
        _record_tick(cols, t, x, y, course, out)
        phases.append(out.phase)
        if keep_outputs:
            outputs.append(out)
        # Inner loop: dead time, saturation, first-order lag (exact over the tick); the flown
        # acceleration is its mean over the tick.
        target = a_sat = max(-a_lim, min(a_lim, a_cmd))
        if delay_ticks:
            pending.append(a_sat)
            target = pending.pop(0)
        if tau > 0:
            a_next = target + (a_ach - target) * lag
            a_mean = target + (a_ach - target) * tau / dt * (1.0 - lag)
        else:
            a_next = a_mean = target
        cols["a_sat"].append(a_sat)
        cols["a_ach"].append(a_mean)
        if i == n_max:
            break
        if profile is not None:
            V = profile.speed_m_s(out.s_proj_m)
        x, y, psi = unicycle_step(x, y, psi, V, a_mean, dt)
        x += wind[0] * dt
        y += wind[1] * dt
        a_ach = a_next
    return _sim_result(cols, phases, finished, outputs)


def _record_tick(cols: dict[str, list[float]], t_s: float, x_m: float, y_m: float, course_rad: float,
                 out: GuidanceOutput) -> None:
    """Append one tick's state and command to the columns (``a_sat`` and ``a_ach`` are appended by
    the caller)."""
    for key, value in (("t", t_s), ("x", x_m), ("y", y_m), ("course", course_rad), ("a", out.a_cmd_m_s2),
                       ("d", out.crosstrack_m), ("k1", out.k1), ("k2", out.k2)):
        cols[key].append(value)


def _sim_result(cols: dict[str, list[float]], phases: list[str], finished: bool,
                outputs: list[GuidanceOutput]) -> SimResult:
    """The recorded per-tick columns as a :class:`SimResult`, with its tracking metrics."""
    arr = {k: np.asarray(v, dtype=float) for k, v in cols.items()}
    result = SimResult(arr["t"], arr["x"], arr["y"], arr["course"], arr["a"], arr["a_ach"],
                       arr["d"], phases, arr["k1"], arr["k2"], finished, outputs=outputs,
                       a_sat_m_s2=arr["a_sat"])
    result.metrics = tracking_metrics(arr["t"], arr["d"], arr["a_ach"], phases)  # what was flown
    return result
