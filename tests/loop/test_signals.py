"""The flight's SIGTERM handling: the first one ends the flight, a second one cannot cut its clean-up short."""

from __future__ import annotations

import os
import signal
import time

import pytest

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
