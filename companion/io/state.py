"""Vehicle state as received from the autopilot, with the validity checks (no pymavlink here).

A ``LOCAL_POSITION_NED`` sample is copied into a :class:`PositionSample` only after
:func:`position_problem` found nothing wrong: NaN/inf fields and values outside physically
sensible bounds are rejected at the link and counted, never passed to the guidance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Largest accepted distance of a local position from the origin (metres, per axis).
MAX_POSITION_M = 100_000.0
#: Largest accepted velocity component (m/s).
MAX_VELOCITY_M_S = 300.0


@dataclass(frozen=True)
class PositionSample:
    """The fields of one LOCAL_POSITION_NED (NED, metres, m/s) plus when it was received."""

    time_boot_ms: int
    x_ned_m: float
    y_ned_m: float
    z_ned_m: float
    vx_ned_m_s: float
    vy_ned_m_s: float
    vz_ned_m_s: float
    received_s: float = math.nan  # receiver's monotonic clock when the sample arrived

    @property
    def time_s(self) -> float:
        """Autopilot time of the sample (seconds since its boot)."""
        return self.time_boot_ms / 1000.0


def position_problem(time_boot_ms, x, y, z, vx, vy, vz) -> str | None:
    """Why these LOCAL_POSITION_NED fields are unusable, or None when they are fine.

    >>> position_problem(10, 1.0, 2.0, -3.0, 0.0, 0.0, 0.0) is None
    True
    >>> position_problem(10, float("nan"), 2.0, -3.0, 0.0, 0.0, 0.0)
    'nan'
    """
    values = (x, y, z, vx, vy, vz)
    if not all(isinstance(v, (int, float)) for v in values):
        return "nan"
    if not all(math.isfinite(v) for v in values):
        return "nan"
    if any(abs(v) > MAX_POSITION_M for v in (x, y, z)):
        return "out_of_range"
    if any(abs(v) > MAX_VELOCITY_M_S for v in (vx, vy, vz)):
        return "out_of_range"
    if not isinstance(time_boot_ms, int) or time_boot_ms < 0:
        return "out_of_range"
    return None


def yaw_problem(roll, pitch, yaw) -> str | None:
    """Why ATTITUDE angles are unusable (NaN or beyond +-2 pi), or None."""
    for v in (roll, pitch, yaw):
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            return "nan"
        if abs(v) > 2.0 * math.pi + 1e-6:
            return "out_of_range"
    return None


@dataclass(frozen=True)
class GlobalOrigin:
    """The autopilot's local-frame origin as GPS_GLOBAL_ORIGIN reports it.

    ``lat_deg``/``lon_deg`` are WGS-84 (the message carries degE7); ``alt_amsl_m`` is the
    message's altitude, which both PX4 and ArduPilot give above mean sea level (mm on the wire),
    not above the ellipsoid. ``received_s`` is the link clock at reception.
    """

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    received_s: float


def global_origin_from_wire(latitude_e7: int, longitude_e7: int, altitude_mm: int,
                            received_s: float) -> GlobalOrigin | None:
    """A GPS_GLOBAL_ORIGIN's fields (degE7, degE7, mm) as a :class:`GlobalOrigin`, or None when
    they are out of range (latitude beyond +-90 deg, longitude beyond +-180 deg, altitude beyond
    +-100 km): the link and the log reader apply this one check.

    >>> global_origin_from_wire(473977420, 85455940, 488000, 0.0).lat_deg
    47.397742
    >>> global_origin_from_wire(910000000, 0, 0, 0.0) is None
    True
    """
    lat, lon, alt = latitude_e7 * 1e-7, longitude_e7 * 1e-7, altitude_mm * 1e-3
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and abs(alt) < 1.0e5):
        return None
    return GlobalOrigin(lat, lon, alt, received_s=received_s)
