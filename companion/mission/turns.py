"""A mission slowed where its path turns tighter than the vehicle can fly at the asked speed.

A path of curvature ``kappa`` flown at ``V`` asks ``V^2 |kappa|`` of lateral acceleration before
any correction. Where that is more than the vehicle's horizontal acceleration limit, no guidance
law can hold the path: every law saturates there and the vehicle runs wide (the paper's sine
asks 3.66 m/s^2 at 5 m/s; ArduCopter in GUIDED flies 2.5 m/s^2, its ``WPNAV_ACCEL``). An
autopilot's own missions slow down for such turns; so does a flight here, once it knows the
limit: the speed is lowered so that the path asks at most ``along_track.turn_accel_share`` of
the limit (0.8 by default, the rest left to the corrections), braking before each turn and
speeding up after it at ``along_track.accel_max_m_s2``
(:func:`companion.geometry.profile.turn_limited_speed`).

Only flights do this (``companion fly``, ``bench sitl``, and ``replay`` of them), where the limit
is the one the flight uses (:func:`companion.loop.limits.mission_with_limit`). Simulations and the
benches fly the speeds as given: the paper's scenarios and the tracking bench compare laws at
one speed. A mission whose turns all keep within the share is returned as it is.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from companion.geometry.profile import PathProfile, grid, turn_limited_speed
from companion.mission.model import Mission

#: The slowest a turn slows a flight to (a turn tighter than this speed allows is flown at it).
TURN_SPEED_MIN_M_S = 1.0


def slowed_for_turns(mission: Mission, a_max_m_s2: float) -> tuple[Mission, str | None]:
    """``mission`` flown within ``turn_accel_share * a_max_m_s2`` in its path's turns, and the log
    line saying how much slower (None, and the mission itself, when nothing changes: an unknown
    limit, a share of 0, or turns that already keep within it).

    The speed table becomes the mission's profile (built for a flat mission: its height constant,
    its vertical hold then on the ``vertical:`` limits); ``speed_m_s`` becomes the speed at the
    path start, as for any profile. An altitude profile keeps its heights: slower, it climbs
    slower than it was smoothed for, within the same limits.
    """
    limits = mission.profile_limits
    share = limits.turn_accel_share
    if share <= 0.0 or not (math.isfinite(a_max_m_s2) and a_max_m_s2 > 0.0):
        return mission, None
    lateral = share * a_max_m_s2
    path, profile = mission.path, mission.profile
    s = profile.s_m if profile is not None else grid(path.length_m)
    speed = profile.speed_m_s_table if profile is not None else np.full(s.size, mission.speed_m_s)
    kappa = path.curvature_array(s)
    slowed = turn_limited_speed(speed, kappa, float(s[1] - s[0]), lateral, limits.along_accel_max_m_s2,
                                path.closed, TURN_SPEED_MIN_M_S)
    if np.array_equal(slowed, speed):
        return mission, None
    alt = profile.alt_m if profile is not None else np.full(s.size, mission.altitude_m)
    new = PathProfile(s, alt, slowed, path.closed, limits)
    v0 = new.speed_m_s(0.0)
    changed = slowed < speed
    line = (f"slower in the path's turns: down to {float(slowed[changed].min()):.2f} m/s over "
            f"{100.0 * float(np.mean(changed)):.0f} % of the path, so that V^2 kappa <= {share:g} x "
            f"{a_max_m_s2:.3g} m/s^2 (along_track.turn_accel_share)")
    if np.any(slowed * slowed * np.abs(kappa) > lateral * (1.0 + 1e-9)):
        line += (f"; tighter than that at {TURN_SPEED_MIN_M_S:g} m/s in places, flown at "
                 f"{TURN_SPEED_MIN_M_S:g} m/s there")
    guidance = dataclasses.replace(mission.guidance, speed_m_s=v0)
    return dataclasses.replace(mission, profile=new, speed_m_s=v0, guidance=guidance), line
