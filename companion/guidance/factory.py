"""The one way the companion builds its guidance law for a flight, a replay, a synthetic log or
``companion sim``: every mission ``guidance.method`` (:data:`companion.guidance.types.METHODS`).

- ``fixed_l1``, ``corrector``, ``predictive``: the paper's two-phase object
  (:class:`companion.guidance.two_phase.TwoPhaseGuidance`), mid-course then close range;
- ``ap_l1``, ``npfg``, ``pure_pursuit``: the baselines (:mod:`companion.guidance.baselines`), flown
  as their autopilots fly them, from any start without a mid-course phase (docs/guidance.md),
  tuned by ``period_s`` / ``lookahead_m`` (None: the law's own default) and, for ``npfg``, the
  mission's known wind.
"""

from __future__ import annotations

import dataclasses

from companion.geometry.paths import Path
from companion.guidance.baselines import (
    ApL1Guidance,
    ApL1Params,
    NpfgGuidance,
    NpfgParams,
    PurePursuitGuidance,
    PurePursuitParams,
)
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import TWO_PHASE_METHODS, GuidanceLaw, GuidanceParams


def make_law(path: Path, params: GuidanceParams, rate_hz: float, speed_m_s: float) -> GuidanceLaw:
    """The guidance of ``path`` with ``params`` at the loop's rate and the flight's speed.

    ``rate_hz`` and ``speed_m_s`` replace the fields of the same names in ``params``: the loop
    decides the rate, the mission the (commanded) ground speed. The baselines read the speed from
    each tick's state, as their autopilots do.

    >>> from companion.geometry.paths import waypoint_path
    >>> line = waypoint_path([(0.0, 0.0), (100.0, 0.0)])
    >>> type(make_law(line, GuidanceParams(method="npfg"), 50.0, 5.0)).__name__
    'NpfgGuidance'
    """
    params = dataclasses.replace(params, rate_hz=float(rate_hz), speed_m_s=float(speed_m_s))
    if params.method in TWO_PHASE_METHODS:
        return TwoPhaseGuidance(path, params)
    if params.method == "ap_l1":
        ap = ApL1Params() if params.period_s is None else ApL1Params(period_s=params.period_s)
        return ApL1Guidance(path, ap)
    if params.method == "npfg":
        npfg = NpfgParams(wind_x_m_s=params.wind_x_m_s, wind_y_m_s=params.wind_y_m_s)
        if params.period_s is not None:
            npfg = dataclasses.replace(npfg, period_s=params.period_s)
        return NpfgGuidance(path, npfg)
    assert params.method == "pure_pursuit"  # GuidanceParams validates the method
    pp = PurePursuitParams() if params.lookahead_m is None else PurePursuitParams(lookahead_m=params.lookahead_m)
    return PurePursuitGuidance(path, pp)
