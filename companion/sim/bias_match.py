"""The velocity bias a simulator should fly, matched through the estimator that measures it.

:func:`companion.sim.identify.pooled_across_track_bias` fits a first-order Gauss-Markov bias
(``sigma``, ``tau``) to the drift that flights of about a minute show. On such flights that fit is
biased: a bias that wanders over many seconds looks, over one minute, partly like a constant
offset and a turn of the velocity, which :func:`companion.sim.identify.velocity_offset` takes
out, and the fitted ``tau`` comes out short. Measured on the mock's own PX4 flights, which fly a
known 0.259 m/s over 4.54 s, it gave 0.219 m/s over 2.2 s. Setting a simulator to the fit of
real flights therefore does not make its flights *measure* like the real ones.

This module matches what is measured instead (indirect inference). For each candidate ``tau``, a
bias of that correlation time is drawn on both axes (``runs`` times) and integrated into each
real flight's own track (its reported velocities unchanged, so only the drift is synthetic).
The drift left after :func:`~companion.sim.identify.velocity_offset` takes out the offset and
the turn is measured as the real one is: the RMS change over the lags :data:`MATCH_LAGS_S`,
pooled over the flights. The expected structure is linear in ``sigma``, so each ``tau`` gets its
``sigma`` by least squares in log space. The ``tau`` whose structure fits best is kept, with its
``sigma``. Pure: arrays in, numbers out; seeded, so the same flights give the same answer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from companion.sim.identify import (ACROSS_MIN_SPEED_M_S, Samples, gauss_markov_drift, velocity_integral,
                                   velocity_offset)
from companion.sim.wander import usable_pairs

#: Lags (s) at which the drift left after the offset and turn is compared.
MATCH_LAGS_S = (0.5, 1.0, 2.0, 5.0)
#: Candidate correlation times (s).
MATCH_TAUS_S = (1.0, 1.5, 2.0, 3.0, 4.5, 6.0, 7.0, 8.0, 9.0, 10.0, 12.0, 15.0, 20.0)


@dataclass(frozen=True)
class BiasMatch:
    """The matched bias and how well it fits.

    sigma_m_s, tau_s : the Gauss-Markov bias whose measured structure fits the flights' best.
    measured_m : the flights' structure, RMS drift change (m) at each of :data:`MATCH_LAGS_S`.
    expected_m : the matched bias's expected structure at the same lags.
    misfit_by_tau : log-RMS misfit of each candidate ``tau`` (with its own best ``sigma``).
    """

    sigma_m_s: float
    tau_s: float
    measured_m: tuple[float, ...]
    expected_m: tuple[float, ...]
    misfit_by_tau: dict[float, float]


def _rest(f: Samples, pos_ne_m: np.ndarray, min_speed_m_s: float) -> tuple[np.ndarray, np.ndarray, float]:
    _, _, rest, ok, dt = velocity_offset(f.t_s, pos_ne_m, f.vel_ne_m_s, f.valid, f.t_autopilot_s, min_speed_m_s)
    return rest[:, 0], ok, dt


def _structure(rests: list[tuple[np.ndarray, np.ndarray, float]]) -> np.ndarray:
    """RMS change at each lag, every usable pair of every flight pooled (no pair spans two flights)."""
    out = []
    for lag in MATCH_LAGS_S:
        squares, count = 0.0, 0
        for rest, ok, dt in rests:
            k = int(round(lag / dt))
            if k < 1 or k >= rest.size:
                continue
            use = usable_pairs(ok, k)
            d = (rest[k:] - rest[:-k])[use]
            squares += float(d @ d)
            count += d.size
        out.append(math.sqrt(squares / count) if count else math.nan)
    return np.array(out)


def measured_structure(flights: list[Samples], min_speed_m_s: float = ACROSS_MIN_SPEED_M_S) -> np.ndarray:
    """How the flights' velocity bias is measured here: the RMS change of the drift across the
    track left after :func:`~companion.sim.identify.velocity_offset` takes out the offset and the
    turn, at each of :data:`MATCH_LAGS_S`, every usable pair of every flight pooled (m)."""
    if any(f.pos_ne_m is None for f in flights):
        raise ValueError("bias structure: a flight has no positions")
    return _structure([_rest(f, np.asarray(f.pos_ne_m, float), min_speed_m_s) for f in flights])


def expected_structure(flights: list[Samples], tau_s: float, runs: int = 20, seed: int = 0,
                       min_speed_m_s: float = ACROSS_MIN_SPEED_M_S) -> np.ndarray:
    """The structure a unit bias (``sigma`` = 1 m/s) of correlation time ``tau_s`` is expected to
    show on these flights' tracks, measured as :func:`match_bias` measures the flights (RMS over
    ``runs`` seeded draws)."""
    rng = np.random.default_rng(seed)
    tracks = [velocity_integral(f.t_s, f.vel_ne_m_s, f.t_autopilot_s) for f in flights]
    squares = np.zeros(len(MATCH_LAGS_S))
    for _ in range(runs):
        rests = []
        for f, track in zip(flights, tracks):
            drift = gauss_markov_drift(rng, track.shape, 1.0, tau_s, float(f.t_s[1] - f.t_s[0]))
            rests.append(_rest(f, track + drift, min_speed_m_s))
        squares += _structure(rests) ** 2
    return np.sqrt(squares / runs)


def match_bias(flights: list[Samples], taus_s: tuple[float, ...] = MATCH_TAUS_S, runs: int = 150, seed: int = 0,
               min_speed_m_s: float = ACROSS_MIN_SPEED_M_S) -> BiasMatch:
    """The Gauss-Markov bias whose flights would measure like these (module docstring).
    ValueError when there are no flights or one has no positions."""
    if not flights:
        raise ValueError("match bias: expected at least one flight, got none")
    measured = measured_structure(flights, min_speed_m_s)
    good = np.isfinite(measured) & (measured > 0)
    if good.sum() < 2:
        raise ValueError("match bias: the flights hold too few usable pairs of samples")
    best: tuple[float, float, float, np.ndarray] | None = None
    misfit: dict[float, float] = {}
    for tau in taus_s:
        unit = expected_structure(flights, tau, runs, seed, min_speed_m_s)
        log_ratio = np.log(measured[good] / unit[good])
        sigma = math.exp(float(np.mean(log_ratio)))
        misfit[tau] = float(np.sqrt(np.mean((log_ratio - math.log(sigma)) ** 2)))
        if best is None or misfit[tau] < best[2]:
            best = (sigma, tau, misfit[tau], sigma * unit)
    assert best is not None
    sigma, tau, _, expected = best
    return BiasMatch(sigma, tau, tuple(float(v) for v in measured), tuple(float(v) for v in expected), misfit)
