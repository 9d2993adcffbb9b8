"""``method: predictive``: Park's look-ahead pursuit plus a receding-horizon plan, both chosen
online by rollouts of a vehicle model with inner-loop lag and acceleration limit, trading
cross-track error against acceleration with one knob, lambda.

Why a new law
-------------
The paper's corrector searches its weights with an ideal vehicle (the course turns the instant
the command changes) and scores cross-track error only. Once the autopilot's inner loop lags the
command (a multicopter or plane follows a lateral-acceleration or turn-rate demand with a time
constant of a few tenths of a second), a short look-ahead that tracks tightly in the ideal model
rings, and nothing in the search sees it. This law keeps the L1 pursuit geometry (Park 2007) as
its feedback core and adds:

1. **A model of the vehicle in the rollouts**: unicycle at constant airspeed, first-order lag
   ``lag_s`` from the commanded to the achieved lateral acceleration, ``|a| <= a_max_m_s2``, a
   known steady wind. The law tracks the achieved acceleration ``a_hat`` itself, from its own
   command history through the same lag model.
2. **One cost, one knob**: ``sum_k ((d_k - r_k)^2 + lambda u_k^2) dt`` over ``horizon_s`` (d the
   cross-track error, u the commanded acceleration, r the capture reference of item 6).
   ``lambda`` (s^4) is the user's one knob: small values track as tightly as the vehicle allows,
   larger values fly smoother.
3. **Look-ahead distance chosen online**: every ``reopt_period_s``, ``n_candidates`` distances
   (geometric between ``l_min_m`` and ``l_max_m``) are rolled out in one numpy batch and the
   cheapest is kept.
4. **A correction plan**: ``plan_segments`` piecewise-constant accelerations over the horizon,
   added to the pursuit command, refined by Gauss-Newton (see :meth:`PredictiveGuidance.reoptimise`).
   Between re-optimisations the executed command is ``clip(pursuit(L) + plan(t), +-a_max)``:
   feedback stays in the loop and the plan adds the anticipation (turning in before a bend,
   compensating the lag) that feedback alone cannot.
5. **Limits respected**: every command, executed or rolled out, is clipped to ``a_max``, so the
   flown maximum never exceeds the vehicle's limit and the search knows about saturation.
6. **A capture reference**: the cost does not ask for ``d = 0`` at once but for the cross-track
   error to die out as a critically damped second-order response from where the vehicle is,
   ``r(t) = (d0 + (d0' + d0 / T) t) exp(-t / T)`` with ``T = capture_tc_scale lambda^(1/4)``
   (lambda^(1/4) is the time scale of ``d^2 + lambda a^2`` for a double integrator), re-anchored
   at every re-optimisation; a rate away from the path is not followed (d0' taken as 0). Without
   it, the many metres of error of an approach outweigh, in ``d^2``, the few decimetres of an
   overshoot, so the plan dived at the path and crossed it; with it, an approach flattens out
   in time. On the path (d0, d0' of millimetres) the reference is millimetres too and the cost is
   the plain ``d^2``. See :func:`capture_reference`.

7. **A model monitor** (``adapt_model``, on with a mission's ``vehicle:`` block): when the
   lateral acceleration the vehicle flies departs from the model (more lag, less acceleration),
   the law plans with the candidate model that explains it, or drops the plan and flies its
   feedback core; see :class:`ModelMonitor`.
8. **A cost to go at the horizon** (``terminal_cost``): each rollout is charged, where it ends,
   the least cost of bringing its deviation from the path back to zero (the Riccati solution of
   the linearised vehicle under the same cost, :func:`cost_to_go_factor`). Without it the plan
   eased off its last corrections, whose cost fell past the horizon, and a large lambda cut
   inside what it flew.
9. **An overshoot weighed more** (``overshoot_weight``): a rollout step beyond the path, on the
   far side from where the vehicle is (more than ``SIDE_MIN_OFFSET_M`` off), is charged
   ``overshoot_weight^2`` times its squared error, so a join lands rather than crossing the path
   to arrive a fraction sooner (:func:`weigh_overshoot`). It fades out over the decade of
   lambda below 0.03, where a setting asks for the tightest join the vehicle can fly
   (:meth:`PredictiveParams.overshoot_weight_in_use`).
10. **A wide turner's approach charged at the band** (``approach_at_band``): a vehicle whose turn
    at the limit is at least ``WIDE_TURN_RADIUS_M`` wide (``V^2 / a_max``; 10 m/s at 5 m/s^2)
    and that has not yet come within ``SIDE_MIN_OFFSET_M`` of the path charges each rollout's
    error, until the rollout first comes that close, as if it lay on that band's edge: the
    approach costs its time, not its metres (:func:`charge_approach_at_band`). Charged for its
    metres, a fast vehicle dived square at the path and landed on its far side.
11. **A course observer** (``course_tc_s``, an option, off by default): the law reads the course
    its lag model turns by its commands, pulled towards the reported course with that time
    constant (:class:`CourseObserver`), for an estimate that jitters quicker than the vehicle
    turns; on the real PX4 it saved less acceleration than it cost tracking.

Far from the path the look-ahead circle may not reach it; the pursuit then uses
``L_eff = max(L, sqrt(2) |d|)``, a 45 degree capture angle as ArduPilot's L1 controller does.
Pointing away, that goal lies behind the beam: the law then turns round at the limit
``a_max`` (with none stated, at its bound ``2 V^2 / L``), never sharper than ``2 V^2 / 3 m``
(``HOVER_TURN_LOOK_M``: a copter near hover has no course to turn round from), and does not
plan; within two of that turn's radii of the path it turns the short way onto the path's
direction, so that the turn runs beside the path instead of across it
(:mod:`companion.guidance.capture`, our addition; ``docs/guidance.md``, "Capture far from the
path"). An open path is continued straight past its end, as the baselines do.

Pure maths (numpy; scipy for the Riccati equation of the cost to go), deterministic: the same
sequence of inputs gives the same outputs.
``docs/benchmarks.md`` shows its fronts against the other laws and where a baseline still wins.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from companion.geometry.frames import angle_diff_rad, wrap_pi
from companion.guidance import rollout_kernel
from companion.guidance.capture import SIDE_MIN_OFFSET_M, capture_command_m_s2, pursuit_capture_side
from companion.guidance.path_frame import PathLike, frame_output, frame_samples, path_frame
from companion.guidance.types import DEFAULT_LAMBDA_S4, SCHEDULE_TOLERANCE_S, GuidanceOutput, VehicleState

SQRT2 = math.sqrt(2.0)
WINDOW_SPACING_M = 1.0  # spacing of the local path samples the rollouts project onto
WINDOW_HOME_INDEX = 2  # the window's sample at the projection it was built from (it starts 2 m behind)
BAND_MARGIN_M = 3.0  # the nearest sample is searched within this much path, plus the motion, of the last one
MIN_SPEED_M_S = 0.1
FD_STEP_M_S2 = 0.05  # finite-difference step of the plan Jacobian
LINE_SEARCH = np.array([1.0, 0.5, 0.25])  # step fractions tried (in one batch) after a Gauss-Newton step
HORIZON_TIME_CONSTANTS = 4.0  # the shortest horizon, in closed-loop time constants (e^-4: 2 %)
OVERSHOOT_FULL_LAMBDA_S4 = 0.03  # overshoot_weight in full from this lambda; none a decade below
HOVER_TURN_LOOK_M = 3.0  # the turn round is no sharper than the pursuit's bound 2 V^2 / L at this look-ahead
WIDE_TURN_RADIUS_M = 20.0  # from this turn radius at the limit (V^2 / a_max) up, a join's approach is charged at the band


@dataclass(frozen=True)
class PredictiveParams:
    """Tuning and vehicle model of :class:`PredictiveGuidance`.

    Attributes
    ----------
    lambda_s4 : weight of the squared acceleration against the squared cross-track error in the
        rollout cost (s^4), >= 0. The one tuning knob.
    lag_s : time constant tau of the inner loop's first-order response to the commanded lateral
        acceleration, >= 0 (0: ideal vehicle).
    a_max_m_s2 : lateral-acceleration limit of the vehicle, > 0 (``math.inf``: none).
    l_min_m, l_max_m : bounds of the look-ahead distance the search may choose, 0 < min <= max.
    n_candidates : look-ahead distances tried per re-optimisation (geometric spacing), >= 1.
    horizon_s : rollout horizon, > 0; longer at a large lambda (see :meth:`horizon`).
    rollout_dt_s : rollout integration step, > 0.
    reopt_period_s : time between re-optimisations, > 0.
    plan_segments : number of piecewise-constant acceleration corrections over ``horizon_s``,
        >= 1 (as many more as a longer horizon takes at the same length).
    refine_iterations : Gauss-Newton refinements of the corrections per re-optimisation, >= 0
        (0: the look-ahead search alone).
    wind_x_m_s, wind_y_m_s : known steady wind, ENU, used by the rollouts.
    curvature_ff : share, in [0, 1], of the pursuit's implied curvature at the closest point
        replaced by the path's own curvature there (see :func:`pursuit_command`); 0 is Park's
        pursuit as it is.
    capture_tc_scale : time constant of the capture reference (see :func:`capture_reference`)
        as a multiple of ``lambda_s4 ** 0.25`` (s per s), >= 0; 0 (or lambda 0) penalises the
        cross-track error itself, as the law did before the reference.
    adapt_model : watch the lateral acceleration the vehicle actually flies and, when it departs
        from the model (more lag, less acceleration), plan with the candidate model that explains
        it, or fall back to the feedback core (see :class:`ModelMonitor`).
    terminal_cost : charge every rollout, at its horizon, the cost of bringing its deviation from
        the path back to zero afterwards (see :func:`cost_to_go_factor`); False is the law as it
        was, whose plan did not see past its horizon.
    overshoot_weight : factor, >= 1, on the cross-track residual of every rollout step beyond the
        path, on the far side from where the vehicle is at the re-optimisation (see
        :func:`weigh_overshoot`); 1 weighs both sides the same, as the law did before. In full
        from lambda 0.03 up, less below (:meth:`overshoot_weight_in_use`).
    approach_at_band : for a vehicle whose turn at the limit is wide (``V^2 / a_max`` at least
        ``WIDE_TURN_RADIUS_M``) and that has not yet come within ``SIDE_MIN_OFFSET_M`` of the
        path, charge each rollout's cross-track error, until the rollout first comes that close,
        as if it lay on that band's edge (see :func:`charge_approach_at_band`); False charges
        the whole approach, as the law did before.
    course_tc_s : time constant (s), >= 0, of the course observer (:func:`observe_course`); 0
        hands the law the course as reported. Above 0 the law reads the course the lag model
        turns by its own commands, pulled towards the reported course with this time constant,
        so that an estimate that jitters quicker than the vehicle turns (PX4 SIH's,
        docs/real_firmware.md, "The course observed through the model") is not answered with
        acceleration.
    """

    lambda_s4: float = DEFAULT_LAMBDA_S4
    lag_s: float = 0.0
    a_max_m_s2: float = math.inf
    l_min_m: float = 1.5
    l_max_m: float = 30.0
    n_candidates: int = 9
    horizon_s: float = 5.0
    rollout_dt_s: float = 0.2
    reopt_period_s: float = 0.2
    plan_segments: int = 10
    refine_iterations: int = 2
    wind_x_m_s: float = 0.0
    wind_y_m_s: float = 0.0
    curvature_ff: float = 1.0
    capture_tc_scale: float = 0.6
    adapt_model: bool = False
    terminal_cost: bool = True
    overshoot_weight: float = 4.0
    approach_at_band: bool = True
    course_tc_s: float = 0.0

    def __post_init__(self) -> None:
        def number(name: str) -> float:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
                raise ValueError(f"{name}: expected a number, got {value!r}")
            return float(value)

        for name in ("adapt_model", "terminal_cost", "approach_at_band"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected true or false, got {getattr(self, name)!r}")
        if not 0.0 <= number("curvature_ff") <= 1.0:
            raise ValueError(f"curvature_ff: expected a number in [0, 1], got {self.curvature_ff!r}")
        for name in ("lambda_s4", "lag_s", "capture_tc_scale", "course_tc_s"):
            if not (math.isfinite(number(name)) and number(name) >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {getattr(self, name)!r}")
        if not (math.isfinite(number("overshoot_weight")) and number("overshoot_weight") >= 1):
            raise ValueError(f"overshoot_weight: expected a finite number >= 1, got {self.overshoot_weight!r}")
        if not number("a_max_m_s2") > 0:
            raise ValueError(f"a_max_m_s2: expected a number > 0 (inf for none), got {self.a_max_m_s2!r}")
        for name in ("l_min_m", "l_max_m", "horizon_s", "rollout_dt_s", "reopt_period_s"):
            if not (math.isfinite(number(name)) and number(name) > 0):
                raise ValueError(f"{name}: expected a finite number > 0, got {getattr(self, name)!r}")
        if self.l_max_m < self.l_min_m:
            raise ValueError(f"l_max_m: expected >= l_min_m ({self.l_min_m}), got {self.l_max_m!r}")
        for name, low in (("n_candidates", 1), ("plan_segments", 1), ("refine_iterations", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
        for name in ("wind_x_m_s", "wind_y_m_s"):
            if not math.isfinite(number(name)):
                raise ValueError(f"{name}: expected a finite number, got {getattr(self, name)!r}")

    def capture_tc_s(self) -> float:
        """Time constant of the capture reference (s); 0 when it is disabled."""
        return float(self.capture_tc_scale * self.lambda_s4 ** 0.25)

    def overshoot_weight_in_use(self) -> float:
        """The overshoot weight at this lambda: ``overshoot_weight`` from ``OVERSHOOT_FULL_LAMBDA_S4`` up.

        Below, it falls linearly in ``log10 lambda`` to 1 (both sides weighed the same) a decade
        lower: a setting that asks for the tightest tracking the vehicle can fly buys its join
        with an overshoot, and the full weight kept it from turning as hard as that asks
        (docs/benchmarks.md, "The overshoot weight at the smallest lambdas").

        >>> [round(PredictiveParams(lambda_s4=lam).overshoot_weight_in_use(), 2) for lam in (0.001, 0.003, 0.01, 0.03, 1.0)]
        [1.0, 1.0, 2.57, 4.0, 4.0]
        """
        if self.lambda_s4 >= OVERSHOOT_FULL_LAMBDA_S4:
            return self.overshoot_weight
        if self.lambda_s4 <= 0.0:
            return 1.0
        share = min(max(1.0 + math.log10(self.lambda_s4 / OVERSHOOT_FULL_LAMBDA_S4), 0.0), 1.0)
        return 1.0 + (self.overshoot_weight - 1.0) * share

    def horizon(self) -> tuple[float, int]:
        """The rollout horizon (s) and its number of plan segments (each about ``horizon_s / plan_segments``).

        ``horizon_s``, or, if longer, ``HORIZON_TIME_CONSTANTS`` closed-loop time constants of the
        cost, ``sqrt(2) lambda^(1/4)`` (the linear-quadratic regulator of ``d^2 + lambda a^2`` on a
        double integrator has its poles at ``(-1 +- i) / (sqrt(2) lambda^(1/4))``): from lambda
        0.61 s^4 on. A plan whose horizon ends sooner eases off the corrections whose effect
        falls past it; a smooth setting drifted decimetres off a figure-eight without flying
        less acceleration.
        """
        horizon = max(self.horizon_s, HORIZON_TIME_CONSTANTS * SQRT2 * self.lambda_s4 ** 0.25)
        segments = max(self.plan_segments, int(round(horizon / self.horizon_s * self.plan_segments)))
        return horizon, segments

    def candidates_m(self) -> np.ndarray:
        """The look-ahead distances the search tries (geometric from l_min_m to l_max_m)."""
        if self.n_candidates == 1:
            return np.array([math.sqrt(self.l_min_m * self.l_max_m)])
        return np.geomspace(self.l_min_m, self.l_max_m, self.n_candidates)


class _Window:
    """Path samples from just behind the vehicle to beyond the horizon, for batched projections.

    An open path is continued straight along its end tangent, as the baselines do past the end.
    """

    def __init__(self, path: PathLike, s0_m: float, length_m: float) -> None:
        total = float(path.length_m)
        self.s0_m, self.closed, self.total_m = float(s0_m), bool(path.closed), total
        s = s0_m + np.arange(-WINDOW_HOME_INDEX * WINDOW_SPACING_M, length_m + WINDOW_SPACING_M, WINDOW_SPACING_M)
        beyond = np.zeros(0)
        if path.closed:
            s = np.mod(s, total)
        else:
            beyond = s[s > total] - total  # continued straight along the end tangent
            s = s[s <= total]
            s = np.clip(s, 0.0, total)
        # any object with the scalar Path queries too (e.g. an exact circle in the tests)
        x, y, tx, ty, k = frame_samples(path, s)
        if beyond.size:
            ex, ey = (float(c) for c in path.point(total))
            etx, ety = (float(c) for c in path.tangent(total))
            x = np.concatenate([x, ex + beyond * etx])
            y = np.concatenate([y, ey + beyond * ety])
            tx = np.concatenate([tx, np.full(beyond.size, etx)])
            ty = np.concatenate([ty, np.full(beyond.size, ety)])
            k = np.concatenate([k, np.zeros(beyond.size)])
        # Contiguous (the samples may be views of one table): the compiled loops are compiled for
        # contiguous arrays when they are loaded, and another layout would compile anew in flight.
        self.x, self.y, self.tx, self.ty, self.k = (np.ascontiguousarray(a, dtype=float) for a in (x, y, tx, ty, k))
        self.index = np.arange(self.x.size)
        self._from: np.ndarray | None = None

    # The numpy rollouts project onto the window every step, where the cost is the number of numpy
    # calls: what depends on the window alone is stacked once, so that one fancy index reads it
    # all (built on first use: the compiled rollouts and tick never read them). ``xy`` broadcasts
    # against the vehicles' positions; ``at_nearest[:, i]`` is the position, the tangent, the
    # tangent swapped and half the curvature of sample i; ``at_goal[:, j]`` the sample before j (j
    # itself for the first) and the step from it to j; ``at_kappa[:, i]`` the curvature and its
    # step to the next sample (none for the last).
    @functools.cached_property
    def xy(self) -> np.ndarray:
        return np.stack([self.x, self.y])[:, None, :]

    @functools.cached_property
    def at_nearest(self) -> np.ndarray:
        return np.stack([self.x, self.y, self.tx, self.ty, self.ty, self.tx, 0.5 * self.k])

    @functools.cached_property
    def at_goal(self) -> np.ndarray:
        x, y = self.x, self.y
        before = np.maximum(self.index - 1, 0)
        return np.stack([x[before], y[before], x - x[before], y - y[before]])

    @functools.cached_property
    def at_kappa(self) -> np.ndarray:
        after = np.minimum(self.index + 1, self.x.size - 1)
        return np.stack([self.k, self.k[after] - self.k])

    def index_of(self, s_m: float) -> int:
        """The sample at arc length ``s_m`` (the law's own projection), clipped to the window."""
        ds = s_m - self.s0_m
        if self.closed and self.total_m > 0.0:
            ds = (ds + 0.5 * self.total_m) % self.total_m - 0.5 * self.total_m
        return int(min(max(WINDOW_HOME_INDEX + int(round(ds / WINDOW_SPACING_M)), 0), self.x.size - 1))

    def from_samples(self, i: np.ndarray) -> np.ndarray:
        """Row r: which samples have an index >= ``i[r]``."""
        if self._from is None:
            # An n x n table pays for itself over the steps of the rollouts, not for the single
            # row of a tick nor for a far vehicle's long window.
            if i.size == 1 or self.x.size > 600:
                return self.index >= i[:, None]
            self._from = self.index[None, :] >= self.index[:, None]  # row i: from sample i on
        return self._from.take(i, axis=0)


_ROW_STARTS: dict[tuple[int, int], np.ndarray] = {}


def _row_starts(rows: int, columns: int) -> np.ndarray:
    """Where each row starts in a flattened ``(rows, columns)`` array, cached (the rollouts
    pick one element per row with it every step)."""
    key = (rows, columns)
    r = _ROW_STARTS.get(key)
    if r is None:
        r = _ROW_STARTS[key] = np.arange(rows) * columns
    return r


def _const(value: float) -> np.ndarray:
    """``value`` as a 0-d array: the per-step arithmetic takes its constants so, as numpy
    converts a Python float afresh on every call (a third of the cost of an operation on a few
    dozen numbers). The results are the same."""
    return np.array(float(value))


_SPACING, _MINUS_SPACING = _const(WINDOW_SPACING_M), _const(-WINDOW_SPACING_M)
_MIN_SPEED, _SQRT2, _PI, _TWO_PI = _const(MIN_SPEED_M_S), _const(SQRT2), _const(math.pi), _const(2.0 * math.pi)
_ZERO, _ONE, _TWO, _TINY_M, _TINY_STEP_M = _const(0.0), _const(1.0), _const(2.0), _const(1e-6), _const(1e-12)


def _project(win: _Window, xy: np.ndarray, band: _Band | None = None,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nearest sample of every column of ``xy`` (x and y in rows), signed cross-track error
    (positive left), squared distance matrix, ``win.at_nearest`` at the nearest sample, and the
    distance along its tangent (not clipped).

    With a ``band``, the nearest sample is searched only near each row's previous one (see
    :class:`_Band`), and the band moves on to the sample found; the squared distance matrix
    returned is the whole window's (the goal search needs it)."""
    dxy = win.xy - xy[:, :, None]
    dxy *= dxy
    r2 = dxy[0] + dxy[1]
    i = r2.argmin(axis=1) if band is None else band.nearest(r2)
    near = win.at_nearest.take(i, axis=1)
    e = xy - near[:2]  # from the sample to the vehicle
    te = near[2:4] * e
    along = te[0] + te[1]
    # Distance to the osculating circle at the nearest sample, to second order: the normal offset
    # from the tangent line minus kappa along^2 / 2 (the tangent line alone is off by up to
    # kappa spacing^2 / 8, 4 mm on a 30 m arc: the size of the differences the fronts measure).
    # Past either end of the window (a vehicle before an open path's start) the nearest sample
    # is the end one and ``along`` is unbounded: the correction is only meant within one spacing.
    along_c = np.minimum(np.maximum(along, _MINUS_SPACING), _SPACING)
    ne = near[4:6] * e  # ty ex, tx ey
    d = ne[1] - ne[0] - near[6] * along_c * along_c
    return i, d, r2, near, along


class _Band:
    """Keeps each row's projection on its own branch of a path that comes back near itself.

    The window holds the path from just behind the vehicle to beyond the horizon; where the path
    crosses itself (a figure-eight, a self-crossing survey) or loops back within that length, the
    nearest window sample can lie on a later branch, and a projection taken over the whole window
    jumps to it: the pursuit then chases the path a loop ahead, and the rollouts score the wrong
    branch. A projection that follows the vehicle moves continuously instead, as the law's own
    (:func:`~companion.guidance.path_frame.path_frame` with its hint) and the benches' measurement do.
    So each row's nearest sample is searched from ``back_m`` behind to ``ahead_m`` ahead of the
    sample it had before (its "centre"); the band moves with the rows. A band that spans the
    whole window (a vehicle farther from the path than the window is long) changes nothing.
    """

    def __init__(self, win: _Window, centre: np.ndarray, back_m: float, ahead_m: float) -> None:
        self.centre = np.asarray(centre, dtype=np.intp)
        back = int(math.ceil(back_m / WINDOW_SPACING_M))
        ahead = int(math.ceil(ahead_m / WINDOW_SPACING_M))
        n = win.x.size
        self.whole = back >= n and ahead >= n
        self._win = win
        self.back, self.ahead = back, ahead  # in samples
        self._penalty: np.ndarray | None = None
        # The numpy rollouts search every step: a table, one row per centre, 0 inside the band and
        # inf outside, made on their first search (the compiled rollouts never search here).
        self._tabled = not self.whole and self.centre.size > 1 and n <= 600

    def nearest(self, r2: np.ndarray) -> np.ndarray:
        """The nearest sample of each row within its band; the band moves there."""
        if not self.whole:
            if self._tabled:
                if self._penalty is None:
                    offset = self._win.index[None, :] - self._win.index[:, None]
                    self._penalty = np.where((offset >= -self.back) & (offset <= self.ahead), 0.0, np.inf)
                r2 = r2 + self._penalty.take(self.centre, axis=0)
            else:
                offset = self._win.index - self.centre[:, None]
                r2 = np.where((offset >= -self.back) & (offset <= self.ahead), r2, np.inf)
        self.centre = r2.argmin(axis=1)
        return self.centre


def _band(win: _Window, centre: np.ndarray, speed_m_s: float, interval_s: float, crosstrack_m: float) -> _Band:
    """The band of a vehicle at ``crosstrack_m`` from the path moving at ``speed_m_s``, searched
    every ``interval_s``: its motion over one interval ahead, plus a margin, plus twice its
    distance from the path both ways (near the centre of a bend, the projection of a vehicle off
    the path runs faster than the vehicle)."""
    off = BAND_MARGIN_M + 2.0 * abs(crosstrack_m)
    return _Band(win, centre, off, off + 2.0 * speed_m_s * interval_s)


def _nearest(win: _Window, x: np.ndarray, y: np.ndarray, band: _Band | None = None,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest sample index, signed cross-track error (positive left) and squared distance matrix."""
    i, d, r2, _, _ = _project(win, np.stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)]), band)
    return i, d, r2


def capture_reference(d0_m: float, d_rate0_m_s: float, tc_s: float, t_s: np.ndarray) -> np.ndarray:
    """The cross-track error the rollout cost asks for, ``t_s`` seconds after a re-optimisation.

    A critically damped second-order decay with time constant ``tc_s`` from the error ``d0_m``
    and its rate ``d_rate0_m_s`` at the re-optimisation::

        r(t) = (d0 + (d0' + d0 / T) t) exp(-t / T)

    so ``r(0) = d0``, ``r'(0) = d0'`` and ``r -> 0``. A rate *away* from the path
    (``d0 d0' > 0``) is not followed: it is taken as 0, so the reference turns back at once
    (``r = d0 (1 + t/T) exp(-t/T)``). A rate towards the path is kept, so an approach is asked to
    flatten out progressively rather than to stop dead; with ``d0' = -d0/T`` the reference is the
    plain exponential ``d0 exp(-t/T)``. ``tc_s <= 0`` returns zeros (the plain ``d^2`` cost).
    """
    t = np.asarray(t_s, dtype=float)
    if not tc_s > 0.0:
        return np.zeros_like(t)
    rate = 0.0 if d0_m * d_rate0_m_s > 0.0 else d_rate0_m_s
    return (d0_m + (rate + d0_m / tc_s) * t) * np.exp(-t / tc_s)


def weigh_overshoot(residuals: np.ndarray, d_ref_m: np.ndarray | None, sqrt_dt: float, weight: float) -> np.ndarray:
    """The rollouts' cross-track residuals with every step beyond the path weighed ``weight`` times.

    ``residuals`` are :meth:`PredictiveGuidance.rollout`'s ``(K, 2 * steps + 3)``: ``(d - r)
    sqrt(dt)`` at the even columns before the last three, with ``r = d_ref_m`` (the capture
    reference, :func:`capture_reference`; its first value is the vehicle's error ``d0`` at the
    re-optimisation). A step whose ``d`` lies across the path from ``d0`` (``d d0 < 0``) is an
    overshoot: it is charged ``weight^2`` times its squared error. A join is measured from where
    it touches the path, so an overshoot there is error that counts in full, while the approach
    before it is not tracking error yet; the plain ``d^2`` weighs a metre of approach like a
    metre of overshoot, and the plan crossed the path to arrive a fraction sooner. Within
    ``SIDE_MIN_OFFSET_M`` of the path (on it, tracking) nothing changes, nor with ``weight``
    1 or without a reference (``d_ref_m`` None). Returns a new array; ``residuals`` is not changed.

    >>> r = np.array([[0.5, 0.0, -0.5, 0.0, 0.0, 0.0, 0.0]])  # d - r at two steps (dt 1), three to go
    >>> weigh_overshoot(r, np.array([2.0, 0.0]), 1.0, 3.0)  # d = 2.5 (near side), then -0.5 (beyond)
    array([[ 0.5,  0. , -1.5,  0. ,  0. ,  0. ,  0. ]])
    >>> weigh_overshoot(r, np.array([0.5, 0.0]), 1.0, 3.0)  # 0.5 m off: on the path, unchanged
    array([[ 0.5,  0. , -0.5,  0. ,  0. ,  0. ,  0. ]])
    """
    if d_ref_m is None or weight == 1.0 or abs(float(d_ref_m[0])) <= SIDE_MIN_OFFSET_M:
        return residuals
    d0 = float(d_ref_m[0])
    out: np.ndarray = residuals.copy()
    err = out[:, 0:-3:2]
    beyond = (err / sqrt_dt + d_ref_m) * d0 < 0.0
    out[:, 0:-3:2] = np.where(beyond, weight * err, err)
    return out


def charge_approach_at_band(residuals: np.ndarray, d_ref_m: np.ndarray, sqrt_dt: float, weight: float) -> np.ndarray:
    """The rollouts' residuals of a join, charged as the bench measures one: from the touch.

    ``residuals`` and ``d_ref_m`` as in :func:`weigh_overshoot` (``d_ref_m[0]`` the vehicle's
    error ``d0`` at the re-optimisation, more than ``SIDE_MIN_OFFSET_M`` off). Each row's steps
    before it first comes within ``SIDE_MIN_OFFSET_M`` of the path are charged as if they lay on
    that band's edge, ``+-SIDE_MIN_OFFSET_M`` on their own side; from there on its error ``d``
    itself (no capture reference), ``weight`` times beyond the path (``d d0 < 0``). The
    acceleration residuals and the cost to go (the last three) are kept. The approach is then
    charged for the time it takes, not for its metres: a fast vehicle charged for those metres
    dived square at the path and, its turn at the limit tens of metres wide, landed on the far
    side of it (docs/benchmarks.md, "The approach charged at the band"). Returns a new array.

    >>> r = np.zeros((1, 11))  # four steps (dt 1), three to go; reference (5, 2, 0.5, 0)
    >>> r[0, 0:-3:2] = np.array([5.0, 3.0, 0.8, -0.2]) - np.array([5.0, 2.0, 0.5, 0.0])
    >>> charge_approach_at_band(r, np.array([5.0, 2.0, 0.5, 0.0]), 1.0, 4.0)[0, 0:-3:2]
    array([ 1. ,  1. ,  0.8, -0.8])
    """
    d0 = float(d_ref_m[0])
    out: np.ndarray = residuals.copy()
    d = out[:, 0:-3:2] / sqrt_dt + d_ref_m
    before = ~np.logical_or.accumulate(np.abs(d) <= SIDE_MIN_OFFSET_M, axis=1)  # not yet within the band
    charged = np.where(before, np.sign(d) * SIDE_MIN_OFFSET_M, d)
    charged = np.where(~before & (d * d0 < 0.0), weight * charged, charged)
    out[:, 0:-3:2] = charged * sqrt_dt
    return out


def approach_charged_at_band(params: PredictiveParams, joined: bool, v_air_m_s: float, d0_m: float) -> bool:
    """Whether the rollouts charge the approach at the band (``params.approach_at_band``): a wide
    turner (``V^2 / a_max >= WIDE_TURN_RADIUS_M``, the stated limit), ``d0_m`` more than
    ``SIDE_MIN_OFFSET_M`` off the path and not ``joined`` (that close since the law started).

    >>> p = PredictiveParams(a_max_m_s2=5.0)
    >>> [approach_charged_at_band(p, False, v, -40.0) for v in (9.9, 10.0)]  # 19.6 and 20 m turns
    [False, True]
    """
    return (params.approach_at_band and not joined and abs(d0_m) > SIDE_MIN_OFFSET_M
            and v_air_m_s * v_air_m_s >= WIDE_TURN_RADIUS_M * params.a_max_m_s2)


def cost_to_go_factor(lag_s: float, lambda_s4: float) -> np.ndarray:
    """The cost of a deviation from the path left at a rollout's horizon, as a factor.

    A 3 x 3 matrix ``M`` such that ``|M x|^2 = x' P x`` is the least cost
    ``integral (d^2 + lambda u^2) dt`` of bringing the deviation ``x = (d, d', a)`` (cross-track
    error in m, its rate in m/s, the achieved lateral acceleration less the path's ``V^2 kappa``
    in m/s^2) back to zero, for the linearised vehicle ``d'' = a``, ``a' = (u - a) / tau``
    (``d'' = u`` with ``lag_s`` 0, when the third column of ``M`` is zero): the solution ``P``
    of the continuous algebraic Riccati equation, the infinite-horizon optimum of the cost the
    rollouts count over their horizon. For the ideal vehicle it has a closed form,
    ``P = [[sqrt(2) lambda^(1/4), lambda^(1/2)], [lambda^(1/2), sqrt(2) lambda^(3/4)]]``.

    The rollouts add ``M x_T`` to their residuals: without it a plan saw nothing past its horizon,
    so, the larger ``lambda`` was, the more it cut a bend whose way back to the path fell beyond
    the horizon (``docs/benchmarks.md``). Zero for ``lambda_s4`` 0 (no cost to go back).
    """
    from scipy.linalg import solve_continuous_are

    if not lambda_s4 > 0.0:
        return np.zeros((3, 3))
    p = np.zeros((3, 3))
    if lag_s > 0.0:
        a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0 / lag_s]])
        b = np.array([[0.0], [0.0], [1.0 / lag_s]])
        p[:] = solve_continuous_are(a, b, np.diag([1.0, 0.0, 0.0]), np.array([[lambda_s4]]))
    else:
        a2 = np.array([[0.0, 1.0], [0.0, 0.0]])
        b2 = np.array([[0.0], [1.0]])
        p[:2, :2] = solve_continuous_are(a2, b2, np.diag([1.0, 0.0]), np.array([[lambda_s4]]))
    w, v = np.linalg.eigh(0.5 * (p + p.T))
    # C order, as the compiled rollouts were compiled for (another layout would compile anew in flight)
    factor: np.ndarray = np.ascontiguousarray(np.sqrt(np.maximum(w, 0.0))[:, None] * v.T)
    return factor


_cost_to_go_cached = functools.lru_cache(maxsize=64)(cost_to_go_factor)  # per (lag, lambda) planned with
_NO_COST_TO_GO = np.zeros((3, 3))  # terminal_cost off


def _cost_to_go(win: _Window, xy: np.ndarray, h: np.ndarray, a_act: np.ndarray, speed: np.ndarray,
                wind: np.ndarray | None, band: _Band, factor: np.ndarray) -> np.ndarray:
    """The last three residuals of the numpy rollouts: ``factor`` (:func:`cost_to_go_factor`)
    times each row's deviation ``(d, d', a - V^2 kappa)`` where it ends (positions ``xy``,
    headings ``h``, achieved accelerations ``a_act``)."""
    ground = speed * np.stack([np.cos(h), np.sin(h)])
    if wind is not None:
        ground += wind
    _, d_end, _, near, _ = _project(win, xy, band)
    rate_end = near[2] * ground[1] - near[3] * ground[0]  # across the path, left positive
    a_dev = a_act - (ground[0] * ground[0] + ground[1] * ground[1]) * _TWO * near[6]
    residuals: np.ndarray = (factor @ np.stack([d_end, rate_end, a_dev])).T
    return residuals


def pursuit_command(win: _Window, x: np.ndarray, y: np.ndarray, course_rad: np.ndarray, speed_m_s: np.ndarray,
                    look_m: np.ndarray, a_max_m_s2: float, curvature_ff: float = 0.0, lead_s: float = 0.0,
                    band: _Band | None = None,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Batched pursuit command (arrays of equal length; returns commands, L_eff, goal x, goal y,
    and the signed cross-track error at the vehicle).

    Park's ``2 V^2 sin(eta) / L_eff`` towards the first path sample (linearly interpolated) at
    distance ``L_eff = max(L, sqrt(2) |d|)`` ahead of the vehicle's closest sample, clipped to
    ``+-a_max``.

    With ``curvature_ff`` = c > 0, the curvature the pursuit *implies* at the closest point P is
    replaced, in proportion c, by the path's curvature there (NPFG's feed-forward):
    ``a = pursuit - c (2 V^2 sin(eta_P) / |PG| - V^2 kappa_P)``, eta_P the angle from the tangent
    at P to the chord from P to the goal G. ``2 V^2 sin(eta_P) / |PG|`` is the pursuit command of
    a vehicle sitting on P along the tangent: on a circular arc it equals ``V^2 kappa`` exactly
    (so the term vanishes there), on a straight leading into a bend it is the early turn-in that
    makes every pursuit law cut the bend, which c = 1 removes. Off the path the feedback part
    (pursuit minus its on-path value) is unchanged. ``kappa_P`` is read ``V lead_s`` metres
    beyond P (the law passes its lag model's time constant): a first-order inner loop follows a
    curvature ramp one time constant late, and leading the feed-forward by it cancels that.

    With a ``band`` (:class:`_Band`) the closest sample is searched near each row's previous one,
    so that the goal stays on the vehicle's branch of a path that crosses itself.
    """
    a, l_eff, goal, d = _pursue(win, np.stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)]),
                                course_rad, speed_m_s, look_m, curvature_ff, lead_s, band)
    if a_max_m_s2 < math.inf:
        a = np.minimum(np.maximum(a, -a_max_m_s2), a_max_m_s2)
    return a, l_eff, goal[0], goal[1], d


def _pursue(win: _Window, xy: np.ndarray, course_rad: np.ndarray, speed_m_s: np.ndarray, look_m: np.ndarray,
            curvature_ff: float, lead_s: float, band: _Band | None = None,
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`pursuit_command` (not clipped) for the positions ``xy`` (x and y in rows): returns
    the commands, L_eff, the goals (x and y in rows) and the cross-track errors.

    The rollouts call this every step, with a few dozen rows against a window of a hundred
    samples or so: its cost is the number of numpy calls, which x and y stacked in one array and
    the window's stacked tables keep low. Every number is the plain formula's, operand for
    operand, so the results are the same to the last bit.
    """
    n = win.x.size
    v = np.maximum(speed_m_s, _MIN_SPEED)
    i0, d, r2, near, along = _project(win, xy, band)
    l_eff = np.maximum(look_m, _SQRT2 * np.abs(d))
    # The goal sample j: the first at index >= i0 and distance >= L_eff (else the last one).
    r = np.sqrt(r2)
    ahead = r >= l_eff[:, None]
    ahead &= win.from_samples(i0)
    j = ahead.argmax(axis=1)
    at_j = _row_starts(j.size, n) + j  # (row, j) in the flattened matrices
    has = ahead.ravel().take(at_j)
    r_flat = r.ravel()
    r_j, r_jm = r_flat.take(at_j), r_flat.take(at_j - 1)
    # Interpolated between j - 1 and j where a sample j > i0 was found (then r_jm < L_eff <= r_j,
    # as j - 1 was not far enough, and the fraction lies in [0, 1]), else at j (r_j and r_jm are
    # not used then). Where none was found, argmax gave j = 0 <= i0.
    frac = np.where(j > i0, (l_eff - r_jm) / np.maximum(r_j - r_jm, _TINY_STEP_M), _ONE)
    at_goal = win.at_goal.take(np.where(has, j, n - 1), axis=1)
    goal = at_goal[:2] + frac * at_goal[2:]
    to_goal = goal - xy
    eta = np.mod(np.arctan2(to_goal[1], to_goal[0]) - course_rad + _PI, _TWO_PI) - _PI
    vv = v * v
    w2 = vv * _TWO  # 2 V^2 (doubling is exact: the same number as (2 V) V)
    a = w2 * np.sin(eta) / np.maximum(np.hypot(to_goal[0], to_goal[1]), _TINY_M)
    if curvature_ff:
        # P: the vehicle projected on the osculating circle of its nearest sample, to second order
        # in the distance along (continuous in the vehicle's position, unlike the sample itself);
        # the tangent there is the sample's turned by kappa along, and the curvature is
        # interpolated to it. With the sample's tangent line for both, the term swung
        # 2 V^2 kappa along / L every sample passed (0.5 m/s^2 on a 30 m circle at 5 m/s and L 3 m),
        # a sawtooth in the command that the rollouts, stepping a sample at a time, saw in phase.
        along_c = np.minimum(np.maximum(along, _MINUS_SPACING), _SPACING)
        bow = near[6] * along_c * along_c  # kappa along^2 / 2, to the left of the tangent
        chord = goal - (near[:2] + along * near[2:4])  # from P to the goal
        chord[0] += bow * near[3]
        chord[1] -= bow * near[2]
        # The curvature is read ``lead_s`` ahead (V lead_s metres): a first-order inner loop of
        # time constant tau follows a ramp of command tau late, so leading it by tau cancels that.
        pos = i0 + (along + v * lead_s) / _SPACING
        pos = np.minimum(np.maximum(pos, _ZERO), n - 1.0)
        lo = np.minimum(pos.astype(int), n - 2) if n > 1 else np.zeros_like(i0)
        at_kappa = win.at_kappa.take(lo, axis=1)
        kappa = at_kappa[0] + (pos - lo) * at_kappa[1]
        length = np.maximum(np.hypot(chord[0], chord[1]), _TINY_M)
        cross = near[4:6] * chord  # ty cx, tx cy
        dot = near[2:4] * chord  # tx cx, ty cy
        turn = near[6] * _TWO * along_c  # kappa along
        sin_eta_p = (cross[1] - cross[0] - turn * (dot[0] + dot[1])) / length  # cross(tangent at P, chord) / |chord|
        a = a - curvature_ff * (w2 * sin_eta_p / length - vv * kappa)
    return a, l_eff, goal, d


def tick_pursuit(win: _Window, band: _Band, state: VehicleState, look_m: float, curvature_ff: float, lead_s: float,
                 kernel: rollout_kernel.Kernel | None) -> tuple[float, float, float, float]:
    """:func:`pursuit_command` (not clipped) for one vehicle in its band: the command, L_eff and
    the goal; by the compiled loop when ``kernel`` is given (the same numbers to rounding)."""
    if kernel is not None:
        a, _, l_eff, gx, gy = kernel.pursuit(
            win.x, win.y, win.tx, win.ty, win.k, WINDOW_SPACING_M, float(state.x_m), float(state.y_m),
            float(state.course_rad), max(float(state.speed_m_s), MIN_SPEED_M_S), float(look_m),
            float(curvature_ff), float(lead_s), int(band.centre[0]), band.back, band.ahead, band.whole)
        return a, l_eff, gx, gy
    a_, l_, gx_, gy_, _ = pursuit_command(
        win, np.array([state.x_m]), np.array([state.y_m]), np.array([state.course_rad]),
        np.array([state.speed_m_s]), np.array([look_m]), math.inf, curvature_ff, lead_s, band)
    return float(a_[0]), float(l_[0]), float(gx_[0]), float(gy_[0])


def _project_one(win: _Window, band: _Band, x_m: float, y_m: float,
                 kernel: rollout_kernel.Kernel | None) -> tuple[int, float]:
    """The nearest window sample of one point within its band, and its signed cross-track error
    (:func:`_nearest`; by the compiled loop when ``kernel`` is given)."""
    if kernel is not None:
        return kernel.project(win.x, win.y, win.tx, win.ty, win.k, WINDOW_SPACING_M, float(x_m), float(y_m),
                              int(band.centre[0]), band.back, band.ahead, band.whole)
    i0, d, _ = _nearest(win, np.array([x_m]), np.array([y_m]), band)
    return int(i0[0]), float(d[0])


#: Below this ground speed (m/s) the course observer hands the law the reported course: near
#: hover a course is noise, and the model's turn rate a / V is no prediction.
OBSERVER_MIN_SPEED_M_S = 1.0


def observe_course(course_hat_rad: float, reported_rad: float, a_from_m_s2: float, a_to_m_s2: float,
                   speed_m_s: float, dt_s: float, tc_s: float) -> float:
    """One step of the course observer (``PredictiveParams.course_tc_s``): the observed course
    turned by the lateral acceleration the lag model flew over ``dt_s`` (from ``a_from_m_s2`` to
    ``a_to_m_s2``, the trapezoid, at ``speed_m_s``), then moved towards the reported course by
    ``1 - exp(-dt_s / tc_s)`` of the (wrapped) difference. Frame-agnostic (any horizontal frame
    whose angles grow in the sense a positive acceleration turns); radians, wrapped to (-pi, pi].

    A complementary filter: a change of the reported course slower than about ``tc_s`` passes
    (a disturbance, a model that turns too little), a quicker one is replaced by the model's own
    turn, which has no lag of its own. With a model that turns as the vehicle does and a reported
    course that follows it, the observer stays on it exactly:

    >>> a, v, dt = 2.0, 5.0, 0.02  # a steady turn
    >>> hat = 0.0
    >>> for k in range(1, 51):
    ...     hat = observe_course(hat, a / v * dt * k, a, a, v, dt, 0.3)
    >>> abs(hat - a / v * dt * 50) < 1e-12
    True

    An offset of the reported course decays as ``exp(-t / tc_s)``; flying straight, a reported
    step of 0.1 rad is half followed after ``tc_s ln 2``:

    >>> hat = 0.0
    >>> for k in range(int(round(0.3 * math.log(2) / 0.002))):
    ...     hat = observe_course(hat, 0.1, 0.0, 0.0, v, 0.002, 0.3)
    >>> round(hat, 3)
    0.05
    """
    turned = course_hat_rad + 0.5 * (a_from_m_s2 + a_to_m_s2) / speed_m_s * dt_s
    gap = angle_diff_rad(reported_rad, turned)
    return wrap_pi(turned + (1.0 - math.exp(-dt_s / tc_s)) * gap)


def air_heading(state: VehicleState, wind_x_m_s: float, wind_y_m_s: float) -> tuple[float, float]:
    """Air heading (rad) and airspeed (m/s, at least ``MIN_SPEED_M_S``) from the ground velocity
    and the known wind (the state's frame)."""
    gx = state.speed_m_s * math.cos(state.course_rad) - wind_x_m_s
    gy = state.speed_m_s * math.sin(state.course_rad) - wind_y_m_s
    return math.atan2(gy, gx), max(math.hypot(gx, gy), MIN_SPEED_M_S)


class CourseObserver:
    """The course :class:`PredictiveGuidance` reads (``PredictiveParams.course_tc_s``): the reported
    one with a time constant of 0; else :func:`observe_course` every tick, and the reported course
    on the first tick or below ``OBSERVER_MIN_SPEED_M_S`` (the observer restarts from it)."""

    def __init__(self, tc_s: float) -> None:
        self.tc_s = float(tc_s)
        self.course_rad: float | None = None  # the observed course, once there is one

    def observe(self, state: VehicleState, dt_s: float | None, a_from_m_s2: float, a_to_m_s2: float) -> VehicleState:
        """``state`` with its course observed, ``dt_s`` after the last tick (None: the first), over
        which the lag model's acceleration went from ``a_from_m_s2`` to ``a_to_m_s2``."""
        if not self.tc_s > 0.0:
            return state
        hat = self.course_rad
        if hat is None or dt_s is None or state.speed_m_s < OBSERVER_MIN_SPEED_M_S:
            self.course_rad = float(state.course_rad)
            return state
        self.course_rad = observe_course(hat, float(state.course_rad), a_from_m_s2, a_to_m_s2,
                                         float(state.speed_m_s), dt_s, self.tc_s)
        return dataclasses.replace(state, course_rad=self.course_rad)


# Model monitor (adapt_model): candidate lags and limits as multiples of the nominal ones.
MONITOR_LAG_FACTORS = (0.5, 1.0, 1.5, 2.0, 3.0, 4.0)
MONITOR_LAG_FLOOR_S = 0.2  # the candidates of a nominal lag of 0 (ideal: unknown) are multiples of this
MONITOR_A_MAX_FACTORS = (1.0, 0.7, 0.5)
MONITOR_GAP_FACTOR = 3.0  # a step this many times the usual one: ticks were skipped or coasted
MONITOR_OBS_TC_S = 0.2  # low-pass of the observed (and each candidate's) lateral acceleration
MONITOR_ERR_TC_S = 4.0  # averaging time of each candidate's squared prediction error
MONITOR_WARMUP_S = 3.0  # no switching before this much flight
MONITOR_SWITCH_RATIO = 0.6  # a candidate replaces the model in use when its error is below this share
MONITOR_FALLBACK_SHARE = 0.5  # unexplained share of the observed acceleration that drops the plan
# A candidate limit below the stated one may be switched to only once the commands have stayed
# beyond it this long (the longest such stretch, forgotten over MONITOR_ERR_TC_S): a shorter
# excursion a lag or a dead time explains as well (ModelMonitor).
MONITOR_LIMIT_EVIDENCE_S = 1.0


class ModelMonitor:
    """Which first-order model (lag, limit) explains the lateral acceleration the vehicle flies.

    A bank of candidate models (:data:`MONITOR_LAG_FACTORS` x :data:`MONITOR_A_MAX_FACTORS` times
    the nominal lag and limit) each runs the law's own commands through its lag and limit; the
    observed lateral acceleration ``V dcourse/dt`` and every candidate's output go through the
    same low-pass (:data:`MONITOR_OBS_TC_S`), and each candidate's squared error is averaged over
    :data:`MONITOR_ERR_TC_S`. The model in use switches to the best candidate when its error is
    under :data:`MONITOR_SWITCH_RATIO` of the one in use (hysteresis; the nominal model to begin
    with). Over a gap in the ticks (skipped, or coasted by the flight loop while a step ran
    late: the vehicle then flew setpoints the law did not choose) nothing is compared and the
    candidates restart from the observation. ``unexplained`` is the error of the model in use over the observed acceleration's
    mean square: above :data:`MONITOR_FALLBACK_SHARE` no candidate stands for the vehicle and the
    law flies its feedback core alone (no plan). Pure arithmetic on the inputs: deterministic.

    A candidate whose limit is below the stated one is switched to only on evidence of that limit:
    the commands must have stayed beyond it for :data:`MONITOR_LIMIT_EVIDENCE_S` (the longest such
    stretch, forgotten over :data:`MONITOR_ERR_TC_S`). A turn's entry, commanded at the limit for
    a few tenths of a second, is flown late by a vehicle with a dead time the candidates do not
    have, and a lower limit explains that lateness as well as a longer lag does. Real ArduCopter
    flights took half the limit so on a straight (the error of a take-off transient 25 s before)
    or in a turn's first 0.2 s, and the plan, re-made for it mid-turn, swung the vehicle 0.44 m out
    (docs/real_firmware.md).

    The law plans with the limit of the model in use but holds its command at the vehicle's
    stated limit: a command held at a model limit below the vehicle's would fly every candidate
    limit alike, and the monitor could never see the vehicle fly more. A real ArduCopter's
    monitor once took half the limit read from the autopilot, exactly a U-turn's ``V^2 / R``,
    and kept it through the turn, 3.1 m wide (docs/real_firmware.md).
    """

    def __init__(self, lag_s: float, a_max_m_s2: float):
        base = lag_s if lag_s > 0.0 else MONITOR_LAG_FLOOR_S
        lags = [f * base for f in MONITOR_LAG_FACTORS]
        if lag_s <= 0.0:
            lags[1] = 0.0  # the nominal (ideal) model itself
        limits = [f * a_max_m_s2 for f in MONITOR_A_MAX_FACTORS] if a_max_m_s2 < math.inf else [math.inf]
        grid_lag, grid_lim = np.meshgrid(np.array(lags), np.array(limits), indexing="ij")
        self.lags = grid_lag.ravel()
        self.limits = grid_lim.ravel()
        self.current = int(MONITOR_LAG_FACTORS.index(1.0) * len(limits))  # nominal lag, full limit
        n = self.lags.size
        self._limited = self.limits < float(np.max(self.limits))  # the candidates that need evidence
        self._beyond_s = np.zeros(n)  # how long the commands have now stayed beyond each limit
        self._evidence_s = np.zeros(n)  # the longest such stretch, forgotten over MONITOR_ERR_TC_S
        self._a = np.zeros(n)
        self._a_f = np.zeros(n)
        self._err = np.zeros(n)
        self._obs_f = 0.0
        self._obs_ms = 0.0
        self._prev: tuple[float, float] | None = None  # (t_s, course_rad)
        self._dt_usual: float | None = None
        self._t0: float | None = None
        self.unexplained = 0.0

    @property
    def lag_s(self) -> float:
        return float(self.lags[self.current])

    @property
    def a_max_m_s2(self) -> float:
        return float(self.limits[self.current])

    def update(self, t_s: float, course_rad: float, speed_m_s: float, last_cmd_m_s2: float) -> None:
        """Advance with the state of this tick and the command held since the previous one."""
        if self._t0 is None:
            self._t0 = t_s
        prev, self._prev = self._prev, (t_s, course_rad)
        if prev is None or not t_s > prev[0]:
            return
        dt = t_s - prev[0]
        dpsi = math.remainder(course_rad - prev[1], 2.0 * math.pi)
        observed = max(speed_m_s, MIN_SPEED_M_S) * dpsi / dt
        # the usual step: a running mean (tick times jitter with the samples' arrival)
        usual = self._dt_usual = dt if self._dt_usual is None else self._dt_usual + 0.05 * (dt - self._dt_usual)
        if dt > MONITOR_GAP_FACTOR * usual:
            # Ticks were skipped or coasted: the vehicle flew setpoints this law did not choose.
            # Compare nothing over the gap; restart every candidate from what is observed.
            self._a[:] = observed
            self._beyond_s[:] = 0.0
            self._a_f[:] = observed
            self._obs_f = observed
            return
        beta = 1.0 - math.exp(-dt / MONITOR_OBS_TC_S)
        gamma = 1.0 - math.exp(-dt / MONITOR_ERR_TC_S)
        with np.errstate(divide="ignore", over="ignore"):
            alpha = np.where(self.lags > 0.0, 1.0 - np.exp(-dt / np.maximum(self.lags, 1e-9)), 1.0)
        target = np.clip(last_cmd_m_s2, -self.limits, self.limits)
        self._beyond_s = np.where(abs(last_cmd_m_s2) > self.limits, self._beyond_s + dt, 0.0)
        self._evidence_s = np.maximum(self._evidence_s * (1.0 - gamma), self._beyond_s)
        # the course change over the tick is the mean of the acceleration over it: compare means
        a_mean = self._a + (target - self._a) * alpha * 0.5
        self._a += (target - self._a) * alpha
        self._a_f += (a_mean - self._a_f) * beta
        self._obs_f += (observed - self._obs_f) * beta
        self._err += ((self._obs_f - self._a_f) ** 2 - self._err) * gamma
        self._obs_ms += (self._obs_f ** 2 - self._obs_ms) * gamma
        if t_s - self._t0 < MONITOR_WARMUP_S:
            return
        unproven = self._limited & (self._evidence_s < MONITOR_LIMIT_EVIDENCE_S)
        best = int(np.argmin(np.where(unproven, np.inf, self._err)))
        if self._err[best] < MONITOR_SWITCH_RATIO * self._err[self.current]:
            self.current = best
        self.unexplained = float(self._err[self.current] / (self._obs_ms + 0.05))

    @property
    def fallback(self) -> bool:
        return self.unexplained > MONITOR_FALLBACK_SHARE


class PredictiveGuidance:
    """The predictive law on a :class:`~companion.geometry.paths.Path`; see the module docstring.

    Same interface as the other laws: ``step(t_s, VehicleState) -> GuidanceOutput``.
    """

    method = "predictive"

    def __init__(self, path: PathLike, params: PredictiveParams | None = None) -> None:
        self.path = path
        self.params = params if params is not None else PredictiveParams()
        p = self.params
        self._candidates = p.candidates_m()
        self._horizon_s, self._segments = p.horizon()
        self._steps = max(1, int(round(self._horizon_s / p.rollout_dt_s)))
        self._segment_s = self._horizon_s / self._segments
        # rollout step k -> plan segment
        self._seg_of_step = np.minimum(
            (np.arange(self._steps) * p.rollout_dt_s / self._segment_s).astype(int), self._segments - 1)
        self._s_hint: float | None = None
        self._look_m = float(self._candidates[len(self._candidates) // 2])
        self._plan = np.zeros(self._segments)  # acceleration corrections, one per segment
        # A correction larger than the vehicle's limit (or, with none, than the pursuit's command
        # at 10 m/s and a 3 m look-ahead) can only saturate: bound the plan there.
        self._plan_bound = p.a_max_m_s2 if p.a_max_m_s2 < math.inf else 2.0 * 10.0**2 / HOVER_TURN_LOOK_M
        self._plan_t0 = 0.0
        self._a_hat = 0.0  # lateral acceleration the vehicle is flying, per the lag model
        self._last_cmd = 0.0
        self._last_t: float | None = None
        self._observer = CourseObserver(p.course_tc_s)  # the course the law reads
        self._next_reopt_t = -math.inf
        self._win: _Window | None = None
        self._s_win, self._d_win = 0.0, 0.0  # the law's projection and cross-track error, this tick
        self.reoptimisations = 0
        # The vehicle model the law plans with: the nominal one, or what the monitor found.
        self._lag_s, self._a_max = p.lag_s, p.a_max_m_s2
        self.monitor = ModelMonitor(p.lag_s, p.a_max_m_s2) if p.adapt_model else None
        self._joined = False  # within SIDE_MIN_OFFSET_M of the path since the law started
        self._capture_side = 0  # the side of the capture turn (companion.guidance.capture), 0: none
        # The rollouts compiled (companion.guidance.rollout_kernel) when numba is installed; the
        # numpy ones otherwise, or with this set False. Compiled (or loaded) before the first tick.
        self._kernel = rollout_kernel.load()
        self.compiled = self._kernel is not None

    def start_projection_at(self, s_m: float) -> None:
        """Seed the projection (e.g. at the path start when a mid-course phase hands over)."""
        self._s_hint = float(s_m)

    # -- the vehicle model the law believes ---------------------------------------------------
    def _alpha(self, dt_s: float) -> float:
        return 1.0 if self._lag_s <= 0.0 else 1.0 - math.exp(-dt_s / self._lag_s)

    def rollout(self, state: VehicleState, look_m: np.ndarray, plans: np.ndarray,
                d_ref_m: np.ndarray | None = None) -> np.ndarray:
        """Batched closed-loop rollouts; returns the residuals ``(K, 2 * steps + 3)``.

        Row k flies pursuit with look-ahead ``look_m[k]`` plus the piecewise-constant correction
        ``plans[k]`` through the lag and the limit. The cost of a row is the sum of its squared
        residuals: ``sum ((d - r)^2 + lambda u^2) dt``, r the capture reference ``d_ref_m`` (one
        value per rollout step; None: zero), plus the cost to go from where it ends (the last
        three, :func:`cost_to_go_factor`; zero with ``terminal_cost`` off); an overshoot beyond the
        path weighs ``overshoot_weight`` times (:func:`weigh_overshoot`); a wide turner's approach
        is charged at the band (:func:`charge_approach_at_band`, :func:`approach_charged_at_band`).
        """
        p = self.params
        win = self._win
        assert win is not None  # set by reoptimise() before any rollout
        k = look_m.size
        heading, v_air = air_heading(state, p.wind_x_m_s, p.wind_y_m_s)
        step_plans = plans.T[self._seg_of_step]  # every row's correction at every step
        cff, lead, limit = p.curvature_ff, self._lag_s, self._a_max
        to_go = _cost_to_go_cached(self._lag_s, p.lambda_s4) if p.terminal_cost else _NO_COST_TO_GO
        band = _band(win, np.full(k, win.index_of(self._s_win)), v_air, p.rollout_dt_s, self._d_win)
        if self._kernel is not None and self.compiled:
            res = self._kernel.rollout(
                win.x, win.y, win.tx, win.ty, win.k, WINDOW_SPACING_M, float(state.x_m), float(state.y_m),
                heading, float(self._a_hat), np.ascontiguousarray(look_m, dtype=float),
                np.ascontiguousarray(step_plans, dtype=float), v_air, float(p.wind_x_m_s), float(p.wind_y_m_s),
                self._alpha(p.rollout_dt_s), float(p.rollout_dt_s), float(cff), float(lead), float(limit),
                int(band.centre[0]), band.back, band.ahead, band.whole,
                np.zeros(self._steps) if d_ref_m is None else np.ascontiguousarray(d_ref_m, dtype=float),
                math.sqrt(p.rollout_dt_s), math.sqrt(p.lambda_s4 * p.rollout_dt_s), MIN_SPEED_M_S, to_go)
        else:
            res = self._rollout_numpy(state, heading, v_air, win, look_m, step_plans, d_ref_m, band, to_go)
        sqrt_dt, weight = math.sqrt(p.rollout_dt_s), p.overshoot_weight_in_use()
        if d_ref_m is not None and approach_charged_at_band(p, self._joined, v_air, float(d_ref_m[0])):
            return charge_approach_at_band(res, d_ref_m, sqrt_dt, weight)
        return weigh_overshoot(res, d_ref_m, sqrt_dt, weight)

    def _rollout_numpy(self, state: VehicleState, heading: float, v_air: float, win: _Window, look_m: np.ndarray,
                       step_plans: np.ndarray, d_ref_m: np.ndarray | None, band: _Band, to_go: np.ndarray) -> np.ndarray:
        """:meth:`rollout` in numpy (the compiled loops' arithmetic, step by step for every row);
        ``heading``, ``v_air``: the vehicle's air heading and airspeed (:meth:`_air`)."""
        p = self.params
        k = look_m.size
        cff, lead, limit = p.curvature_ff, self._lag_s, self._a_max
        h = np.full(k, heading)
        xy = np.empty((2, k))  # x and y in rows, as the pursuit takes them
        xy[0], xy[1] = state.x_m, state.y_m
        a_act = np.full(k, self._a_hat)
        dt = _const(p.rollout_dt_s)
        alpha, speed, half = _const(self._alpha(p.rollout_dt_s)), _const(v_air), _const(0.5)
        # ground velocity = air velocity + wind; a zero wind is skipped (V cos(h) is never -0.0)
        wind = np.array([[p.wind_x_m_s], [p.wind_y_m_s]]) if p.wind_x_m_s or p.wind_y_m_s else None
        trig = np.empty((2, k))
        ds, us = [], []
        for n in range(self._steps):
            np.cos(h, out=trig[0])
            np.sin(h, out=trig[1])
            ground = speed * trig
            if wind is not None:
                ground += wind
            u, _, _, d = _pursue(win, xy, np.arctan2(ground[1], ground[0]), np.hypot(ground[0], ground[1]), look_m,
                                 cff, lead, band)
            u += step_plans[n]
            if limit < math.inf:
                u = np.minimum(np.maximum(u, -limit), limit)
            ds.append(d)
            us.append(u)
            a_act = a_act + (u - a_act) * alpha
            dh = a_act / speed * dt
            mid = h + half * dh
            np.cos(mid, out=trig[0])
            np.sin(mid, out=trig[1])
            ground = speed * trig
            if wind is not None:
                ground += wind
            xy = xy + ground * dt
            h = h + dh
        d_steps, u_steps = np.array(ds), np.array(us)
        if d_ref_m is not None:
            d_steps -= d_ref_m[:, None]
        res = np.empty((k, 2 * self._steps + 3))
        res[:, 0:-3:2] = (d_steps * math.sqrt(p.rollout_dt_s)).T
        res[:, 1:-3:2] = (u_steps * math.sqrt(p.lambda_s4 * p.rollout_dt_s)).T
        res[:, -3:] = _cost_to_go(win, xy, h, a_act, speed, wind, band, to_go)
        return res

    def _shifted_plan(self, t_s: float) -> np.ndarray:
        """The previous plan re-read from ``t_s`` on (segments past its horizon decay to zero), each
        new segment the old one holding its middle: at the defaults (0.2-s period, 0.5-s segments)
        as it stands (docs/benchmarks.md, "A plan that alternated far off the path")."""
        mids = t_s - self._plan_t0 + (np.arange(self._segments) + 0.5) * self._segment_s
        idx = np.floor(mids / self._segment_s).astype(int)
        return np.where(idx < self._segments, self._plan[np.minimum(idx, self._segments - 1)], 0.0)

    def _reference(self, state: VehicleState) -> np.ndarray | None:
        """The capture reference over the rollout steps, from the vehicle's error and its rate."""
        tc = self.params.capture_tc_s()
        if not tc > 0.0:
            return None
        win = self._win
        assert win is not None  # set by reoptimise() before any rollout
        i, d0 = _project_one(win, self._tick_band(state), state.x_m, state.y_m,
                             self._kernel if self.compiled else None)
        vx = state.speed_m_s * math.cos(state.course_rad)
        vy = state.speed_m_s * math.sin(state.course_rad)
        rate = float(win.tx[i] * vy - win.ty[i] * vx)  # ground velocity across the path, left positive
        return capture_reference(d0, rate, tc, np.arange(self._steps) * self.params.rollout_dt_s)

    def _window(self, state: VehicleState, s_proj_m: float, crosstrack_m: float) -> _Window:
        """The local path samples the pursuit and the rollouts use: from the projection, as far as
        the horizon (and a far vehicle's look-ahead) reaches."""
        p = self.params
        v_g = max(state.speed_m_s, MIN_SPEED_M_S)
        reach = v_g * (self._horizon_s + p.reopt_period_s) * 1.3 + 1.5 * max(p.l_max_m, SQRT2 * abs(crosstrack_m)) + 5.0
        self._s_win, self._d_win = s_proj_m, crosstrack_m
        return _Window(self.path, s_proj_m, reach)

    def _tick_band(self, state: VehicleState) -> _Band:
        """The band of the vehicle itself: around the law's own projection (continuous along the
        path), as wide as the vehicle's distance from it asks."""
        win = self._win
        assert win is not None
        return _band(win, np.array([win.index_of(self._s_win)]), state.speed_m_s, 0.0, self._d_win)

    def reoptimise(self, t_s: float, state: VehicleState, s_proj_m: float, crosstrack_m: float) -> float:
        """Choose the look-ahead distance and refine the correction plan; returns the plan's cost.

        1. One batched rollout holds every candidate look-ahead distance flown with the previous
           plan (shifted to now) and with no plan, and the shifted plan perturbed segment by
           segment at the previous look-ahead. The cheapest candidate is kept; if it has no plan,
           the plan restarts from zero and step 2 starts there, with a Jacobian taken at zero
           (docs/benchmarks.md, "A plan that alternated far off the path").
        2. Gauss-Newton on the plan: the perturbed rows give the Jacobian of the residuals, the
           damped normal equations a step (scaled into the limit), and a second batched rollout
           tries the full, half and quarter step; a step is kept only if it lowers the cost.
           ``refine_iterations`` > 1 repeats step 2 around the new plan.
        """
        p = self.params
        self._win = self._window(state, s_proj_m, crosstrack_m)
        d_ref = self._reference(state)
        plan = self._shifted_plan(t_s)
        look = self._candidates
        k = look.size
        m = plan.size
        eps = FD_STEP_M_S2
        refine = p.refine_iterations > 0
        # Rows: every candidate with the shifted plan, and with no plan (a plan gone stale or
        # saturated can always be dropped); the shifted plan perturbed (the Jacobian for step 2).
        rows_look = np.concatenate([look, look, np.full(m if refine else 0, self._look_m)])
        plans = np.zeros((rows_look.size, m))
        plans[:k] = plan
        if refine:
            plans[2 * k:] = plan + eps * np.eye(m)
        res = self.rollout(state, rows_look, plans, d_ref)
        costs = np.einsum("ij,ij->i", res[:2 * k], res[:2 * k])
        best = int(np.argmin(costs))
        previous = int(np.argmin(np.abs(look - self._look_m)))
        self._look_m = float(look[best % k])
        cost = float(costs[best])
        if best >= k:  # dropping the plan is cheapest: start again from zero, refine from there
            plan = np.zeros(m)
        if refine:
            r0 = res[best] if best >= k else res[previous]
            rows = self.rollout(state, np.full(m, self._look_m), eps * np.eye(m), d_ref) if best >= k else res[2 * k:]
            jac = (rows - r0).T / eps
            for iteration in range(p.refine_iterations):
                jtj = jac.T @ jac
                damping = 1e-6 + 1e-3 * np.trace(jtj) / m
                step = np.linalg.solve(jtj + damping * np.eye(m), -jac.T @ r0)
                # Into the limit as a whole (far off, a clip element by element turned it anywhere).
                step *= min(1.0, self._plan_bound / max(float(np.max(np.abs(step))), 1e-12))
                trial = np.clip(plan + np.outer(LINE_SEARCH, step), -self._plan_bound, self._plan_bound)
                rc = self.rollout(state, np.full(len(LINE_SEARCH), self._look_m), trial, d_ref)
                cc = np.einsum("ij,ij->i", rc, rc)
                j = int(np.argmin(cc))
                if cc[j] >= cost:
                    break
                plan, cost = trial[j], float(cc[j])
                if iteration + 1 < p.refine_iterations:
                    pert = np.tile(plan, (m + 1, 1))
                    pert[1:] += eps * np.eye(m)
                    r = self.rollout(state, np.full(m + 1, self._look_m), pert, d_ref)
                    r0 = r[0]
                    jac = (r[1:] - r0).T / eps
        self._plan = plan
        self._plan_t0 = t_s
        self.reoptimisations += 1
        return cost

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        p = self.params
        a_from, dt = self._a_hat, None if self._last_t is None else max(t_s - self._last_t, 0.0)
        if dt is not None:  # advance the lag model over the last tick with the last command,
            flown = min(max(self._last_cmd, -self._a_max), self._a_max)  # as far as the model flies it
            self._a_hat += (flown - self._a_hat) * self._alpha(dt)
        self._last_t = t_s
        monitor = self.monitor
        if monitor is not None:  # it reads the course as reported: what the vehicle flew
            monitor.update(t_s, state.course_rad, state.speed_m_s, self._last_cmd)
            self._lag_s = monitor.lag_s
            self._a_max = min(monitor.a_max_m_s2, p.a_max_m_s2)
            if monitor.fallback:
                self._plan = np.zeros(self._segments)
        state = self._observer.observe(state, dt, a_from, self._a_hat)
        f = path_frame(self.path, state.x_m, state.y_m, self._s_hint, state.course_rad)
        self._s_hint = f.s_m
        self._s_win, self._d_win = f.s_m, f.crosstrack_m
        self._joined = self._joined or abs(f.crosstrack_m) <= SIDE_MIN_OFFSET_M
        reoptimised = False
        if self._capture_side:  # turning round (below): no plan, only the goal is needed
            self._win = self._window(state, f.s_m, f.crosstrack_m)
        elif t_s >= self._next_reopt_t or self._win is None:
            self.reoptimise(t_s, state, f.s_m, f.crosstrack_m)
            self._next_reopt_t = t_s + p.reopt_period_s - SCHEDULE_TOLERANCE_S
            reoptimised = True
        assert self._win is not None  # set just above
        a, l_eff, gx, gy = tick_pursuit(self._win, self._tick_band(state), state, self._look_m, p.curvature_ff,
                                        self._lag_s, self._kernel if self.compiled else None)
        seg = min(int((t_s - self._plan_t0) / self._segment_s), self._segments - 1)
        correction = 0.0 if monitor is not None and monitor.fallback else float(self._plan[seg])
        # At the vehicle's stated limit; the model's limit is the plan's (ModelMonitor: why).
        a_cmd = min(max(a + correction, -p.a_max_m_s2), p.a_max_m_s2)
        # Capture (companion.guidance.capture): the pursuit's goal behind the beam, the vehicle
        # is pointing away; turn round at the limit (none stated: 2 V^2 / L), no sharper than
        # 2 V^2 / HOVER_TURN_LOOK_M (near hover, course is noise), instead of planning.
        speed = max(state.speed_m_s, MIN_SPEED_M_S)
        bound_look = HOVER_TURN_LOOK_M if math.isfinite(self._a_max) else self._look_m
        a_turn = min(self._a_max, capture_command_m_s2(1, speed, bound_look))
        behind = pursuit_capture_side(state, f, gx, gy, self._capture_side, speed * speed / a_turn)
        ended = bool(self._capture_side) and not behind
        self._capture_side = behind
        if self._capture_side:
            a_cmd = self._capture_side * a_turn
            correction = 0.0
            self._plan = np.zeros(self._segments)
        elif ended:
            self._next_reopt_t = -math.inf  # plan afresh on the next tick
        self._last_cmd = a_cmd
        extra = {"lookahead_m": l_eff, "correction_m_s2": correction, "a_hat_m_s2": self._a_hat,
                 "capture_side": self._capture_side}
        if monitor is not None:
            extra.update({"model_lag_s": self._lag_s, "model_a_max_m_s2": self._a_max,
                          "model_unexplained": monitor.unexplained})
        return frame_output(self.path, f, a_cmd, (gx, gy), extra, reoptimised)
