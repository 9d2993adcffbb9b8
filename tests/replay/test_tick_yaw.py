"""The attitude yaw a replayed tick is given is the one the live tick had, not an ATTITUDE that
arrived while it was computing (the course falls back to the yaw below 0.5 m/s: a hovering start)."""

from __future__ import annotations

import math
import struct

from companion.io.state import PositionSample
from companion.loop.tick import TickConfig, compute_tick
from companion.guidance.types import GuidanceOutput
from companion.replay.flightlog import DEBUG_INDEX, read_flight
from replay_tlogtools import TlogBuilder

YAW_USED = 0.3  # the ATTITUDE the tick read
YAW_LATER = 0.9  # the ATTITUDE logged after it, before the tick's record


class Straight:
    def step(self, t_s, state):
        return GuidanceOutput(a_cmd_m_s2=0.0, phase="close_range", crosstrack_m=0.0, s_proj_m=0.0)


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def write_log(path, old_layout: bool) -> None:
    log = TlogBuilder()
    ap, comp = log.sender(1, 1), log.sender(1, 191)
    sample = PositionSample(1000, 0.0, 0.0, -10.0, 0.0, 0.0, 0.0)  # hovering: the course is the yaw
    result = compute_tick(Straight(), 0, 0.0, sample, 0.01, TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0),
                          yaw_ned_rad=YAW_USED)
    row = list(result.debug)
    if old_layout:  # a log written before the tick's yaw was recorded: NaN padding there
        row[DEBUG_INDEX["debug_layout"]] = row[DEBUG_INDEX["yaw_ned_rad"]] = math.nan
    row += [math.nan] * (58 - len(row))
    sp = result.setpoint
    packets = [  # (component, message)
        (1, ap.local_position_ned_encode(1000, 0.0, 0.0, -10.0, 0.0, 0.0, 0.0)),
        (1, ap.attitude_encode(1000, 0.0, 0.0, YAW_USED, 0.0, 0.0, 0.0)),
        (1, ap.attitude_encode(1010, 0.0, 0.0, YAW_LATER, 0.0, 0.0, 0.0)),
        (191, comp.debug_float_array_encode(1000 * 1000, b"guidance", 0, row)),
        (191, comp.set_position_target_local_ned_encode(1010, 1, 1, 1, 1479, 0.0, 0.0, 0.0, sp.vx_ned_m_s,
                                                        sp.vy_ned_m_s, sp.vz_ned_m_s, 0.0, 0.0, 0.0, 0.0,
                                                        sp.yaw_rate_ned_rad_s)),
    ]
    for i, (component, msg) in enumerate(packets):
        log.add(0.001 * i, 1, component, msg)
    log.write(path)


def test_the_tick_is_replayed_with_the_yaw_it_recorded(tmp_path):
    write_log(tmp_path / "f.tlog", old_layout=False)
    (tick,) = read_flight(tmp_path / "f.tlog").ticks
    assert tick.yaw_ned_rad == f32(YAW_USED)


def test_a_log_from_before_the_field_falls_back_to_the_newest_attitude(tmp_path):
    write_log(tmp_path / "f.tlog", old_layout=True)
    (tick,) = read_flight(tmp_path / "f.tlog").ticks
    assert tick.yaw_ned_rad == f32(YAW_LATER)
