"""Fixtures of the sitl_mock tests (helpers live in ``sitl_mock_helpers``)."""

from __future__ import annotations

import subprocess

import pytest
from sitl_mock_helpers import Client, MockProcess, free_udp_port


@pytest.fixture
def port() -> int:
    return free_udp_port()


@pytest.fixture
def mock_factory():
    """Start mocks (and clients) that are always stopped at the end of the test."""
    started: list = []

    def start(*args: str, client: bool = True, port: int | None = None):
        port = port or free_udp_port()
        cl = Client(port) if client else None
        mock = MockProcess("--link", f"udpout:127.0.0.1:{port}", *args)
        started.append((mock, cl))
        return mock, cl

    yield start
    for mock, cl in started:
        try:
            mock.stop()
        except subprocess.TimeoutExpired:
            mock.proc.kill()
        if cl is not None:
            cl.close()
