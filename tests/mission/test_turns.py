"""A flight slows down where the path turns tighter than the vehicle's limit allows at the asked
speed (companion.mission.turns, applied by companion.loop.limits.mission_with_limit)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from companion.geometry.profile import ProfileLimits
from companion.guidance.types import VehicleModel
from companion.loop.limits import AutopilotLimit, mission_with_limit
from companion.mission import load_mission
from companion.mission.turns import slowed_for_turns

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
WPNAV = AutopilotLimit(2.5, "WPNAV_ACCEL 250 cm/s^2")


def sine_curvature_max() -> float:
    """The paper sine's largest curvature, from its formula: |y''| / (1 + y'^2)^1.5 on x in [-15, 300]."""
    x = np.linspace(-15.0, 300.0, 400_001)
    dy = 10 * 0.078 * np.cos(0.078 * x) - 20 * 0.082 * np.sin(0.082 * x)
    d2y = -10 * 0.078 ** 2 * np.sin(0.078 * x) - 20 * 0.082 ** 2 * np.cos(0.082 * x)
    return float(np.max(np.abs(d2y) / (1 + dy * dy) ** 1.5))


def test_the_paper_sine_on_arducopter_is_flown_slower_in_its_tightest_turn():
    mission = load_mission(str(MISSIONS / "paper_sine.yaml"))
    assert mission.profile is None and mission.profile_limits.turn_accel_share == 0.8
    used, line = mission_with_limit(mission, WPNAV)
    k_max = sine_curvature_max()
    assert 25.0 * k_max > 2.0  # the premise: at 5 m/s the path alone asks more than 0.8 x 2.5
    v = used.profile.speed_m_s_table
    assert v.min() == pytest.approx(math.sqrt(2.0 / k_max), rel=2e-3)
    assert v.max() == 5.0 and used.speed_m_s == used.guidance.speed_m_s == used.profile.speed_m_s(0.0)
    assert np.all(used.profile.alt_m == mission.altitude_m)  # flat: its height unchanged
    assert f"down to {math.sqrt(2.0 / k_max):.2f} m/s" in line and "0.8 x 2.5 m/s^2" in line
    assert line.startswith("acceleration limit 2.5 m/s^2 from the autopilot's WPNAV_ACCEL")


@pytest.mark.parametrize("name", ["racetrack", "figure_eight", "survey_lawnmower"])
def test_missions_whose_turns_keep_within_the_share_fly_as_asked(name):
    mission = load_mission(str(MISSIONS / f"{name}.yaml"))
    used, line = mission_with_limit(mission, WPNAV)
    assert used.profile is None and used.speed_m_s == mission.speed_m_s and "slower" not in line


def test_the_limit_used_decides_a_vehicle_block_wins_and_a_share_of_zero_turns_it_off():
    mission = load_mission(str(MISSIONS / "paper_sine.yaml"))
    k_max = sine_curvature_max()
    # PX4's tilt limit (9.8 m/s^2): 0.8 x 9.8 is more than the sine's 3.66 m/s^2
    assert mission_with_limit(mission, AutopilotLimit(9.80665, "MPC_TILTMAX_AIR 45 deg"))[0].profile is None
    with_vehicle = dataclasses.replace(mission, vehicle=VehicleModel(a_max_m_s2=3.0, lag_s=0.3))
    used, _ = mission_with_limit(with_vehicle, WPNAV)
    assert used.profile.speed_m_s_table.min() == pytest.approx(math.sqrt(0.8 * 3.0 / k_max), rel=2e-3)
    off = dataclasses.replace(mission, profile_limits=ProfileLimits(turn_accel_share=0.0))
    assert mission_with_limit(off, WPNAV)[0].profile is None
    assert slowed_for_turns(mission, math.inf) == (mission, None)


def test_an_altitude_profile_keeps_its_heights_and_the_speed_is_lowered_in_its_turn(tmp_path):
    text = ("name: climb-turn\nframe: local_enu\nspeed_m_s: 6.0\naltitude_m: '10 + 0.02*s'\n"
            "path: {type: parametric, x_of_s: '8*cos(s)', y_of_s: '8*sin(s)', s_range: [0, 3.14159]}\n")
    f = tmp_path / "climb_turn.yaml"
    f.write_text(text)
    mission = load_mission(str(f))
    used, line = mission_with_limit(mission, WPNAV)
    assert np.array_equal(used.profile.alt_m, mission.profile.alt_m)
    # a half circle of 8 m: V = sqrt(0.8 * 2.5 * 8) = 4 m/s in the middle of the turn
    assert used.profile.speed_m_s(used.profile.length_m / 2) == pytest.approx(4.0, rel=1e-6)
    assert "down to 4.00 m/s" in line



def test_a_flight_slowed_in_its_turns_expects_the_progress_of_its_slowest_speed():
    # The "not moving" check expects a share of the mission speed; slowed to 3.70 m/s in the
    # sine's tightest turn, the flight must not be held to its 5 m/s.
    from companion.loop.runner import FlightRunner, FlyOptions
    from companion.replay.replay import tick_config_for

    used, _ = mission_with_limit(load_mission(str(MISSIONS / "paper_sine.yaml")), WPNAV)
    runner = FlightRunner(used, FlyOptions(connect="udpin:127.0.0.1:14999", rate_hz=50.0))
    health = runner._health_monitor(tick_config_for(used, 50.0))
    assert health.speed_m_s == pytest.approx(math.sqrt(2.0 / sine_curvature_max()), rel=2e-3)


def test_a_turn_too_tight_even_for_1_m_s_is_flown_at_1_m_s_and_the_log_says_so(tmp_path):
    # A 0.3 m circle: 0.8 x 2.5 m/s^2 allows sqrt(2 * 0.3) = 0.77 m/s, below the 1 m/s floor.
    f = tmp_path / "tiny.yaml"
    f.write_text("name: tiny\nspeed_m_s: 3.0\npath: {type: parametric, x_of_s: '0.3*cos(s)', "
                 "y_of_s: '0.3*sin(s)', s_range: [0, 6.283185307179586], closed: true}\nguidance: {l1_m: 1.0}\n")
    used, line = mission_with_limit(load_mission(str(f)), WPNAV)
    assert np.allclose(used.profile.speed_m_s_table, 1.0)
    assert "down to 1.00 m/s" in line and "flown at 1 m/s there" in line
