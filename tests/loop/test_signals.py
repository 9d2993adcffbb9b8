"""The flight's signal handling: the first SIGTERM ends the flight and a second one cannot cut its
clean-up short; no interrupt falls between a setpoint's send and its record."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from companion.io.link import _SendHold
from companion.loop.runner import _raise_terminate, _Terminate


def _deliver_sigterm() -> None:
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.05)  # the handler runs at the next bytecode boundary of the main thread


def test_the_first_sigterm_ends_the_flight_and_a_second_one_during_clean_up_is_ignored():
    previous = signal.signal(signal.SIGTERM, _raise_terminate)
    try:
        with pytest.raises(_Terminate):
            _deliver_sigterm()
        _deliver_sigterm()  # as a supervisor repeating its SIGTERM while the tlog is being flushed
    finally:
        signal.signal(signal.SIGTERM, previous)


# Ctrl-C or SIGTERM reaching the companion while its main thread sends a setpoint, with the
# handlers the runner installs. The signal may go to any thread that does not block it (here a
# plain thread; in a flight, numpy's and scipy's BLAS threads or the guidance worker), and its
# arrival makes the main thread run the handler at its next bytecode. Run in a fresh interpreter,
# whose threads the test knows.
_SEND_DURING_A_SIGNAL = """
import os, signal, sys, threading, time
from companion.io.link import _TlogTap, hold_interrupts_during_sends
from companion.loop.runner import _raise_terminate, _Terminate

class Wire:
    sent = []
    def send(self, packet):
        self.sent.append(packet)
        os.kill(os.getpid(), getattr(signal, sys.argv[1]))
        time.sleep(0.2)  # a handler that can run now would run before the record
        return True

class Tlog:
    records = []
    def write(self, packet):
        self.records.append(packet)

class Link:
    _transport, tlog, sent = Wire(), Tlog(), 0

threading.Thread(target=threading.Event().wait, daemon=True).start()  # blocks no signal
hold_interrupts_during_sends(_raise_terminate)
try:
    _TlogTap(Link()).write(b"setpoint")
    print("no interrupt")
except (KeyboardInterrupt, _Terminate):
    print(len(Wire.sent), len(Tlog.records))
"""


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_an_interrupt_while_a_setpoint_is_sent_waits_for_its_record_whichever_thread_takes_it(sig):
    out = subprocess.run([sys.executable, "-c", _SEND_DURING_A_SIGNAL, sig], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    # One packet on the wire, one in the tlog; the interrupt raised after both (not swallowed).
    assert out.stdout.split() == ["1", "1"], out.stdout


def test_only_the_main_threads_sends_hold_the_handlers():
    """Handlers run in the main thread; a send in another thread must not defer them (the deferred
    handler would then run, and raise, in that thread instead of the main one)."""
    hold, calls = _SendHold(), []
    handler = hold.wrap(lambda signum, frame: calls.append(signum))
    inside, release = threading.Event(), threading.Event()

    def send_elsewhere():
        with hold:
            inside.set()
            release.wait(10)

    worker = threading.Thread(target=send_elsewhere)
    worker.start()
    inside.wait(10)
    handler(signal.SIGINT, None)  # the main thread, while the other thread is inside a send
    assert calls == [signal.SIGINT]
    release.set()
    worker.join(10)
    with hold:  # the main thread's own send: held until it leaves
        handler(signal.SIGTERM, None)
        assert calls == [signal.SIGINT]
    assert calls == [signal.SIGINT, signal.SIGTERM]
