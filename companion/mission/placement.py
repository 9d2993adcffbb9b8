"""Placing a geodetic mission in the autopilot's local frame.

The autopilot reports positions (LOCAL_POSITION_NED) about its own EKF origin, which it
announces in GPS_GLOBAL_ORIGIN; a ``geodetic`` mission's ENU frame is centred on the mission's
``origin``. :func:`onto_autopilot_origin` moves the mission onto the autopilot's origin: the flight
(:mod:`companion.loop.runner`) does it with the origin the autopilot sends, replay
(:mod:`companion.replay.replay`) with the one recorded in the log.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from companion.geometry import geodetic
from companion.geometry.paths import Path
from companion.mission.model import Mission


class GeodeticPoint(Protocol):
    """A WGS-84 point (``companion.io.state.GlobalOrigin`` is one)."""

    @property
    def lat_deg(self) -> float: ...

    @property
    def lon_deg(self) -> float: ...


@dataclass(frozen=True)
class OriginShift:
    """How a geodetic mission was moved onto the autopilot's local origin.

    Attributes
    ----------
    east_m, north_m : ENU position of the mission's ``origin`` in the autopilot's local frame
        (the translation applied to the path and the start).
    max_error_m : the largest horizontal distance, over the path's nodes, between the translated
        point and the exact WGS-84 transform of that point into the autopilot's frame.
    autopilot_origin : the GPS_GLOBAL_ORIGIN used.
    """

    east_m: float
    north_m: float
    max_error_m: float
    autopilot_origin: GeodeticPoint


def onto_autopilot_origin(mission: Mission, ap_origin: GeodeticPoint) -> tuple[Mission, OriginShift]:
    """A geodetic mission with its path and start translated into the autopilot's local ENU frame.

    The mission's ENU frame is centred on ``mission.origin``; LOCAL_POSITION_NED is centred on the
    autopilot's EKF origin ``ap_origin``. The offset (east, north) of ``mission.origin`` seen from
    ``ap_origin`` is computed exactly (WGS-84 -> ECEF -> ENU, :mod:`companion.geometry.geodetic`)
    and added to every path node and to the start; tangents and curvature are unchanged.

    Both points are taken at one height, the mission's flight height ``origin.alt_m +
    altitude_m``: GPS_GLOBAL_ORIGIN's altitude is above mean sea level while ``origin.alt_m`` is
    above the ellipsoid, and the geoid separation (up to ~100 m) must not leak into the offset.
    Heights only scale horizontal distances by ~1.6e-7 per metre, so this costs nothing.

    A translation ignores the rotation between the two ENU frames (their axes differ by about
    d/R, d the distance between the origins, R the Earth's radius, plus a meridian convergence
    of about (d_east/R) tan(lat) about the vertical). A path point r metres from the mission's
    origin is therefore misplaced by about r d (1 + |tan lat|) / R: 1 km of path 100 m from the
    EKF origin at 47 deg gives ~3 cm. The exact error over the path's nodes is measured and
    returned in :class:`OriginShift` (``max_error_m``) so the flight can report it.

    Returns
    -------
    (mission, OriginShift)
    """
    o = mission.origin
    height_m = o.alt_m + mission.altitude_m
    e, n, _ = geodetic.enu_from_geodetic(o.lat_deg, o.lon_deg, height_m,
                                         ap_origin.lat_deg, ap_origin.lon_deg, height_m)
    east_m, north_m = float(e), float(n)
    path = mission.path
    xs = np.asarray(path.x_table_m)
    ys = np.asarray(path.y_table_m)
    # Exact: path nodes (ENU about the mission origin, at flight height) -> WGS-84 -> ENU about
    # the autopilot's origin at the same height.
    lat, lon, h = geodetic.geodetic_from_enu(xs, ys, np.zeros_like(xs), o.lat_deg, o.lon_deg, height_m)
    ex, ny, _ = geodetic.enu_from_geodetic(lat, lon, h, ap_origin.lat_deg, ap_origin.lon_deg, height_m)
    max_error_m = float(np.max(np.hypot(ex - (xs + east_m), ny - (ys + north_m))))
    moved = Path(path.s_table_m, xs + east_m, ys + north_m, path.tx_table, path.ty_table,
                    path.k_table_1_m, path.closed)
    start = mission.start
    if start is not None:
        start = dataclasses.replace(start, x_m=start.x_m + east_m, y_m=start.y_m + north_m)
    shifted = dataclasses.replace(mission, path=moved, start=start)
    return shifted, OriginShift(east_m, north_m, max_error_m, ap_origin)
