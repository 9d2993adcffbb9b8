"""Fixtures of the sitl_mock tests (helpers live in ``sitl_mock_helpers``)."""

from __future__ import annotations

import subprocess

import pytest
from sitl_mock_helpers import Client, MockProcess, free_udp_port


@pytest.fixture
def port() -> int:
    return free_udp_port()


@pytest.fixture
def first_order_vehicle(tmp_path):
    """``--vehicle-model`` args for a plain first-order copter (0.3 s, 5 m/s^2): for tests of the
    protocol, where PX4's identified slow tail (a velocity step's last 14 % comes over about 10 s,
    as on the real SIH) would only slow the check that the commanded velocity is flown."""
    f = tmp_path / "first-order-vehicle.yaml"
    f.write_text("vehicle: {lag_s: 0.3, a_max_m_s2: 5.0}\n")
    return ("--vehicle-model", str(f))


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
