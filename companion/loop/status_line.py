"""The flight's live status line, as one pure function of what the loop knows at a tick.

The flight loop fills a :class:`StatusFields` per tick and hands :func:`format_status_line`'s
text to its ``Status`` printer (rewritten in place on a terminal, once a second otherwise). An
unknown value (NaN: no rate measured before the second tick, no altitude before the first
position) prints as ``--``, never ``nan``.

Example
-------
>>> print(format_status_line(StatusFields(
...     t_s=12.34, phase="close_range", crosstrack_m=0.123, a_cmd_m_s2=-0.5, rate_hz=49.96,
...     link_age_s=0.4, rejected={}, mode="OFFBOARD", armed=True, altitude_m=10.04,
...     ground_speed_m_s=5.01, path_fraction=0.4249)))
t   12.3 s  close_range  OFFBOARD armed  alt 10.0 m  gs 5.0 m/s  path  42 %  xtrack  +0.12 m  a_cmd  -0.50 m/s2    50.0 Hz  link ok  rejected 0
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

#: A heartbeat younger than this shows ``link ok``; older ``link quiet N s``.
LINK_OK_S = 1.5


@dataclass(frozen=True)
class StatusFields:
    """What one status line shows. NaN (or None for the guidance fields on a hold) = unknown.

    ``rate_hz`` is the scheduler's achieved rate so far (NaN before two ticks); ``rejected`` the
    link's rejected-packet counts by reason; ``mode`` the autopilot's mode name (``""``: not
    known); ``armed`` None when not known; ``path_fraction`` the along-path progress
    ``s / length`` (0..1); ``health`` a health check's short verdict (``""`` when ok); ``ignored``
    the messages whose id the dialect does not know (not errors; shown when nonzero).
    """

    t_s: float
    phase: str
    crosstrack_m: float | None
    a_cmd_m_s2: float | None
    rate_hz: float
    link_age_s: float
    rejected: dict = field(default_factory=dict)
    mode: str = ""
    armed: bool | None = None
    altitude_m: float = math.nan
    ground_speed_m_s: float = math.nan
    path_fraction: float = math.nan
    health: str = ""
    ignored: int = 0


def _num(value, fmt: str, width: int) -> str:
    if isinstance(value, (int, float)) and math.isfinite(value):
        return format(value, fmt).rjust(width)
    return "--".rjust(width)


def format_status_line(s: StatusFields) -> str:
    """One line: time, phase, mode and armed state, altitude, ground speed, percent of the path,
    cross-track error, a_cmd, achieved rate, link state, rejected packets (and a health verdict)."""
    armed = "" if s.armed is None else (" armed" if s.armed else " disarmed")
    mode = f"{s.mode or '?'}{armed}"
    pct = s.path_fraction * 100.0 if isinstance(s.path_fraction, (int, float)) else math.nan
    rej_total = sum(s.rejected.values())
    rej = str(rej_total)
    if rej_total:  # the split by reason, largest first (bad_data 12, nan 3, ...)
        split = sorted(((n, k) for k, n in s.rejected.items() if n), reverse=True)
        rej = f"{rej_total} ({', '.join(f'{k} {n}' for n, k in split)})"
    link = ("link ok" if s.link_age_s < LINK_OK_S
            else f"link quiet {_num(s.link_age_s, '.1f', 0)} s")
    line = (f"t {_num(s.t_s, '.1f', 6)} s  {s.phase:<11}  {mode}  alt {_num(s.altitude_m, '.1f', 0)} m  "
            f"gs {_num(s.ground_speed_m_s, '.1f', 0)} m/s  path {_num(pct, '.0f', 3)} %  "
            f"xtrack {_num(s.crosstrack_m, '+.2f', 6)} m  a_cmd {_num(s.a_cmd_m_s2, '+.2f', 6)} m/s2  "
            f"{_num(s.rate_hz, '.1f', 6)} Hz  {link}  rejected {rej}")
    if s.ignored:
        line += f"  ignored {s.ignored} (unknown ids)"
    if s.health:
        line += f"  {s.health}"
    return line
