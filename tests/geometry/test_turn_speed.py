"""The speed lowered for the path's turns (companion.geometry.profile.turn_limited_speed), checked
against the closed forms of braking and turning, and its invariants on random tables."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from companion.geometry.profile import turn_limited_speed

DS = 0.05


def test_an_arc_between_straights_is_flown_at_the_capped_speed_braked_for_and_left_at_a_long():
    # A 10 m radius arc from 100 to 130 m, 6 m/s asked, 2 m/s^2 allowed for the turn, 0.5 m/s^2
    # along the track. In the arc V^2 = 2 * 10 = 20; braking from 36 to 20 at 0.5 m/s^2 takes
    # (36 - 20) / (2 * 0.5) = 16 m, so it starts at 84 m, and the speed is back at 146 m.
    s = np.arange(0.0, 250.0 + DS / 2, DS)
    kappa = np.where((s >= 100.0) & (s <= 130.0), 0.1, 0.0)
    v = turn_limited_speed(np.full(s.size, 6.0), kappa, DS, 2.0, 0.5, closed=False)
    assert np.all(np.abs(v[(s >= 100.0) & (s <= 130.0)] ** 2 - 20.0) < 1e-9)
    slowed = s[v < 6.0 - 1e-9]
    assert slowed.min() == pytest.approx(84.0, abs=1.5 * DS) and slowed.max() == pytest.approx(146.0, abs=1.5 * DS)
    mid_brake = np.argmin(np.abs(s - 92.0))  # half way: V^2 = 20 + 2 * 0.5 * 8 = 28
    assert v[mid_brake] ** 2 == pytest.approx(28.0, abs=1e-6)
    assert np.all(v[(s < 84.0 - DS) | (s > 146.0 + DS)] == 6.0)


def test_a_closed_circle_is_flown_at_one_speed_and_a_closed_path_brakes_across_its_joint():
    # A circle of radius 12 m: V = sqrt(0.8 * 2.5 * 12) everywhere.
    n = 2001
    v = turn_limited_speed(np.full(n, 5.0), np.full(n, 1.0 / 12.0), 75.4 / (n - 1), 2.0, 1.0, closed=True)
    assert np.allclose(v, math.sqrt(2.0 * 12.0), rtol=0, atol=1e-12)
    # A closed lap of 200 m with its turn at 0..10 m: the braking lies at the end of the table.
    s = np.arange(0.0, 200.0 + DS / 2, DS)
    kappa = np.where(s <= 10.0, 0.2, 0.0)
    v = turn_limited_speed(np.full(s.size, 5.0), kappa, DS, 2.0, 1.0, closed=True)
    assert v[0] == v[-1] == pytest.approx(math.sqrt(10.0))
    # braking from 25 to 10 takes 7.5 m: it begins 7.5 m before the joint, at 192.5 m
    assert s[(s > 100.0) & (v < 5.0 - 1e-9)].min() == pytest.approx(192.5, abs=1.5 * DS)


def test_turns_within_the_share_are_left_as_asked():
    s = np.arange(0.0, 100.0, DS)
    asked = 4.0 + np.sin(s / 10.0)  # any speeds
    kappa = np.full(s.size, 0.05)   # asks at most 25 * 0.05 = 1.25 m/s^2
    assert np.array_equal(turn_limited_speed(asked, kappa, DS, 1.25, 1.0, closed=False), asked)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), lateral=st.floats(0.5, 6.0), along=st.floats(0.2, 3.0),
       closed=st.booleans())
def test_never_faster_than_asked_or_the_cap_and_changes_at_a_long_at_most(seed, lateral, along, closed):
    rng = np.random.default_rng(seed)
    n = 800
    ds = 0.25
    kappa = np.convolve(rng.normal(0.0, 0.15, n), np.ones(25) / 25.0, mode="same")
    if closed:  # one speed round a lap (a periodic table), its last node the first
        asked = np.full(n, rng.uniform(1.0, 12.0))
        kappa[-1] = kappa[0]
    else:  # held speeds rate-limited in V^2, as a speed table is
        v2 = np.repeat(rng.uniform(1.0, 12.0, 8), n // 8) ** 2
        for i in range(1, n):
            v2[i] = min(max(v2[i], v2[i - 1] - 2 * along * ds), v2[i - 1] + 2 * along * ds)
        asked = np.sqrt(v2)
    v = turn_limited_speed(asked, kappa, ds, lateral, along, closed)
    assert np.all(np.isfinite(v)) and np.all(v > 0.0)
    assert np.all(v <= asked + 1e-12)
    assert np.all(v * v * np.abs(kappa) <= lateral * (1 + 1e-9))
    steps = np.abs(np.diff(v * v))
    assert np.all(steps <= 2.0 * along * ds * (1 + 1e-9))
    if closed:
        assert v[-1] == v[0]


def test_a_turn_too_tight_for_the_floor_speed_is_flown_at_it_and_slower_asks_stay():
    s = np.arange(0.0, 60.0 + DS / 2, DS)
    kappa = np.where((s >= 30.0) & (s <= 31.0), 50.0, 0.0)  # a 2 cm radius: 2 m/s^2 allows 0.2 m/s
    asked = np.where(s < 10.0, 0.5, 5.0)                     # 0.5 m/s asked over the first 10 m
    v = turn_limited_speed(asked, kappa, DS, 2.0, 1.0, closed=False, min_speed_m_s=1.0)
    assert np.all(v[(s >= 30.0) & (s <= 31.0)] == 1.0)
    assert np.all(v[s < 10.0 - DS] == 0.5)
    # from 0.5 m/s it speeds up at 1 m/s^2: past 1 m/s after (1 - 0.25) / 2 = 0.375 m
    assert v.min() == 0.5 and np.all(v[s >= 10.5] >= 1.0)
