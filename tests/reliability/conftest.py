"""Shared set-up of the reliability tests: import path for the helpers, the slow-run switch.

The long fuzzing run is off by default. Turn it on with ``--run-slow`` (when pytest is started
on this folder, e.g. ``pytest tests/reliability --run-slow``) or ``COMPANION_RUN_SLOW=1``.
"""

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


def pytest_addoption(parser):
    try:
        parser.addoption("--run-slow", action="store_true", default=False,
                         help="run the long variants (e.g. the 100,000-datagram fuzzing run)")
    except ValueError:
        pass  # already added by another conftest


def run_slow(config) -> bool:
    return bool(config.getoption("--run-slow", default=False)) or os.environ.get("COMPANION_RUN_SLOW") == "1"


@pytest.fixture
def slow_enabled(request) -> bool:
    return run_slow(request.config)
