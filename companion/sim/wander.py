"""A velocity-estimate bias that wanders more while the vehicle manoeuvres: its model and its fit.

The autopilot's velocity estimate is off by a bias ``b`` that the velocity loop flies, so the
reported position leaves the integral of the reported velocity by the integral of ``b``
(docs/vehicle_model.md). On ArduCopter SITL that bias wanders three times as fast while the
acceleration changes (a capture, a sine) as on a straight leg or in a steady turn. The model, on
each horizontal axis, is a first-order Gauss-Markov process whose level follows the manoeuvre::

    b[i+1] = phi b[i] + sigma_i sqrt(1 - phi^2) w[i],        phi = exp(-dt / tc_s),  w ~ N(0, 1)
    sigma_i^2 = sigma_m_s^2 + (jerk_gain_s2 * min(j_i, jerk_max_m_s3))^2

``sigma_i`` is the level the bias would settle to if the jerk ``j_i`` were held; ``j`` is the
**manoeuvre jerk** (:func:`manoeuvre_jerk_m_s3`): the rate of change of the horizontal
acceleration vector, ``|d a / dt|``, through a first-order low-pass of :data:`JERK_TC_S`. With
``jerk_gain_s2 = 0`` it is the plain bias ``vel_bias_m_s`` / ``vel_bias_tc_s`` of the
``vehicle:`` block.

The fit (:func:`fit_jerk_wander`)
---------------------------------
The drift ``e`` (position minus the integral of velocity) changes over a window of ``K`` samples
by ``dt`` times the sum of ``b`` over it. Its variance is linear in ``sigma_m_s^2`` and
``jerk_gain_s2^2``, each weighted by what the process's filter makes of the flight's own
``sigma_i^2`` history before and inside the window (:func:`window_variance`). So the two squares
are a non-negative weighted least squares of the windows' squared changes (iterated to the
Gaussian likelihood, each squared change weighted by its expected variance), at the correlation
time given (the bias's own, fitted by ``companion.sim.identify``), for each cap
``jerk_max_m_s3`` of :data:`JERK_MAX_GRID_M_S3`, the likeliest cap kept.

Pure numpy/scipy: arrays in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls
from scipy.signal import lfilter

#: Time constant of the low-pass that turns ``|d a / dt|`` into the manoeuvre jerk (s). The mock
#: (``sitl_mock.vehicle``) computes its jerk with the same constant.
JERK_TC_S = 0.5
#: Windows over which the drift's changes are fitted (s): shorter than the correlation time, where
#: the changes follow the jerk of their own second, and as long, where they carry its past.
WANDER_WINDOWS_S = (0.5, 1.0, 2.0)
#: Caps of the jerk tried (m/s^3); ArduCopter SITL's wander stops growing at about 1.2.
JERK_MAX_GRID_M_S3 = (0.4, 0.6, 0.8, 1.0, 1.2, 1.5, 2.0, 3.0, 5.0)
IRLS_ROUNDS = 12
BOOTSTRAP_RUNS = 30  # drifts drawn from the fitted process for the standard errors
BOOTSTRAP_SEED = 0


@dataclass(frozen=True)
class JerkWander:
    """A fitted wander (see the module docstring); ``se_*`` are 1-sigma standard errors
    (:func:`fit_jerk_wander`)."""

    sigma_m_s: float
    jerk_gain_s2: float
    jerk_max_m_s3: float
    tc_s: float
    se_sigma_m_s: float
    se_jerk_gain_s2: float
    windows: int  # squared changes fitted (each axis counts)


def manoeuvre_jerk_m_s3(acc_ne_m_s2: np.ndarray, dt_s: float, tc_s: float = JERK_TC_S) -> np.ndarray:
    """The manoeuvre jerk on a uniform grid: ``|d a / dt|`` of the horizontal acceleration
    (``(N, 2)``, m/s^2, step ``dt_s``), low-passed causally with time constant ``tc_s``.

    >>> t = np.arange(0.0, 10.0, 0.02)
    >>> acc = np.column_stack([0.3 * t, np.zeros_like(t)])       # a steady 0.3 m/s^3
    >>> round(float(manoeuvre_jerk_m_s3(acc, 0.02)[-1]), 6)
    0.3
    """
    acc = np.asarray(acc_ne_m_s2, float)
    raw = np.zeros(len(acc))
    raw[1:] = np.hypot(*(np.diff(acc, axis=0) / dt_s).T)
    if len(raw) > 1:
        raw[0] = raw[1]
    alpha = 1.0 - math.exp(-dt_s / tc_s)
    zi = [(1.0 - alpha) * raw[0]] if len(raw) else [0.0]
    return np.asarray(lfilter([alpha], [1.0, -(1.0 - alpha)], raw, zi=zi)[0], float)


def window_variance(level2: np.ndarray, dt_s: float, tc_s: float, k: int) -> np.ndarray:
    """Variance of the drift's change over ``k`` samples, ``e[n + k] - e[n]``, for each start ``n``
    (``len(level2) - k`` of them), for a bias whose squared level is ``level2[i]`` at step ``i``
    (the process of the module docstring, its past before the first sample held at ``level2[0]``;
    ``e[n] = dt * sum(b[:n])``).

    A constant level ``sigma^2`` gives ``2 sigma^2 tc^2 (T / tc - 1 + exp(-T / tc))`` for
    ``T = k dt`` much longer than ``dt`` (the closed form of ``companion.sim.identify.velocity_bias``).
    """
    x = np.asarray(level2, float)
    n = len(x) - k
    if k < 1 or n < 1:
        return np.zeros(0)
    phi = math.exp(-dt_s / tc_s)
    p2 = phi * phi
    scale = dt_s * dt_s * (1.0 - p2) / (1.0 - phi) ** 2
    # kicks before the window: sum_{i <= n - 1} phi^(2 (n - 1 - i)) level2[i], the past held at level2[0]
    before = x[0] / (1.0 - p2)
    y = lfilter([1.0], [1.0, -p2], x, zi=[p2 * before])[0]
    past = np.concatenate([[before], y[:-1]])[:n] * (1.0 - phi ** k) ** 2
    # kicks inside it: sum_{r = 0}^{k - 2} (1 - phi^(k - 1 - r))^2 level2[n + r]
    inside = np.zeros(n)
    if k >= 2:
        h = (1.0 - phi ** (k - 1 - np.arange(k - 1))) ** 2
        inside = np.correlate(x, h, mode="valid")[:n]
    return np.asarray(scale * (past + inside), float)


def usable_pairs(ok: np.ndarray, k: int) -> np.ndarray:
    """Where a pair of samples ``k`` apart can be used: both valid and no invalid sample between
    them (``k < len(ok)``)."""
    breaks = np.cumsum(~ok)
    return np.asarray(ok[:-k] & ok[k:] & (breaks[k:] == breaks[:-k]), bool)


def _rows(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], dt_s: float, tc_s: float,
          jerk_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Regressors ``(X, d2)``: per window (half-overlapping) and axis, the variance terms of
    ``sigma^2`` and ``gain^2``, and the squared change."""
    xs, ds = [], []
    for window_s in WANDER_WINDOWS_S:
        k = max(1, int(round(window_s / dt_s)))
        for e, ok, jerk in segments:
            if len(ok) <= k:
                continue
            use = usable_pairs(ok, k)
            use[np.arange(len(use)) % max(1, k // 2) != 0] = False  # windows half-overlapping
            j2 = np.minimum(jerk, jerk_max) ** 2
            x = np.column_stack([window_variance(np.ones(len(ok)), dt_s, tc_s, k),
                                 window_variance(j2, dt_s, tc_s, k)])[use]
            d = (e[k:] - e[:-k])[use]
            for col in range(d.shape[1]):
                xs.append(x)
                ds.append(d[:, col] ** 2)
    if not xs:
        return np.zeros((0, 2)), np.zeros(0)
    return np.vstack(xs), np.concatenate(ds)


def _likeliest(x: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative ``(sigma^2, gain^2)`` maximising the Gaussian likelihood of the squared
    changes (iteratively reweighted least squares) and its negative log-likelihood."""
    p, _ = nnls(x, d2)
    floor = 1e-6 * max(float(np.mean(d2)), 1e-300)
    for _ in range(IRLS_ROUNDS):
        expected = np.maximum(x @ p, floor)
        p, _ = nnls(x / expected[:, None], d2 / expected)
    expected = np.maximum(x @ p, floor)
    return p, float(np.sum(np.log(expected) + d2 / expected))


def fit_jerk_wander(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], dt_s: float,
                    tc_s: float) -> JerkWander | None:
    """Fit the wander (module docstring) to drifts ``e`` (``(N, axes)``, m), their valid samples
    ``ok`` and manoeuvre jerks ``(N,)`` (m/s^3), one triple per flight on the grid ``dt_s``, at
    the bias's correlation time ``tc_s``. None when fewer than 50 windows can be used.

    The standard errors are a parametric bootstrap's (seeded): the spread of the same fit on
    :data:`BOOTSTRAP_RUNS` drifts drawn from the fitted process over the same samples and jerks.
    Where the flights cannot tell the still level from the jerk's share (a log that manoeuvres
    throughout), the draws trade one for the other and both errors come out large.
    """
    best = _fit_on_grid(segments, dt_s, tc_s)
    if best is None:
        return None
    p, jerk_max, windows = best
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    draws = []
    for _ in range(BOOTSTRAP_RUNS):
        drawn = [(_draw_drift(rng, ok, jerk, p, jerk_max, dt_s, tc_s, e.shape[1]), ok, jerk) for e, ok, jerk in segments]
        fit = _fit_on_grid(drawn, dt_s, tc_s)
        if fit is not None:
            draws.append(np.sqrt(fit[0]))
    se = np.std(np.array(draws), axis=0, ddof=1) if len(draws) > 2 else np.full(2, math.inf)
    sigma, gain = (float(v) for v in np.sqrt(p))
    if gain <= 0.0:
        jerk_max = JERK_MAX_GRID_M_S3[0]  # no jerk term: its cap means nothing
    return JerkWander(sigma_m_s=sigma, jerk_gain_s2=gain, jerk_max_m_s3=jerk_max, tc_s=tc_s,
                      se_sigma_m_s=float(se[0]), se_jerk_gain_s2=float(se[1]), windows=windows)


def _fit_on_grid(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], dt_s: float,
                 tc_s: float) -> tuple[np.ndarray, float, int] | None:
    """``(sigma^2, gain^2)``, the cap and the number of windows of the likeliest cap; None when
    fewer than 50 windows can be used."""
    best = None
    for jerk_max in JERK_MAX_GRID_M_S3:
        x, d2 = _rows(segments, dt_s, tc_s, jerk_max)
        if len(d2) < 50:
            return None
        p, nll = _likeliest(x, d2)
        if best is None or nll < best[1] - 1e-9:
            best = (p, nll, jerk_max, len(d2))
    assert best is not None
    return best[0], best[2], best[3]


def _draw_drift(rng: np.random.Generator, ok: np.ndarray, jerk: np.ndarray, p: np.ndarray, jerk_max: float,
                dt_s: float, tc_s: float, axes: int) -> np.ndarray:
    """A drift drawn from the process ``(sigma^2, gain^2) = p`` over a flight's jerks (module
    docstring), started at its level."""
    phi = math.exp(-dt_s / tc_s)
    level = np.sqrt(p[0] + p[1] * np.minimum(jerk, jerk_max) ** 2)[:, None]
    kicks = rng.standard_normal((len(ok), axes)) * level * math.sqrt(1.0 - phi * phi)
    kicks[0] = rng.standard_normal(axes) * level[0]
    b = np.asarray(lfilter([1.0], [1.0, -phi], kicks, axis=0), float)
    e = np.zeros_like(b)
    e[1:] = np.cumsum(b[:-1], axis=0) * dt_s
    return e
