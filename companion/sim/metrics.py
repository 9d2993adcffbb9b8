"""Tracking metrics shared by every command that reports figures (sim, fly, demo, replay, bench).

One definition, one set of names: ``d_rms_m``, ``d_max_m``, ``a_rms_m_s2``, ``a_max_m_s2``,
``duration_s``, ``samples``, and ``phases`` (the same keys per guidance phase).

All series are sampled once per guidance tick (uniform weighting per tick):

- ``d_rms_m``    sqrt(mean(d^2)), d the cross-track error (distance to the closest path point)
- ``d_max_m``    max |d|
- ``a_rms_m_s2`` sqrt(mean(a^2)), a the commanded lateral acceleration
- ``a_max_m_s2`` max |a|
- ``duration_s`` last time minus first time (0 for fewer than two samples)

Missions with an altitude or speed profile (``companion.geometry.profile``) add, when the caller
passes the series:

- ``h_rms_m``       sqrt(mean(e_h^2)), e_h = measured altitude minus the profile's h(s) at the
  vehicle's projection s (the vertical error)
- ``h_max_m``       max |e_h|
- ``v_err_rms_m_s`` sqrt(mean(e_v^2)), e_v = measured horizontal ground speed minus the profile's
  V(s) (the along-track speed error)
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from companion.geometry.profile import PathProfile

#: The row name of the whole-flight figures in every metrics table (sim, fly, demo, replay).
OVERALL_ROW = "overall"

METRIC_KEYS = ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "duration_s", "samples")
#: Added when the vertical / speed error series are given.
PROFILE_METRIC_KEYS = ("h_rms_m", "h_max_m", "v_err_rms_m_s")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def _summary(t_s: np.ndarray, d_m: np.ndarray, a_m_s2: np.ndarray, h_err_m: np.ndarray | None = None,
             v_err_m_s: np.ndarray | None = None) -> dict[str, Any]:
    out = _summary_2d(t_s, d_m, a_m_s2)
    if h_err_m is not None:
        out["h_rms_m"] = _rms(h_err_m)
        out["h_max_m"] = float(np.max(np.abs(h_err_m))) if h_err_m.size else math.nan
    if v_err_m_s is not None:
        out["v_err_rms_m_s"] = _rms(v_err_m_s)
    return out


def _summary_2d(t_s: np.ndarray, d_m: np.ndarray, a_m_s2: np.ndarray) -> dict[str, Any]:
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
    t_s: Sequence[float] | np.ndarray,
    crosstrack_m: Sequence[float] | np.ndarray,
    a_cmd_m_s2: Sequence[float] | np.ndarray,
    phase: Sequence[str] | None = None,
    *,
    h_err_m: Sequence[float] | None = None,
    v_err_m_s: Sequence[float] | None = None,
) -> dict[str, Any]:
    """Overall and per-phase tracking metrics of one flight (simulated, flown or replayed).

    Parameters
    ----------
    t_s, crosstrack_m, a_cmd_m_s2 : sequences of equal length, one entry per guidance tick.
    phase : optional phase name per tick (e.g. ``"midcourse"``, ``"close_range"``).
    h_err_m, v_err_m_s : optional vertical and along-track speed errors per tick (missions with a
        profile): add ``h_rms_m``, ``h_max_m`` and ``v_err_rms_m_s``.

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
    h = None if h_err_m is None else np.asarray(h_err_m, dtype=float)
    v = None if v_err_m_s is None else np.asarray(v_err_m_s, dtype=float)
    for name, series in (("h_err_m", h), ("v_err_m_s", v)):
        if series is not None and series.shape != t.shape:
            raise ValueError(f"series lengths differ: t {t.shape}, {name} {series.shape}")
    out = _summary(t, d, a, h, v)
    phases: dict[str, dict[str, Any]] = {}
    if phase is not None:
        names = np.asarray(list(phase), dtype=object)
        if names.shape != t.shape:
            raise ValueError(f"phase length {names.shape} differs from t {t.shape}")
        for name in dict.fromkeys(names.tolist()):
            mask = names == name
            phases[str(name)] = _summary(t[mask], d[mask], a[mask], None if h is None else h[mask],
                                         None if v is None else v[mask])
    out["phases"] = phases
    return out


def profile_errors(profile: PathProfile | None, s_proj_m: Sequence[float], alt_m: Sequence[float],
                   ground_speed_m_s: Sequence[float]) -> dict[str, np.ndarray]:
    """The vertical and along-track speed errors of a flight against a mission's profile.

    Returns ``{"h_err_m": ..., "v_err_m_s": ...}`` (the keyword arguments of
    :func:`tracking_metrics`), or ``{}`` when ``profile`` is None (a flat, constant-speed mission:
    no extra metrics). ``s_proj_m`` is the arc length of each tick's projection; ticks without
    one (NaN) are compared at the path start.

    >>> from companion.geometry.profile import ProfileLimits, build_profile
    >>> p = build_profile(100.0, False, ProfileLimits(), alt_target=lambda s: 10 + 0.1 * s,
    ...                   speed_target=5.0)
    >>> e = profile_errors(p, [50.0], [15.5], [4.0])
    >>> round(float(e["h_err_m"][0]), 6), round(float(e["v_err_m_s"][0]), 6)
    (0.5, -1.0)
    """
    if profile is None:
        return {}
    s = [x if math.isfinite(x) else 0.0 for x in s_proj_m]
    h_ref = np.array([profile.altitude_m(x) for x in s])
    v_ref = np.array([profile.speed_m_s(x) for x in s])
    return {"h_err_m": np.asarray(alt_m, dtype=float) - h_ref,
            "v_err_m_s": np.asarray(ground_speed_m_s, dtype=float) - v_ref}
