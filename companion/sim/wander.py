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
``vehicle:`` block. The vehicle may fly ``b`` through a first-order low-pass of time constant
``smooth_s`` (``vel_bias_smooth_s``, :func:`smooth_bias`; 0: ``b`` as it is): ArduCopter SITL's
drift, given the changes over 0.5-2 s that a first-order bias fitted to them has, is smoother
within those seconds (:func:`fit_smoothing`).

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
#: Smoothing times of the bias tried by :func:`fit_smoothing` (s); 0 is the first-order process.
SMOOTH_GRID_S = tuple(round(0.1 * i, 1) for i in range(16))
#: The drift's fast part: what a centred moving average over this long leaves (s).
FAST_WINDOW_S = 2.0
SMOOTH_DRAWS = 20  # drifts drawn per smoothing tried
SMOOTH_SEED = 0
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


def window_variance(level2: np.ndarray, dt_s: float, tc_s: float, k: int, smooth_s: float = 0.0) -> np.ndarray:
    """Variance of the drift's change over ``k`` samples, ``e[n + k] - e[n]``, for each start ``n``
    (``len(level2) - k`` of them), for a bias whose squared level is ``level2[i]`` at step ``i``
    (the process of the module docstring, its past before the first sample held at ``level2[0]``;
    ``e[n] = dt * sum(b[:n])``), smoothed over ``smooth_s`` (:func:`smooth_bias`; 0: not).

    A constant level ``sigma^2`` gives ``2 sigma^2 tc^2 (T / tc - 1 + exp(-T / tc))`` for
    ``T = k dt`` much longer than ``dt`` (the closed form of ``companion.sim.identify.velocity_bias``).
    """
    x = np.asarray(level2, float)
    n = len(x) - k
    if k < 1 or n < 1:
        return np.zeros(0)
    if smooth_s > 0.0:
        return _smoothed_window_variance(x, dt_s, tc_s, k, smooth_s)
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


def _smoothed_window_variance(x: np.ndarray, dt_s: float, tc_s: float, k: int, smooth_s: float) -> np.ndarray:
    """:func:`window_variance` of a smoothed bias, from the impulse response: the kick sized by
    ``level2[i]`` enters ``b[i + 1]``, the smoothed bias follows it as :func:`smooth_bias`, and the
    window's change weighs it by ``dt`` times the response summed over the window. The past before
    the first sample is held at ``level2[0]`` for as long as the response lasts (twelve times both
    time constants)."""
    phi = math.exp(-dt_s / tc_s)
    a = 1.0 - math.exp(-dt_s / smooth_s)
    past = int(math.ceil(12.0 * (tc_s + smooth_s) / dt_s))
    j = np.arange(past + k + 1)
    response = np.where(j >= 1, phi ** np.maximum(j - 1, 0), 0.0)  # b[i + j] for a unit kick at i
    response = lfilter([a], [1.0, -(1.0 - a)], response)
    cum = np.concatenate([[0.0], np.cumsum(response)])
    d = np.arange(-(k - 1), past + 1)  # window start minus kick index
    weight2 = (dt_s * (cum[np.maximum(0, d + k)] - cum[np.maximum(0, d)])) ** 2
    kicks = np.concatenate([np.full(past, x[0]), x]) * (1.0 - phi * phi)
    full = np.convolve(kicks, weight2)  # full[m] = sum_q kicks[m - q] weight2[q], q = d + k - 1
    return np.asarray(full[past + k - 1:past + k - 1 + len(x) - k], float)


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
                dt_s: float, tc_s: float, axes: int, smooth_s: float = 0.0) -> np.ndarray:
    """A drift drawn from the process ``(sigma^2, gain^2) = p`` over a flight's jerks (module
    docstring), started at its level, its bias smoothed over ``smooth_s`` (:func:`smooth_bias`)."""
    phi = math.exp(-dt_s / tc_s)
    level = np.sqrt(p[0] + p[1] * np.minimum(jerk, jerk_max) ** 2)[:, None]
    kicks = rng.standard_normal((len(ok), axes)) * level * math.sqrt(1.0 - phi * phi)
    kicks[0] = rng.standard_normal(axes) * level[0]
    b = smooth_bias(np.asarray(lfilter([1.0], [1.0, -phi], kicks, axis=0), float), dt_s, smooth_s)
    e = np.zeros_like(b)
    e[1:] = np.cumsum(b[:-1], axis=0) * dt_s
    return e


def smooth_bias(bias: np.ndarray, dt_s: float, smooth_s: float) -> np.ndarray:
    """The bias (``(N, axes)``, one row per step ``dt_s``) through a first-order low-pass of time
    constant ``smooth_s``, started at its first row: ``s[i] = s[i-1] + a (b[i] - s[i-1])``, ``a = 1 -
    exp(-dt / smooth_s)``, as the mock steps it. ``smooth_s = 0``: the bias itself."""
    b = np.asarray(bias, float)
    if smooth_s <= 0.0 or not len(b):
        return b
    a = 1.0 - math.exp(-dt_s / smooth_s)
    return np.asarray(lfilter([a], [1.0, -(1.0 - a)], b, axis=0, zi=(1.0 - a) * b[:1])[0], float)


def drift_moments(e: np.ndarray, ok: np.ndarray, dt_s: float) -> np.ndarray:
    """``[sum of squares, count]`` of the drift's fast part and of its changes over 1 s, pooled over
    its axes: ``[[fast2, n_fast], [change2, n_change]]``.

    The fast part is what a centred moving average over :data:`FAST_WINDOW_S` (an odd number of
    samples) leaves, inside each run of valid samples at least three windows long (a window's
    length cut from both ends); the changes are those over 1 s within a run."""
    e2 = np.asarray(e, float).reshape(len(ok), -1)
    n = 2 * int(round(FAST_WINDOW_S / dt_s / 2.0)) + 1  # odd: the average centred on a sample
    k = max(1, int(round(1.0 / dt_s)))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(ok, int), [0]])))
    out = np.zeros((2, 2))
    for start, stop in zip(edges[::2], edges[1::2]):
        x = e2[start:stop]
        if len(x) < 3 * n:
            continue
        mean = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x]), axis=0)
        centred = (mean[n:] - mean[:-n]) / n  # the mean of x[i:i + n], centred on i + n // 2
        fast = (x[n // 2:n // 2 + len(centred)] - centred)[n:-n]
        change = x[k:] - x[:-k]
        out += [[float(np.sum(fast ** 2)), fast.size], [float(np.sum(change ** 2)), change.size]]
    return out


def model_moments(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], dt_s: float, wander: JerkWander,
                  smooth_s: float, draws: int = SMOOTH_DRAWS, seed: int = SMOOTH_SEED) -> tuple[float, float]:
    """``(fast, change)``: the RMS fast part and 1-s change (:func:`drift_moments`) of ``draws``
    drifts drawn from the wander, smoothed over ``smooth_s``, over each segment's own valid samples
    and jerks (segments as :func:`fit_jerk_wander`'s; seeded)."""
    rng = np.random.default_rng(seed)
    p = np.array([wander.sigma_m_s ** 2, wander.jerk_gain_s2 ** 2])
    total = np.zeros((2, 2))
    for _ in range(draws):
        for e, ok, jerk in segments:
            axes = np.asarray(e).reshape(len(ok), -1).shape[1]
            drawn = _draw_drift(rng, ok, jerk, p, wander.jerk_max_m_s3, dt_s, wander.tc_s, axes, smooth_s)
            total += drift_moments(drawn, ok, dt_s)
    fast, change = np.sqrt(total[:, 0] / total[:, 1])
    return float(fast), float(change)


@dataclass(frozen=True)
class BiasSmoothing:
    """What :func:`fit_smoothing` found: the bias's smoothing time (s) and the factor on the
    wander's levels that gives back the drift's changes over 1 s; the measured and the fitted
    process's ratio of the drift's fast part to those changes."""

    smooth_s: float
    level_scale: float
    ratio_measured: float
    ratio_model: float


def fit_smoothing(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], dt_s: float,
                  wander: JerkWander) -> BiasSmoothing | None:
    """The smoothing of a fitted wander's bias (:func:`smooth_bias`) that gives back the drifts'
    fast part (:func:`drift_moments`): segments as :func:`fit_jerk_wander`'s.

    A first-order bias fitted to the drift's changes over 0.5-2 s can wander faster within those
    seconds than the log's does (ArduCopter SITL's: docs/vehicle_model.md). The ratio of the fast
    part to the 1-s changes does not depend on the levels; for each smoothing of
    :data:`SMOOTH_GRID_S` it is measured on :data:`SMOOTH_DRAWS` drifts drawn over the flights' own
    valid samples and jerks (the same draws for every smoothing), and the smoothing whose ratio
    lies nearest the log's (in log ratio) is kept; ``level_scale`` then restores the 1-s changes.
    None when the segments hold no fast part to measure.
    """
    measured = sum((drift_moments(e, ok, dt_s) for e, ok, _ in segments), np.zeros((2, 2)))
    if measured[0, 1] == 0 or measured[1, 1] == 0 or measured[0, 0] <= 0.0:
        return None
    fast, change = np.sqrt(measured[:, 0] / measured[:, 1])
    best = None
    for smooth_s in SMOOTH_GRID_S:
        m_fast, m_change = model_moments(segments, dt_s, wander, smooth_s)
        miss = abs(math.log((m_fast / m_change) / (fast / change)))
        if best is None or miss < best[0] - 1e-12:
            best = (miss, BiasSmoothing(smooth_s=smooth_s, level_scale=float(change / m_change),
                                        ratio_measured=float(fast / change), ratio_model=float(m_fast / m_change)))
    assert best is not None
    return best[1]
