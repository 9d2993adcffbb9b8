"""The two-phase guidance of the paper (Algorithm 1): mid-course, then close-range following.

    guidance = TwoPhaseGuidance(path, GuidanceParams(method="corrector"))
    out = guidance.step(t_s, VehicleState(x_m, y_m, course_rad, speed_m_s))
    out.a_cmd_m_s2, out.phase, out.k1, out.k2, out.lookahead_xy_m, out.corrector_xy_m

One object per flight: it keeps the previous projection (so the projection follows the path
continuously), the current gains and the mid-course plan. Deterministic: the same sequence of
``step`` calls gives the same outputs.

Phases
------
``midcourse``
    Entered on the first tick when the trigger fires (``params.midcourse_trigger``):

    - ``"auto"`` (default): the vehicle is at least ``2 R`` from the path start, R the
      initiation circle radius (``params.circle_radius_m``). This is the paper's distance test
      with the circle actually flown in place of R0; it fires on straight starts too. A closed
      path has no start to fly to (its ``s = 0`` is where its description begins), so there
      the distance is to the closest path point: a vehicle within ``2 R`` of a closed path joins
      it where it is (our choice, docs/guidance.md).
    - ``"paper"``: at least ``2 R0`` away, R0 the radius of curvature of the path at its start
      (on a nearly straight start R0 is huge and this never fires).
    - ``"off"``: never.

    See :mod:`companion.guidance.midcourse` for the circles, the contact point and the switch.
    Our addition: the turn-in is held while the closest path point lies behind the beam (a start
    beside the path, far from its start, heading away: :mod:`companion.guidance.capture`).
``close_range``
    Constant L1 (``method="fixed_l1"``), the corrector-aided command with online gains
    (``method="corrector"``), or the predictive law (``method="predictive"``: this phase is
    delegated to one :class:`~companion.guidance.predictive.PredictiveGuidance` built from
    ``lambda_s4``, ``rollout_tau_s`` (its lag), ``a_max_m_s2`` and the wind; it chooses its own
    look-ahead between 1.5 and 30 m, so ``l1_m`` is not used there; its outputs carry ``k1 = k2 =
    NaN`` (no corrector weights) and ``extra`` holds ``lookahead_m``, ``correction_m_s2`` and
    ``a_hat_m_s2``; ``reoptimised`` marks its re-optimisation ticks, every 0.2 s). For the first
    two: When no path point ahead leaves the L1 circle (the vehicle is more
    than L1 from the path, or a closed path lies wholly inside the circle) it steers at its
    projection with Park's command ``2 V^2 sin(eta) / max(|d|, L1)``, and, while the projection
    lies behind the beam, turns towards it at ``2 V^2 / L1`` (the capture,
    :mod:`companion.guidance.capture`, our addition to the paper), so that
    ``|a| <= 2 V^2 / L1`` holds in every case and a vehicle pointing away comes back.
``finished``
    On an open path, when the look-ahead point would run past the path end (the end is within
    L1 of the vehicle and no point ahead leaves the L1 circle): the paper's "while the
    look-ahead point is not the end of path". With ``method="predictive"``, when the projection
    reaches the path end (the law continues the path straight up to there). The command is
    then 0. A closed path never finishes.
"""

from __future__ import annotations

import math

from companion.geometry.paths import Path
from companion.guidance.capture import capture_command_m_s2, capture_side
from companion.guidance.corrector import corrector_command
from companion.guidance.l1 import l1_command
from companion.guidance.midcourse import MidcourseGuidance, MidcoursePlan
from companion.guidance.optimiser import GainOptimiser, ratio_from_gains
from companion.guidance.path_frame import first_projection_s
from companion.guidance.predictive import PredictiveGuidance, PredictiveParams
from companion.guidance.types import (
    SCHEDULE_TOLERANCE_S,
    TWO_PHASE_METHODS,
    GuidanceOutput,
    GuidanceParams,
    VehicleState,
    frozen_maker,
)


# Below this ground speed the rollouts are meaningless (hovering, taking off): gains are kept.
MIN_OPTIMISE_SPEED_M_S = 0.3

_output = frozen_maker(GuidanceOutput)  # every field by name, filled at once


class TwoPhaseGuidance:
    """Algorithm 1 of the paper as one object fed once per tick.

    Parameters
    ----------
    path : the reference path (local ENU).
    params : tuning; ``params.method`` selects constant L1, the corrector-aided law or the
        predictive law (a baseline method is built by :func:`companion.guidance.factory.make_law`).
    """

    def __init__(self, path: Path, params: GuidanceParams):
        if params.method not in TWO_PHASE_METHODS:
            raise ValueError(f"method: the two-phase guidance flies {', '.join(TWO_PHASE_METHODS)}, "
                             f"got {params.method!r} (companion.guidance.factory.make_law builds it)")
        self.path = path
        self.params = params
        self._optimiser = GainOptimiser(path, params) if params.method == "corrector" else None
        self._predictive = None
        if params.method == "predictive":
            self._predictive = PredictiveGuidance(path, PredictiveParams(
                lambda_s4=params.lambda_s4, lag_s=params.rollout_tau_s, a_max_m_s2=params.a_max_m_s2,
                wind_x_m_s=params.wind_x_m_s, wind_y_m_s=params.wind_y_m_s, adapt_model=params.adapt_model,
                course_tc_s=params.course_tc_s))
        self._started = False
        self._midcourse: MidcourseGuidance | None = None
        self._finished = False
        self._s_proj: float | None = None
        self._s_look: float | None = None
        self._capture_side = 0  # the side of the bounded capture turn (companion.guidance.capture)
        self._s_turn_in: float | None = None  # projection during the mid-course turn-in
        self._k1 = 1.0 if params.method == "fixed_l1" else params.k1_max
        self._k2 = 0.0
        self._t_next_opt = -math.inf
        # Commands held since _t_cmd, for the inner-loop estimate of the rollouts.
        self._a_cmd_prev = 0.0
        self._a_est = 0.0
        self._t_cmd: float | None = None

    # ------------------------------------------------------------------ public
    @property
    def midcourse_plan(self) -> MidcoursePlan | None:
        """The mid-course plan (None when the mid-course phase was not triggered)."""
        return None if self._midcourse is None else self._midcourse.plan

    def should_trigger_midcourse(self, state: VehicleState) -> bool:
        """Whether the mid-course phase starts from ``state`` (the trigger rules above)."""
        p = self.params
        if p.midcourse_trigger == "off":
            return False
        sx, sy = self.path.start_xy_m
        dist = math.hypot(state.x_m - sx, state.y_m - sy)
        if p.midcourse_trigger == "paper":
            r0 = self.path.radius_of_curvature_m(0.0)
            return dist >= 2.0 * r0
        if self.path.closed:
            cx, cy = self.path.point(self.path.project(state.x_m, state.y_m))
            dist = math.hypot(state.x_m - cx, state.y_m - cy)
        return dist >= 2.0 * p.circle_radius_m

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        """One guidance tick: the lateral acceleration command and its internals."""
        if not self._started:
            self._started = True
            if self.should_trigger_midcourse(state):
                self._midcourse = MidcourseGuidance(self.path.start_xy_m,
                                                    self.path.start_heading_rad,
                                                    self.params.circle_radius_m, self.params.l1_m)
        if self._finished:
            return self._finished_output(state)
        out = None
        if self._midcourse is not None and self._midcourse.stage != "done":
            out = self._midcourse_step(t_s, state)
        if out is None:
            out = self._close_range_step(t_s, state)
        if self.params.rollout_tau_s > 0:
            self._remember_command(t_s, out.a_cmd_m_s2)
        return out

    # ------------------------------------------------------------------ phases
    def _midcourse_step(self, t_s: float, state: VehicleState) -> GuidanceOutput | None:
        mc = self._midcourse
        assert mc is not None  # step() calls this only in the mid-course phase
        a, stage, done = mc.step(t_s, state.x_m, state.y_m, state.course_rad, state.speed_m_s,
                                 mc.stage == "turn_in" and self._path_behind(state))
        if done:
            mc.stage = "done"
            self._s_proj = 0.0  # close range starts at the path start
            if self._predictive is not None:
                self._predictive.start_projection_at(0.0)
            return None
        sx, sy = self.path.start_xy_m
        # The paper takes the distance to the path start as the mid-course cross-track error.
        dist = math.hypot(state.x_m - sx, state.y_m - sy)
        plan = mc.plan
        assert plan is not None
        return GuidanceOutput(
            a_cmd_m_s2=a, phase="midcourse", crosstrack_m=dist, s_proj_m=0.0,
            lookahead_xy_m=mc.lookahead_xy_m,
            extra={"stage": stage, "circle": plan.chosen.circle.name, "case": plan.case,
                   "rule": plan.rule, "contact_xy_m": plan.chosen.contact_xy_m},
        )

    def _path_behind(self, state: VehicleState) -> bool:
        """Whether the closest path point lies behind the beam (the mid-course turn-in is then
        held: :mod:`companion.guidance.capture`); the projection is carried tick to tick."""
        s = self.path.project(state.x_m, state.y_m, self._s_turn_in)
        self._s_turn_in = s
        px, py, tx, ty, _ = self.path.frame(s)
        return capture_side(state.x_m, state.y_m, state.course_rad, px, py, tx, ty, 0) != 0

    def _close_range_step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        if self._predictive is not None:
            return self._predictive_step(t_s, state)
        path, p = self.path, self.params
        x, y, course, V = state.x_m, state.y_m, state.course_rad, state.speed_m_s
        s_proj = path.project(x, y, self._s_proj) if self._s_proj is not None else first_projection_s(path, x, y, course)
        self._s_proj = s_proj
        px, py, tx, ty, _ = path.frame(s_proj)
        dx, dy = x - px, y - py
        dist = math.hypot(dx, dy)
        crosstrack = dist if tx * dy - ty * dx >= 0.0 else -dist
        s_look = path.lookahead(x, y, p.l1_m, s_proj)
        if s_look is None:
            ex, ey = path.end_xy_m
            if not path.closed and math.hypot(x - ex, y - ey) <= p.l1_m:
                self._finished = True
                return self._finished_output(state, s_proj, crosstrack)
            # Farther than L1 from the path: steer at the projection, with a bounded turn while
            # it lies behind the beam (companion.guidance.capture). (A closed path lying wholly
            # inside the L1 circle has no look-ahead point either: there the projection is nearer
            # than L1 and Park's distance is held at L1 to keep |a| <= 2 V^2 / L1.)
            self._capture_side = capture_side(x, y, course, px, py, tx, ty, self._capture_side)
            if self._capture_side:
                a = capture_command_m_s2(self._capture_side, V, p.l1_m)
            else:
                a, _, d = l1_command(x, y, course, V, px, py)
                if d < p.l1_m:
                    a *= d / p.l1_m
            return GuidanceOutput(a_cmd_m_s2=a, phase="close_range", crosstrack_m=crosstrack,
                                  s_proj_m=s_proj, k1=self._k1, k2=self._k2, lookahead_xy_m=(px, py),
                                  extra={"no_lookahead": True, "capture_side": self._capture_side})
        self._capture_side = 0
        self._s_look = s_look
        lx, ly, ltx, lty, lk = path.frame(s_look)
        if p.method == "fixed_l1":
            a, _, _ = l1_command(x, y, course, V, lx, ly)
            return GuidanceOutput(a_cmd_m_s2=a, phase="close_range", crosstrack_m=crosstrack,
                                  s_proj_m=s_proj, k1=1.0, k2=0.0, lookahead_xy_m=(lx, ly))
        reoptimised = False
        if t_s >= self._t_next_opt and V > MIN_OPTIMISE_SPEED_M_S:
            assert self._optimiser is not None  # method "corrector"
            warm = ratio_from_gains(self._k1, self._k2)
            k1, k2, window = self._optimiser.optimise(x, y, course, V, s_proj, s_look, warm,
                                                      self._a_achieved_estimate(t_s))
            self._k1, self._k2 = k1, k2
            self._t_next_opt = t_s + window - SCHEDULE_TOLERANCE_S
            reoptimised = True
        terms = corrector_command(x, y, course, V, p.l1_m, (px, py, tx, ty),
                                  (lx, ly, ltx, lty, lk), self._k1, self._k2)
        # a GuidanceOutput filled at once: the 50 Hz path
        return _output(a_cmd_m_s2=terms.a_cmd_m_s2, phase="close_range", crosstrack_m=crosstrack, s_proj_m=s_proj,
                       k1=self._k1, k2=self._k2, lookahead_xy_m=(lx, ly), corrector_xy_m=terms.corrector_xy_m,
                       reoptimised=reoptimised,
                       extra={"a12_m_s2": terms.a12_m_s2, "a14_m_s2": terms.a14_m_s2, "w1": terms.w1,
                              "w2": terms.w2})

    def _predictive_step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        """The close-range phase of ``method="predictive"``: the predictive law's own step."""
        assert self._predictive is not None  # method "predictive"
        out = self._predictive.step(t_s, state)
        self._s_proj = out.s_proj_m
        if out.phase == "finished":
            self._finished = True
            return self._finished_output(state, out.s_proj_m, out.crosstrack_m)
        return out

    def _a_achieved_estimate(self, t_s: float) -> float:
        """The inner loop's acceleration now, if it lags the commands by ``rollout_tau_s``."""
        tau = self.params.rollout_tau_s
        if tau <= 0 or self._t_cmd is None:
            return 0.0
        lag = math.exp(-max(t_s - self._t_cmd, 0.0) / tau)
        return self._a_cmd_prev + (self._a_est - self._a_cmd_prev) * lag

    def _remember_command(self, t_s: float, a_cmd: float) -> None:
        self._a_est = self._a_achieved_estimate(t_s)
        self._a_cmd_prev = a_cmd
        self._t_cmd = t_s

    def _finished_output(self, state: VehicleState, s_proj: float | None = None,
                         crosstrack: float | None = None) -> GuidanceOutput:
        if s_proj is None:
            s_proj = self.path.project(state.x_m, state.y_m, self._s_proj)
        if crosstrack is None:
            crosstrack = self.path.crosstrack_m(state.x_m, state.y_m, s_proj)
        predictive = self._predictive is not None  # no corrector weights: k1 = k2 = NaN
        return GuidanceOutput(a_cmd_m_s2=0.0, phase="finished", crosstrack_m=crosstrack,
                              s_proj_m=s_proj, k1=math.nan if predictive else self._k1,
                              k2=math.nan if predictive else self._k2)
