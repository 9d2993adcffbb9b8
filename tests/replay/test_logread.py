"""Reading tlogs: every record found, damage reported at its byte offset, never a traceback."""

from __future__ import annotations

import math
import random
import struct
from collections import Counter
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.io.logread import TlogReader, mode_name, read_tlog
from replay_tlogtools import TlogBuilder, heartbeat, iter_frames, local_position

DATA = Path("/work/shared/data")
COPTER_LOG = DATA / "ardupilot-copter-sitl-sine.tlog"


def mixed_traffic_log() -> TlogBuilder:
    """An autopilot, a companion, a ground station (MAVLink 1) and a camera, interleaved."""
    b = TlogBuilder()
    for i in range(100):
        t = i * 0.02
        b.add(t, 1, 1, local_position(i * 20, float(i), 0.0, -10.0, 1.0, 0.0, 0.0))
        b.add(t + 0.001, 1, 191, mavlink.MAVLink_set_position_target_local_ned_message(
            i * 20, 1, 1, 1, 1479, 0, 0, 0, 1.0, 0.0, 0.0, 0, 0, 0, 0, 0.1))
        if i % 10 == 0:
            b.add(t + 0.002, 255, 190, heartbeat(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID),
                  mavlink1=True)
            b.add(t + 0.003, 1, 100, heartbeat(mavlink.MAV_TYPE_CAMERA, mavlink.MAV_AUTOPILOT_INVALID))
    return b


def test_interleaved_senders_and_both_mavlink_versions_are_all_read(tmp_path):
    b = mixed_traffic_log()
    path = b.write(tmp_path / "mixed.tlog")
    records, warnings = read_tlog(path)
    assert warnings == []
    assert len(records) == len(b.records) == 220
    by_source = Counter((r.src_system, r.src_component, r.msg_type) for r in records)
    assert by_source[(1, 1, "LOCAL_POSITION_NED")] == 100
    assert by_source[(1, 191, "SET_POSITION_TARGET_LOCAL_NED")] == 100
    assert by_source[(255, 190, "HEARTBEAT")] == 10
    assert by_source[(1, 100, "HEARTBEAT")] == 10
    assert {r.mavlink_version for r in records if r.src_system == 255} == {1}
    assert {r.mavlink_version for r in records if r.src_system == 1} == {2}
    # offsets and times come from the framing written by the builder
    assert [r.offset for r in records] == b.offsets()
    assert records[1].time_s == pytest.approx(1_795_000_000.001, abs=1e-6)
    assert records[50].msg.x == pytest.approx(records[50].msg.time_boot_ms / 20)


def test_signed_mavlink2_packets_are_read_without_the_key(tmp_path):
    b = TlogBuilder()
    for i in range(5):
        b.add(i * 0.1, 1, 1, local_position(i, 1.0, 2.0, 3.0, 0, 0, 0), signing_key=bytes(range(32)))
    data = b.to_bytes()
    assert all(p[2] & 1 for _, _, p in iter_frames(data))  # really signed
    records, warnings = read_tlog(b.write(tmp_path / "signed.tlog"))
    assert warnings == [] and len(records) == 5
    assert records[4].msg.time_boot_ms == 4


def test_only_requested_ids_are_decoded_but_all_are_counted(tmp_path):
    path = mixed_traffic_log().write(tmp_path / "mixed.tlog")
    reader = TlogReader(path, decode_ids={mavlink.MAVLINK_MSG_ID_HEARTBEAT})
    records = list(reader)
    assert len(records) == 220
    assert all((r.msg is not None) == (r.msg_type == "HEARTBEAT") for r in records)


def test_file_cut_mid_packet_warns_at_the_cut_record_and_keeps_the_rest(tmp_path):
    b = mixed_traffic_log()
    data = b.to_bytes()
    offsets = b.offsets()
    cut_record = 150
    cut_at = offsets[cut_record] + 8 + 5  # inside the packet header
    path = tmp_path / "cut.tlog"
    path.write_bytes(data[:cut_at])
    records, warnings = read_tlog(path)
    assert len(records) == cut_record
    assert len(warnings) == 1
    assert warnings[0].offset == offsets[cut_record]
    assert warnings[0].length == cut_at - offsets[cut_record]
    assert "truncated" in warnings[0].reason or "ends" in warnings[0].reason


def test_garbage_in_the_middle_is_skipped_with_its_offset_and_length(tmp_path):
    b = mixed_traffic_log()
    data = b.to_bytes()
    offsets = b.offsets()
    rng = random.Random(7)
    # garbage rich in start bytes, to tempt a resync in the wrong place
    garbage = bytes(rng.choice([0xFD, 0xFE, 0x00, rng.randrange(256)]) for _ in range(301))
    at = offsets[80]
    path = tmp_path / "garbage.tlog"
    path.write_bytes(data[:at] + garbage + data[at:])
    records, warnings = read_tlog(path)
    assert len(records) == len(b.records)
    assert [(w.offset, w.length) for w in warnings] == [(at, len(garbage))]
    assert records[80].offset == at + len(garbage)


def test_flipped_byte_inside_a_packet_loses_only_that_record(tmp_path):
    b = mixed_traffic_log()
    data = bytearray(b.to_bytes())
    offsets = b.offsets()
    victim = 42
    data[offsets[victim] + 8 + 12] ^= 0x55  # a payload byte: the checksum no longer matches
    path = tmp_path / "flipped.tlog"
    path.write_bytes(bytes(data))
    records, warnings = read_tlog(path)
    assert len(records) == len(b.records) - 1
    assert [w.offset for w in warnings] == [offsets[victim]]
    assert warnings[0].length == offsets[victim + 1] - offsets[victim]
    assert "checksum" in warnings[0].reason or "CRC" in warnings[0].reason


def test_record_with_a_wild_timestamp_is_rejected(tmp_path):
    b = mixed_traffic_log()
    data = bytearray(b.to_bytes())
    offsets = b.offsets()
    struct.pack_into(">Q", data, offsets[10], 2**62)  # year ~146000
    path = tmp_path / "wildtime.tlog"
    path.write_bytes(bytes(data))
    records, warnings = read_tlog(path)
    assert len(records) == len(b.records) - 1
    assert [w.offset for w in warnings] == [offsets[10]]


def test_a_file_of_noise_reads_as_no_records_without_raising(tmp_path):
    path = tmp_path / "noise.tlog"
    path.write_bytes(bytes(random.Random(1).randrange(256) for _ in range(5000)))
    records, warnings = read_tlog(path)
    assert records == []
    assert warnings and warnings[0].offset == 0


@pytest.mark.parametrize(
    "autopilot, mav_type, custom_mode, expected",
    [
        (mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_TYPE_QUADROTOR, 6 << 16, "OFFBOARD"),
        (mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_TYPE_QUADROTOR, (4 << 16) | (3 << 24), "LOITER"),
        (mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_TYPE_FIXED_WING, (4 << 16) | (4 << 24), "MISSION"),
        (mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_QUADROTOR, 4, "GUIDED"),
        (mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_QUADROTOR, 17, "BRAKE"),
        (mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_FIXED_WING, 15, "GUIDED"),
        (mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_GROUND_ROVER, 4, "HOLD"),
        (mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_QUADROTOR, 999, "custom_mode 999"),
    ],
)
def test_custom_modes_decode_to_the_autopilots_names(autopilot, mav_type, custom_mode, expected):
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert mode_name(autopilot, mav_type, base, custom_mode) == expected


# -- the real ArduCopter SITL log -----------------------------------------------------------

@pytest.fixture(scope="module")
def copter_records():
    records, warnings = read_tlog(COPTER_LOG)
    return records, warnings


def test_copter_log_has_the_two_senders_its_readme_names(copter_records):
    records, _ = copter_records
    heartbeats = {(r.src_system, r.src_component): (r.msg.type, r.msg.autopilot)
                  for r in records if r.msg_type == "HEARTBEAT"}
    assert heartbeats == {
        (1, 1): (mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA),
        (1, 191): (mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID),
    }
    assert {r.mavlink_version for r in records} == {2}


def test_copter_log_damage_is_reported_and_everything_else_read(copter_records):
    records, warnings = copter_records
    # The file has short stretches that are not records (a cut STATUSTEXT, stray bytes);
    # each is reported once with its offset, and together they are a few dozen bytes.
    assert warnings, "the real log has unreadable stretches near its start"
    assert all(w.offset < 2000 for w in warnings)
    assert sum(w.length for w in warnings) < 100
    # pymavlink's own tlog reader, run independently, never finds a message kind more often
    from pymavlink import mavutil
    theirs = Counter()
    conn = mavutil.mavlink_connection(str(COPTER_LOG), dialect="ardupilotmega")
    while (msg := conn.recv_msg()) is not None:
        theirs[msg.get_type()] += 1
    ours = Counter(r.msg_type for r in records)
    for kind, count in theirs.items():
        if kind != "BAD_DATA" and not kind.startswith("UNKNOWN"):
            assert ours[kind] >= count, kind
    assert ours["LOCAL_POSITION_NED"] == theirs["LOCAL_POSITION_NED"]


def test_copter_log_setpoints_match_the_readme(copter_records):
    records, _ = copter_records
    setpoints = [r for r in records if r.msg_type == "SET_POSITION_TARGET_LOCAL_NED"]
    assert {r.msg.type_mask for r in setpoints} == {0b010111000111}
    assert {r.msg.coordinate_frame for r in setpoints} == {mavlink.MAV_FRAME_LOCAL_NED}
    span_s = setpoints[-1].time_s - setpoints[0].time_s
    assert 28.0 < span_s < 32.0  # "about 30 s of setpoints"
    positions = [r for r in records if r.msg_type == "LOCAL_POSITION_NED"]
    setpoint_rate = (len(setpoints) - 1) / span_s
    assert setpoint_rate == pytest.approx(50.0, rel=0.02)  # "at the LOCAL_POSITION_NED rate"
    assert positions[-1].msg.x == pytest.approx(106.0, abs=2.0)  # ends about 106 m north
    xtrack = [r for r in records if r.msg_type == "NAMED_VALUE_FLOAT" and r.msg.name == "xtrack"]
    assert len(xtrack) == len(setpoints)


def test_copter_log_stream_requests_and_arm_refusals_match_the_readme(copter_records):
    records, _ = copter_records
    intervals = {int(r.msg.param1): r.msg.param2 for r in records
                 if r.msg_type == "COMMAND_LONG" and r.msg.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL}
    assert intervals[mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED] == 20000  # 50 Hz
    assert intervals[mavlink.MAVLINK_MSG_ID_ATTITUDE] == 50000  # 20 Hz
    assert intervals[mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == 100000  # 10 Hz
    arm_acks = [r for r in records if r.msg_type == "COMMAND_ACK"
                and r.msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM]
    refused = [r for r in arm_acks if r.msg.result != mavlink.MAV_RESULT_ACCEPTED]
    accepted = [r for r in arm_acks if r.msg.result == mavlink.MAV_RESULT_ACCEPTED]
    assert refused and accepted
    refusing_s = accepted[0].time_s - records[0].time_s
    assert 40.0 < refusing_s < 48.0  # "refused for about 44 s"
    reasons = [r.msg.text for r in records if r.msg_type == "STATUSTEXT" and r.msg.text.startswith("Arm:")]
    assert len(reasons) >= len(refused)


def _same(u, v) -> bool:
    if isinstance(u, list):
        return len(u) == len(v) and all(_same(p, q) for p, q in zip(u, v))
    if isinstance(u, float) and math.isnan(u):
        return isinstance(v, float) and math.isnan(v)
    return u == v


@pytest.mark.parametrize("source", ["copter", "mixed", "companion"])
def test_light_decoding_gives_pymavlinks_field_values(source, tmp_path):
    if source == "companion":  # DEBUG_FLOAT_ARRAY rows: a long float array, NaN-padded
        from companion.replay.synthetic import write_synthetic_flight

        path = tmp_path / "companion.tlog"
        write_synthetic_flight(path, duration_s=2.0)
    else:
        path = COPTER_LOG if source == "copter" else mixed_traffic_log().write(tmp_path / "mixed.tlog")
    full = list(TlogReader(path))
    light = list(TlogReader(path, light=True))
    assert [r.offset for r in full] == [r.offset for r in light]
    for a, b in zip(full, light):
        assert b.msg.get_type() == a.msg.get_type()
        for name in a.msg.get_fieldnames():
            assert _same(getattr(a.msg, name), getattr(b.msg, name)), (a.msg_type, name)


def test_light_decoding_still_rejects_a_bad_checksum(tmp_path):
    b = mixed_traffic_log()
    data = bytearray(b.to_bytes())
    offsets = b.offsets()
    data[offsets[7] + 8 + 12] ^= 0x01
    path = tmp_path / "flipped.tlog"
    path.write_bytes(bytes(data))
    reader = TlogReader(path, light=True)
    assert len(list(reader)) == len(b.records) - 1
    assert [w.offset for w in reader.warnings] == [offsets[7]]


def test_fast_and_general_record_paths_agree_on_a_damaged_log(tmp_path):
    """Light reading takes a one-function path for ordinary records and falls back to the
    general one on anything unusual; full decoding always takes the general one. On a log with
    garbage, a flipped payload byte, a wild timestamp and a cut end, both must accept the same
    records at the same offsets and report the same stretches."""
    b = mixed_traffic_log()
    data = bytearray(b.to_bytes())
    offsets = b.offsets()
    data[offsets[30] + 8 + 12] ^= 0x10  # bad checksum
    struct.pack_into(">Q", data, offsets[55], 2**62)  # implausible timestamp
    rng = random.Random(3)
    garbage = bytes(rng.choice([0xFD, 0xFE, rng.randrange(256)]) for _ in range(97))
    at = offsets[120]
    damaged = bytes(data[:at]) + garbage + bytes(data[at:-5])  # and the last packet cut short
    path = tmp_path / "damaged.tlog"
    path.write_bytes(damaged)
    full = TlogReader(path)
    light = TlogReader(path, light=True)
    full_records, light_records = list(full), list(light)
    assert [(r.offset, r.msg_id, r.src_system, r.src_component, r.mavlink_version, r.time_s)
            for r in full_records] == \
        [(r.offset, r.msg_id, r.src_system, r.src_component, r.mavlink_version, r.time_s)
         for r in light_records]
    assert len(light_records) == len(b.records) - 3  # checksum, timestamp, cut end
    # (the reasons' wording differs: pymavlink's decode words its own checksum failures)
    assert [(w.offset, w.length) for w in full.warnings] == [(w.offset, w.length) for w in light.warnings]
    cut_at = at + len(garbage) + (offsets[-1] - at)  # the last record, shifted by the garbage
    assert [w.offset for w in light.warnings] == [offsets[30], offsets[55], at, cut_at]
