"""The one way the companion builds its guidance law for a flight, a replay or a synthetic log."""

from __future__ import annotations

import dataclasses

from companion.geometry.paths import Path
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams


def make_law(path: Path, params: GuidanceParams, rate_hz: float, speed_m_s: float) -> TwoPhaseGuidance:
    """The two-phase guidance of ``path`` with ``params`` at the loop's rate and the flight's speed.

    ``rate_hz`` and ``speed_m_s`` replace the fields of the same names in ``params``: the loop
    decides the rate, the mission the (commanded) ground speed.
    """
    params = dataclasses.replace(params, rate_hz=float(rate_hz), speed_m_s=float(speed_m_s))
    return TwoPhaseGuidance(path, params)
