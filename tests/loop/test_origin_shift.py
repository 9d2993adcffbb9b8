"""Moving a geodetic mission onto the autopilot's origin: the offset and the translation's error.

Offsets are checked against local radii of curvature (independent of companion.geometry.geodetic);
the translation's error against the bound r d (1 + |tan lat|) / R stated in docs/flying.md.
"""

import math

import pytest

from companion.geometry.paths import waypoint_path
from companion.io.link import GlobalOrigin
from companion.loop.runner import onto_autopilot_origin
from companion.mission import Mission
from companion.mission.model import GeodeticOrigin, StartState

A_M = 6378137.0
E2 = (1.0 / 298.257223563) * (2.0 - 1.0 / 298.257223563)


def displaced(lat_deg, lon_deg, east_m, north_m, h_m=0.0):
    phi = math.radians(lat_deg)
    w = math.sqrt(1.0 - E2 * math.sin(phi) ** 2)
    m_m = A_M * (1.0 - E2) / w ** 3 + h_m
    n_m = A_M / w + h_m
    return lat_deg + math.degrees(north_m / m_m), lon_deg + math.degrees(east_m / (n_m * math.cos(phi)))


def mission_at(origin, length_m=1000.0, start=None):
    path = waypoint_path([(0.0, 0.0), (length_m / 2, 0.0), (length_m, 0.0)])
    return Mission(name="line", path=path, speed_m_s=5.0, altitude_m=10.0, frame="geodetic",
                   origin=origin, start=start)


@pytest.mark.parametrize("lat_deg", [0.0, 47.4, -35.4, 70.0])
def test_the_offset_is_the_mission_origin_seen_from_the_autopilot_origin(lat_deg):
    ap = GlobalOrigin(lat_deg, 8.5, 400.0, received_s=0.0)
    lat, lon = displaced(lat_deg, 8.5, -30.0, 60.0, h_m=10.0)
    m = mission_at(GeodeticOrigin(lat, lon, 0.0), start=StartState(1.0, 2.0, 0.5))
    moved, shift = onto_autopilot_origin(m, ap)
    assert shift.east_m == pytest.approx(-30.0, abs=0.002)
    assert shift.north_m == pytest.approx(60.0, abs=0.002)
    x0, y0 = moved.path.start_xy_m
    assert (x0, y0) == pytest.approx((-30.0 + 0.0, 60.0), abs=0.002)
    assert (moved.start.x_m, moved.start.y_m) == pytest.approx((1.0 + shift.east_m, 2.0 + shift.north_m))
    assert moved.start.heading_rad == 0.5 and moved.path.length_m == pytest.approx(m.path.length_m)
    # The origins' altitudes (400 m AMSL vs 0 m ellipsoidal) did not leak into the offset above;
    # the translation's error over 1 km of path is within the stated bound.
    assert shift.max_error_m <= 1000.0 * math.hypot(30.0, 60.0) * (1 + abs(math.tan(math.radians(lat_deg)))) / A_M


def test_the_translation_error_stays_within_the_stated_bound_and_grows_with_distance():
    lat0 = 47.0
    errors = []
    for d_m in (100.0, 1000.0, 5000.0):
        ap = GlobalOrigin(lat0, 8.0, 500.0, received_s=0.0)
        lat, lon = displaced(lat0, 8.0, d_m, 0.0, h_m=10.0)
        _, shift = onto_autopilot_origin(mission_at(GeodeticOrigin(lat, lon, 0.0)), ap)
        bound = 1000.0 * d_m * (1 + math.tan(math.radians(lat0))) / A_M
        assert shift.max_error_m <= bound
        errors.append(shift.max_error_m)
    # 100 m apart, 1 km of path: centimetres; the error grows about linearly with d.
    assert errors[0] < 0.04 and errors[2] > 20 * errors[0]
