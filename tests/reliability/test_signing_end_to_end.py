"""MAVLink 2 signing end to end: ``--signing-key-file`` on ``companion fly`` and on sitl_mock.

- The same key on both (the companion given a passphrase, the mock the 64 hex characters of its
  SHA-256, which must be the same key): the flight works; unsigned and wrongly signed messages
  injected into both directions from the peers' own addresses, and the autopilot's own signed
  positions replayed, are rejected, counted, and change nothing (the guidance never sees the
  forged positions, the vehicle never follows the forged setpoints).
- The companion without the key: the autopilot drops everything it sends, so OFFBOARD is never
  acknowledged and the companion refuses to fly.
- Different keys: the companion rejects every autopilot message and never pairs.
"""

from __future__ import annotations

import hashlib
import time
from types import SimpleNamespace

import pytest

from figures import record
from harness import (MSG_LOCAL_POSITION_NED, PHASE_HOLD, Companion, Mock, free_udp_port, guidance_records,
                     read_tlog, write_mission)
from mavframes import Encoder
from udp_proxy import FaultProxy, msgid_of

F_PHASE, F_Y = 2, 9
PASSPHRASE = "correct horse battery staple"
KEY = hashlib.sha256(PASSPHRASE.encode()).digest()
OTHER_KEY = bytes(range(32))


def signed(msg) -> bool:
    """The frame as recorded is MAVLink 2 with the signed flag and the 13-byte signature."""
    buf = bytes(msg.get_msgbuf())
    return buf[0] == 0xFD and bool(buf[2] & 0x01) and len(buf) == 10 + buf[1] + 2 + 13


def test_same_key_flies_and_forged_messages_both_ways_are_rejected_and_counted(tmp_path):
    (tmp_path / "companion.key").write_text(PASSPHRASE + "\n")
    (tmp_path / "mock.key").write_text(KEY.hex() + "\n")
    port = free_udp_port()
    mission = write_mission(tmp_path)
    comp = Companion(mission, port, tmp_path / "c.tlog", "--max-duration-s", "5",
                     "--signing-key-file", str(tmp_path / "companion.key"))
    unsigned = Encoder(1, 1)
    wrong = Encoder(1, 1, signing_key=OTHER_KEY)
    unsigned_c = Encoder(1, 191)
    wrong_c = Encoder(1, 191, signing_key=OTHER_KEY)
    n_each = 0
    replayed = 0
    captured = []
    with FaultProxy(port) as proxy:
        def capture(datagram: bytes) -> bool:
            if msgid_of(datagram) == MSG_LOCAL_POSITION_NED:
                captured.append(datagram)
            return False
        proxy.up.faults.drop_if = capture
        mock = Mock(f"udpout:127.0.0.1:{proxy.port}", "--signing-key-file", str(tmp_path / "mock.key"),
                    tlog=tmp_path / "m.tlog")
        try:
            comp.wait_flying()
            old = list(captured[-40:])  # genuine signed positions, soon old
            t_ms = 50_000_000
            end = time.monotonic() + 2.0
            while time.monotonic() < end:
                # To the companion: a position 30 m north of the path, newer than anything real.
                proxy.inject_to_companion(unsigned.local_position(t_ms, x=30.0, vy=5.0))
                proxy.inject_to_companion(wrong.local_position(t_ms + 1, x=30.0, vy=5.0))
                # To the autopilot: fly north at 5 m/s.
                proxy.inject_to_autopilot(unsigned_c.position_target(vx=5.0))
                proxy.inject_to_autopilot(wrong_c.position_target(vx=5.0))
                # Genuine, correctly signed positions of the autopilot, replayed: their signing
                # timestamps are older than the stream's newest, so they fail the signature check.
                proxy.inject_to_companion(old[n_each % len(old)])
                replayed += 1
                n_each += 1
                t_ms += 20
                time.sleep(0.02)
            rc, summary = comp.result()
        finally:
            mock_summary = mock.stop()
    assert rc == 0 and summary["exit"] == "max duration", comp.stderr
    rej = summary["link"]["rejected"]
    assert rej["unsigned"] >= 0.9 * n_each, rej
    assert rej["bad_signature"] >= 0.9 * (n_each + replayed), rej
    assert rej["old_sample"] == 0  # the replays never got past the signature check
    assert mock_summary["unsigned"] >= 0.9 * n_each and mock_summary["bad_signature"] >= 0.9 * n_each
    msgs = read_tlog(tmp_path / "c.tlog")
    # Every message received and recorded by the companion is signed (incompat flag 0x01) ...
    received = [m for m in msgs if m.get_srcComponent() == 1]
    assert received and all(signed(m) for m in received)
    # ... and so is everything it sent (the tlog holds the bytes as sent).
    # (DEBUG_FLOAT_ARRAY and the companion's STATUSTEXT events are tlog-only records, never sent.)
    sent = [m for m in msgs if m.get_srcComponent() == 191 and m.get_type() not in ("DEBUG_FLOAT_ARRAY", "STATUSTEXT")]
    assert sent and all(signed(m) for m in sent)
    # The forged positions never reached the guidance; the forged setpoints never moved the vehicle.
    g = [r for r in guidance_records(msgs) if r.data[F_PHASE] != PHASE_HOLD]
    assert g and all(abs(r.data[F_Y]) < 0.5 for r in g)
    assert summary["hold_ticks"] == 0
    record("signing_same_key", forged_each_kind=n_each, signed_replays=replayed, companion_rejected=rej,
           mock_unsigned=mock_summary["unsigned"], mock_bad_signature=mock_summary["bad_signature"])


@pytest.fixture(scope="module")
def mismatched_keys(tmp_path_factory):
    """Two refusals run side by side (each waits seconds for answers that never come): a
    companion without a key, and one with a different key, each against a signing mock."""
    tmp = tmp_path_factory.mktemp("mismatched_keys")
    (tmp / "mock.key").write_text(KEY.hex())
    (tmp / "other.key").write_text(OTHER_KEY.hex())
    mission = write_mission(tmp)
    port_a, port_b = free_udp_port(), free_udp_port()
    comp_a = Companion(mission, port_a, tmp / "a.tlog")
    comp_b = Companion(mission, port_b, tmp / "b.tlog", "--signing-key-file", str(tmp / "other.key"),
                       "--heartbeat-timeout-s", "3")
    mock_a = mock_b = None
    try:
        mock_a = Mock(f"udpout:127.0.0.1:{port_a}", "--signing-key-file", str(tmp / "mock.key"),
                      tlog=tmp / "ma.tlog")
        mock_b = Mock(f"udpout:127.0.0.1:{port_b}", "--signing-key-file", str(tmp / "mock.key"))
        rc_a, summary_a = comp_a.result(60)
        rc_b, summary_b = comp_b.result(60)
    finally:
        comp_a.kill()
        comp_b.kill()
        mock_a_summary = mock_a.stop() if mock_a is not None else {}
        if mock_b is not None:
            mock_b.stop()
    return SimpleNamespace(
        no_key=SimpleNamespace(rc=rc_a, summary=summary_a, stderr=comp_a.stderr, mock=mock_a_summary,
                               mock_tlog=tmp / "ma.tlog"),
        other_key=SimpleNamespace(rc=rc_b, summary=summary_b, stderr=comp_b.stderr))


def test_companion_without_the_key_is_ignored_by_a_signing_autopilot_and_does_not_fly(mismatched_keys):
    f = mismatched_keys.no_key
    assert f.rc in (1, 2), f.stderr  # refused to start: no ACK for its requests
    assert f.summary["ticks"] == 0
    assert f.mock["unsigned"] > 0 and f.mock["rx_frames_ok"] == 0
    # The autopilot never acted on anything from the companion.
    assert not [m for m in read_tlog(f.mock_tlog) if m.get_srcComponent() == 191]


def test_different_keys_never_pair(mismatched_keys):
    f = mismatched_keys.other_key
    assert f.rc == 2, f.stderr
    assert "no HEARTBEAT" in f.stderr
    assert f.summary["link"]["rejected"]["bad_signature"] > 0
    assert f.summary["link"]["received"] == 0
