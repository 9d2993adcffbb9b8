"""WGS-84 geodetic coordinates to and from a local East-North-Up frame.

The conversion is exact (no flat-earth approximation): geodetic -> Earth-centred Earth-fixed
(ECEF) -> a rotation into the ENU axes at the origin. The inverse uses Bowring's method with
Newton refinement, accurate to well below a millimetre anywhere near the Earth's surface.

Conventions: latitude and longitude in degrees (north and east positive), heights in metres above
the WGS-84 ellipsoid. ENU: x east, y north, z up, metres, origin at the given geodetic point.

References: NIMA TR8350.2 (WGS-84 constants); B. Hofmann-Wellenhof et al., *GNSS* (2008), 5.6.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: WGS-84 semi-major axis (m) and flattening.
#: Three coordinates of one or many points (arrays of one shape, 0-d for a scalar input).
Triple = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)  # second eccentricity squared


def ecef_from_geodetic(lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike) -> Triple:
    """Earth-centred Earth-fixed coordinates (m) of geodetic points (arrays or scalars)."""
    lat = np.radians(np.asarray(lat_deg, dtype=float))
    lon = np.radians(np.asarray(lon_deg, dtype=float))
    h = np.asarray(alt_m, dtype=float)
    sin_lat = np.sin(lat)
    n_m = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)  # prime vertical radius
    x = (n_m + h) * np.cos(lat) * np.cos(lon)
    y = (n_m + h) * np.cos(lat) * np.sin(lon)
    z = (n_m * (1.0 - WGS84_E2) + h) * sin_lat
    return x, y, z


def geodetic_from_ecef(x_m: ArrayLike, y_m: ArrayLike, z_m: ArrayLike) -> Triple:
    """Geodetic latitude, longitude (degrees) and ellipsoidal height (m) of ECEF points."""
    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    z = np.asarray(z_m, dtype=float)
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    # Bowring's initial guess, then Newton-like fixed-point refinement of the latitude.
    theta = np.arctan2(z * WGS84_A_M, p * WGS84_B_M)
    lat = np.arctan2(z + WGS84_EP2 * WGS84_B_M * np.sin(theta) ** 3,
                     p - WGS84_E2 * WGS84_A_M * np.cos(theta) ** 3)
    for _ in range(3):
        sin_lat = np.sin(lat)
        n_m = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
        lat = np.arctan2(z + WGS84_E2 * n_m * sin_lat, p)
    sin_lat, cos_lat = np.sin(lat), np.cos(lat)
    n_m = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
    # Height: projection onto the normal (well conditioned at every latitude).
    h = p * cos_lat + z * sin_lat - n_m * (1.0 - WGS84_E2 * sin_lat * sin_lat)
    return np.degrees(lat), np.degrees(lon), h


def _enu_rotation(lat0_deg: float, lon0_deg: float) -> NDArray[np.float64]:
    """Rows: the east, north and up unit vectors at the origin, in ECEF."""
    lat0, lon0 = math.radians(lat0_deg), math.radians(lon0_deg)
    sl, cl = math.sin(lat0), math.cos(lat0)
    so, co = math.sin(lon0), math.cos(lon0)
    return np.array([
        [-so, co, 0.0],
        [-sl * co, -sl * so, cl],
        [cl * co, cl * so, sl],
    ])


def enu_from_geodetic(lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike, lat0_deg: float, lon0_deg: float,
                      alt0_m: float) -> Triple:
    """Local ENU coordinates (m) of geodetic points about the origin ``(lat0, lon0, alt0)``.

    Parameters
    ----------
    lat_deg, lon_deg, alt_m : the points (scalars or arrays of one shape).
    lat0_deg, lon0_deg, alt0_m : the origin.

    Returns
    -------
    (east_m, north_m, up_m)

    Examples
    --------
    >>> e, n, u = enu_from_geodetic(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    >>> float(e), float(n), float(u)
    (0.0, 0.0, 0.0)
    """
    x, y, z = ecef_from_geodetic(lat_deg, lon_deg, alt_m)
    x0, y0, z0 = ecef_from_geodetic(lat0_deg, lon0_deg, alt0_m)
    d = np.stack([x - x0, y - y0, z - z0])
    rot = _enu_rotation(lat0_deg, lon0_deg)
    east, north, up = np.tensordot(rot, d, axes=1)
    return east, north, up


def geodetic_from_enu(east_m: ArrayLike, north_m: ArrayLike, up_m: ArrayLike, lat0_deg: float, lon0_deg: float,
                      alt0_m: float) -> Triple:
    """Inverse of :func:`enu_from_geodetic`: ``(lat_deg, lon_deg, alt_m)`` of local ENU points."""
    rot = _enu_rotation(lat0_deg, lon0_deg)
    enu = np.stack([np.asarray(east_m, float), np.asarray(north_m, float), np.asarray(up_m, float)])
    dx, dy, dz = np.tensordot(rot.T, enu, axes=1)
    x0, y0, z0 = ecef_from_geodetic(lat0_deg, lon0_deg, alt0_m)
    return geodetic_from_ecef(x0 + dx, y0 + dy, z0 + dz)
