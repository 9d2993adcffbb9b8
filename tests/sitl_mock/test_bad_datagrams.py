"""Bad datagrams are counted by reason and dropped: they never crash the mock nor move the vehicle."""

from __future__ import annotations

import math
import random
import socket
import time

from pymavlink import mavutil
from sitl_mock_helpers import Client

M = mavutil.mavlink
VEL_ONLY = 0b0000_1111_1100_0111


def packer():
    return mavutil.mavlink.MAVLink(None, srcSystem=255, srcComponent=190)


def velocity_frame(mav, vn: float) -> bytes:
    msg = mav.set_position_target_local_ned_encode(0, 1, 1, M.MAV_FRAME_LOCAL_NED, VEL_ONLY, 0, 0, 0, vn, 0, 0,
                                                   0, 0, 0, 0, 0)
    return bytes(msg.pack(mav))


def mock_address(client: Client):
    client.wait("HEARTBEAT")
    (address,) = client.conn.clients  # pymavlink's udpin records who sent to it
    return address


def hover_position(client: Client):
    client.drain()
    return client.wait("LOCAL_POSITION_NED", 5.0)


def send_paced(sock: socket.socket, address, datagrams: list[bytes]) -> None:
    for i, data in enumerate(datagrams):
        sock.sendto(data, address)
        if i % 50 == 49:
            time.sleep(0.005)  # stay well inside the receive buffer


def test_each_kind_of_bad_datagram_is_counted_by_reason_and_moves_nothing(mock_factory):
    mock, client = mock_factory("--autopilot", "ardupilot", "--start-airborne", "--start-alt-m", "10",
                                "--speedup", "4", "--vel-bias-m-s", "0", "--vel-offset-m-s", "0")  # a hover that stays put
    address = mock_address(client)
    assert client.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == M.MAV_RESULT_ACCEPTED  # GUIDED: obeys targets
    assert client.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 50000) == M.MAV_RESULT_ACCEPTED
    before = hover_position(client)
    mav = packer()
    rng = random.Random(1)
    garbage = [bytes(rng.choice([b for b in range(256) if b not in (0xFD, 0xFE)]) for _ in range(rng.randint(1, 60)))
               for _ in range(50)]
    bad_crc = []
    for _ in range(40):
        frame = bytearray(velocity_frame(mav, 5.0))
        frame[-1] ^= 0xFF
        bad_crc.append(bytes(frame))
    truncated = [velocity_frame(mav, 5.0)[: rng.randint(3, 30)] for _ in range(30)]
    unknown = [bytes([0xFD, 4, 0, 0, i, 255, 190, 0xFE, 0xFF, 0xFF, 1, 2, 3, 4, 0x12, 0x34]) for i in range(20)]
    bad_flags = []
    for _ in range(10):
        frame = bytearray(velocity_frame(mav, 5.0))
        frame[2] = 0x02
        bad_flags.append(bytes(frame))
    nan_values = [velocity_frame(mav, math.nan) for _ in range(10)]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        send_paced(sock, address, garbage + bad_crc + truncated + unknown + bad_flags + nan_values)
        time.sleep(0.5)
        after = hover_position(client)
        assert math.dist((before.x, before.y, before.z), (after.x, after.y, after.z)) < 1e-3
        # The same frame, intact, is obeyed: the path the bad ones took does lead to the vehicle.
        for _ in range(10):
            sock.sendto(velocity_frame(mav, 5.0), address)
            time.sleep(0.02)
    assert client.wait("LOCAL_POSITION_NED", 5.0, lambda m: m.vx > 1.0) is not None
    mock.stop()
    counts = mock.summary()
    assert mock.proc.returncode == 0
    expected = {"garbage": 50, "bad_crc": 40, "truncated": 30, "unknown_id": 20, "bad_flags": 10, "bad_value": 10,
                "unsigned": 0, "bad_signature": 0, "decode_error": 0, "handler_error": 0}
    assert {k: int(counts[k]) for k in expected} == expected
    assert int(counts["rx_dropped"]) == 160


def test_random_and_mutated_datagrams_never_stop_the_mock(mock_factory):
    mock, client = mock_factory("--speedup", "4", "--start-airborne", "--start-alt-m", "5")
    address = mock_address(client)
    mav = packer()
    rng = random.Random(2026)
    valid = [velocity_frame(mav, 3.0), bytes(mav.command_long_encode(1, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav)),
             bytes(mav.param_set_encode(1, 1, b"COM_OF_LOSS_T", -1.0, 9).pack(mav))]
    datagrams = []
    for i in range(3000):
        kind = i % 3
        if kind == 0:
            datagrams.append(bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 280))))
        else:
            frame = bytearray(rng.choice(valid))
            for _ in range(rng.randint(1, 4)):
                frame[rng.randrange(len(frame))] = rng.getrandbits(8)
            if kind == 2:
                frame = frame[: rng.randint(1, len(frame))] + bytes([0xFD]) * rng.randint(0, 3)
            datagrams.append(bytes(frame))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        send_paced(sock, address, datagrams)
    time.sleep(0.5)
    # Still alive, still answering, still in Hold, still disarmable only by a real command.
    assert client.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == M.MAV_RESULT_ACCEPTED
    hb = client.wait("HEARTBEAT")
    assert hb.custom_mode == (4 << 16) | (3 << 24)
    mock.stop()
    counts = mock.summary()
    assert mock.proc.returncode == 0
    assert int(counts["rx_datagrams"]) >= 3000
    assert int(counts["rx_dropped"]) >= 2000
