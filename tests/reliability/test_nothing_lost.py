"""Nothing lost: the flight log is complete and readable however the companion stops.

Endings: SIGINT (Ctrl-C), SIGTERM, a link timeout (the autopilot dies) and an exception raised
inside the guidance loop. For each, the companion's tlog must

- end exactly on a record boundary (8-byte timestamp + one whole MAVLink frame, checked by
  walking the file with the frame-length arithmetic of the MAVLink spec, not with pymavlink);
- be read to the end by pymavlink's ``mavlogdump.py`` with the same number of messages;
- hold every setpoint the autopilot received from it (compared byte for byte with the mock's
  own tlog of what it accepted), i.e. be complete up to the last message sent.

An unwritable log path is refused at start, before any link is opened.
"""

from __future__ import annotations

import signal
import struct
import time

import pytest

from harness import Companion, Mock, free_udp_port, mavlogdump, read_tlog, write_mission

SETPOINT = "SET_POSITION_TARGET_LOCAL_NED"


def walk_tlog(path) -> list[bytes]:
    """Frames of a tlog by the spec's arithmetic; AssertionError if it does not end on a boundary."""
    data = path.read_bytes()
    frames = []
    i = 0
    while i < len(data):
        assert len(data) - i >= 8 + 3, f"{path}: partial record at byte {i}"
        usec = struct.unpack(">Q", data[i:i + 8])[0]
        assert 1.6e15 < usec < 4e15, f"{path}: bad timestamp at byte {i}"
        j = i + 8
        magic, length = data[j], data[j + 1]
        if magic == 0xFD:
            size = 10 + length + 2 + (13 if data[j + 2] & 0x01 else 0)
        elif magic == 0xFE:
            size = 6 + length + 2
        else:
            raise AssertionError(f"{path}: no MAVLink magic at byte {j}")
        assert j + size <= len(data), f"{path}: frame cut at the end (byte {j})"
        frames.append(data[j:j + size])
        i = j + size
    return frames


def check_log_complete(tlog, mock_tlog=None) -> dict:
    frames = walk_tlog(tlog)
    assert frames, f"{tlog}: empty"
    dump = mavlogdump(tlog)
    assert dump.returncode == 0, dump.stderr
    lines = [ln for ln in dump.stdout.splitlines() if ln.strip()]
    assert len(lines) == len(frames), (len(lines), len(frames))
    msgs = read_tlog(tlog)
    assert len(msgs) == len(frames) and not [m for m in msgs if m.get_type() == "BAD_DATA"]
    out = {"records": len(frames)}
    if mock_tlog is not None:
        ours = {bytes(m.get_msgbuf()) for m in msgs if m.get_type() == SETPOINT}
        theirs = [bytes(m.get_msgbuf()) for m in read_tlog(mock_tlog)
                  if m.get_type() == SETPOINT and m.get_srcComponent() == 191]
        assert theirs, "the autopilot received no setpoint"
        missing = [b for b in theirs if b not in ours]
        assert not missing, f"{len(missing)} setpoints the autopilot received are missing from the tlog"
        out["setpoints_received_by_autopilot"] = len(theirs)
    return out


@pytest.fixture(scope="module")
def signalled_flights(tmp_path_factory):
    """Two flights side by side, one stopped with SIGINT (Ctrl-C), one with SIGTERM, 1.5 s into
    the guidance loop. Returns {signal name: (rc, stderr, directory, mission file)}."""
    out = {}
    runs = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        tmp = tmp_path_factory.mktemp(sig.name)
        port = free_udp_port()
        mission = write_mission(tmp)
        comp = Companion(mission, port, tmp / "c.tlog")
        runs.append((sig, tmp, mission, comp, Mock(f"udpout:127.0.0.1:{port}", tlog=tmp / "m.tlog")))
    try:
        for _, _, _, comp, _ in runs:
            comp.wait_flying()
        time.sleep(1.5)
        for sig, _, _, comp, _ in runs:
            comp.signal(sig)
        for sig, tmp, mission, comp, _ in runs:
            out[sig.name] = (comp.wait(30), comp.stderr, tmp, mission)
        time.sleep(0.3)  # let the mocks record anything still in flight
    finally:
        for _, _, _, comp, mock in runs:
            comp.kill()
            mock.stop()
    return out


@pytest.mark.parametrize("sig, expected_rc", [("SIGINT", 130), ("SIGTERM", 1)], ids=["SIGINT", "SIGTERM"])
def test_signal_mid_flight_leaves_a_complete_readable_tlog(signalled_flights, sig, expected_rc):
    rc, stderr, tmp, mission = signalled_flights[sig]
    assert rc == expected_rc, stderr
    assert "Traceback" not in stderr
    check_log_complete(tmp / "c.tlog", tmp / "m.tlog")
    assert (tmp / "c.tlog.mission.yaml").read_text() == mission.read_text()


def test_link_timeout_leaves_a_complete_readable_tlog_and_stops_sending(tmp_path):
    port = free_udp_port()
    mission = write_mission(tmp_path)
    comp = Companion(mission, port, tmp_path / "c.tlog", "--link-timeout-s", "1")
    mock = Mock(f"udpout:127.0.0.1:{port}", tlog=tmp_path / "m.tlog")
    comp.wait_flying()
    time.sleep(1.0)
    t_kill = time.time()
    mock.kill()
    rc, summary = comp.result(30)
    assert rc == 2, comp.stderr
    assert "heartbeat lost" in summary["exit"]
    check_log_complete(tmp_path / "c.tlog")
    msgs = read_tlog(tmp_path / "c.tlog")
    last_sp = max(m._timestamp for m in msgs if m.get_type() == SETPOINT)
    # The last heartbeat came at most 1 s before the kill; timeout 1 s; then nothing more.
    assert last_sp - t_kill < 1.0 + 0.3
    assert summary["setpoints_sent"] == len([m for m in msgs if m.get_type() == SETPOINT])


class ExplodingGuidance:
    """The mission's guidance that raises after ``n`` ticks (a bug in the loop)."""

    def __init__(self, inner, n: int):
        self.inner, self.n, self.calls = inner, n, 0

    def step(self, t_s, state):
        self.calls += 1
        if self.calls > self.n:
            raise RuntimeError("injected failure in the guidance")
        return self.inner.step(t_s, state)


def test_exception_in_the_loop_leaves_a_complete_readable_tlog(tmp_path):
    from companion.loop.runner import FlightRunner, FlyOptions, Status, make_guidance
    from companion.mission import load_mission

    port = free_udp_port()
    mission = load_mission(str(write_mission(tmp_path)))
    mock = Mock(f"udpout:127.0.0.1:{port}", tlog=tmp_path / "m.tlog")
    guidance = ExplodingGuidance(make_guidance(mission, 50.0), n=60)
    runner = FlightRunner(mission, FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0,
                                              tlog_path=str(tmp_path / "c.tlog"), heartbeat_timeout_s=20.0),
                          Status(quiet=True), guidance=guidance)
    try:
        with pytest.raises(RuntimeError, match="injected failure"):
            runner.run()
        time.sleep(0.3)
    finally:
        mock.stop()
    assert runner.summary["ticks"] == 60
    info = check_log_complete(tmp_path / "c.tlog", tmp_path / "m.tlog")
    assert info["setpoints_received_by_autopilot"] >= 60


def test_unwritable_log_path_is_refused_before_the_link_is_opened(tmp_path):
    blocker = tmp_path / "not_a_directory"
    blocker.write_text("a file where the log directory should be")
    mission = write_mission(tmp_path)
    port = free_udp_port()
    t0 = time.monotonic()
    comp = Companion(mission, port, blocker / "flight.tlog")
    rc, _ = comp.result(30)
    assert rc == 2
    assert time.monotonic() - t0 < 15  # not after waiting for a heartbeat (20 s)
    assert "companion: error:" in comp.stderr and "not_a_directory" in comp.stderr
    assert "Traceback" not in comp.stderr


def test_nearly_full_disk_is_refused_before_the_link_is_opened(tmp_path, monkeypatch):
    """The log's file system reports 1 MiB free (below the writer's 20 MiB floor): the flight is
    refused with a LogError naming the path, before any link is opened (nobody is listening on
    the port, so reaching the link would mean a 20 s heartbeat wait)."""
    import collections
    import shutil

    from companion.errors import LogError
    from companion.loop.runner import FlightRunner, FlyOptions, Status
    from companion.mission import load_mission

    usage = collections.namedtuple("usage", "total used free")
    real = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage",
                        lambda p: usage(real(p).total, real(p).total - 2**20, 2**20))
    mission = load_mission(str(write_mission(tmp_path)))
    port = free_udp_port()
    runner = FlightRunner(mission, FlyOptions(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0,
                                              tlog_path=str(tmp_path / "c.tlog"), heartbeat_timeout_s=20.0),
                          Status(quiet=True))
    t0 = time.monotonic()
    with pytest.raises(LogError, match=r"c\.tlog.*free"):
        runner.run()
    assert time.monotonic() - t0 < 5.0
    assert runner.link is None


def test_children_get_a_working_ctrl_c_even_when_started_from_a_background_shell():
    # A background shell starts pytest with SIGINT ignored and children inherit that: the
    # SIGINT test above would then wait for a flight that never sees its Ctrl-C.
    import sys

    from harness import Proc

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # as `pytest ... &` would start
    try:
        child = Proc([sys.executable, "-c",
                      "import signal; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)"])
    finally:
        signal.signal(signal.SIGINT, previous)
    assert child.wait(30) == 0
    assert "".join(child.out).strip() == "True"
