"""The corrector point, (x3, y3), the weights and the corrector's bound, against hand geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.guidance.corrector import (
    corrector_command,
    corrector_command_array,
    corrector_point,
    lookahead_speed_m_s,
)

V = 5.0
L1 = 10.0


def test_corrector_point_on_a_hand_drawn_scene():
    # Vehicle at (0, 2) heading east; projection (0, 0) with the path tangent at 30 deg;
    # look-ahead point (8, 8). The green line is x = 8 (perpendicular to east through P2);
    # the tangent line y = x tan30 meets it at (8, 8 tan30).
    t = (math.cos(math.pi / 6), math.sin(math.pi / 6))
    p4 = corrector_point(0.0, 2.0, 1.0, 0.0, 0.0, 0.0, t[0], t[1], 8.0, 8.0)
    assert p4 == pytest.approx((8.0, 8.0 * math.tan(math.pi / 6)))


def test_corrector_point_with_a_slanted_velocity():
    # Velocity at 90 deg (north): the green line through P2 = (3, 10) is y = 10. The tangent
    # line from (1, 0) with direction (1, 1)/sqrt2 meets y = 10 at (11, 10).
    s = 1 / math.sqrt(2)
    p4 = corrector_point(0.0, 0.0, 0.0, 1.0, 1.0, 0.0, s, s, 3.0, 10.0)
    assert p4 == pytest.approx((11.0, 10.0))


def test_no_corrector_point_when_the_tangent_is_parallel_to_the_green_line():
    # Flying north across a path running east: the tangent (east) is parallel to the green line.
    assert corrector_point(0.0, -3.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 5.0, 5.0) is None
    terms = corrector_command(0.0, -3.0, math.pi / 2, V, L1, (0.0, 0.0, 1.0, 0.0),
                              (6.0, 5.0, 1.0, 0.0, 0.05), 1.0, 100.0)
    assert not terms.corrector_used
    assert terms.a_cmd_m_s2 == pytest.approx(terms.a12_m_s2)


def test_p3_is_the_point_straight_ahead_on_the_green_line_and_l23_the_lateral_offset():
    # Vehicle at origin heading east, look-ahead at 10 m, 30 deg left: P3 = (10 cos30, 0).
    x2, y2 = 10 * math.cos(math.pi / 6), 10 * math.sin(math.pi / 6)
    terms = corrector_command(0.0, 0.0, 0.0, V, L1, (0.0, -1.0, 1.0, 0.0),
                              (x2, y2, math.cos(0.8), math.sin(0.8), 0.05), 1.0, 1.0)
    assert terms.p3_xy_m == pytest.approx((x2, 0.0))
    assert terms.l23_m == pytest.approx(5.0)  # L1 sin(eta12)
    # The tangent at the projection (0, -1) is east: the corrector point is (x2, -1), 1 m right.
    assert terms.corrector_xy_m == pytest.approx((x2, -1.0))
    assert terms.l43_m == pytest.approx(1.0)
    assert terms.l_c_m == pytest.approx(math.hypot(x2, 1.0))
    assert terms.a14_m_s2 == pytest.approx(2 * V * V * (-1.0) / (x2 * x2 + 1.0))


def test_weights_follow_the_paper_formulas():
    x2, y2 = 10 * math.cos(0.2), 10 * math.sin(0.2)
    k = 0.04  # curvature at P2: R_L1 = 25 m
    t2 = (math.cos(0.5), math.sin(0.5))
    terms = corrector_command(0.0, 0.0, 0.0, V, L1, (0.0, -0.5, 1.0, 0.0), (x2, y2, t2[0], t2[1], k), 0.7, 300.0)
    # v_l from |P2 - P1| constant: v_l cos(angle(LOS, t2)) = V cos(eta12).
    v_l = V * math.cos(0.2) / math.cos(0.5 - 0.2)
    assert terms.v_l_m_s == pytest.approx(v_l)
    v_m = (V + v_l) / 2
    w1 = 0.7 * 25.0 / (1 + terms.l23_m)
    w2 = 300.0 * v_m / (25.0 * (1 + terms.l43_m))
    assert terms.w1 == pytest.approx(w1)
    assert terms.w2 == pytest.approx(w2)
    expected = (w1 * terms.a12_m_s2 + w2 * terms.a14_m_s2) / (w1 + w2)
    assert terms.a_cmd_m_s2 == pytest.approx(expected)


def test_straight_stretch_gives_the_look_ahead_command():
    terms = corrector_command(0.0, 2.0, 0.1, V, L1, (0.0, 0.0, 1.0, 0.0), (9.8, 0.0, 1.0, 0.0, 0.0), 1.0, 1e4)
    assert terms.radius_l1_m == math.inf
    assert terms.a_cmd_m_s2 == pytest.approx(terms.a12_m_s2)
    # k1 = 0 on a straight: both weights vanish, the rule falls back to a12.
    terms0 = corrector_command(0.0, 2.0, 0.1, V, L1, (0.0, 0.0, 1.0, 0.0), (9.8, 0.0, 1.0, 0.0, 0.0), 0.0, 1e4)
    assert terms0.a_cmd_m_s2 == pytest.approx(terms0.a12_m_s2)


def test_vehicle_on_the_path_uses_itself_as_projection():
    # On a line heading along it: P4 = P3 = P2 on the line, every command is zero.
    terms = corrector_command(5.0, 0.0, 0.0, V, L1, (5.0, 0.0, 1.0, 0.0), (15.0, 0.0, 1.0, 0.0, 0.01), 1.0, 1e3)
    assert terms.corrector_xy_m == pytest.approx((15.0, 0.0))
    assert terms.a_cmd_m_s2 == pytest.approx(0.0, abs=1e-12)


def test_look_ahead_point_speed_is_capped_when_the_path_runs_across_the_line_of_sight():
    # LOS east, path at P2 heading north: v_l would be infinite.
    assert lookahead_speed_m_s(V, 0, 0, 1, 0, 10, 0, 0, 1) == pytest.approx(10 * V)
    assert lookahead_speed_m_s(V, 0, 0, 1, 0, 10, 0, 1, 0) == pytest.approx(V)


def test_corrector_bound_is_two_v2_over_l1_for_any_geometry():
    rng = np.random.default_rng(7)
    bound = 2 * V * V / L1
    for _ in range(3000):
        course = rng.uniform(-math.pi, math.pi)
        eta = rng.uniform(-math.pi, math.pi)
        x2, y2 = L1 * math.cos(course + eta), L1 * math.sin(course + eta)
        pa = rng.uniform(-math.pi, math.pi)
        proj = (rng.uniform(-8, 8), rng.uniform(-8, 8), math.cos(pa), math.sin(pa))
        la = rng.uniform(-math.pi, math.pi)
        look = (x2, y2, math.cos(la), math.sin(la), rng.uniform(-0.3, 0.3))
        k1, k2 = rng.uniform(0, 1), 10 ** rng.uniform(-2, 6)
        terms = corrector_command(0.0, 0.0, course, V, L1, proj, look, k1, k2)
        assert abs(terms.a_cmd_m_s2) <= bound + 1e-9
        if abs(eta) <= math.radians(60) and terms.corrector_used:
            # Below 60 deg the analytic bound V^2 / (L1 cos eta12) holds without saturation.
            assert abs(terms.a14_m_s2) <= V * V / (L1 * math.cos(eta)) + 1e-9


def test_vectorised_command_matches_the_scalar_one():
    rng = np.random.default_rng(3)
    for _ in range(300):
        course = rng.uniform(-math.pi, math.pi)
        eta = rng.uniform(-1.4, 1.4)
        x2, y2 = L1 * math.cos(course + eta), L1 * math.sin(course + eta)
        pa = course + rng.uniform(-1, 1)
        proj = (rng.uniform(-3, 3), rng.uniform(-3, 3), math.cos(pa), math.sin(pa))
        la = course + rng.uniform(-1, 1)
        look = (x2, y2, math.cos(la), math.sin(la), rng.uniform(-0.2, 0.2))
        k1, k2 = rng.uniform(0, 1), 10 ** rng.uniform(-2, 6)
        scalar = corrector_command(0.0, 0.0, course, V, L1, proj, look, k1, k2).a_cmd_m_s2
        vec = corrector_command_array(np.zeros(1), np.zeros(1), np.array([course]), V, L1, proj[0], proj[1],
                                      proj[2], proj[3], x2, y2, look[2], look[3], look[4],
                                      np.array([k1]), np.array([k2]))
        assert vec[0] == pytest.approx(scalar, rel=1e-9, abs=1e-12)
