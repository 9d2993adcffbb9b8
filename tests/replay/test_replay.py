"""``companion replay``: a faithful log replays within tolerance, an edited one is caught at the tick.

The companion-style logs here come from :func:`write_synthetic_flight`, which runs the same
per-tick function as the flight loop against a kinematic vehicle and records what the loop
records. The edits are made on the bytes (value changed, checksum refreshed), so the replay sees
exactly what a tampered or buggy recording would contain.
"""

from __future__ import annotations

import json
import math
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from companion.cli.main import main
from companion.io.logread import read_tlog
from companion.replay.replay import replay_log
from companion.replay.synthetic import write_synthetic_flight
from replay_tlogtools import iter_frames, refresh_crc

COPTER_LOG = Path("/work/shared/data/ardupilot-copter-sitl-sine.tlog")
COPTER_MISSION = Path("/work/shared/data/ardupilot-copter-sitl-sine.yaml")

SPT_ID = 84
DFA_ID = 350
SPT_VX_OFFSET = 10 + 4 + 3 * 4  # header, time_boot_ms, x, y, z
SPT_YAW_RATE_OFFSET = 10 + 4 + 10 * 4  # header, time_boot_ms, x .. yaw
DFA_DATA_OFFSET = 10 + 8 + 2 + 10  # header, time_usec, array_id, name (data is an extension field)
FLIGHT_S = 30.0


@pytest.fixture(scope="module")
def flight(tmp_path_factory) -> Path:
    """A 30 s companion flight starting 25 m south of the racetrack: mid-course, then close range."""
    path = tmp_path_factory.mktemp("flight") / "flight.tlog"
    write_synthetic_flight(path, duration_s=FLIGHT_S, start_offset_m=(0.0, -25.0))
    return path


def copy_flight(flight: Path, dest: Path) -> Path:
    shutil.copy(flight, dest)
    shutil.copy(str(flight) + ".mission.yaml", str(dest) + ".mission.yaml")
    return dest


def companion_packets(data: bytes, msg_id: int) -> list[tuple[int, int]]:
    """(packet start offset, packet length) of each message ``msg_id`` from component 191."""
    out = []
    for offset, _, packet in iter_frames(data):
        if packet[0] == 0xFD and packet[6] == 191 and (packet[7] | packet[8] << 8 | packet[9] << 16) == msg_id:
            out.append((offset + 8, len(packet)))
    return out


def edit_float(data: bytearray, packet_at: int, length: int, field_offset: int, delta: float) -> tuple[float, float]:
    packet = bytearray(data[packet_at:packet_at + length])
    (old,) = struct.unpack_from("<f", packet, field_offset)
    struct.pack_into("<f", packet, field_offset, old + delta)
    refresh_crc(packet)
    data[packet_at:packet_at + length] = packet
    return old, struct.unpack_from("<f", packet, field_offset)[0]


def test_faithful_companion_log_replays_within_tolerance_exit_0(flight, capsys):
    assert main(["replay", str(flight), "--json"]) == 0
    j = json.loads(capsys.readouterr().out)
    ticks = int(FLIGHT_S * 50)
    assert j["kind"] == "companion"
    assert j["steps_compared"] == ticks
    assert j["within_tolerance"] is True and j["first_divergence"] is None
    assert j["rate_hz"] == 50.0
    for p in j["per_phase"].values():
        assert p["yaw_rate_max_rad_s"] <= 0.01 and p["vel_max_m_s"] <= 0.05
    # both phases were flown and the switch happened at the same tick time in log and replay
    assert set(j["per_phase"]) == {"midcourse", "close_range"}
    assert j["phase_switches"]["logged"] == j["phase_switches"]["replayed"]
    assert [s["to"] for s in j["phase_switches"]["logged"]] == ["close_range"]
    assert set(j["phases"]) == {"midcourse", "close_range"}
    for key in ("d_rms_m", "a_rms_m_s2", "a_max_m_s2"):
        assert j[key] is not None and j[key] >= 0


def test_flight_tracking_figures_are_the_recorded_ones(flight):
    # Independent: read the recorded rows directly and apply the metric definitions by hand.
    records, _ = read_tlog(flight)
    rows = [r.msg.data for r in records if r.msg_type == "DEBUG_FLOAT_ARRAY"]
    d = np.array([row[4] for row in rows])
    a = np.array([row[3] for row in rows])
    close = np.array([row[2] == 1 for row in rows])
    j = replay_log(flight).to_json()
    assert j["d_rms_m"] == pytest.approx(math.sqrt(np.mean(d * d)), rel=1e-9)
    assert j["a_max_m_s2"] == pytest.approx(np.max(np.abs(a)), rel=1e-9)
    assert j["phases"]["close_range"]["d_rms_m"] == pytest.approx(math.sqrt(np.mean(d[close] ** 2)), rel=1e-9)


@pytest.mark.parametrize("field_offset, delta, reason", [
    (SPT_YAW_RATE_OFFSET, 0.05, "yaw_rate"),
    (SPT_VX_OFFSET, -0.3, "velocity"),
])
def test_one_altered_setpoint_is_caught_at_that_tick_exit_1(flight, tmp_path, capsys, field_offset, delta, reason):
    tampered = copy_flight(flight, tmp_path / "tampered.tlog")
    data = bytearray(tampered.read_bytes())
    setpoints = companion_packets(bytes(data), SPT_ID)
    victim = 1234  # a close-range tick (the switch is near 20 s = tick 1000)
    old, new = edit_float(data, *setpoints[victim], field_offset, delta)
    tampered.write_bytes(bytes(data))

    assert main(["replay", str(tampered), "--json"]) == 1
    j = json.loads(capsys.readouterr().out)
    fd = j["first_divergence"]
    assert j["within_tolerance"] is False
    assert fd["tick"] == victim
    assert fd["time_s"] == pytest.approx(victim / 50.0, abs=0.002)
    assert fd["reasons"] == [reason]
    key = "yaw_rate_rad_s" if reason == "yaw_rate" else "vx_m_s"
    assert fd["logged"][key] == pytest.approx(new, abs=1e-6)
    assert fd["replayed"][key] == pytest.approx(old, abs=1e-5)
    assert abs(fd["logged"][key] - fd["replayed"][key]) == pytest.approx(abs(delta), rel=1e-3)
    assert j["steps_compared"] == int(FLIGHT_S * 50)


def test_altered_recorded_phase_is_caught_as_a_phase_divergence(flight, tmp_path):
    tampered = copy_flight(flight, tmp_path / "phase.tlog")
    data = bytearray(tampered.read_bytes())
    rows = companion_packets(bytes(data), DFA_ID)
    victim = 500  # mid-course: recorded phase code 0, rewritten as 1 (close_range)
    old, new = edit_float(data, *rows[victim], DFA_DATA_OFFSET + 2 * 4, 1.0)
    assert (old, new) == (0.0, 1.0)
    tampered.write_bytes(bytes(data))
    result = replay_log(tampered)
    assert result.exit_code == 1
    assert result.first_divergence["tick"] == victim
    assert result.first_divergence["reasons"] == ["phase"]


def test_log_cut_mid_packet_warns_and_replays_what_is_left(flight, tmp_path, capsys):
    cut = copy_flight(flight, tmp_path / "cut.tlog")
    data = cut.read_bytes()
    rows = companion_packets(data, DFA_ID)
    at, _ = rows[800]
    cut.write_bytes(data[:at + 20])  # inside tick 800's guidance row
    assert main(["replay", str(cut), "--json"]) == 0
    captured = capsys.readouterr()
    j = json.loads(captured.out)
    assert j["steps_compared"] == 800
    assert f"byte {at - 8}:" in captured.err
    assert j["warnings"][0]["offset"] == at - 8


def test_csv_and_plot_are_written(flight, tmp_path, capsys):
    csv_path, png_path = tmp_path / "ticks.csv", tmp_path / "replay.png"
    assert main(["replay", str(flight), "--csv", str(csv_path), "--plot", str(png_path)]) == 0
    out = capsys.readouterr().out
    assert "WITHIN tolerance" in out and "first divergence: none" in out
    lines = csv_path.read_text().splitlines()
    assert len(lines) == 1 + int(FLIGHT_S * 50)
    assert lines[0].startswith("t_s,tick,phase_logged,phase_replayed")
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_log_without_setpoints_exits_2(tmp_path, capsys):
    from replay_tlogtools import TlogBuilder, heartbeat

    b = TlogBuilder()
    for i in range(10):
        b.add(i * 1.0, 1, 1, heartbeat(2, 3, 4))
    path = b.write(tmp_path / "heartbeats.tlog")
    assert main(["replay", str(path), "--mission", str(COPTER_MISSION)]) == 2
    err = capsys.readouterr().err
    assert "nothing to replay" in err and "Traceback" not in err


def test_missing_mission_exits_2_naming_the_expected_file(flight, tmp_path, capsys):
    lonely = tmp_path / "lonely.tlog"
    shutil.copy(flight, lonely)
    assert main(["replay", str(lonely)]) == 2
    assert "lonely.tlog.mission.yaml" in capsys.readouterr().err


# -- the real ArduCopter log (flown by another controller) ---------------------------------

def crosstrack_by_dense_sampling(x_east: float, y_north: float) -> float:
    """Signed distance to x = 8 sin(0.08 y), left of the northbound path positive, by brute force."""
    ys = np.arange(y_north - 3.0, y_north + 3.0, 0.0005)
    xs = 8.0 * np.sin(0.08 * ys)
    dist = np.hypot(xs - x_east, ys - y_north)
    i = int(np.argmin(dist))
    east_of_path = x_east > xs[i]
    return -dist[i] if east_of_path else dist[i]


@pytest.fixture(scope="module")
def copter_replay():
    return replay_log(COPTER_LOG, COPTER_MISSION)


def test_copter_log_replays_without_crash_and_differs_as_expected(capsys):
    assert main(["replay", str(COPTER_LOG), "--mission", str(COPTER_MISSION), "--json"]) == 1
    j = json.loads(capsys.readouterr().out)
    assert j["kind"] == "setpoints"
    assert j["steps_compared"] == 1500  # every logged setpoint had a position before it
    assert j["within_tolerance"] is False and j["first_divergence"] is not None
    assert j["warnings"]  # the damaged stretches near the start of the file


def test_copter_log_positions_and_crosstrack_match_independent_geometry(copter_replay):
    s = copter_replay.series
    assert s["y_enu_m"][-1] == pytest.approx(106.0, abs=2.0)  # ends about 106 m north
    for i in range(0, s["t_s"].size, 97):
        expected = crosstrack_by_dense_sampling(s["x_enu_m"][i], s["y_enu_m"][i])
        assert s["crosstrack_m"][i] == pytest.approx(expected, abs=2e-3)


def test_copter_log_crosstrack_is_a_few_decimetres_rms(copter_replay):
    s = copter_replay.series
    d = s["crosstrack_m"]
    half = d[d.size // 2:]
    # README: "about 0.4 m RMS". Measured here (perpendicular distance): 0.38 m over the whole
    # 30 s of setpoints, 0.27 m over its second half; see docs/replay.md.
    assert copter_replay.tracking["d_rms_m"] == pytest.approx(0.4, abs=0.05)
    assert 0.2 < math.sqrt(np.mean(half * half)) < 0.45
    assert copter_replay.tracking["d_rms_m"] == pytest.approx(math.sqrt(np.mean(d * d)), rel=1e-12)


SAT_ID = 82
SAT_QX_OFFSET = 10 + 4 + 4  # header, time_boot_ms, q[0] (w)


@pytest.fixture(scope="module")
def plane_flight(tmp_path_factory) -> Path:
    """A 12 s fixed-wing flight: SET_ATTITUDE_TARGET setpoints (bank for a coordinated turn)."""
    path = tmp_path_factory.mktemp("plane") / "plane.tlog"
    write_synthetic_flight(path, duration_s=12.0, output="attitude")
    return path


def test_fixed_wing_log_replays_within_tolerance_by_attitude(plane_flight):
    result = replay_log(plane_flight)
    j = result.to_json()
    assert j["within_tolerance"] is True and j["steps_compared"] == 600
    p = j["per_phase"]["close_range"]
    assert p["attitude_max_rad"] <= 0.01 and p["vel_max_m_s"] is None
    # the replayed roll is the coordinated-turn bank of the replayed a_cmd: phi = atan(a / g), NED sign
    s = result.series
    expected = -np.arctan(s["a_replayed_m_s2"] / 9.80665)
    limit = math.radians(35.0)
    assert np.allclose(s["roll_replayed_rad"], np.clip(expected, -limit, limit), atol=1e-9)


def test_fixed_wing_altered_attitude_is_caught_at_that_tick(plane_flight, tmp_path):
    tampered = copy_flight(plane_flight, tmp_path / "plane.tlog")
    data = bytearray(tampered.read_bytes())
    victim = 345
    at, length = companion_packets(bytes(data), SAT_ID)[victim]
    edit_float(data, at, length, SAT_QX_OFFSET, 0.05)  # about 0.1 rad more roll
    tampered.write_bytes(bytes(data))
    result = replay_log(tampered)
    fd = result.first_divergence
    assert result.exit_code == 1
    assert fd["tick"] == victim and fd["reasons"] == ["attitude"]
    assert 0.05 < fd["attitude_diff_rad"] < 0.15


def test_interleaved_second_vehicle_and_ground_station_do_not_disturb_the_replay(flight, tmp_path):
    """Before every position of the flown vehicle, a second vehicle (system 2) reports a position
    with the same time_boot_ms 50 m away, and a ground station (255/190) sends a MAVLink 1
    heartbeat: replay must still pick the flown vehicle's samples."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    other = mavlink.MAVLink(None, srcSystem=2, srcComponent=1)
    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    out = bytearray()
    for _, time_us, packet in iter_frames(flight.read_bytes()):
        msg_id = packet[7] | packet[8] << 8 | packet[9] << 16
        if packet[5] == 1 and packet[6] == 1 and msg_id == 32:
            (boot_ms,) = struct.unpack_from("<I", packet, 10)
            decoy = mavlink.MAVLink_local_position_ned_message(boot_ms, 50.0, 50.0, -10.0, 1.0, 1.0, 0.0)
            hb = mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)
            out += struct.pack(">Q", time_us - 200) + bytes(decoy.pack(other))
            out += struct.pack(">Q", time_us - 100) + bytes(hb.pack(gcs, force_mavlink1=True))
        out += struct.pack(">Q", time_us) + packet
    busy = tmp_path / "busy.tlog"
    busy.write_bytes(bytes(out))
    shutil.copy(str(flight) + ".mission.yaml", str(busy) + ".mission.yaml")
    result = replay_log(busy)
    assert result.flight.warnings == []
    assert result.within_tolerance and result.steps_compared == int(FLIGHT_S * 50)


def test_position_dropout_holds_are_replayed_with_the_flights_stale_limit(tmp_path):
    """The stream stops from 4.0 s to 5.0 s; the flight ran with --stale-s 0.5 (not recorded).
    Ticks with 0.3 < age <= 0.5 s flew on, older ones held: replay must infer a limit that
    reproduces both, and with the default 0.3 s it would not."""
    from companion.mission import load_mission
    from companion.replay.flightlog import read_flight
    from companion.replay.replay import replay_flight, tick_config_for

    path = tmp_path / "dropout.tlog"
    write_synthetic_flight(path, duration_s=12.0, dropout_s=(4.0, 5.0), stale_s=0.5)
    j = replay_log(path).to_json()
    assert j["within_tolerance"] is True
    switches = [(s["from"], s["to"], round(s["time_s"], 2)) for s in j["phase_switches"]["logged"]]
    # the last sample is from t = 3.98 s, 4 ms old then: it passes 0.5 s at t = 4.476 s (tick 4.48)
    assert switches == [("close_range", "hold", 4.48), ("hold", "close_range", 5.0)]
    assert j["phase_switches"]["replayed"] == j["phase_switches"]["logged"]

    mission = load_mission(str(path) + ".mission.yaml")
    default = replay_flight(read_flight(path), mission, config=tick_config_for(mission, 50.0))
    assert default.first_divergence is not None and default.first_divergence["reasons"][-1] == "phase"
    assert default.first_divergence["time_s"] == pytest.approx(4.28, abs=0.011)  # age first > 0.3 s


@pytest.fixture(scope="module")
def coasting_flight(tmp_path_factory) -> Path:
    """Every re-optimising step outlives its tick by two ticks (as in the runner's worker thread):
    those ticks send coast setpoints, the late row is recorded afterwards without a setpoint."""
    path = tmp_path_factory.mktemp("coast") / "coast.tlog"
    write_synthetic_flight(path, duration_s=20.0, coast_ticks=2)
    return path


def test_coasting_ticks_are_replayed_with_coast_setpoint(coasting_flight):
    records, _ = read_tlog(coasting_flight)
    rows = sum(r.msg_type == "DEBUG_FLOAT_ARRAY" for r in records)
    setpoints = sum(r.msg_type == "SET_POSITION_TARGET_LOCAL_NED" for r in records)
    # each episode: the slow step's tick and the next coast (2 setpoints without a row), then
    # its row is recorded late and the third tick is stepped afresh: one step fewer per episode
    episodes = 1000 - rows
    assert setpoints == 1000 and episodes >= 3
    j = replay_log(coasting_flight).to_json()
    assert j["within_tolerance"] is True
    assert j["ticks"] == rows
    assert j["steps_compared"] == rows - episodes  # late rows are stepped, not compared
    # the two coasts before the first row (the very first step re-optimises) are outside the loop
    assert j["per_phase"]["coast"]["steps"] == 2 * episodes - 2
    assert j["per_phase"]["coast"]["vel_max_m_s"] <= 0.05


def test_altered_coast_setpoint_is_caught(coasting_flight, tmp_path):
    tampered = copy_flight(coasting_flight, tmp_path / "coast.tlog")
    data = bytearray(tampered.read_bytes())
    frames = list(iter_frames(bytes(data)))
    # a setpoint not preceded by a row within the same tick is a coast; take one after the start
    coast_at = None
    for (_, prev_us, prev), (off, us, pkt) in zip(frames, frames[1:]):
        msg_id = pkt[7] | pkt[8] << 8 | pkt[9] << 16
        prev_id = prev[7] | prev[8] << 8 | prev[9] << 16
        if pkt[6] == 191 and msg_id == SPT_ID and prev_id != DFA_ID and us - 1_795_000_000_000_000 > 2_000_000:
            coast_at = (off + 8, len(pkt), us)
            break
    assert coast_at is not None
    edit_float(data, coast_at[0], coast_at[1], SPT_YAW_RATE_OFFSET, 0.05)
    tampered.write_bytes(bytes(data))
    result = replay_log(tampered)
    fd = result.first_divergence
    assert result.exit_code == 1
    assert fd["coast"] is True and fd["reasons"] == ["yaw_rate"]
    assert fd["time_s"] == pytest.approx((coast_at[2] - 1_795_000_000_000_000) / 1e6, abs=0.02)


def test_synthetic_log_streams_the_recorded_arducopter_telemetry_at_its_rates(flight):
    """The synthetic flight's telemetry has the rates stated in TELEMETRY_STREAMS_HZ, and those are
    the rates the real ArduCopter SITL log streams while it is being commanded (ATTITUDE: the
    rate ``companion fly`` requests)."""
    from collections import Counter

    from companion.io.logread import MSG_NAME
    from companion.loop.runner import FlyOptions
    from companion.replay.synthetic import TELEMETRY_STREAMS_HZ

    records, warnings = read_tlog(flight, decode_ids=())
    assert warnings == []
    counts = Counter(MSG_NAME[r.msg_id] for r in records if r.src_component == 1)
    for name, hz in TELEMETRY_STREAMS_HZ.items():
        assert counts[name] == pytest.approx(hz * FLIGHT_S, abs=1), name
    assert counts["LOCAL_POSITION_NED"] == round(50 * FLIGHT_S)
    assert TELEMETRY_STREAMS_HZ["ATTITUDE"] == FlyOptions.attitude_rate_hz

    # The real log, over the 30 s its controller sent setpoints.
    real, _ = read_tlog(COPTER_LOG, decode_ids=())
    spt = [r.time_s for r in real if r.msg_id == SPT_ID]
    t0, t1 = spt[0], spt[-1]
    real_counts = Counter(MSG_NAME[r.msg_id] for r in real if t0 <= r.time_s <= t1 and r.src_component == 1)
    for name in ("GLOBAL_POSITION_INT", "GPS_RAW_INT", "VFR_HUD", "SYS_STATUS", "HEARTBEAT"):
        assert real_counts[name] / (t1 - t0) == pytest.approx(TELEMETRY_STREAMS_HZ[name], rel=0.25), name
