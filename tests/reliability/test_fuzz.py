"""Fuzzing the running companion and the running mock autopilot over loopback UDP.

``companion fly`` flies the line mission against ``python -m sitl_mock`` through the proxy of
:mod:`udp_proxy`. Meanwhile :mod:`fuzz` sends both processes a stream of bad datagrams: to the
companion from the proxy's socket (its pinned peer, so the datagrams get past the address check
and reach the parser and the field checks) and, one in ten, from a stranger's socket; to the mock
from the proxy's autopilot-facing socket (its peer). Expected:

- neither process crashes or stalls (both alive when the fuzzer is done; the companion kept its
  50 Hz loop and never held for want of data; the mock kept streaming and stayed in OFFBOARD;
  the companion then stops cleanly on SIGTERM);
- every datagram is dropped and counted by reason, in the companion's final summary and status
  and in the mock's exit summary;
- no setpoint is computed from a rejected message: every guidance tick's position is one of the
  accepted LOCAL_POSITION_NED records of the tlog (rejected messages are never recorded), and
  every setpoint sent is finite.

The CI run sends ``FUZZ_CI_PER_TARGET`` datagrams to each process; ``--run-slow`` (or
``COMPANION_RUN_SLOW=1``) sends ``FUZZ_SLOW_PER_TARGET`` to each.
"""

from __future__ import annotations

import math
import signal
import socket
import threading
import time
from collections import Counter

import pytest

from figures import record
from fuzz import Fuzzer
from harness import PHASE_HOLD, Companion, Mock, free_udp_port, guidance_records, read_tlog, write_mission
from udp_proxy import FaultProxy

FUZZ_CI_PER_TARGET = 50_000
FUZZ_SLOW_PER_TARGET = 250_000
RATE_PER_TARGET_HZ = 5_000  # datagrams per second to each process
F_PHASE, F_X, F_Y = 2, 8, 9


class FuzzSender(threading.Thread):
    """Sends ``per_target`` fuzz datagrams to each process at a steady rate."""

    def __init__(self, proxy: FaultProxy, companion_port: int, per_target: int, seed: int = 1):
        super().__init__(daemon=True)
        self.proxy = proxy
        self.to_companion = Fuzzer("companion", seed)
        self.to_autopilot = Fuzzer("autopilot", seed + 1)
        self.per_target = per_target
        self.stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.stranger.bind(("127.0.0.1", 0))
        self.companion_addr = ("127.0.0.1", companion_port)
        self.sent = Counter()
        self.from_stranger = 0
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            batch = max(1, RATE_PER_TARGET_HZ // 100)
            t0 = time.monotonic()
            n = 0
            while n < self.per_target:
                for _ in range(min(batch, self.per_target - n)):
                    _, d = self.to_companion.datagram()
                    if n % 10 == 9:
                        self.stranger.sendto(d, self.companion_addr)
                        self.from_stranger += 1
                    else:
                        self.proxy.inject_to_companion(d)
                    self.sent["companion"] += 1
                    _, d = self.to_autopilot.datagram()
                    self.proxy.inject_to_autopilot(d)
                    self.sent["autopilot"] += 1
                    n += 1
                # Pace against the wall clock: n datagrams due at n / rate.
                ahead = t0 + n / RATE_PER_TARGET_HZ - time.monotonic()
                if ahead > 0:
                    time.sleep(ahead)
        except BaseException as err:  # noqa: BLE001 - reported by the test
            self.error = err
        finally:
            self.stranger.close()


def run_fuzz(tmp_path, per_target: int) -> None:
    port = free_udp_port()
    mission = write_mission(tmp_path)
    fuzz_s = per_target / RATE_PER_TARGET_HZ
    # Stopped by SIGTERM once the fuzzer is done; the duration limit is only a backstop.
    comp = Companion(mission, port, tmp_path / "c.tlog", "--max-duration-s", f"{4 * fuzz_s + 30:.0f}")
    with FaultProxy(port) as proxy:
        mock = Mock(f"udpout:127.0.0.1:{proxy.port}")
        try:
            comp.wait_flying()
            sender = FuzzSender(proxy, port, per_target)
            t0 = time.monotonic()
            sender.start()
            sender.join(timeout=fuzz_s * 4 + 60)
            send_s = time.monotonic() - t0
            assert not sender.is_alive(), "the fuzzer could not send in time"
            assert sender.error is None, sender.error
            time.sleep(0.5)  # the last datagrams are handled
            alive_after = mock.p.poll() is None and comp.p.poll() is None
            comp.signal(signal.SIGTERM)
            rc, summary = comp.result(timeout_s=60)
        finally:
            mock_summary = mock.stop()
    # -------------------------------------------------------------- neither crashed nor stalled
    assert alive_after, ("a process died during the fuzzing:\n--- companion\n" + comp.stderr[-3000:]
                         + "\n--- mock\n" + mock.stderr[-3000:])
    assert rc == 1 and summary["exit"] == "SIGTERM", comp.stderr[-3000:]
    assert "Traceback" not in comp.stderr and "Traceback" not in mock.stderr
    assert summary["rate_hz_achieved"] >= 40.0, summary["rate_hz_achieved"]
    assert summary["hold_ticks"] == 0  # the real positions kept coming and were accepted
    assert summary["ticks"] >= 40 * send_s
    # -------------------------------------------------------------- counted by reason
    rej = summary["link"]["rejected"]
    for reason in ("bad_crc", "bad_data", "wrong_system", "wrong_address", "nan", "out_of_range"):
        assert rej[reason] > 0, (reason, rej)
    assert summary["link"]["ignored_unknown_id"] > 0  # ids the dialect does not know: not errors
    assert (summary["link"]["rejected_total"] + summary["link"]["ignored_unknown_id"]
            >= 0.9 * sender.sent["companion"])
    # The live status line carries the split by reason too.
    status = [ln for ln in comp.stderr.splitlines() if ln.startswith("t ") and "rejected" in ln]
    assert status and all(k in status[-1] for k in ("bad_data", "bad_crc", "nan", "out_of_range")), status[-1:]
    for reason in ("garbage", "truncated", "bad_flags", "unknown_id", "bad_crc", "bad_value"):
        assert mock_summary[reason] > 0, (reason, mock_summary)
    assert mock_summary["rx_dropped"] >= 0.9 * sender.sent["autopilot"]
    # -------------------------------------------------------------- nothing built on a rejected message
    msgs = read_tlog(tmp_path / "c.tlog")
    accepted_pos = {}
    for m in msgs:
        if m.get_type() == "LOCAL_POSITION_NED":
            assert (m.get_srcSystem(), m.get_srcComponent()) == (1, 1)
            assert all(math.isfinite(v) for v in (m.x, m.y, m.z, m.vx, m.vy, m.vz))
            accepted_pos[m.time_boot_ms] = (m.y, m.x)  # ENU (east, north)
        if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
            assert all(math.isfinite(v) for v in (m.vx, m.vy, m.vz, m.yaw_rate))
    g = [r for r in guidance_records(msgs) if r.data[F_PHASE] != PHASE_HOLD]
    assert len(g) == summary["ticks"]
    for r in g:
        e, n = accepted_pos[r.time_usec // 1000]
        assert (r.data[F_X], r.data[F_Y]) == pytest.approx((e, n), abs=1e-4)
    assert all(abs(r.data[F_Y]) < 0.5 for r in g)  # the mock was never pushed off the path
    record("fuzz", per_target=per_target, send_s=send_s, sent=dict(sender.sent),
           companion_from_stranger=sender.from_stranger,
           kinds_to_companion=dict(sender.to_companion.counts),
           kinds_to_autopilot=dict(sender.to_autopilot.counts),
           companion_rejected=rej, companion_rejected_total=summary["link"]["rejected_total"],
           companion_rate_hz=summary["rate_hz_achieved"], companion_tick_ms=summary["tick_ms"],
           companion_ticks=summary["ticks"], companion_hold_ticks=summary["hold_ticks"],
           mock={k: v for k, v in mock_summary.items() if isinstance(v, int)}, crashes=0)


def test_fuzzing_both_processes_over_udp_drops_and_counts_everything(tmp_path, slow_enabled):
    run_fuzz(tmp_path, FUZZ_SLOW_PER_TARGET if slow_enabled else FUZZ_CI_PER_TARGET)


class Flooder(threading.Thread):
    """Sends pre-built fuzz datagrams as fast as one thread can, for ``duration_s``."""

    def __init__(self, send, fuzzer: Fuzzer, duration_s: float):
        super().__init__(daemon=True)
        self.send = send
        self.data = [fuzzer.datagram()[1] for _ in range(5000)]
        self.duration_s = duration_s
        self.sent = 0

    def run(self) -> None:
        end = time.monotonic() + self.duration_s
        while time.monotonic() < end:
            for d in self.data[:500]:
                self.send(d)
            self.sent += 500
            self.data = self.data[500:] + self.data[:500]


def test_flood_at_full_speed_degrades_to_hold_never_to_a_stall(tmp_path):
    """Both processes flooded for 3 s as fast as loopback allows (well over 100,000 datagrams a
    second, far more than either can read: the kernel drops most, real positions included).
    The companion's loop must keep ticking and, starved of positions, hold; then resume."""
    port = free_udp_port()
    mission = write_mission(tmp_path)
    comp = Companion(mission, port, tmp_path / "c.tlog", "--max-duration-s", "60")
    with FaultProxy(port) as proxy:
        mock = Mock(f"udpout:127.0.0.1:{proxy.port}")
        try:
            comp.wait_flying()
            floods = [Flooder(proxy.inject_to_companion, Fuzzer("companion", 5), 3.0),
                      Flooder(proxy.inject_to_autopilot, Fuzzer("autopilot", 6), 3.0)]
            t_end_flood = time.time() + 3.0
            for f in floods:
                f.start()
            for f in floods:
                f.join(timeout=30)
            time.sleep(1.5)
            alive_after = mock.p.poll() is None and comp.p.poll() is None
            comp.signal(signal.SIGTERM)
            rc, summary = comp.result(timeout_s=60)
        finally:
            mock_summary = mock.stop()
    assert alive_after, comp.stderr[-2000:] + mock.stderr[-2000:]
    assert rc == 1 and summary["exit"] == "SIGTERM", comp.stderr[-2000:]
    assert "Traceback" not in comp.stderr and "Traceback" not in mock.stderr
    sent = sum(f.sent for f in floods)
    assert sent > 100_000
    # The loop kept its rhythm: no tick anywhere near a stall, most ticks on time.
    assert summary["rate_hz_achieved"] >= 30.0, summary["rate_hz_achieved"]
    assert summary["tick_ms"]["max"] < 250.0, summary["tick_ms"]
    # After the flood: guidance again, on fresh positions.
    g = guidance_records(read_tlog(tmp_path / "c.tlog"))
    after = [r for r in g if r._timestamp > t_end_flood + 0.5]
    assert after and all(r.data[F_PHASE] != PHASE_HOLD for r in after)
    record("flood", sent_total=sent, flood_s=3.0, companion_rejected_total=summary["link"]["rejected_total"],
           companion_rate_hz=summary["rate_hz_achieved"], companion_tick_ms=summary["tick_ms"],
           companion_hold_ticks=summary["hold_ticks"], companion_ticks=summary["ticks"],
           mock_rx_datagrams=mock_summary["rx_datagrams"], mock_overruns=mock_summary["overruns"])
