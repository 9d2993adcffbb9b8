"""A small loopback UDP proxy that injects link faults between an autopilot and the companion.

::

    autopilot (udpout:127.0.0.1:proxy.port) <--> [ap socket | proxy | companion socket] <--> companion (udpin:PORT)

The autopilot sends to ``proxy.port``; the proxy learns the autopilot's address from the first
datagram and forwards everything to the companion from one fixed socket of its own, so the
companion pins that socket as its peer. Replies from the companion go back to the autopilot's
address. Both directions can be faulted independently:

- ``loss``: drop each datagram with this probability;
- ``duplicate``: send each datagram twice with this probability;
- ``reorder``: hold a datagram back with this probability and send it after the next one (or
  after ``reorder_hold_s`` if no other datagram comes);
- ``drop_if``: a predicate ``f(datagram) -> bool`` for targeted drops (e.g. every
  LOCAL_POSITION_NED during a blackout); ``blackout(msgid, duration_s)`` sets one.

The tests also inject their own datagrams: :meth:`inject_to_companion` sends from the proxy's
companion-facing socket (the companion's pinned peer: the datagram is "from the autopilot's
address"), :meth:`inject_to_autopilot` from the autopilot-facing socket.

Counters (per direction ``"up"`` = to the companion, ``"down"`` = to the autopilot): datagrams
seen, forwarded, dropped (random loss / targeted), duplicated, reordered, injected.
"""

from __future__ import annotations

import random
import select
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable

MAGIC_V2 = 0xFD
MAGIC_V1 = 0xFE


def msgid_of(datagram: bytes) -> int | None:
    """Message id of the first MAVLink frame of a datagram (None if it does not start with one)."""
    if len(datagram) >= 10 and datagram[0] == MAGIC_V2:
        return datagram[7] | (datagram[8] << 8) | (datagram[9] << 16)
    if len(datagram) >= 6 and datagram[0] == MAGIC_V1:
        return datagram[5]
    return None


@dataclass
class Faults:
    """Fault settings of one direction (mutable while the proxy runs)."""

    loss: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    reorder_hold_s: float = 0.05
    drop_if: Callable[[bytes], bool] | None = None


@dataclass
class _Direction:
    faults: Faults = field(default_factory=Faults)
    counts: Counter = field(default_factory=Counter)
    held: list = field(default_factory=list)  # [(deadline, datagram)]


class FaultProxy:
    """Forward UDP datagrams between an autopilot and a companion, with faults.

    Parameters
    ----------
    companion_port : the companion's ``udpin`` port on 127.0.0.1.
    seed : seed of the fault dice (faults are reproducible for a given datagram sequence).
    """

    def __init__(self, companion_port: int, seed: int = 0):
        self.companion_addr = ("127.0.0.1", int(companion_port))
        self.ap_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.ap_sock.bind(("127.0.0.1", 0))
        self.port = self.ap_sock.getsockname()[1]
        self.comp_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.comp_sock.bind(("127.0.0.1", 0))
        for s in (self.ap_sock, self.comp_sock):
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 21)
            s.setblocking(False)
        self.ap_addr: tuple | None = None
        self.up = _Direction()  # autopilot -> companion
        self.down = _Direction()  # companion -> autopilot
        self.rng = random.Random(seed)
        self.lock = threading.Lock()
        self.events: list[tuple[float, str]] = []  # (unix time, text) of fault switches
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fault-proxy", daemon=True)

    # ---------------------------------------------------------------- control
    def start(self) -> "FaultProxy":
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.ap_sock.close()
        self.comp_sock.close()

    def __enter__(self) -> "FaultProxy":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def note(self, text: str) -> float:
        """Record a timestamped event (unix time, as in tlogs) and return its time."""
        t = time.time()
        with self.lock:
            self.events.append((t, text))
        return t

    def blackout(self, msgid: int, duration_s: float, direction: str = "up") -> tuple[float, float]:
        """Drop every datagram carrying ``msgid`` for ``duration_s`` from now. Returns (start, end) unix times."""
        d = self.up if direction == "up" else self.down
        t0 = time.time()
        t1 = t0 + duration_s

        def drop(datagram: bytes) -> bool:
            return time.time() < t1 and msgid_of(datagram) == msgid
        d.faults.drop_if = drop
        self.note(f"blackout msgid {msgid} {duration_s:g} s")
        return t0, t1

    def inject_to_companion(self, datagram: bytes) -> None:
        """Send from the companion-facing socket (the companion's pinned peer address)."""
        self._sendto(self.comp_sock, datagram, self.companion_addr)
        self.up.counts["injected"] += 1

    def inject_to_autopilot(self, datagram: bytes) -> None:
        """Send from the autopilot-facing socket to the autopilot's address (once it is known)."""
        if self.ap_addr is not None:
            self._sendto(self.ap_sock, datagram, self.ap_addr)
            self.down.counts["injected"] += 1

    # ---------------------------------------------------------------- forwarding
    @staticmethod
    def _sendto(sock, datagram: bytes, addr) -> None:
        try:
            sock.sendto(datagram, addr)
        except OSError:
            pass  # nobody listening yet, or a full buffer: a lost datagram

    def _forward(self, d: _Direction, sock, addr, datagram: bytes) -> None:
        f = d.faults
        d.counts["seen"] += 1
        if f.drop_if is not None and f.drop_if(datagram):
            d.counts["dropped_targeted"] += 1
            return
        if f.loss and self.rng.random() < f.loss:
            d.counts["dropped_loss"] += 1
            return
        copies = 2 if f.duplicate and self.rng.random() < f.duplicate else 1
        if copies == 2:
            d.counts["duplicated"] += 1
        if f.reorder and not d.held and self.rng.random() < f.reorder:
            d.held.append((time.monotonic() + f.reorder_hold_s, datagram))
            d.counts["reordered"] += 1
            return
        for _ in range(copies):
            self._sendto(sock, datagram, addr)
            d.counts["forwarded"] += 1
        self._release(d, sock, addr, force=True)

    def _release(self, d: _Direction, sock, addr, force: bool = False) -> None:
        now = time.monotonic()
        keep = []
        for deadline, datagram in d.held:
            if force or now >= deadline:
                self._sendto(sock, datagram, addr)
                d.counts["forwarded"] += 1
            else:
                keep.append((deadline, datagram))
        d.held = keep

    def _run(self) -> None:
        socks = [self.ap_sock, self.comp_sock]
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select(socks, [], [], 0.01)
            except (OSError, ValueError):
                return
            for sock in ready:
                for _ in range(512):
                    try:
                        datagram, addr = sock.recvfrom(65535)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        continue
                    with self.lock:
                        if sock is self.ap_sock:
                            self.ap_addr = addr
                            self._forward(self.up, self.comp_sock, self.companion_addr, datagram)
                        elif self.ap_addr is not None:
                            self._forward(self.down, self.ap_sock, self.ap_addr, datagram)
            with self.lock:
                self._release(self.up, self.comp_sock, self.companion_addr)
                if self.ap_addr is not None:
                    self._release(self.down, self.ap_sock, self.ap_addr)
