"""The live status line: every field by hand, and no ``nan`` on the first line."""

from __future__ import annotations

import math

from companion.loop.scheduler import FakeClock, FixedRateScheduler
from companion.loop.status_line import StatusFields, format_status_line


def fields(**kw):
    base = dict(t_s=0.0, phase="midcourse", crosstrack_m=80.0, a_cmd_m_s2=1.25, rate_hz=50.0,
                link_age_s=0.2, rejected={})
    base.update(kw)
    return StatusFields(**base)


def test_first_line_shows_no_nan_before_the_rate_is_measured():
    sched = FixedRateScheduler(50.0, FakeClock())
    sched.wait_next()
    assert math.isnan(sched.current_rate_hz())  # one tick: no rate yet
    line = format_status_line(fields(rate_hz=sched.current_rate_hz()))
    assert "nan" not in line and "    -- Hz" in line
    assert "alt -- m" in line and "gs -- m/s" in line and "path  -- %" in line and "? " in line


def test_every_field_by_hand():
    line = format_status_line(fields(
        t_s=61.26, phase="close_range", crosstrack_m=-0.456, a_cmd_m_s2=2.0, rate_hz=48.04,
        link_age_s=2.04, rejected={"nan": 3, "bad_data": 12, "unsigned": 0}, mode="GUIDED",
        armed=False, altitude_m=9.96, ground_speed_m_s=14.96, path_fraction=1.0,
        health="WARN clock"))
    assert line == ("t   61.3 s  close_range  GUIDED disarmed  alt 10.0 m  gs 15.0 m/s  path 100 %  "
                    "xtrack  -0.46 m  a_cmd  +2.00 m/s2    48.0 Hz  link quiet 2.0 s  "
                    "rejected 15 (bad_data 12, nan 3)  WARN clock")


def test_a_hold_tick_has_no_guidance_figures():
    line = format_status_line(fields(phase="hold", crosstrack_m=None, a_cmd_m_s2=None))
    assert "xtrack     -- m  a_cmd     -- m/s2" in line
