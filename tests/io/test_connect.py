"""Connecting: connection strings as pymavlink spells them, one-line failures, no files left behind."""

from __future__ import annotations

import socket
import threading
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from companion.errors import LinkError, LogError
from companion.io.link import MavLink, connect_autopilot
from companion.io.tlog import TlogWriter
from peer import FakeAutopilot


def free_port(kind=socket.SOCK_DGRAM):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def heartbeats_until(stop: threading.Event, ap: FakeAutopilot, period_s=0.05):
    while not stop.is_set():
        ap.heartbeat()
        time.sleep(period_s)


def test_udp_listens_like_udpin_as_pymavlink_and_mavproxy_take_it():
    # pymavlink: mavlink_connection("udp:...") is mavudp(input=True), a server socket.
    port = free_port()
    link = MavLink(f"udp:127.0.0.1:{port}")
    ap = FakeAutopilot(("127.0.0.1", port), system_id=3)
    ap.heartbeat()
    end = time.monotonic() + 2.0
    while link.info is None and time.monotonic() < end:
        link.poll(0.05)
    assert link.info is not None and link.info.system_id == 3
    link.send_heartbeat()  # replies go to the paired autopilot's address
    assert any(m.get_type() == "HEARTBEAT" for m in ap.drain(0.3))
    link.close(); ap.close()


def test_refused_tcp_is_one_line_without_pymavlinks_sleeping_noise(capfd):
    port = free_port(socket.SOCK_STREAM)  # nothing listens there
    t0 = time.monotonic()
    with pytest.raises(LinkError) as err:
        MavLink(f"tcp:127.0.0.1:{port}")
    out, errtext = capfd.readouterr()
    assert out == "" and errtext == ""  # pymavlink prints "[Errno 111] Connection refused sleeping"
    msg = str(err.value)
    assert "\n" not in msg and "Errno" not in msg
    assert msg.startswith(f"tcp:127.0.0.1:{port}: connection refused")
    assert err.value.__cause__ is None
    assert time.monotonic() - t0 < 3.0  # two quiet retries, half a second apart


def test_tcp_link_pairs_and_a_closed_connection_is_one_line():
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    port = srv.getsockname()[1]
    link = MavLink(f"tcp:127.0.0.1:{port}")
    conn, _ = srv.accept()
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    conn.sendall(mav.heartbeat_encode(2, 3, 0, 4, 4).pack(mav))  # ArduPilot copter
    end = time.monotonic() + 2.0
    while link.info is None and time.monotonic() < end:
        link.poll(0.05)
    assert (link.info.autopilot, link.info.vehicle) == ("ardupilot", "copter")
    link.send_heartbeat()
    conn.settimeout(2.0)
    assert conn.recv(1024)[:1] == b"\xfd"  # our MAVLink 2 heartbeat arrived
    conn.close()
    with pytest.raises(LinkError, match=r"^tcp:127\.0\.0\.1:\d+: connection closed by the autopilot$"):
        for _ in range(100):
            link.poll(0.05)
    link.close(); srv.close()


def test_serial_baud_rate_that_is_not_a_number_names_the_baud_rate():
    with pytest.raises(LinkError) as err:
        MavLink("/dev/ttyACM0,abc")
    msg = str(err.value)
    assert msg == ("/dev/ttyACM0,abc: baud rate 'abc' is not a positive whole number "
                   "(expected DEVICE,BAUD, e.g. /dev/ttyACM0,921600)")
    assert "invalid literal" not in msg


@pytest.mark.parametrize("connect, words", [
    ("udpin:127.0.0.1:notaport", "port 'notaport' is not a number 1..65535"),
    ("udpin:127.0.0.1:70000", "port '70000' is not a number 1..65535"),
    ("tcp:5760", "expected tcp:HOST:PORT"),
])
def test_malformed_addresses_are_one_line(connect, words):
    with pytest.raises(LinkError, match=words):
        MavLink(connect)


def test_waiting_for_the_heartbeat_reports_what_and_how_long():
    port = free_port()
    lines = []
    link = MavLink(f"udp:127.0.0.1:{port}")
    with pytest.raises(LinkError, match="no HEARTBEAT from an autopilot within 2.2 s"):
        link.wait_heartbeat(2.2, progress=lines.append)
    link.close()
    head = f"waiting for a HEARTBEAT from an autopilot on udp:127.0.0.1:{port} (listening on 127.0.0.1:{port}): "
    assert [line[len(head):] for line in lines] == ["0 s of 2.2 s", "1 s of 2.2 s", "2 s of 2.2 s"]
    assert all(line.startswith(head) for line in lines)


def test_failed_connection_creates_no_file(tmp_path):
    tlog_path = tmp_path / "logs" / "flight.tlog"
    TlogWriter(tlog_path).check_writable()
    with pytest.raises(LinkError):
        connect_autopilot(f"udpin:127.0.0.1:{free_port()}", heartbeat_timeout_s=0.3)
    with pytest.raises(LinkError):
        connect_autopilot(f"tcp:127.0.0.1:{free_port(socket.SOCK_STREAM)}", heartbeat_timeout_s=0.3)
    assert list(tmp_path.iterdir()) == []


def test_unusable_log_path_is_refused_before_connecting_and_creates_nothing(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(LogError, match="cannot write the flight log"):
        TlogWriter(blocker / "sub" / "x.tlog").check_writable()
    with pytest.raises(LogError, match="free"):
        TlogWriter(tmp_path / "logs" / "y.tlog", min_free_bytes=1 << 62).check_writable()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_packets_before_the_tlog_exists_are_recorded_first_with_their_times(tmp_path):
    port = free_port()
    ap = FakeAutopilot(("127.0.0.1", port), system_id=9)
    stop = threading.Event()
    sender = threading.Thread(target=heartbeats_until, args=(stop, ap), daemon=True)
    sender.start()
    try:
        link = connect_autopilot(f"udpin:127.0.0.1:{port}", heartbeat_timeout_s=5.0)
    finally:
        stop.set()
        sender.join()
    paired_at = time.time()
    time.sleep(0.05)
    tlog = TlogWriter(tmp_path / "f.tlog").open()
    link.attach_tlog(tlog)
    link.send_heartbeat()
    link.close(); tlog.close(); ap.close()
    log = mavutil.mavlink_connection(str(tmp_path / "f.tlog"))
    msgs = []
    while (m := log.recv_match()) is not None:
        msgs.append(m)
    first_ap = next(m for m in msgs if m.get_srcSystem() == 9)
    assert first_ap.get_type() == "HEARTBEAT" and first_ap._timestamp <= paired_at
    times = [m._timestamp for m in msgs]
    assert times == sorted(times)
    assert msgs[-1].get_srcSystem() == 1 and msgs[-1]._timestamp > paired_at  # recorded after attach
