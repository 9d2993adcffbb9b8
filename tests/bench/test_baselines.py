"""The baseline laws against hand geometry: steady commands on a circle, the command at a known
offset from a line, the sign flip of a mirrored scene, convergence onto a line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.guidance.baselines import (
    ApL1Guidance,
    ApL1Params,
    NpfgGuidance,
    NpfgParams,
    PurePursuitGuidance,
    PurePursuitParams,
)
from companion.guidance.baselines.npfg import bearing_feasibility
from companion.guidance.types import VehicleState
from bench_scenes import CirclePath, LinePath, fly, mirror_path, mirror_state

V = 5.0


def on_circle(radius_m: float) -> VehicleState:
    # On the anticlockwise circle at angle 0, flying along it (course +90 deg).
    return VehicleState(radius_m, 0.0, math.pi / 2, V)


# --- ArduPilot L1 ---------------------------------------------------------------------------

def test_ap_l1_gain_and_distance_follow_period_and_damping():
    p = ApL1Params(period_s=17.0, damping=0.75)
    assert p.gain == pytest.approx(4 * 0.75**2)
    assert p.l1_m(5.0) == pytest.approx(0.75 * 17.0 * 5.0 / math.pi)


def test_ap_l1_on_a_circle_commands_k_v2_over_2r():
    # Chord geometry: the L1 point on a circle of radius R seen from a point on it, along the
    # tangent, is at eta = asin(L1 / 2R), so a = K V^2 sin(eta) / L1 = K V^2 / (2 R).
    r = 30.0
    law = ApL1Guidance(CirclePath(r), ApL1Params(period_s=10.0, damping=0.75, xtrack_i_gain=0.0))
    out = law.step(0.0, on_circle(r))
    assert out.a_cmd_m_s2 == pytest.approx(4 * 0.75**2 * V**2 / (2 * r), rel=1e-6)
    assert out.crosstrack_m == pytest.approx(0.0, abs=1e-9)


def test_ap_l1_offset_from_a_line_inside_the_capture_angle():
    # Straight line, vehicle d = 3 m left and flying parallel: Nu = -asin(d / L1),
    # a = K V^2 sin(Nu) / L1 = -K V^2 d / L1^2.
    p = ApL1Params(period_s=10.0, damping=0.75, xtrack_i_gain=0.0)
    l1 = 0.75 * 10.0 * V / math.pi
    out = ApL1Guidance(LinePath(x0=-100.0), p).step(0.0, VehicleState(0.0, 3.0, 0.0, V))
    assert out.a_cmd_m_s2 == pytest.approx(-4 * 0.75**2 * V**2 * 3.0 / l1**2, rel=1e-6)
    assert out.crosstrack_m == pytest.approx(3.0)


def test_ap_l1_far_from_a_line_flies_the_45_degree_capture_angle():
    p = ApL1Params(period_s=10.0, damping=0.75, xtrack_i_gain=0.0)
    l1 = 0.75 * 10.0 * V / math.pi
    out = ApL1Guidance(LinePath(x0=-100.0), p).step(0.0, VehicleState(0.0, -50.0, 0.0, V))
    assert out.a_cmd_m_s2 == pytest.approx(4 * 0.75**2 * V**2 / l1 * math.sin(math.pi / 4), rel=1e-9)


def test_ap_l1_crosstrack_integrator_accumulates_the_small_capture_angle():
    p = ApL1Params(period_s=10.0, damping=0.75, xtrack_i_gain=0.02)
    l1 = 0.75 * 10.0 * V / math.pi
    law = ApL1Guidance(LinePath(x0=-100.0), p)
    st = VehicleState(0.0, 0.5, 0.0, V)  # asin(0.5 / 11.9) = 2.4 deg < 5 deg
    law.step(0.0, st)
    out = law.step(0.05, st)
    assert out.extra["xtrack_i_rad"] == pytest.approx(-math.asin(0.5 / l1) * 0.02 * 0.05, rel=1e-6)


# --- NPFG -----------------------------------------------------------------------------------

def test_npfg_on_a_circle_without_wind_commands_exactly_v2_over_r():
    # On track and aligned: look-ahead angle pi/2, bearing = tangent, no feedback; the
    # feed-forward with full track proximity and feasibility is V^2 kappa.
    r = 30.0
    out = NpfgGuidance(CirclePath(r), NpfgParams()).step(0.0, on_circle(r))
    assert out.a_cmd_m_s2 == pytest.approx(V**2 / r, rel=1e-9)


def test_npfg_half_the_track_error_bound_from_a_line():
    # n = 0.5 -> look-ahead angle pi/8; the bearing is pi/2 - pi/8 off the track towards it, so
    # a = -k_p V sin(pi/2 - pi/8) = -k_p V cos(pi/8) for a vehicle left of the line.
    p = NpfgParams(period_s=10.0, damping=0.7)
    e_b = V * p.period_s * p.damping
    out = NpfgGuidance(LinePath(x0=-100.0), p).step(0.0, VehicleState(0.0, e_b / 2, 0.0, V))
    k_p = 4 * math.pi * 0.7 / 10.0
    assert out.a_cmd_m_s2 == pytest.approx(-k_p * V * math.cos(math.pi / 8), rel=1e-9)


def test_npfg_light_cross_wind_on_track_holds_the_crab_angle():
    # Wind 3 m/s from the right of a line along +x, airspeed 5: flying the ground track along
    # the line needs ground speed 4 with the air velocity (4, -3): no command.
    p = NpfgParams(wind_y_m_s=3.0)
    law = NpfgGuidance(LinePath(x0=-100.0), p)
    out = law.step(0.0, VehicleState(0.0, 0.0, 0.0, 4.0))
    assert out.a_cmd_m_s2 == pytest.approx(0.0, abs=1e-9)
    # The same ground velocity without accounting for the wind would be a heading error.
    out_no_wind = NpfgGuidance(LinePath(x0=-100.0), NpfgParams()).step(0.0, VehicleState(0.0, 0.0, 0.3, 4.0))
    assert out_no_wind.a_cmd_m_s2 < 0.0


def test_npfg_bearing_feasibility_closed_form():
    # Half the buffer left: sin^2(pi/4) = 0.5; head wind counts the full wind speed.
    assert bearing_feasibility(9.25, 0.0, 10.0, 9.25, 1.5) == pytest.approx(0.5)
    assert bearing_feasibility(0.0, -12.0, 10.0, 12.0, 1.5) == 0.0
    assert bearing_feasibility(1.0, 1.0, 10.0, 1.4, 1.5) == pytest.approx(1.0)


def test_npfg_excess_head_wind_still_commands_a_bounded_turn():
    p = NpfgParams(wind_x_m_s=-8.0)
    out = NpfgGuidance(LinePath(x0=-100.0), p).step(0.0, VehicleState(0.0, 20.0, math.pi, 3.0))
    assert math.isfinite(out.a_cmd_m_s2)
    assert abs(out.a_cmd_m_s2) <= p.p_gain_1_s * 5.0 + 1e-9  # feedback saturates at k_p V_a


# --- pure pursuit ---------------------------------------------------------------------------

def test_pure_pursuit_on_a_circle_commands_v2_over_r():
    r = 30.0
    out = PurePursuitGuidance(CirclePath(r), PurePursuitParams(lookahead_m=12.0)).step(0.0, on_circle(r))
    assert out.a_cmd_m_s2 == pytest.approx(V**2 / r, rel=1e-6)


def test_pure_pursuit_offset_from_a_line():
    ld = 10.0
    out = PurePursuitGuidance(LinePath(x0=-100.0), PurePursuitParams(lookahead_m=ld)).step(
        0.0, VehicleState(0.0, -4.0, 0.0, V))
    assert out.a_cmd_m_s2 == pytest.approx(2 * V**2 * 4.0 / ld**2, rel=1e-6)


def test_pure_pursuit_far_from_the_path_aims_at_the_closest_point():
    out = PurePursuitGuidance(LinePath(x0=-100.0), PurePursuitParams(lookahead_m=10.0)).step(
        0.0, VehicleState(0.0, 50.0, 0.0, V))
    assert out.lookahead_xy_m == pytest.approx((0.0, 0.0))
    assert out.a_cmd_m_s2 == pytest.approx(-2 * V**2 / 50.0, rel=1e-9)


# --- all laws -------------------------------------------------------------------------------

LAWS = [
    ("ap_l1", lambda path: ApL1Guidance(path, ApL1Params(period_s=8.0))),
    ("npfg", lambda path: NpfgGuidance(path, NpfgParams(period_s=6.0))),
    ("pure_pursuit", lambda path: PurePursuitGuidance(path, PurePursuitParams(lookahead_m=8.0))),
]


@pytest.mark.parametrize("name,make", LAWS)
@pytest.mark.parametrize("scene", [
    (CirclePath(25.0, cx=3.0, cy=-2.0, phi0_rad=0.4), VehicleState(26.0, 9.0, 2.3, V)),
    (CirclePath(25.0, ccw=False), VehicleState(-20.0, 4.0, -1.2, V)),
    (LinePath(x0=-50.0, y0=2.0, heading_rad=0.3), VehicleState(0.0, 6.0, -0.2, V)),
])
def test_mirroring_the_scene_flips_the_command(name, make, scene):
    path, state = scene
    a = make(path).step(0.0, state)
    b = make(mirror_path(path)).step(0.0, mirror_state(state))
    assert abs(a.a_cmd_m_s2) > 1e-3
    assert b.a_cmd_m_s2 == pytest.approx(-a.a_cmd_m_s2, rel=1e-6, abs=1e-9)
    assert b.crosstrack_m == pytest.approx(-a.crosstrack_m, rel=1e-6, abs=1e-9)


@pytest.mark.parametrize("name,make", LAWS)
def test_converges_onto_a_line_from_8_m_off(name, make):
    series = fly(make(LinePath(x0=-20.0, length_m=2000.0)), VehicleState(0.0, 8.0, 0.0, V), 60.0)
    d = series[:, 1]
    assert abs(d[0]) == pytest.approx(8.0)
    assert np.max(np.abs(d[-250:])) < 0.05  # the last 5 s within 5 cm
    assert np.max(np.abs(series[:, 2])) < 10.0


@pytest.mark.parametrize("name,make", LAWS)
def test_settles_onto_a_circle_within_a_small_offset(name, make):
    r = 30.0
    series = fly(make(CirclePath(r)), VehicleState(r + 4.0, 0.0, math.pi / 2, V), 60.0)
    assert np.max(np.abs(series[-250:, 1])) < 1.0
    # steady state: the command settles near the turn demand of the circle it flies
    assert np.mean(series[-250:, 2]) == pytest.approx(V**2 / r, rel=0.1)


@pytest.mark.parametrize("name,make", LAWS)
def test_library_circle_path_gives_the_same_command_as_the_hand_circle(name, make):
    # The production Path (arc-length table, its own projection and look-ahead) against the
    # closed-form circle: same scene, same command.
    from companion.geometry.paths import parametric_path

    r = 30.0
    lib = parametric_path(lambda u: r * np.cos(u), lambda u: r * np.sin(u), (0.0, 2 * math.pi), closed=True)
    state = VehicleState(r + 2.0, 1.0, 1.7, V)
    a_lib = make(lib).step(0.0, state).a_cmd_m_s2
    a_hand = make(CirclePath(r)).step(0.0, state).a_cmd_m_s2
    assert a_lib == pytest.approx(a_hand, rel=1e-4, abs=1e-6)


def test_pure_pursuit_past_the_end_of_an_open_path_continues_it_straight():
    # Line to (1000, 0); vehicle at (995, 1): goal E + u t at distance 10 with w = E - P = (5, -1),
    # u = -5 + sqrt(25 - 26 + 100) -> goal (1000 + sqrt(99) - 5, 0).
    law = PurePursuitGuidance(LinePath(length_m=1000.0), PurePursuitParams(lookahead_m=10.0))
    out = law.step(0.0, VehicleState(995.0, 1.0, 0.0, V))
    gx = 995.0 + math.sqrt(99.0)
    assert out.lookahead_xy_m == pytest.approx((gx, 0.0), abs=1e-6)
    assert out.a_cmd_m_s2 == pytest.approx(2 * V**2 * math.sin(math.atan2(-1.0, gx - 995.0)) / 10.0, rel=1e-6)
