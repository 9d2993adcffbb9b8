"""Off the path and pointing away, every law comes back: d_max <= 2 L + d0.

``d0`` is the start's distance to the path and ``L`` the law's own length: L1 for ``fixed_l1``
and ``corrector``, the L1 distance ``zeta T V / pi`` for ``ap_l1``, the track-error bound
``V T zeta`` for ``npfg``, the look-ahead for ``pure_pursuit``, ``V * horizon`` for
``predictive``. Distances are measured from the simulated track to the path's closed form (the
sine, the line) or to a dense sample of its points (the racetrack), not from what a law reports.
The capture rule itself: ``companion.guidance.capture`` (docs/guidance.md).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.geometry.paths import function_path, waypoint_path
from companion.guidance.baselines import ApL1Params, NpfgParams
from companion.guidance.capture import capture_command_m_s2, capture_side
from companion.guidance.factory import make_law
from companion.guidance.predictive import PredictiveParams
from companion.guidance.two_phase import TwoPhaseGuidance
from companion.guidance.types import GuidanceParams, VehicleState
from companion.mission import load_mission
from companion.sim.simulator import LagModel, simulate

MISSIONS_DIR = Path(__file__).resolve().parents[2] / "missions"

V_M_S = 5.0
RATE_HZ = 50.0
L1_M = 10.0
LAWS = ("fixed_l1", "corrector", "ap_l1", "npfg", "pure_pursuit", "predictive")


def sine_y(x):
    return 10.0 * np.sin(0.078 * x) + 20.0 * np.cos(0.082 * x)


def law_length_m(method: str) -> float:
    """The law's own length (module docstring)."""
    if method == "ap_l1":
        p = ApL1Params()
        return p.damping * p.period_s * V_M_S / math.pi
    if method == "npfg":
        p = NpfgParams()
        return V_M_S * p.period_s * p.damping
    if method == "predictive":
        return V_M_S * PredictiveParams().horizon_s
    return L1_M  # fixed_l1, corrector (l1_m), pure_pursuit (lookahead_m)


def _sine_distance(x, y):
    xs = np.linspace(-15.0, 300.0, 63_001)
    ys = sine_y(xs)
    return np.array([np.min(np.hypot(xs - a, ys - b)) for a, b in zip(x, y)])


def _line_distance(x, y):
    xc = np.clip(x, 0.0, 300.0)
    return np.hypot(x - xc, y)


def _racetrack():
    return load_mission(MISSIONS_DIR / "racetrack.yaml").path


def _sampled_distance(path):
    s = np.linspace(0.0, path.length_m, 40_001)
    px, py = path.point_array(s)

    def distance(x, y):
        return np.array([np.min(np.hypot(px - a, py - b)) for a, b in zip(x, y)])
    return distance


SCENES = {
    # name: (path builder, distance to it, start x, y, heading deg, start distance d0 by hand)
    # The issue's case: 15.5 m below the sine's start (-15, y(-15) = -2.503 m), heading south.
    "paper_sine": (lambda: function_path(sine_y, (-15.0, 300.0)), _sine_distance,
                   -15.0, -18.0, -90.0, 18.0 + float(sine_y(-15.0))),
    # 40 m off the middle of a 300 m line, heading away from it.
    "line_40m": (lambda: waypoint_path([(0.0, 0.0), (300.0, 0.0)]), _line_distance, 150.0, -40.0, -90.0, 40.0),
    # 15 m outside the racetrack's southern straight (y = 0, the path start at the origin), heading away.
    "racetrack_south": (_racetrack, None, 10.0, -15.0, -90.0, 15.0),
    # 15 m outside its northern straight (y = 60), far from the path start, heading away.
    "racetrack_north": (_racetrack, None, -20.0, 75.0, 90.0, 15.0),
}


def fly(scene: str, method: str, model: LagModel | None = None):
    build, distance, x0, y0, heading_deg, d0 = SCENES[scene]
    path = build()
    if distance is None:
        distance = _sampled_distance(path)
    params = GuidanceParams(method=method, l1_m=L1_M, rate_hz=RATE_HZ, speed_m_s=V_M_S)
    if method == "predictive" and model is not None:
        params = GuidanceParams(method=method, rate_hz=RATE_HZ, speed_m_s=V_M_S, rollout_tau_s=model.tau_s,
                                a_max_m_s2=model.a_max_m_s2)
    law = make_law(path, params, RATE_HZ, V_M_S)
    start = VehicleState(x0, y0, math.radians(heading_deg), V_M_S)
    t_max = (d0 + 2.0 * law_length_m(method)) * 4.0 / V_M_S + 60.0 if path.closed else None
    res = simulate(path, law, start, params, model=model, t_max_s=t_max)
    d = distance(res.x_m[::5], res.y_m[::5])
    return res, d, d0


@pytest.mark.parametrize("scene", sorted(SCENES))
@pytest.mark.parametrize("method", LAWS)
def test_every_law_returns_from_off_the_path_heading_away(scene, method):
    res, d, d0 = fly(scene, method)
    bound = 2.0 * law_length_m(method) + d0
    assert np.max(d) <= bound, (scene, method, float(np.max(d)), bound)
    assert np.min(d[len(d) // 2:]) < 1.0, (scene, method)  # and it reaches the path
    assert np.all(np.isfinite(res.a_cmd_m_s2))


@pytest.mark.parametrize("method", LAWS)
def test_the_issue_case_returns_in_the_lag_model_too(method):
    res, d, d0 = fly("paper_sine", method, LagModel(tau_s=0.3, a_max_m_s2=5.0))
    assert np.max(d) <= 2.0 * law_length_m(method) + d0
    assert np.min(d[len(d) // 2:]) < 1.0


def test_start_distance_of_the_issue_case_by_hand():
    # y(-15) = 10 sin(-1.17) + 20 cos(-1.23) = -9.20751 + 6.68475; the sine rises from there, so
    # the closest point to (-15, -18) is the path start.
    assert SCENES["paper_sine"][5] == pytest.approx(18.0 - 9.20751 + 6.68475, abs=1e-4)
    d = _sine_distance(np.array([-15.0]), np.array([-18.0]))
    assert d[0] == pytest.approx(SCENES["paper_sine"][5], abs=1e-6)


def test_capture_turns_towards_a_closest_point_dead_astern_on_the_side_the_path_goes():
    # Vehicle at the origin heading south, the closest point 15 m north: dead astern.
    assert capture_side(0.0, 0.0, -math.pi / 2, 0.0, 15.0, 1.0, 0.0, 0) == 1  # path going east: left
    assert capture_side(0.0, 0.0, -math.pi / 2, 0.0, 15.0, -1.0, 0.0, 0) == -1  # going west: right
    # Behind on the right: turn right, and keep that side while it stays behind.
    assert capture_side(0.0, 0.0, 0.0, -10.0, -1.0, 0.0, 1.0, 0) == -1
    assert capture_side(0.0, 0.0, 0.0, -10.0, 1.0, 0.0, 1.0, -1) == -1
    # Ahead of the beam: the law's own command.
    assert capture_side(0.0, 0.0, 0.0, 10.0, 30.0, 1.0, 0.0, 1) == 0
    # Mirroring the scene (y -> -y) flips the side.
    assert capture_side(0.0, 0.0, math.pi / 2, 0.0, -15.0, 1.0, 0.0, 0) == -1
    # The bounded turn is the law's largest command 2 V^2 / L.
    assert capture_command_m_s2(-1, 5.0, 10.0) == pytest.approx(-5.0)


def test_capture_takes_over_only_without_a_lookahead_point():
    path = waypoint_path([(0.0, 0.0), (300.0, 0.0)])
    params = GuidanceParams(method="fixed_l1", l1_m=L1_M, midcourse_trigger="off")
    # 5 m off the line, heading away: within L1, the L1 point exists; Park's command, not the capture.
    out = TwoPhaseGuidance(path, params).step(0.0, VehicleState(100.0, -5.0, -math.pi / 2, V_M_S))
    assert "capture_side" not in out.extra
    # 40 m off, heading away: no L1 point; the closest point (100, 0) is dead astern; the path
    # goes east, to the vehicle's left: turn left at 2 V^2 / L1 = 5 m/s^2.
    out = TwoPhaseGuidance(path, params).step(0.0, VehicleState(100.0, -40.0, -math.pi / 2, V_M_S))
    assert out.extra["capture_side"] == 1 and out.a_cmd_m_s2 == pytest.approx(5.0)


@pytest.mark.parametrize("l1_m", [5.0, 10.0, 30.0])
def test_the_start_course_on_a_circle_is_the_chord_to_the_l1_point(l1_m):
    """On a circle of radius R the L1 point subtends 2 asin(L1 / 2R) at the centre, and the chord
    to it leans asin(L1 / 2R) from the tangent, towards the inside."""
    from companion.geometry.paths import parametric_path
    from companion.guidance.capture import start_course_rad

    r = 50.0  # about (0, 50), anticlockwise from (0, 0) going east
    circle = parametric_path(lambda u: r * np.sin(u), lambda u: r - r * np.cos(u), (0.0, 2.0 * math.pi), closed=True)
    assert start_course_rad(circle, 0.0, 0.0, l1_m) == pytest.approx(math.asin(l1_m / (2.0 * r)), abs=1e-4)
    # 20 m outside the circle below its start: beyond L1 (< 20 m), straight at the closest point (0, 0)
    if l1_m < 20.0:
        assert start_course_rad(circle, 0.0, -20.0, l1_m) == pytest.approx(math.pi / 2, abs=1e-6)
