"""Online selection of the corrector gains k1, k2 (paper section III-B.3).

Every ``dt_online = min(d_limit, R_proj) / V`` seconds (``d_limit = d_limit_factor * L1``,
``R_proj`` the radius of curvature at the vehicle's projection), the paper's kinematics (eq. 1)
are rolled forward over ``dt_online`` for every candidate pair (k1, k2) and the pair with the
smallest RMS cross-track error over that window is kept until the next re-optimisation.

Only the ratio matters. The command is a weighted mean, so (k1, k2) and (c k1, c k2) give the
same command: the search is over ``rho = k2 / k1`` in ``[0, inf]``. Its useful range is wide,
because ``w2 / w1 = rho v_m k^2 (1 + l23) / (1 + l43)`` and the squared curvature ``k^2`` of a
path like the paper's sine runs from about 1e-6 to 2e-2 1/m^2: the candidates are spaced
logarithmically over ``RHO_LOG10_RANGE`` and include both pure ends, ``k2 = 0`` (constant L1)
and ``k1 = 0`` (the corrector alone), plus the previous optimum and four neighbours within half
a grid step of it (warm start: as the optimum drifts along the path, these follow it between the
grid points). All candidates are rolled out in one batch. A second, smaller batch then refines the
best finite ratio within one grid step on either side (``REFINE_OFFSETS``): the cost can dip
sharply between two grid points, and two flights whose states differ by centimetres must not
choose gains half a decade apart because the grid point on one side of the dip came out a
little cheaper in one and a little dearer in the other (docs/guidance.md, "The gains refined
between the grid points"). A ratio maps back to bounded gains: ``k1 = k1_max,
k2 = rho k1_max`` while that stays within ``k2_max``, else ``k2 = k2_max, k1 = k2_max / rho``.

With ``params.rollout_tau_s > 0`` the rollouts also model a first-order inner loop of that
time constant (started from the guidance's estimate of the achieved acceleration), so the gains
are chosen for the vehicle that will fly them; 0 (default) is the paper's ideal inner loop.

The rollouts of all candidates run at once (numpy arrays over candidates) with a rollout step
of at least the guidance tick and at most ``window / ROLLOUT_MAX_STEPS``; projection and
look-ahead points are tracked by Newton steps from the previous ones, which is exact enough over
the short window and much cheaper than a fresh search.
"""

from __future__ import annotations

import math

import numpy as np

from companion.geometry.paths import Path
from companion.guidance.corrector import corrector_command_vxy
from companion.guidance.types import GuidanceParams

#: Below this curvature (1/m) the path counts as straight for the search: there the corrector's
#: weight ``w2' = k2 v_m k^2 / (1 + l43)`` is at most 1e-11 of ``w1'`` for every candidate.
STRAIGHT_CURVATURE_1_M = 1e-9
RHO_LOG10_RANGE = (-1.0, 7.0)
RHO_COARSE_COUNT = 17  # log-spaced ratios in the first batch (half a decade apart)
WARM_OFFSETS = (-0.5, -0.25, 0.0, 0.25, 0.5)  # around the previous optimum, in grid steps
#: The second batch, around the first batch's best finite ratio, in grid steps.
REFINE_OFFSETS = (-0.75, -0.5, -0.25, -0.125, 0.125, 0.25, 0.5, 0.75)
ROLLOUT_MAX_STEPS = 20


def gains_from_ratio(rho: float, k1_max: float, k2_max: float) -> tuple[float, float]:
    """Bounded gains (k1, k2) with ``k2 / k1 = rho`` (``rho = inf`` gives ``(0, k2_max)``)."""
    if rho <= 0.0:
        return k1_max, 0.0
    if math.isinf(rho):
        return 0.0, k2_max
    if k1_max * rho <= k2_max:
        return k1_max, k1_max * rho
    return k2_max / rho, k2_max


def ratio_from_gains(k1: float, k2: float) -> float:
    if k2 <= 0.0:
        return 0.0
    if k1 <= 0.0:
        return math.inf
    return k2 / k1


class GainOptimiser:
    """Chooses (k1, k2) by rolling the kinematics forward for many candidates at once.

    Parameters
    ----------
    path : the reference path.
    params : guidance parameters (``l1_m``, ``rate_hz``, ``k1_max``, ``k2_max``,
        ``d_limit_factor`` are used).
    """

    def __init__(self, path: Path, params: GuidanceParams):
        self.path = path
        self.params = params
        lo, hi = RHO_LOG10_RANGE
        self._coarse_log10 = np.linspace(lo, hi, RHO_COARSE_COUNT)
        self._step_log10 = (hi - lo) / (RHO_COARSE_COUNT - 1)
        self._refine_log10 = self._step_log10 * np.array(REFINE_OFFSETS)

    def window_s(self, s_proj_m: float, speed_m_s: float) -> float:
        """``min(d_limit, R_proj) / V``: the rollout horizon and the time until the next re-optimisation."""
        k = abs(self.path.curvature(s_proj_m))
        r_proj = math.inf if k < 1e-12 else 1.0 / k
        d_online = min(self.params.d_limit_factor * self.params.l1_m, r_proj)
        return d_online / max(speed_m_s, 1e-3)

    def _rollout_steps(self, window_s: float) -> int:
        """Rollout steps over a window: one per guidance tick, at most ``ROLLOUT_MAX_STEPS``."""
        return max(1, min(ROLLOUT_MAX_STEPS, int(math.ceil(window_s * self.params.rate_hz))))

    def optimise(self, x_m: float, y_m: float, course_rad: float, speed_m_s: float,
                 s_proj_m: float, s_look_m: float, warm_ratio: float | None = None,
                 a_achieved_m_s2: float = 0.0) -> tuple[float, float, float]:
        """Best gains for the coming window.

        ``a_achieved_m_s2`` is the inner loop's current lateral acceleration, the start of the
        rollouts' first-order lag when ``params.rollout_tau_s > 0`` (unused otherwise).

        Returns
        -------
        (k1, k2, window_s)
        """
        p = self.params
        window = self.window_s(s_proj_m, speed_m_s)
        # A straight reach: wherever the rollouts can take the look-ahead point (each rollout
        # step moves it by V dt plus a Newton correction of at most 2 m), the corrector weighs
        # nothing and every candidate flies constant L1; the search cannot tell them apart, so it
        # is skipped and the gains say what is flown: k2 = 0.
        n_steps = self._rollout_steps(window)
        reach = max(s_look_m, s_proj_m) + speed_m_s * window + 2.0 * n_steps
        if self.path.max_abs_curvature(min(s_proj_m, s_look_m), reach) < STRAIGHT_CURVATURE_1_M:
            return p.k1_max, 0.0, window
        # One batch: both pure ends, the log grid, and the previous optimum with neighbours
        # a quarter and an eighth of the grid step away on each side (the warm start refines).
        finite = list(10.0 ** self._coarse_log10)
        if warm_ratio is not None and 0.0 < warm_ratio < math.inf:
            lw = math.log10(warm_ratio)
            finite += [10.0 ** (lw + f * self._step_log10) for f in WARM_OFFSETS]
        rhos = np.array([0.0] + finite + [math.inf])
        state = (x_m, y_m, course_rad, speed_m_s, s_proj_m, s_look_m, window, a_achieved_m_s2)
        cost = self._rollout_cost(rhos, *state)
        i = int(np.argmin(cost))
        best_rho, best_cost = float(rhos[i]), float(cost[i])
        if 0.0 < best_rho < math.inf:
            near = 10.0 ** (math.log10(best_rho) + self._refine_log10)
            near_cost = self._rollout_cost(near, *state)
            j = int(np.argmin(near_cost))
            if near_cost[j] < best_cost:
                best_rho = float(near[j])
        k1, k2 = gains_from_ratio(best_rho, p.k1_max, p.k2_max)
        return k1, k2, window

    def _rollout_cost(self, rhos: np.ndarray, x_m: float, y_m: float, course_rad: float,
                      speed_m_s: float, s_proj_m: float, s_look_m: float, window_s: float,
                      a_achieved_m_s2: float = 0.0) -> np.ndarray:
        """Mean squared cross-track error over the window for each candidate ratio."""
        p = self.params
        path = self.path
        gains = np.array([gains_from_ratio(float(r), p.k1_max, p.k2_max) for r in rhos])
        k1, k2 = gains[:, 0], gains[:, 1]
        m = rhos.size
        V = speed_m_s
        l1 = p.l1_m
        l1sq = l1 * l1
        n_steps = self._rollout_steps(window_s)
        dt = window_s / n_steps
        x = np.full(m, x_m)
        y = np.full(m, y_m)
        psi = np.full(m, course_rad)
        s_p = np.full(m, s_proj_m)
        s_l = np.full(m, max(s_look_m, s_proj_m))
        s_max = math.inf if path.closed else path.length_m
        sq_sum = np.zeros(m)
        tau = p.rollout_tau_s
        lag = math.exp(-dt / tau) if tau > 0 else 0.0
        mean_factor = tau / dt * (1.0 - lag) if tau > 0 else 0.0
        a_ach = np.full(m, a_achieved_m_s2)
        vdt = V * dt
        frame = path.frame_array
        # cos and sin of the course: the unicycle step below yields the next ones, so each step
        # costs one cos and one sin for the whole batch.
        c_psi, s_psi = np.cos(psi), np.sin(psi)
        # The projection's frame at the end of a step and the look-ahead's starting frame of the
        # next one are independent: one frame_array call on both halves of a 2m-array serves
        # both (it is elementwise, so each half is what its own call would give).
        s_l = np.maximum(s_l + vdt, s_p)
        both = frame(np.concatenate((s_p, s_l)))
        for _ in range(n_steps):
            px, py, tx, ty, k = (v[:m] for v in both)
            lx, ly, ltx, lty = (v[m:] for v in both[:4])
            # Look-ahead: Newton on |p(s) - q|^2 = L1^2 from the previous one, kept ahead of
            # the projection; one step per rollout step is enough as it moves ~V dt between them.
            ex, ey = lx - x, ly - y
            f = ex * ex + ey * ey - l1sq
            df = np.maximum(2.0 * (ex * ltx + ey * lty), 0.5 * l1)
            s_l = np.minimum(np.maximum(s_l - np.minimum(np.maximum(f / df, -2.0), 2.0), s_p), s_max)
            lx, ly, ltx, lty, lk = frame(s_l)
            a = corrector_command_vxy(x, y, c_psi, s_psi, V, l1, px, py, tx, ty, lx, ly, ltx, lty, lk, k1, k2)
            if tau > 0:
                # First-order inner loop, exact over the step; the step uses its mean.
                a, a_ach = a + (a_ach - a) * mean_factor, a + (a_ach - a) * lag
            # Exact unicycle step for a constant turn rate (eq. 1).
            w = a / V
            dpsi = w * dt
            psi_new = psi + dpsi
            c_new, s_new = np.cos(psi_new), np.sin(psi_new)
            small = np.abs(dpsi) < 1e-9
            w_safe = np.where(small, 1.0, w)
            x = x + np.where(small, vdt * c_psi, V / w_safe * (s_new - s_psi))
            y = y + np.where(small, vdt * s_psi, -V / w_safe * (c_new - c_psi))
            psi, c_psi, s_psi = psi_new, c_new, s_new
            # Projection after the step: one Newton step on (p(s) - q) . t(s) = 0 from the
            # previous projection (the vehicle moved V dt), then the cross-track error there.
            dx, dy = px - x, py - y
            g = dx * tx + dy * ty
            dg = np.maximum(1.0 + k * (dy * tx - dx * ty), 0.2)
            s_p = np.minimum(np.maximum(s_p - g / dg, 0.0), s_max)
            s_l = np.maximum(s_l + vdt, s_p)
            both = frame(np.concatenate((s_p, s_l)))
            ex, ey = both[0][:m] - x, both[1][:m] - y
            sq_sum += ex * ex + ey * ey
        return sq_sum / n_steps
