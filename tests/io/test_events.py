"""The companion's own events in the tlog (STATUSTEXT from its component) and in log summary."""

from __future__ import annotations

import socket

from pymavlink import mavutil

from companion.io.link import MAV_SEVERITY_WARNING, MavLink
from companion.io.tlog import TlogWriter
from companion.replay.summary import format_summary, summarise_log

SHORT = "HOLD: position stale"
LONG = ("flight-health failsafe: no progress: 0.0 m in 5 s (expected >= 5.0 m at 5 m/s): "
        "vehicle not moving (on the ground? not flying?); stopping")  # 137 characters: 3 chunks
EXACT = "x" * 100  # two full chunks: an empty third chunk ends it


def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def recorded(tmp_path):
    path = tmp_path / "e.tlog"
    tlog = TlogWriter(path).open()
    link = MavLink(f"udpin:127.0.0.1:{free_port()}", tlog=tlog, source_system=1, source_component=191)
    link.record_event(SHORT)
    link.record_event(LONG, severity=MAV_SEVERITY_WARNING)
    link.record_event(EXACT)
    link.close(); tlog.close()
    return path


def test_events_are_statustext_chunks_from_the_companions_component(tmp_path):
    path = recorded(tmp_path)
    log = mavutil.mavlink_connection(str(path))
    msgs = []
    while (m := log.recv_match(type="STATUSTEXT")) is not None:
        msgs.append(m)
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in msgs} == {(1, 191)}
    assert len(LONG) == 137 and len(msgs) == 1 + 3 + 3  # 137 = 50 + 50 + 37; 100 = 50 + 50 + 0
    assert (msgs[0].id, msgs[0].text) == (0, SHORT)
    assert [(m.id, m.chunk_seq) for m in msgs[1:4]] == [(1, 0), (1, 1), (1, 2)]
    assert "".join(m.text for m in msgs[1:4]) == LONG
    assert [(m.id, m.chunk_seq, len(m.text)) for m in msgs[4:]] == [(2, 0, 50), (2, 1, 50), (2, 2, 0)]
    assert msgs[1].severity == 4


def test_log_summary_lists_the_events_reassembled(tmp_path):
    s = summarise_log(recorded(tmp_path))
    assert [(e["system"], e["component"], e["severity"], e["text"]) for e in s["statustext"]] == [
        (1, 191, "MAV_SEVERITY_INFO", SHORT),
        (1, 191, "MAV_SEVERITY_WARNING", LONG),
        (1, 191, "MAV_SEVERITY_INFO", EXACT),
    ]
    text = format_summary(s)
    assert f"  1/191 WARNING   {LONG}" in text
