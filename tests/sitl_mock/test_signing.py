"""MAVLink 2 signing: signed traffic both ways; unsigned and wrongly signed frames rejected and counted."""

from __future__ import annotations

import hashlib
import time

import pytest
from pymavlink import mavutil
from sitl_mock_helpers import Client, MockProcess, free_udp_port

from sitl_mock.links import load_signing_key

M = mavutil.mavlink
KEY_HEX = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"


def test_key_file_holds_hex_or_a_passphrase(tmp_path):
    hex_file = tmp_path / "hex.key"
    hex_file.write_text(KEY_HEX + "\n")
    assert load_signing_key(str(hex_file)) == bytes.fromhex(KEY_HEX)
    phrase_file = tmp_path / "phrase.key"
    phrase_file.write_text("correct horse battery staple\n")
    assert load_signing_key(str(phrase_file)) == hashlib.sha256(b"correct horse battery staple").digest()
    (tmp_path / "empty.key").write_text("\n")
    with pytest.raises(ValueError, match="empty"):
        load_signing_key(str(tmp_path / "empty.key"))


def signed_client(port: int, key: bytes, source_system: int = 255) -> Client:
    client = Client(port, source_system=source_system)
    client.conn.setup_signing(key, sign_outgoing=True)
    return client


@pytest.mark.parametrize("key_text", [KEY_HEX, "correct horse battery staple"])
def test_signed_link_works_and_unsigned_or_wrongly_signed_commands_are_dropped(tmp_path, key_text):
    key_file = tmp_path / "link.key"
    key_file.write_text(key_text)
    key = load_signing_key(str(key_file))
    port = free_udp_port()
    client = signed_client(port, key)
    mock = MockProcess("--link", f"udpout:127.0.0.1:{port}", "--speedup", "5", "--signing-key-file", str(key_file))
    try:
        hb = client.wait("HEARTBEAT")  # a client holding the key only accepts signed frames
        assert hb is not None and hb._signed
        (address,) = client.conn.clients
        # An unsigned sender and a sender with another key try to arm the vehicle.
        unsigned = mavutil.mavlink.MAVLink(None, srcSystem=250, srcComponent=1)
        wrong = mavutil.mavlink.MAVLink(None, srcSystem=251, srcComponent=1)
        wrong.signing.secret_key = hashlib.sha256(b"not the key").digest()
        wrong.signing.sign_outgoing = True
        wrong.signing.timestamp = int((time.time() - 1420070400) * 1e5)
        for mav in (unsigned, wrong):
            for _ in range(3):
                frame = mav.command_long_encode(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(mav)
                client.conn.port.sendto(bytes(frame), address)
        assert client.wait("COMMAND_ACK", 1.0) is None
        client.drain()
        assert not client.wait("HEARTBEAT").base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
        # The key holder can.
        assert client.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    finally:
        mock.stop()
        client.close()
    counts = mock.summary()
    assert (int(counts["unsigned"]), int(counts["bad_signature"])) == (3, 3)


def test_an_unsigned_client_hears_nothing_it_can_use(tmp_path):
    key_file = tmp_path / "link.key"
    key_file.write_text(KEY_HEX)
    port = free_udp_port()
    client = Client(port)
    mock = MockProcess("--link", f"udpout:127.0.0.1:{port}", "--speedup", "5", "--signing-key-file", str(key_file))
    try:
        hb = client.wait("HEARTBEAT")
        # pymavlink without a key still parses signed frames but cannot vouch for them.
        assert hb is None or not hb._signed
        assert client.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout_s=1.0) is None
    finally:
        mock.stop()
        client.close()
    assert int(mock.summary()["unsigned"]) >= 1
