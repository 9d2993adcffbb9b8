"""Replay runs at the loop rate the flight recorded, not one guessed from the tick times: on the
autopilot's clock under load the ticks' times are irregular (skipped ticks, autopilot time in
10 ms steps) and their median spacing was 0.03 s for a 50 Hz flight (a loaded full run: the
replayed commanded course 1.5 times too far ahead, vx off by 25 mm/s from the first tick)."""

from __future__ import annotations

import math

from companion.guidance.types import GuidanceOutput
from companion.io.state import PositionSample
from companion.loop.tick import TickConfig, compute_tick
from companion.mission import parse_mission
from companion.replay.flightlog import DEBUG_INDEX, read_flight
from companion.replay.replay import flight_rate_hz
from replay_tlogtools import TlogBuilder

# Tick times of a loaded 50 Hz flight on the autopilot's clock: spacings 0.01-0.04 s, median 0.03.
TIMES_S = [0.0, 0.04, 0.07, 0.08, 0.11, 0.15, 0.17, 0.20, 0.24, 0.26, 0.29, 0.33, 0.34]
MISSION = parse_mission("""\
name: line
speed_m_s: 5.0
altitude_m: 10.0
path: {type: waypoints, points_m: [[0, 0], [100, 0]]}
guidance: {l1_m: 10.0, method: corrector, rate_hz: 20}
""", "line.yaml")


class Turning:
    def step(self, t_s, state):
        return GuidanceOutput(a_cmd_m_s2=2.0, phase="close_range", crosstrack_m=0.0, s_proj_m=0.0)


def write_log(path, old_layout: bool) -> None:
    log = TlogBuilder()
    ap, comp = log.sender(1, 1), log.sender(1, 191)
    config = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0)
    for k, t in enumerate(TIMES_S):
        ms = 1000 + round(1000 * t)
        sample = PositionSample(ms, 0.0, 5.0 * t, -10.0, 0.0, 5.0, 0.0)
        row = list(compute_tick(Turning(), k, t, sample, 0.0, config, prev_course_rad=0.0).debug)
        if old_layout:  # written before the layout field: NaN padding from field 27 on
            for name in ("debug_layout", "yaw_ned_rad", "rate_hz"):
                row[DEBUG_INDEX[name]] = math.nan
        row += [math.nan] * (58 - len(row))
        log.add(t, 1, 1, ap.local_position_ned_encode(ms, 0.0, 5.0 * t, -10.0, 0.0, 5.0, 0.0))
        log.add(t + 0.001, 1, 191, comp.debug_float_array_encode(ms * 1000, b"guidance", 0, row))
    log.write(path)


def test_the_recorded_rate_is_the_rate_replayed(tmp_path):
    write_log(tmp_path / "f.tlog", old_layout=False)
    flight = read_flight(tmp_path / "f.tlog")
    assert [tk.debug[DEBUG_INDEX["rate_hz"]] for tk in flight.ticks] == [50.0] * len(TIMES_S)
    assert flight_rate_hz(flight, MISSION) == 50.0  # not the mission's 20 Hz, not the spacing's 33


def test_a_log_from_before_the_field_falls_back_to_the_median_tick_spacing(tmp_path):
    # What replay did for every log: here 1 / 0.03 s, rounded to a whole 33 Hz (within 1 %),
    # the wrong rate the field puts right.
    write_log(tmp_path / "f.tlog", old_layout=True)
    flight = read_flight(tmp_path / "f.tlog")
    spacings = sorted(b - a for a, b in zip(TIMES_S, TIMES_S[1:]))
    assert math.isclose(spacings[len(spacings) // 2], 0.03)
    assert flight_rate_hz(flight, MISSION) == 33.0
