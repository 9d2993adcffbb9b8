"""Tracking metrics shared by every command that reports figures (sim, fly, demo, replay, bench).

One definition, one set of names: ``d_rms_m``, ``d_max_m``, ``a_rms_m_s2``, ``a_max_m_s2``,
``duration_s``, ``samples``, and ``phases`` (the same keys per guidance phase).

All series are sampled once per guidance tick (uniform weighting per tick):

- ``d_rms_m``    sqrt(mean(d^2)), d the cross-track error (distance to the closest path point)
- ``d_max_m``    max |d|
- ``a_rms_m_s2`` sqrt(mean(a^2)), a the commanded lateral acceleration
- ``a_max_m_s2`` max |a|
- ``duration_s`` last time minus first time (0 for fewer than two samples)
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

#: The row name of the whole-flight figures in every metrics table (sim, fly, demo, replay).
OVERALL_ROW = "overall"

METRIC_KEYS = ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "duration_s", "samples")


def _summary(t_s: np.ndarray, d_m: np.ndarray, a_m_s2: np.ndarray) -> dict:
    n = int(t_s.size)
    if n == 0:
        return {"d_rms_m": math.nan, "d_max_m": math.nan, "a_rms_m_s2": math.nan,
                "a_max_m_s2": math.nan, "duration_s": 0.0, "samples": 0}
    return {
        "d_rms_m": float(np.sqrt(np.mean(d_m * d_m))),
        "d_max_m": float(np.max(np.abs(d_m))),
        "a_rms_m_s2": float(np.sqrt(np.mean(a_m_s2 * a_m_s2))),
        "a_max_m_s2": float(np.max(np.abs(a_m_s2))),
        "duration_s": float(t_s[-1] - t_s[0]) if n > 1 else 0.0,
        "samples": n,
    }


def tracking_metrics(
    t_s: Sequence[float],
    crosstrack_m: Sequence[float],
    a_cmd_m_s2: Sequence[float],
    phase: Sequence[str] | None = None,
) -> dict:
    """Overall and per-phase tracking metrics of one flight (simulated, flown or replayed).

    Parameters
    ----------
    t_s, crosstrack_m, a_cmd_m_s2 : sequences of equal length, one entry per guidance tick.
    phase : optional phase name per tick (e.g. ``"midcourse"``, ``"close_range"``).

    Returns
    -------
    dict with :data:`METRIC_KEYS` and ``phases``: ``{name: {METRIC_KEYS...}}`` in order of
    first appearance (empty when ``phase`` is None).

    Examples
    --------
    >>> m = tracking_metrics([0.0, 1.0], [3.0, 4.0], [0.0, 2.0], ["close_range"] * 2)
    >>> round(m["d_rms_m"], 6), m["a_max_m_s2"], m["duration_s"]
    (3.535534, 2.0, 1.0)
    """
    t = np.asarray(t_s, dtype=float)
    d = np.asarray(crosstrack_m, dtype=float)
    a = np.asarray(a_cmd_m_s2, dtype=float)
    if not (t.shape == d.shape == a.shape):
        raise ValueError(f"series lengths differ: t {t.shape}, d {d.shape}, a {a.shape}")
    out = _summary(t, d, a)
    phases: dict[str, dict] = {}
    if phase is not None:
        names = np.asarray(list(phase), dtype=object)
        if names.shape != t.shape:
            raise ValueError(f"phase length {names.shape} differs from t {t.shape}")
        for name in dict.fromkeys(names.tolist()):
            mask = names == name
            phases[str(name)] = _summary(t[mask], d[mask], a[mask])
    out["phases"] = phases
    return out
