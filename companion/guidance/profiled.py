"""The local speed of a speed profile, handed to any guidance law.

Every law reads the vehicle's speed from ``VehicleState.speed_m_s``: the L1 geometry
(``2 V^2 sin(eta) / L1``), the corrector's re-optimisation window (``min(d L1, R) / V``) and its
rollouts, predictive's rollouts and look-ahead. A mission whose speed changes along the path
(:class:`companion.geometry.profile.PathProfile`) flies each law at the local speed ``V(s)`` by
handing it ``V(s)`` at the arc length of the previous tick's projection (the start's before the
first projection, and through the mid-course phase, which reports ``s = 0``). One tick of delay
in ``s`` is ``V dt`` metres, over which the profile changes by at most ``a_long dt`` m/s.

Missions at one constant speed are not wrapped (:func:`companion.loop.driver.make_guidance`), so
they fly exactly as before.
"""

from __future__ import annotations

import math
from typing import Any

from companion.geometry.profile import PathProfile
from companion.guidance.types import GuidanceLaw, GuidanceOutput, VehicleState, frozen_maker

_vehicle_state = frozen_maker(VehicleState)


class ProfiledGuidance:
    """``law`` flown at the profile's local speed; every other attribute is the law's."""

    def __init__(self, law: GuidanceLaw, profile: PathProfile):
        self.law = law
        self.profile = profile
        self._s_m = 0.0

    def __getattr__(self, name: str) -> Any:  # params, path, phase... of the wrapped law
        return getattr(self.law, name)

    @property
    def speed_m_s(self) -> float:
        """The speed the next step will hand to the law."""
        return self.profile.speed_m_s(self._s_m)

    def step(self, t_s: float, state: VehicleState) -> GuidanceOutput:
        local = _vehicle_state(state.x_m, state.y_m, state.course_rad, self.speed_m_s)
        out = self.law.step(t_s, local)
        if math.isfinite(out.s_proj_m):
            self._s_m = out.s_proj_m
        return out
