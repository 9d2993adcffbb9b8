"""Link faults end to end: ``companion fly`` against ``python -m sitl_mock`` over loopback UDP.

Faults come from :mod:`udp_proxy` between the two processes, or from extra processes and
sockets on the companion's port. Expected behaviour (docs/reliability.md):

- loss, reordering and duplication: the flight goes on and converges onto the path;
- old positions replayed from the autopilot's own address are never used;
- a second autopilot (another system id, heard first; ``--target-system 1``) and a stranger (the
  same system id, another address) on the companion's port: ignored and counted; nothing is ever
  sent to them;
- a position blackout: HOLD (zero horizontal velocity) once the newest position is older than
  ``--stale-s``, guidance again when positions return;
- an autopilot restart (heartbeat gap, then the same system id from a new port): the companion
  follows it to the new address and, seeing it no longer in OFFBOARD, stops commanding.

The first four are independent of one another and share one flight (``hostile_link``, run once
for the module) so that the suite stays short; each has its own test of its own outcome.
"""

from __future__ import annotations

import socket
import time
from types import SimpleNamespace

import pytest

from figures import record
from harness import (MSG_LOCAL_POSITION_NED, PHASE_HOLD, Companion, Mock, free_udp_port,
                     guidance_records, read_tlog, write_mission)
from mavframes import Encoder
from udp_proxy import FaultProxy, msgid_of

# DEBUG_FLOAT_ARRAY "guidance" fields (companion/loop/tick.py DEBUG_FIELDS).
F_PHASE, F_XTRACK, F_X, F_Y, F_VN, F_VE, F_AGE, F_SENT = 2, 4, 8, 9, 13, 14, 17, 26


def _rejected(summary: dict) -> dict:
    return summary["link"]["rejected"]


class Stranger:
    """A socket on another port that claims to be the paired autopilot (same system id)."""

    def __init__(self, port: int):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.dest = ("127.0.0.1", port)
        self.enc = Encoder(1, 1)
        self.sent = 0

    def send_burst(self, t_ms: int) -> None:
        # Heartbeat in the hold mode, a position 50 m north of the path.
        for d in (self.enc.heartbeat(custom_mode=(4 << 16) | (3 << 24)),
                  self.enc.local_position(t_ms, x=50.0, y=0.0, vx=0.0, vy=5.0)):
            self.sock.sendto(d, self.dest)
            self.sent += 1

    def received(self) -> int:
        n = 0
        while True:
            try:
                self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return n
            n += 1


@pytest.fixture(scope="module")
def hostile_link(tmp_path_factory):
    """One 7 s flight through every independent fault at once.

    - a second autopilot (system 2, 500 m away) on the companion's port, started first; the
      companion is told ``--target-system 1``;
    - the paired autopilot (4 m north of the path, heading east) behind the proxy, which drops
      20 %, duplicates 10 % and reorders 10 % of the datagrams in both directions once the
      companion flies;
    - a stranger sending heartbeats and positions as system 1 from another port, at 50 Hz;
    - from 2 s to 3.5 s, positions captured 1-2 s earlier replayed from the proxy's socket (the
      address the companion pinned).
    """
    tmp = tmp_path_factory.mktemp("hostile_link")
    port = free_udp_port()
    mission = write_mission(tmp)
    # At 20 % loss, n heartbeats in a row are lost with probability 0.2^n: --link-timeout-s 8
    # makes a false "heartbeat lost" a one-in-a-million event (the default 5 s: 3e-4 a second).
    comp = Companion(mission, port, tmp / "c.tlog", "--max-duration-s", "7", "--target-system", "1",
                     "--link-timeout-s", "8")
    other = Mock(f"udpout:127.0.0.1:{port}", "--start-ned", "500,500", sysid=2, tlog=tmp / "other.tlog")
    time.sleep(1.5)
    stranger = Stranger(port)
    captured = []
    replayed = 0
    mock = None
    with FaultProxy(port, seed=7) as proxy:
        def capture(datagram: bytes) -> bool:
            if msgid_of(datagram) == MSG_LOCAL_POSITION_NED:
                captured.append(datagram)
            return False
        proxy.up.faults.drop_if = capture
        try:
            mock = Mock(f"udpout:127.0.0.1:{proxy.port}", "--start-ned", "4,0")
            comp.wait_flying()
            for d in (proxy.up, proxy.down):
                d.faults.loss, d.faults.duplicate, d.faults.reorder = 0.2, 0.1, 0.1
            t0 = time.monotonic()
            t_ms = 10_000_000
            old = []
            # The stranger stops when the flight does: after its last tick the companion reads
            # no more datagrams, and what it never read cannot be counted as rejected (under load
            # the companion's exit takes long enough for that tail to matter).
            while (comp.p.poll() is None and time.monotonic() - t0 < 30
                   and not any("stopping after" in line for line in comp.err)):
                stranger.send_burst(t_ms)
                t_ms += 20
                dt = time.monotonic() - t0
                if 2.0 <= dt < 3.5:
                    if not old:
                        old = list(captured[-80:-40])  # about 1-2 s old by now (~40 Hz arrive)
                    for d in old[::4]:
                        proxy.inject_to_companion(d)
                        replayed += 1
                time.sleep(0.02)
            rc, summary = comp.result()
        finally:
            other_summary = other.stop()
            mock_summary = mock.stop() if mock is not None else {}
    return SimpleNamespace(rc=rc, summary=summary, stderr=comp.stderr, msgs=read_tlog(tmp / "c.tlog"),
                           proxy_up=proxy.up.counts, proxy_down=proxy.down.counts, mock=mock_summary,
                           other=other_summary, stranger_sent=stranger.sent,
                           stranger_received=stranger.received(), replayed=replayed)


def test_hostile_link_flight_completes(hostile_link):
    assert hostile_link.rc == 0, hostile_link.stderr
    assert hostile_link.summary["exit"] == "max duration"


def test_twenty_percent_loss_with_reordering_and_duplication_still_converges_onto_the_path(hostile_link):
    f = hostile_link
    summary = f.summary
    up, down = f.proxy_up, f.proxy_down
    # The dice really were thrown in both directions (about 20 % of each).
    assert 0.1 < up["dropped_loss"] / up["seen"] < 0.3 and 0.1 < down["dropped_loss"] / down["seen"] < 0.3
    assert up["duplicated"] > 0 and up["reordered"] > 0 and down["duplicated"] > 0
    g = guidance_records(f.msgs)
    xt = [r.data[F_XTRACK] for r in g]
    # Constant-L1 on a straight line is a damped second-order loop (damping 1/sqrt(2) in Park's
    # linearisation, overshoot ~4 %): from 4 m the error never grows past it, and it is gone
    # within the flight.
    assert max(abs(v) for v in xt) <= 4.4
    tail = [abs(v) for r, v in zip(g, xt) if r.data[1] >= 5.0]
    assert tail and max(tail) < 0.5
    # No loss burst of 0.3 s at 50 Hz (15 in a row at 20 %: probability 3e-11): no hold.
    assert summary["hold_ticks"] == 0
    # The mock kept receiving setpoints (about 80 % of them get through, plus the duplicates) and
    # stayed in OFFBOARD: otherwise the companion would have stopped on "pilot override".
    assert f.mock["rx_frames_ok"] >= 0.6 * summary["setpoints_sent"]
    record("loss_reorder_duplicate", proxy_up=dict(up), proxy_down=dict(down),
           d_max_m=summary["d_max_m"], tail_xtrack_max_m=max(tail), hold_ticks=summary["hold_ticks"])


def test_replayed_old_positions_from_the_autopilot_address_are_never_used(hostile_link):
    """A position sample older than the one held (a reordered or replayed datagram) must not
    replace it: the guidance would run on data seconds old while it looks fresh."""
    f = hostile_link
    assert f.replayed > 100
    # Walk the tlog in order: each tick's sample (its time_boot_ms is the record's time_usec)
    # must be the newest position received so far, give or take one stream period. A record
    # flagged "setpoint not sent" (field 26) is a guidance result that came after its tick had
    # coasted: it is logged after positions polled meanwhile, but nothing was sent from it.
    # Under load a stale tick once appeared. Two causes were found: such late records were
    # counted, and the link took a replay read first after a stall of either process for an
    # autopilot reboot (silence alone was its evidence; fixed, see MavLink._position_restart and
    # tests/io/test_link.py).
    newest_ms = -1
    stale_ticks = 0
    for m in f.msgs:
        if m.get_type() == "LOCAL_POSITION_NED":
            newest_ms = max(newest_ms, m.time_boot_ms)
        elif m in guidance_records([m]) and m.data[F_PHASE] != PHASE_HOLD:
            old = m.time_usec // 1000 < newest_ms - 50
            if m.data[F_SENT] == 1.0:
                stale_ticks += old
    assert stale_ticks == 0, f"{stale_ticks} ticks used a position older than one already received"
    assert _rejected(f.summary)["old_sample"] >= 0.9 * f.replayed


def test_second_autopilot_heard_first_is_never_paired_with_nor_answered(hostile_link):
    f = hostile_link
    assert "paired with px4 copter (system 1, component 1)" in f.stderr
    assert _rejected(f.summary)["wrong_system"] > 0  # the second autopilot's messages
    assert f.other["rx_datagrams"] == 0  # nothing was ever sent to it
    msgs = f.msgs
    incoming = [m for m in msgs if (m.get_srcSystem(), m.get_srcComponent()) != (1, 191)]
    assert incoming and all((m.get_srcSystem(), m.get_srcComponent()) == (1, 1) for m in incoming)
    targets = {(m.target_system, m.target_component) for m in msgs
               if m.get_type() in ("SET_POSITION_TARGET_LOCAL_NED", "COMMAND_LONG")}
    assert targets == {(1, 1)}
    record("second_autopilot", rejected_wrong_system=_rejected(f.summary)["wrong_system"],
           other_autopilot_rx_datagrams=f.other["rx_datagrams"])


def test_stranger_on_the_companion_port_is_ignored_and_never_answered(hostile_link):
    f = hostile_link
    assert f.stranger_sent > 200
    assert _rejected(f.summary)["wrong_address"] >= 0.9 * f.stranger_sent  # a few may be lost by UDP
    assert f.stranger_received == 0
    # The guidance only ever saw the paired autopilot's positions (near the path, not 50 m
    # north like the stranger's or 500 m away like the other autopilot's).
    g = guidance_records(f.msgs)
    assert g and all(abs(r.data[F_Y]) < 4.5 for r in g if r.data[F_PHASE] != PHASE_HOLD)
    record("stranger", stranger_sent=f.stranger_sent, rejected_wrong_address=_rejected(f.summary)["wrong_address"],
           stranger_received=f.stranger_received)


def companion_stall_s(records, t0_s: float, t1_s: float, period_s: float = 0.02) -> float:
    """The longest pause of the companion's loop between two tlog times, beyond one tick.

    A gap between consecutive guidance records (or between ``t0_s`` / ``t1_s`` and the nearest
    record) longer than a tick means the loop did not run: the process was descheduled.
    """
    times = [t0_s] + [r._timestamp for r in records if t0_s < r._timestamp < t1_s] + [t1_s]
    return max(0.0, max(b - a for a, b in zip(times, times[1:])) - period_s)


def test_companion_stall_is_the_longest_gap_beyond_a_tick():
    recs = [SimpleNamespace(_timestamp=t) for t in (10.00, 10.02, 10.04, 10.50, 10.52)]
    assert companion_stall_s(recs, 10.0, 10.52) == pytest.approx(0.46 - 0.02)
    assert companion_stall_s(recs, 10.0, 10.04) == pytest.approx(0.0)
    assert companion_stall_s(recs, 9.70, 10.02) == pytest.approx(0.28)  # before the first record


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_one_second_position_blackout_holds_then_resumes(tmp_path, autopilot):
    port = free_udp_port()
    mission = write_mission(tmp_path)
    comp = Companion(mission, port, tmp_path / "c.tlog", "--max-duration-s", "4.5", "--stale-s", "0.3")
    with FaultProxy(port) as proxy:
        mock = Mock(f"udpout:127.0.0.1:{proxy.port}", autopilot=autopilot)
        try:
            comp.wait_flying()
            time.sleep(1.0)
            t_black0, t_black1 = proxy.blackout(MSG_LOCAL_POSITION_NED, 1.0)
            rc, summary = comp.result()
        finally:
            mock.stop()
    assert rc == 0, comp.stderr
    msgs = read_tlog(tmp_path / "c.tlog")
    positions = [m for m in msgs if m.get_type() == "LOCAL_POSITION_NED"]
    g = guidance_records(msgs)
    last_before = max(m._timestamp for m in positions if m._timestamp < t_black0 + 0.005)
    first_after = min(m._timestamp for m in positions if m._timestamp > t_black0 + 0.005)
    assert first_after >= t_black1 - 0.05  # the blackout really cut the positions for ~1 s
    holds = [r for r in g if r.data[F_PHASE] == PHASE_HOLD]
    assert holds, "no HOLD tick during a 1 s position blackout"
    first_hold = min(r._timestamp for r in holds)
    last_hold = max(r._timestamp for r in holds)
    # Every hold tick commands zero horizontal velocity and lies inside the blackout.
    assert all(r.data[F_VN] == 0.0 and r.data[F_VE] == 0.0 for r in holds)
    # Hold starts once the newest sample is older than --stale-s (0.3 s), within about a tick
    # (generous for a loaded machine), and guidance is back within a tick or two of the data.
    # On a machine loaded beyond its cores the companion's own process can be descheduled for a
    # few hundred ms; such a pause shows in its tick records (a gap longer than a tick) and is
    # added to the bound: what is checked is that the hold comes on the first tick the loop
    # runs past the limit, and guidance on the first tick after the data is back.
    stale_to_hold = first_hold - last_before
    stall_before = companion_stall_s(g, last_before, first_hold)
    assert 0.3 <= stale_to_hold <= 0.3 + 0.25 + stall_before, (stale_to_hold, stall_before)
    resumed = [r for r in g if r._timestamp > last_hold and r.data[F_PHASE] != PHASE_HOLD]
    assert resumed
    stall_after = companion_stall_s(g, first_after, resumed[0]._timestamp)
    assert t_black0 < first_hold and last_hold < first_after + 0.1 + stall_after
    assert resumed[0]._timestamp - first_after <= 0.2 + stall_after, stall_after
    # ... and the path following goes on: the vehicle stopped on the path, so it stays on it.
    assert all(abs(r.data[F_XTRACK]) < 0.5 for r in resumed)
    # Hold ticks in the summary match the records; no hold outside the blackout.
    assert summary["hold_ticks"] == len(holds)
    record("position_blackout", autopilot=autopilot, blackout_s=1.0, stale_s=0.3,
           last_position_to_hold_s=stale_to_hold, blackout_start_to_hold_s=first_hold - t_black0,
           positions_back_to_guidance_s=resumed[0]._timestamp - first_after, hold_ticks=len(holds))



def test_autopilot_restart_is_followed_to_its_new_port_and_the_companion_stops_commanding(tmp_path):
    port = free_udp_port()
    mission = write_mission(tmp_path)
    comp = Companion(mission, port, tmp_path / "c.tlog", "--link-timeout-s", "3")
    mock = Mock(f"udpout:127.0.0.1:{port}")
    comp.wait_flying()
    time.sleep(1.0)
    t_kill = time.time()
    mock.kill()  # no goodbye: heartbeats and positions just stop
    time.sleep(1.5)  # heartbeat gap shorter than --link-timeout-s, longer than the re-pin delay
    mock2 = Mock(f"udpout:127.0.0.1:{port}", tlog=tmp_path / "m2.tlog")  # same sysid, new port
    try:
        rc, summary = comp.result(60)
    finally:
        mock2.stop()
    # The restarted autopilot is in its hold mode, not OFFBOARD: the companion must see that
    # (it accepted the new address) and stop, not time out on a dead link.
    assert rc == 1, comp.stderr
    assert "left OFFBOARD" in summary["exit"] or "pilot override" in summary["exit"], summary["exit"]
    assert "heartbeat lost" not in summary["exit"]
    msgs = read_tlog(tmp_path / "c.tlog")
    g = guidance_records(msgs)
    # During the gap: hold (positions stale), with zero horizontal velocity.
    gap = [r for r in g if r._timestamp > t_kill + 0.45]
    assert gap and all(r.data[F_PHASE] == PHASE_HOLD and r.data[F_VN] == 0 and r.data[F_VE] == 0 for r in gap)
    # After the companion saw the restarted autopilot it sent no further setpoint.
    hb_new = [m for m in msgs if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
              and m._timestamp > t_kill + 1.0]
    assert hb_new, "the restarted autopilot's heartbeats were not accepted"
    after = [m for m in msgs if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED" and m._timestamp > hb_new[0]._timestamp + 0.1]
    assert after == []
    assert _rejected(summary)["wrong_address"] == 0


