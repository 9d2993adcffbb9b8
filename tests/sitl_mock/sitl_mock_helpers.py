"""Helpers for the sitl_mock tests: free ports, the mock as a subprocess, a small pymavlink client."""

from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[2]
NAN = math.nan


def free_udp_port() -> int:
    """A UDP port nobody is bound to right now (bind to port 0 and let the kernel choose)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class MockProcess:
    """``python -m sitl_mock`` as a subprocess; waits for the ready line."""

    def __init__(self, *args: str, timeout_s: float = 20.0) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen([sys.executable, "-m", "sitl_mock", *args], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env)
        self.ready_line = self.proc.stdout.readline().strip()
        if not self.ready_line.startswith("sitl_mock ready"):
            self.proc.kill()
            raise RuntimeError(f"mock did not start: {self.ready_line!r} {self.proc.stderr.read()}")
        self.stderr = ""

    def stop(self, timeout_s: float = 20.0) -> str:
        """SIGTERM, wait, and return stderr (the summary line is its last line)."""
        if self.proc.poll() is None:
            self.proc.terminate()
        _, self.stderr = self.proc.communicate(timeout=timeout_s)
        return self.stderr

    def summary(self) -> dict[str, str]:
        line = [ln for ln in self.stderr.splitlines() if ln.startswith("sitl_mock summary")][-1]
        return dict(part.split("=", 1) for part in line.split()[2:])


class Client:
    """A GCS-like pymavlink client listening on a UDP port (the mock's udpout target)."""

    def __init__(self, port: int, source_system: int = 255, source_component: int = 190) -> None:
        self.port = port
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=source_system,
                                               source_component=source_component, dialect="ardupilotmega")
        # Speak MAVLink 2 from the start (pymavlink would switch on the first frame and drop signing set-up).
        self.conn.auto_mavlink_version(b"\xfd")

    @property
    def mav(self):
        return self.conn.mav

    def wait(self, mtype: str, timeout_s: float = 10.0, predicate=None):
        """The next message of a type (optionally satisfying a predicate), or None after the timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            msg = self.conn.recv_match(type=mtype, blocking=True, timeout=0.2)
            if msg is not None and (predicate is None or predicate(msg)):
                return msg
        return None

    def drain(self) -> None:
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def command(self, command: int, *params: float, target=(1, 1), timeout_s: float = 10.0):
        """Send COMMAND_LONG (unset params NaN) and return the matching COMMAND_ACK result."""
        p = list(params) + [NAN] * (7 - len(params))
        self.drain()  # a full receive buffer would drop the ACK
        self.mav.command_long_send(target[0], target[1], command, 0, *p)
        ack = self.wait("COMMAND_ACK", timeout_s, lambda m: m.command == command)
        return None if ack is None else ack.result

    def close(self) -> None:
        self.conn.close()
