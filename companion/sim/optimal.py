"""The physical limit of path tracking: the offline optimum of the cost every causal law pays.

    problem = OptimalProblem.build(path, start, rate_hz=50.0, horizon_s=50.0, model=LagModel(...))
    sol = solve_optimal(problem, lambda_s4=0.03, warm_starts=[law_commands, ...])
    front = BoundFront.from_solutions([sol, ...])
    front.d_rms_m(a_rms_m_s2), gap_pct(law_d_rms_m, law_a_rms_m_s2, front)

For one scenario (path, start, speed, rate, vehicle model) and a weight ``lambda`` (s^4), the
cost of a flight of ``N`` ticks is ::

    J(lambda) = (1/N) sum_{k<N} ( d_k^2 + lambda a_k^2 )

with ``d_k`` the signed distance to the closest path point at the start of tick ``k``
(projection kept continuous along the flight, as the tracking bench measures it) and ``a_k`` the
lateral acceleration the vehicle *flies* over tick ``k``: the mean over the tick of the achieved
acceleration after the dead time, the saturation at ``a_max`` and the first-order lag (in the
ideal model, the command itself). The vehicle is :func:`companion.sim.simulator.simulate`'s:
a unicycle at constant airspeed ``V`` turning at ``a / V``, one command per tick held for the
tick, dead time in whole ticks, ``|a_cmd| <= a_max``, the lag discretised exactly over the tick,
a constant wind added to the ground velocity.

:func:`solve_optimal` minimises ``J`` over every sequence of per-tick commands (the laws' own
control class), the whole flight known in advance, with scipy's L-BFGS-B (box bounds
``|a_cmd| <= a_max``) and an exact gradient: the reverse pass through the discrete dynamics
(:func:`cost_and_gradient`). It refines each warm start (a causal law's commands, or the
optimum at a neighbouring ``lambda``) first as piecewise-constant corrections over coarse blocks
of ticks, then per tick, and keeps the best.

The lower-bound front. For any command sequence with mean flown ``a^2 = A`` and mean ``d^2 = D``
over the same ``N`` ticks, ``J*(lambda) <= D + lambda A`` for every ``lambda`` (weak duality),
so ::

    d_rms >= sqrt(max(0, max_lambda J*(lambda) - lambda a_rms^2))

(:meth:`BoundFront.d_rms_m`). It is a bound only as far as ``J*`` is the global optimum: the
problem is not convex, and a local optimum over-estimates ``J*`` and so the bound. Several
starts are taken and their spread is reported (:attr:`OptimalSolution.costs_by_start`).

Units: SI, local ENU (x east, y north), angles anticlockwise from +x, lateral acceleration
positive to the left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.optimize import minimize
from scipy.signal import lfilter

from companion.geometry.paths import PROJECT_WINDOW_FACTOR, PROJECT_WINDOW_MIN_M, Path
from companion.guidance.path_frame import first_projection_s, path_frame
from companion.guidance.types import VehicleState
from companion.sim.simulator import LagModel

#: Block lengths (ticks) of the coarse-to-fine refinement; the last level is always per tick. From a
#: causal law's commands the per-tick level alone converged as well and sooner on the bench's scenarios.
DEFAULT_LEVELS = (1,)
#: Passes of the vectorised projection before it falls back to projecting tick by tick.
_PROJECTION_PASSES = 6
#: Below this turn angle over a tick (rad) the arc factors use their Taylor series.
_SMALL_TURN_RAD = 1e-4


# ----------------------------------------------------------------------------- the problem
@dataclass(frozen=True)
class OptimalProblem:
    """One scenario over a fixed horizon of ``n_ticks`` ticks.

    Build it with :meth:`build`. ``a_max_m_s2`` is ``inf`` in the ideal model; ``delay_ticks`` is
    the dead time rounded to whole ticks as :func:`~companion.sim.simulator.simulate` does.
    """

    path: Path
    start: VehicleState
    rate_hz: float
    n_ticks: int
    tau_s: float = 0.0
    a_max_m_s2: float = math.inf
    delay_ticks: int = 0
    wind_enu_m_s: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def build(cls, path: Path, start: VehicleState, *, rate_hz: float, horizon_s: float,
              model: LagModel | None = None) -> "OptimalProblem":
        """The problem of flying ``path`` from ``start`` for ``horizon_s`` (whole ticks, rounded down).

        ``start.course_rad`` is the heading and ``start.speed_m_s`` the airspeed ``V``, as in
        :func:`~companion.sim.simulator.simulate`; ``model`` None is the ideal inner loop.
        """
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz: expected a finite number > 0, got {rate_hz!r}")
        if not start.speed_m_s > 0:
            raise ValueError(f"start.speed_m_s: expected > 0, got {start.speed_m_s!r}")
        n = int(math.floor(horizon_s * rate_hz + 1e-9))
        if n < 2:
            raise ValueError(f"horizon_s: expected at least two ticks, got {horizon_s!r} s at {rate_hz!r} Hz")
        if model is None:
            return cls(path, start, float(rate_hz), n)
        return cls(path, start, float(rate_hz), n, tau_s=model.tau_s, a_max_m_s2=model.a_max_m_s2,
                   delay_ticks=int(round(model.delay_s * rate_hz)),
                   wind_enu_m_s=(float(model.wind_enu_m_s[0]), float(model.wind_enu_m_s[1])))

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def horizon_s(self) -> float:
        return self.n_ticks / self.rate_hz

    def lag_coefficients(self) -> tuple[float, float]:
        """``(e, c)``: the achieved acceleration decays by ``e`` over a tick and its mean over the
        tick is ``target + (a_start - target) c`` (both 0 without lag)."""
        if self.tau_s <= 0:
            return 0.0, 0.0
        e = math.exp(-self.dt_s / self.tau_s)
        return e, self.tau_s / self.dt_s * (1.0 - e)


@dataclass(frozen=True)
class Trajectory:
    """A flight of the problem's ``N`` ticks: states at the start of each tick and what was flown.

    ``x_m``, ``y_m``, ``heading_rad`` have ``N + 1`` entries (the last is the state after the
    horizon); ``a_flown_m_s2``, ``crosstrack_m`` and ``s_proj_m`` have ``N`` (one per tick).
    """

    x_m: np.ndarray
    y_m: np.ndarray
    heading_rad: np.ndarray
    a_flown_m_s2: np.ndarray
    crosstrack_m: np.ndarray
    s_proj_m: np.ndarray

    def mean_d2_m2(self) -> float:
        return float(np.mean(self.crosstrack_m ** 2))

    def mean_a2_m2_s4(self) -> float:
        return float(np.mean(self.a_flown_m_s2 ** 2))

    def cost(self, lambda_s4: float) -> float:
        """``J(lambda)`` of this flight."""
        return self.mean_d2_m2() + lambda_s4 * self.mean_a2_m2_s4()


# ----------------------------------------------------------------------------- dynamics
def _arc_factors(delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``S = sin(d)/d``, ``C = (1 - cos d)/d`` and their derivatives, Taylor series near 0.

    A turn of ``d`` rad over a tick of length ``V dt`` from heading ``psi`` moves the vehicle by
    ``V dt (cos psi S - sin psi C, sin psi S + cos psi C)`` (the circular arc of eq. 1).
    """
    small = np.abs(delta) < _SMALL_TURN_RAD
    d = np.where(small, 1.0, delta)
    sd, cd = np.sin(d), np.cos(d)
    s = sd / d
    c = (1.0 - cd) / d
    ds = (d * cd - sd) / (d * d)
    dc = (d * sd - 1.0 + cd) / (d * d)
    d2 = delta * delta
    s = np.where(small, 1.0 - d2 / 6.0, s)
    c = np.where(small, delta / 2.0 - delta * d2 / 24.0, c)
    ds = np.where(small, -delta / 3.0 + delta * d2 / 30.0, ds)
    dc = np.where(small, 0.5 - d2 / 8.0, dc)
    return s, c, ds, dc


def _acting(problem: OptimalProblem, a_cmd_m_s2: np.ndarray) -> np.ndarray:
    """The saturated command acting in each tick: the one issued ``delay_ticks`` earlier (0 before)."""
    n, k = problem.n_ticks, problem.delay_ticks
    acting = np.zeros(n)
    if k < n:
        acting[k:] = a_cmd_m_s2[: n - k]
    return np.clip(acting, -problem.a_max_m_s2, problem.a_max_m_s2)


def flown_acceleration(problem: OptimalProblem, a_cmd_m_s2: np.ndarray) -> np.ndarray:
    """Mean achieved lateral acceleration over each tick for a sequence of ``N`` commands.

    The achieved acceleration starts at 0 and relaxes towards the acting (delayed, saturated)
    command with time constant ``tau_s``, exactly over each tick.
    """
    target = _acting(problem, np.asarray(a_cmd_m_s2, dtype=float))
    e, c = problem.lag_coefficients()
    if e == 0.0:
        return target
    a_start = lfilter([0.0, 1.0 - e], [1.0, -e], target)  # achieved acceleration at each tick start
    return np.asarray((1.0 - c) * target + c * a_start, dtype=float)


def _states(problem: OptimalProblem, a_flown: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Headings, positions and the per-tick arc terms for the flown accelerations."""
    V, dt = problem.start.speed_m_s, problem.dt_s
    delta = a_flown * dt / V
    psi = problem.start.course_rad + np.concatenate(([0.0], np.cumsum(delta)))
    s, c, ds, dc = _arc_factors(delta)
    cos_p, sin_p = np.cos(psi[:-1]), np.sin(psi[:-1])
    step = V * dt
    wx, wy = problem.wind_enu_m_s
    dx = step * (cos_p * s - sin_p * c) + wx * dt
    dy = step * (sin_p * s + cos_p * c) + wy * dt
    x = problem.start.x_m + np.concatenate(([0.0], np.cumsum(dx)))
    y = problem.start.y_m + np.concatenate(([0.0], np.cumsum(dy)))
    # d(dx, dy)/d(delta), for the reverse pass
    ddx = step * (cos_p * ds - sin_p * dc)
    ddy = step * (sin_p * ds + cos_p * dc)
    return psi, x, y, np.stack([dx - wx * dt, dy - wy * dt, ddx, ddy])


# ----------------------------------------------------------------------------- cross-track
def _first_course(x_m: np.ndarray, y_m: np.ndarray) -> float | None:
    """The direction of a trajectory's first step (None if it has none): the course the laws
    took their first projection along."""
    if x_m.size < 2 or (x_m[1] == x_m[0] and y_m[1] == y_m[0]):
        return None
    return math.atan2(float(y_m[1] - y_m[0]), float(x_m[1] - x_m[0]))


def crosstrack_sequential_m(path: Path, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance to the closest path point along a trajectory, projection kept continuous
    (each tick's search starts from the previous tick's projection): ``(d_m, s_m)``.

    The tracking bench's measurement, point by point with :func:`~companion.guidance.path_frame.path_frame`;
    the first point's projection along the trajectory's first step, as the laws take theirs along
    their course (at a crossing of a closed path, the branch flown along:
    :func:`~companion.guidance.path_frame.first_projection_s`).
    """
    d = np.empty(x_m.size)
    s = np.empty(x_m.size)
    hint: float | None = None
    course0 = _first_course(x_m, y_m)
    for i in range(x_m.size):
        f = path_frame(path, float(x_m[i]), float(y_m[i]), hint, course0)
        hint = f.s_m
        s[i], d[i] = f.s_m, f.crosstrack_m
    return d, s


def _scan_window(path: Path, x: np.ndarray, y: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """:meth:`Path.project`'s fallback for every tick at once: the closest table node within the
    search window around the hint, refined by Newton within one node spacing."""
    length = path.length_m
    n = path.s_table_m.size - 1
    h = length / n
    s_hint = np.mod(hint, length) if path.closed else np.clip(hint, 0.0, length)
    px, py, _, _, _ = path.frame_array(s_hint)
    window = PROJECT_WINDOW_FACTOR * np.hypot(x - px, y - py) + PROJECT_WINDOW_MIN_M
    c = (s_hint / h).astype(np.intp)
    w = (window / h).astype(np.intp) + 2
    lo, hi = c - w, c + w + 1
    if path.closed:
        whole = hi - lo >= n
        lo, hi = np.where(whole, 0, lo), np.where(whole, n, hi)
    else:
        lo, hi = np.maximum(lo, 0), np.minimum(hi, n)
    j = np.empty(x.size, dtype=np.intp)
    width = int(np.max(hi - lo)) + 1 if x.size else 1
    rows = max(1, 2_000_000 // width)
    cols = np.arange(width)
    for r0 in range(0, x.size, rows):
        r = slice(r0, r0 + rows)
        idx = lo[r, None] + cols[None, :]
        valid = idx <= hi[r, None]
        idx = np.mod(idx, n) if path.closed else np.minimum(idx, n)
        d2 = (path.x_table_m[idx] - x[r, None]) ** 2 + (path.y_table_m[idx] - y[r, None]) ** 2
        j[r] = idx[np.arange(idx.shape[0]), np.argmin(np.where(valid, d2, np.inf), axis=1)]
    s = j * h
    s_lo, s_hi = s - h, s + h
    if not path.closed:
        s_lo, s_hi = np.maximum(s_lo, 0.0), np.minimum(s_hi, length)
    active = np.ones(x.size, dtype=bool)
    for _ in range(3):
        fx, fy, tx, ty, k = path.frame_array(s)
        dx, dy = fx - x, fy - y
        g = dx * tx + dy * ty
        dg = 1.0 + k * (-dx * ty + dy * tx)
        active &= dg > 1e-9
        step = g / np.where(active, dg, 1.0)
        s = np.where(active, np.clip(s - step, s_lo, s_hi), s)
        active &= np.abs(step) >= 1e-9
        if not active.any():
            break
    return np.mod(s, length) if path.closed else s


def _newton_from_hints(path: Path, x: np.ndarray, y: np.ndarray, hint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Path.project`'s Newton branch for every tick at once: ``(s, settled)``.

    From each hint, at most six Newton steps on ``(P(s) - q) . t(s) = 0``; a tick settles when a
    step falls under 1e-7 m (the arc length before that step is kept, as :meth:`Path.project`
    does) without leaving the search window around the hint or an open path's ends. Unsettled
    ticks are left to :meth:`Path.project`'s window scan.
    """
    length = path.length_m
    s0 = np.mod(hint, length) if path.closed else np.clip(hint, 0.0, length)
    px, py, _, _, _ = path.frame_array(s0)
    window = PROJECT_WINDOW_FACTOR * np.hypot(x - px, y - py) + PROJECT_WINDOW_MIN_M
    result = np.full(s0.size, np.nan)
    live = np.arange(s0.size)  # ticks still iterating
    s = s0.copy()
    for _ in range(6):
        px, py, tx, ty, k = path.frame_array(s)
        xl, yl = x[live], y[live]
        dx, dy = px - xl, py - yl
        g = dx * tx + dy * ty
        dg = 1.0 + k * (-dx * ty + dy * tx)
        keep = dg > 0.05
        step = g / np.where(keep, dg, 1.0)
        done = keep & (np.abs(step) < 1e-7)
        result[live[done]] = np.mod(s[done], length) if path.closed else s[done]
        s = s - step
        keep &= ~done & (np.abs(s - s0[live]) <= window[live])
        if not path.closed:
            keep &= (s >= 0.0) & (s <= length)
        live, s = live[keep], s[keep]
        if not live.size:
            break
    return result, np.isfinite(result)


def _crosstrack_newton(path: Path, x: np.ndarray, y: np.ndarray,
                       s_hint: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The bench's projection (:func:`crosstrack_sequential_m`), vectorised: ``(d, s, nx, ny)``,
    ``n`` the path's left normal at the closest point.

    The bench projects tick ``k`` by :meth:`Path.project` from tick ``k - 1``'s projection. Here
    every tick's projection is first taken from a guess (``s_hint``, e.g. the previous
    evaluation's), then the recursion is iterated for all ticks at once: each pass projects
    tick ``k`` from tick ``k - 1``'s current value, by the vectorised Newton branch or, where it
    does not settle, by the vectorised window scan (both :meth:`Path.project`'s steps), and only
    the ticks whose predecessor changed are redone. Once a pass changes nothing, every tick
    satisfies the bench's recursion from the same first tick, so the result is the bench's.
    After ``_PROJECTION_PASSES`` passes without that, the ticks are projected one by one.
    """
    s_first = first_projection_s(path, float(x[0]), float(y[0]), _first_course(x, y))
    s = np.asarray(s_hint, dtype=float).copy()
    todo = np.arange(1, x.size)  # ticks whose predecessor changed
    s[0] = s_first
    for _ in range(_PROJECTION_PASSES):
        s_new, settled = _newton_from_hints(path, x[todo], y[todo], s[todo - 1])
        bad = ~settled
        if bad.any():
            s_new[bad] = _scan_window(path, x[todo[bad]], y[todo[bad]], s[todo[bad] - 1])
        change = np.abs(s_new - s[todo])
        if path.closed:
            change = np.minimum(change, path.length_m - change)
        s[todo] = s_new
        moved = todo[change > 1e-9]
        todo = moved[moved < x.size - 1] + 1
        if not todo.size:
            break
    else:
        _, s = crosstrack_sequential_m(path, x, y)
    px, py, tx, ty, _ = path.frame_array(s)
    d = tx * (y - py) - ty * (x - px)
    return d, s, -ty, tx


class _Objective:
    """``J`` and its gradient for one problem and ``lambda``, remembering the last projection as
    the next evaluation's hints."""

    def __init__(self, problem: OptimalProblem, lambda_s4: float, s_hint: np.ndarray, scale: float) -> None:
        self.problem = problem
        self.lambda_s4 = lambda_s4
        self.s_hint = s_hint
        self.scale = scale  # the start's cost: the optimiser sees J / J_start, about 1
        self.evaluations = 0

    def __call__(self, a_cmd_m_s2: np.ndarray) -> tuple[float, np.ndarray]:
        self.evaluations += 1
        j, grad, s = cost_and_gradient(self.problem, self.lambda_s4, a_cmd_m_s2, self.s_hint)
        self.s_hint = s
        return j / self.scale, grad / self.scale


def cost_and_gradient(problem: OptimalProblem, lambda_s4: float, a_cmd_m_s2: np.ndarray,
                      s_hint_m: np.ndarray | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """``J(lambda)`` of a command sequence, its exact gradient, and the projections ``s_m``.

    ``s_hint_m`` (one per tick) seeds the vectorised projection; None projects tick by tick as
    the bench does. The gradient is the reverse pass through the discrete dynamics: the distance's
    gradient is the path normal at the closest point (the closest point is stationary), and
    commands that act after the horizon, or sit at the saturation, get 0.
    """
    p = problem
    n, V, dt = p.n_ticks, p.start.speed_m_s, p.dt_s
    u = np.asarray(a_cmd_m_s2, dtype=float)
    a = flown_acceleration(p, u)
    psi, x, y, terms = _states(p, a)
    if s_hint_m is None:
        d, s = crosstrack_sequential_m(p.path, x[:n], y[:n])
        f = p.path.frame_array(s)
        nx, ny = -f[3], f[2]
    else:
        d, s, nx, ny = _crosstrack_newton(p.path, x[:n], y[:n], s_hint_m)
    j = float(np.mean(d * d) + lambda_s4 * np.mean(a * a))
    # Reverse pass. gx[k] = dJ/dx_k for k < n (x_0 is fixed).
    gx = 2.0 / n * d * nx
    gy = 2.0 / n * d * ny
    # x_k = x_0 + sum_{j<k} dx_j: dJ/d(dx_j) = sum_{k>j} gx[k].
    Gx = np.concatenate((np.cumsum(gx[::-1])[::-1][1:], [0.0]))
    Gy = np.concatenate((np.cumsum(gy[::-1])[::-1][1:], [0.0]))
    rot_x, rot_y, ddx, ddy = terms  # d(dx)/dpsi = -rot_y, d(dy)/dpsi = rot_x
    g_psi = -Gx * rot_y + Gy * rot_x
    # psi_j = psi_0 + sum_{i<j} delta_i: dJ/d(delta_i) via psi = sum_{j>i} g_psi[j].
    g_delta = np.concatenate((np.cumsum(g_psi[::-1])[::-1][1:], [0.0])) + Gx * ddx + Gy * ddy
    g_a = g_delta * dt / V + 2.0 * lambda_s4 / n * a
    # Through the lag (the transpose of a causal filter runs it backwards in time).
    e, c = p.lag_coefficients()
    if e == 0.0:
        g_target = g_a
    else:
        g_start = g_a * c
        g_target = (1.0 - c) * g_a + lfilter([0.0, 1.0 - e], [1.0, -e], g_start[::-1])[::-1]
    # Through the dead time and the saturation.
    k = p.delay_ticks
    grad = np.zeros(n)
    if k < n:
        grad[: n - k] = g_target[k:]
        inside = np.abs(u[: n - k]) <= p.a_max_m_s2
        grad[: n - k] *= inside
    return j, grad, s


def trajectory(problem: OptimalProblem, a_cmd_m_s2: Sequence[float] | np.ndarray) -> Trajectory:
    """The flight of ``N`` commands (saturated as the vehicle does), measured as the bench does."""
    u = np.asarray(a_cmd_m_s2, dtype=float)
    if u.shape != (problem.n_ticks,):
        raise ValueError(f"a_cmd_m_s2: expected {problem.n_ticks} commands, got shape {u.shape}")
    a = flown_acceleration(problem, u)
    psi, x, y, _ = _states(problem, a)
    d, s = crosstrack_sequential_m(problem.path, x[: problem.n_ticks], y[: problem.n_ticks])
    return Trajectory(x, y, psi, a, d, s)


# ----------------------------------------------------------------------------- the solver
@dataclass(frozen=True)
class OptimalSolution:
    """The best command sequence found for one ``lambda`` and how it was found.

    ``cost`` is ``J`` re-measured tick by tick (the bench's projection) at ``a_cmd_m_s2``;
    ``costs_by_start`` the same for each start's result (the spread says how non-convex the
    problem is here), ``warm_costs`` each start's own cost before refinement.
    """

    lambda_s4: float
    cost: float
    d_rms_m: float
    a_rms_m_s2: float
    a_cmd_m_s2: np.ndarray
    costs_by_start: tuple[float, ...]
    warm_costs: tuple[float, ...]
    iterations: int
    evaluations: int
    converged: bool
    messages: tuple[str, ...] = field(default=())


def _blocks(n: int, block: int) -> np.ndarray:
    """Index of the block of each tick (blocks of ``block`` ticks)."""
    return np.arange(n) // block


def _refine(problem: OptimalProblem, lambda_s4: float, u0: np.ndarray, levels: Sequence[int],
            max_iter: int, tol: float) -> tuple[np.ndarray, int, int, bool, str]:
    """Coarse-to-fine refinement of one start: piecewise-constant corrections over blocks of
    ``levels[i]`` ticks, the last level per tick under the box bounds."""
    n, a_max = problem.n_ticks, problem.a_max_m_s2
    u = np.clip(u0, -a_max, a_max)
    j0, _, s0 = cost_and_gradient(problem, lambda_s4, u)
    obj = _Objective(problem, lambda_s4, s0, scale=j0 if j0 > 0 else 1.0)
    iters, ok, message = 0, False, ""
    for block in levels:
        if block <= 1:
            bounds = None if not math.isfinite(a_max) else [(-a_max, a_max)] * n
            res = minimize(obj, u, jac=True, method="L-BFGS-B", bounds=bounds,
                           options={"maxiter": max_iter, "maxcor": 10, "ftol": tol, "gtol": 1e-12})
            u = np.asarray(res.x, dtype=float)
        else:
            idx = _blocks(n, block)
            base = u.copy()

            def coarse(v: np.ndarray, base: np.ndarray = base, idx: np.ndarray = idx) -> tuple[float, np.ndarray]:
                j, g = obj(np.clip(base + v[idx], -a_max, a_max))
                return j, np.bincount(idx, weights=g)

            res = minimize(coarse, np.zeros(int(idx[-1]) + 1), jac=True, method="L-BFGS-B",
                           options={"maxiter": max_iter, "maxcor": 10, "ftol": tol, "gtol": 1e-12})
            u = np.clip(base + np.asarray(res.x, dtype=float)[idx], -a_max, a_max)
        iters += int(res.nit)
        ok = bool(res.success)
        message = str(res.message)
    return u, iters, obj.evaluations, ok, message


def solve_optimal(problem: OptimalProblem, lambda_s4: float,
                  warm_starts: Sequence[Sequence[float] | np.ndarray] = (), *,
                  levels: Sequence[int] = DEFAULT_LEVELS, max_iter: int = 1000,
                  tol: float = 1e-12) -> OptimalSolution:
    """Minimise ``J(lambda)`` over per-tick commands from each warm start; keep the best.

    Parameters
    ----------
    problem : the scenario and horizon.
    lambda_s4 : the weight of the flown acceleration, s^4 (the predictive law's ``lambda_s4``).
    warm_starts : command sequences (``N`` each, e.g. a causal law's commands over the horizon,
        or the solution at a neighbouring lambda). None given: a start with every command 0.
    levels : block lengths of the coarse-to-fine refinement (ticks); the last must be 1.
    max_iter, tol : per level, L-BFGS-B's iteration limit, and its tolerance on the reduction of
        the cost per iteration, relative to the start's cost.

    Returns
    -------
    OptimalSolution; its ``cost`` is never above the best warm start's (a start that gets worse
    is replaced by itself).
    """
    if not (math.isfinite(lambda_s4) and lambda_s4 >= 0):
        raise ValueError(f"lambda_s4: expected a finite number >= 0, got {lambda_s4!r}")
    if not levels or levels[-1] != 1:
        raise ValueError(f"levels: the last level must be 1 (per-tick commands), got {tuple(levels)!r}")
    starts = [np.asarray(w, dtype=float) for w in warm_starts] or [np.zeros(problem.n_ticks)]
    best: tuple[float, np.ndarray, Trajectory] | None = None
    costs, warm_costs, messages = [], [], []
    iters = evals = 0
    converged = False
    for w in starts:
        if w.shape != (problem.n_ticks,):
            raise ValueError(f"warm start: expected {problem.n_ticks} commands, got shape {w.shape}")
        w = np.clip(w, -problem.a_max_m_s2, problem.a_max_m_s2)
        warm = trajectory(problem, w).cost(lambda_s4)
        u, it, ev, ok, msg = _refine(problem, lambda_s4, w, levels, max_iter, tol)
        traj = trajectory(problem, u)
        j = traj.cost(lambda_s4)
        if not j <= warm:  # the refinement never makes a start worse
            u, traj, j = w, trajectory(problem, w), warm
        costs.append(j)
        warm_costs.append(warm)
        messages.append(msg)
        iters += it
        evals += ev
        if best is None or j < best[0]:
            best = (j, u, traj)
            converged = ok
    assert best is not None
    j, u, traj = best
    return OptimalSolution(lambda_s4=lambda_s4, cost=j, d_rms_m=math.sqrt(traj.mean_d2_m2()),
                           a_rms_m_s2=math.sqrt(traj.mean_a2_m2_s4()), a_cmd_m_s2=u,
                           costs_by_start=tuple(costs), warm_costs=tuple(warm_costs), iterations=iters,
                           evaluations=evals, converged=converged,
                           messages=tuple(messages))


# ----------------------------------------------------------------------------- the front
@dataclass(frozen=True)
class BoundFront:
    """The lower-bound front from ``J*`` at several ``lambda``: ``(lambda_s4, cost)`` pairs."""

    lambdas_s4: tuple[float, ...]
    costs: tuple[float, ...]

    @classmethod
    def from_solutions(cls, solutions: Sequence[OptimalSolution]) -> "BoundFront":
        return cls(tuple(s.lambda_s4 for s in solutions), tuple(s.cost for s in solutions))

    def d_rms_m(self, a_rms_m_s2: float) -> float:
        """The smallest d_rms any command sequence can have at this flown a_rms (see module doc)."""
        return bound_d_rms(a_rms_m_s2, self)


def bound_d_rms(a_rms_m_s2: float, front: BoundFront) -> float:
    """``sqrt(max(0, max_lambda J*(lambda) - lambda a_rms^2))``: no flight over the same horizon
    with this flown a_rms has a smaller d_rms (weak duality).

    >>> front = BoundFront((0.1, 1.0), (0.5, 2.0))
    >>> round(bound_d_rms(1.0, front), 6)  # max(0.5 - 0.1, 2.0 - 1.0) = 1.0
    1.0
    >>> bound_d_rms(3.0, front)  # every lambda's line is below 0 there
    0.0
    """
    if not front.costs:
        return 0.0
    best = max(j - lam * a_rms_m_s2 * a_rms_m_s2 for lam, j in zip(front.lambdas_s4, front.costs))
    return math.sqrt(max(0.0, best))


def gap_pct(law_d_rms_m: float, law_a_rms_m_s2: float, bound: BoundFront) -> float:
    """Percent of a law's d_rms above the bound at the same a_rms (``inf`` where the bound is 0).

    >>> front = BoundFront((0.1, 1.0), (0.5, 2.0))
    >>> gap_pct(1.25, 1.0, front)
    25.0
    """
    b = bound.d_rms_m(law_a_rms_m_s2)
    if b <= 0.0:
        return math.inf if law_d_rms_m > 0 else 0.0
    return 100.0 * (law_d_rms_m / b - 1.0)


def whole_flight_metrics(problem: OptimalProblem, a_cmd_m_s2: Sequence[float] | np.ndarray) -> dict[str, float]:
    """A law's figures on the bound's terms: its first ``N`` commands replayed through the same
    model, ``d_rms_m`` and ``a_rms_m_s2`` (flown) over the whole horizon, from the start.

    The commands of a causal law's simulated run (``SimResult.a_cmd_m_s2``) give back its flight
    exactly, since the model is deterministic.
    """
    u = np.asarray(a_cmd_m_s2, dtype=float)
    if u.size < problem.n_ticks:
        raise ValueError(f"a_cmd_m_s2: the flight has {u.size} ticks, the horizon {problem.n_ticks}")
    traj = trajectory(problem, u[: problem.n_ticks])
    return {"d_rms_m": math.sqrt(traj.mean_d2_m2()), "a_rms_m_s2": math.sqrt(traj.mean_a2_m2_s4()),
            "a_max_m_s2": float(np.max(np.abs(traj.a_flown_m_s2))),
            "d_max_m": float(np.max(np.abs(traj.crosstrack_m)))}
