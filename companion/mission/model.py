"""The mission value types: what a loaded mission file is, for every other layer."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from companion.geometry.paths import Path
from companion.geometry.profile import PathProfile, ProfileLimits
from companion.guidance.types import GuidanceParams, VehicleModel

ON_FINISH = ("hold", "loiter", "rtl", "land")


@dataclass(frozen=True)
class StartState:
    """Initial vehicle state for simulations, in local ENU (angles anticlockwise from east).

    Missions in ``local_ned`` are converted on loading, so this is always ENU.
    """

    x_m: float
    y_m: float
    heading_rad: float

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "heading_rad"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"start.{name}: expected a finite number, got {value!r}")


@dataclass(frozen=True)
class GeodeticOrigin:
    """The WGS-84 point the local ENU frame of a ``geodetic`` mission is centred on."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        if not (-90.0 <= self.lat_deg <= 90.0):
            raise ValueError(f"origin.lat_deg: expected -90..90, got {self.lat_deg!r}")
        if not (-180.0 <= self.lon_deg <= 180.0):
            raise ValueError(f"origin.lon_deg: expected -180..180, got {self.lon_deg!r}")
        if not math.isfinite(self.alt_m):
            raise ValueError(f"origin.alt_m: expected a finite number, got {self.alt_m!r}")


@dataclass(frozen=True)
class Mission:
    """A validated mission, ready to fly.

    Attributes
    ----------
    name : the mission's name.
    path : the reference path (:class:`companion.geometry.paths.Path`), always in local ENU metres.
    speed_m_s : constant ground speed V (also ``guidance.speed_m_s``).
    altitude_m : flight height above the local origin.
    guidance : :class:`companion.guidance.types.GuidanceParams` built from ``guidance:``,
        ``midcourse:`` and ``speed_m_s``.
    start : initial state for simulations (ENU), or None.
    on_finish : ``"hold"`` (default), ``"loiter"``, ``"rtl"`` or ``"land"``.
    source_text : the YAML text the mission was loaded from (recorded beside a flight's log).
    source_name : the file name (or label) used in error messages.
    frame : the frame the file was written in (``local_enu``, ``local_ned``, ``geodetic``).
    origin : the WGS-84 origin of a ``geodetic`` mission, else None.
    warnings : one-line warnings found while loading (e.g. curvature too tight for L1).
    profile : the altitude and speed along the path
        (:class:`companion.geometry.profile.PathProfile`), or None when both are one number.
        ``altitude_m`` and ``speed_m_s`` are then the profile's values at the path start.
    vehicle : the ``vehicle:`` block (:class:`companion.guidance.types.VehicleModel`), or None.
    accel_feedforward : ``guidance.accel_feedforward``: a velocity-output flight sends its lateral
        command as the setpoint's acceleration target too (:mod:`companion.io.setpoints`); None
        (absent): the autopilot's default (:func:`companion.loop.limits.accel_feedforward_max`).
    tail_compensation : ``guidance.tail_compensation``: a velocity-output flight compensates the
        velocity loop's slow tail (:mod:`companion.guidance.tail_comp`); None (absent): the
        autopilot's default (:func:`companion.loop.limits.velocity_tail`).
    lambda_stated : whether the mission states ``guidance.lambda_s4`` (a mission built in code does);
        when it does not, a flight that compensates the slow tail flies ``predictive`` at
        :data:`companion.guidance.types.TAIL_COMPENSATED_LAMBDA_S4`
        (:func:`companion.loop.limits.mission_for_tail`).
    profile_limits : the ``vertical:`` and ``along_track:`` limits
        (:class:`companion.geometry.profile.ProfileLimits`): those ``profile`` was smoothed to, and
        those a flight slows down for turns with (:func:`companion.mission.turns.slowed_for_turns`)
        even when the mission is flat.
    """

    name: str
    path: Path
    speed_m_s: float
    altitude_m: float = 10.0
    guidance: GuidanceParams = field(default_factory=GuidanceParams)
    start: StartState | None = None
    on_finish: str = "hold"
    source_text: str = ""
    source_name: str = "<mission>"
    frame: str = "local_enu"
    origin: GeodeticOrigin | None = None
    warnings: tuple[str, ...] = ()
    profile: PathProfile | None = None
    vehicle: VehicleModel | None = None
    profile_limits: ProfileLimits = field(default_factory=ProfileLimits)
    accel_feedforward: bool | None = None
    tail_compensation: bool | None = None
    lambda_stated: bool = True

    def __post_init__(self) -> None:
        if self.on_finish not in ON_FINISH:
            raise ValueError(f"on_finish: expected one of {', '.join(ON_FINISH)}, got {self.on_finish!r}")
        if not (math.isfinite(self.speed_m_s) and self.speed_m_s > 0):
            raise ValueError(f"speed_m_s: expected a finite number > 0, got {self.speed_m_s!r}")
        if not (math.isfinite(self.altitude_m) and self.altitude_m > 0):
            raise ValueError(f"altitude_m: expected a finite number > 0, got {self.altitude_m!r}")
