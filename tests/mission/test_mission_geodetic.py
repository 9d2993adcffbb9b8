"""WGS-84 to local ENU, checked against closed forms and published figures."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from companion.geometry.geodetic import (
    WGS84_A_M,
    WGS84_B_M,
    WGS84_E2,
    ecef_from_geodetic,
    enu_from_geodetic,
    geodetic_from_ecef,
    geodetic_from_enu,
)


def test_ecef_of_the_equator_and_the_pole_are_the_semi_axes():
    assert np.allclose(ecef_from_geodetic(0.0, 0.0, 0.0), (WGS84_A_M, 0.0, 0.0), atol=1e-6)
    assert np.allclose(ecef_from_geodetic(0.0, 90.0, 0.0), (0.0, WGS84_A_M, 0.0), atol=1e-6)
    assert np.allclose(ecef_from_geodetic(90.0, 0.0, 0.0), (0.0, 0.0, 6356752.314245), atol=1e-6)
    assert np.allclose(ecef_from_geodetic(0.0, 180.0, 100.0), (-(WGS84_A_M + 100.0), 0.0, 0.0), atol=1e-6)


def test_published_degree_lengths_at_the_equator():
    # One degree of longitude along the equator is 111.320 km, of latitude 110.574 km (Wikipedia,
    # "Latitude", table of degree lengths on WGS-84). 1/100 of a degree keeps the chord = the arc.
    e, n, _ = enu_from_geodetic(0.0, 0.01, 0.0, 0.0, 0.0, 0.0)
    assert float(e) == pytest.approx(1113.20, abs=0.01) and abs(float(n)) < 1e-6
    e, n, _ = enu_from_geodetic(0.01, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert float(n) == pytest.approx(1105.74, abs=0.01) and abs(float(e)) < 1e-6


@pytest.mark.parametrize("lat0", [-60.0, 0.0, 23.5, 47.3977419])
def test_point_on_the_same_parallel_by_hand(lat0):
    # A point on the parallel of the origin, dlon east: it lies on a circle of radius N cos(lat0)
    # about the polar axis, so east = N cos(lat0) sin(dlon) and up/north come from 1 - cos(dlon).
    dlon = 0.003
    n_m = WGS84_A_M / math.sqrt(1 - WGS84_E2 * math.sin(math.radians(lat0)) ** 2)
    rho = n_m * math.cos(math.radians(lat0))
    e, n, u = enu_from_geodetic(lat0, 8.0 + dlon, 0.0, lat0, 8.0, 0.0)
    drop = rho * (1 - math.cos(math.radians(dlon)))
    assert float(e) == pytest.approx(rho * math.sin(math.radians(dlon)), abs=1e-6)
    assert float(n) == pytest.approx(drop * math.sin(math.radians(lat0)), abs=1e-6)
    assert float(u) == pytest.approx(-drop * math.cos(math.radians(lat0)), abs=1e-6)


def test_height_moves_a_point_straight_up():
    e, n, u = enu_from_geodetic(47.0, 8.0, 530.0, 47.0, 8.0, 500.0)
    assert (float(e), float(n), float(u)) == pytest.approx((0.0, 0.0, 30.0), abs=1e-6)


def test_meridian_displacement_matches_the_meridian_radius():
    lat0, dlat = 45.0, 0.002
    mid = math.radians(lat0 + dlat / 2)
    m_m = WGS84_A_M * (1 - WGS84_E2) / (1 - WGS84_E2 * math.sin(mid) ** 2) ** 1.5
    _, n, _ = enu_from_geodetic(lat0 + dlat, 0.0, 0.0, lat0, 0.0, 0.0)
    assert float(n) == pytest.approx(m_m * math.radians(dlat), abs=1e-3)


@settings(max_examples=80, deadline=None)
@given(lat=st.floats(-89.0, 89.0), lon=st.floats(-179.0, 179.0), alt=st.floats(-400, 9000),
       e=st.floats(-5000, 5000), n=st.floats(-5000, 5000), u=st.floats(-100, 100))
def test_enu_round_trip(lat, lon, alt, e, n, u):
    lat1, lon1, alt1 = geodetic_from_enu(e, n, u, lat, lon, alt)
    e2, n2, u2 = enu_from_geodetic(lat1, lon1, alt1, lat, lon, alt)
    assert (float(e2), float(n2), float(u2)) == pytest.approx((e, n, u), abs=1e-6)


def test_ecef_round_trip_near_the_poles():
    for lat in (-89.999, 89.9999, 90.0):
        x, y, z = ecef_from_geodetic(lat, 10.0, 123.0)
        lat1, _, alt1 = geodetic_from_ecef(x, y, z)
        assert float(lat1) == pytest.approx(lat, abs=1e-9) and float(alt1) == pytest.approx(123.0, abs=1e-6)
    assert WGS84_B_M == pytest.approx(6356752.314245, abs=1e-6)
