"""The mock autopilot (``python -m sitl_mock``) as a child process, for ``companion demo`` and the
benchmarks. The companion talks to it only over the wire: nothing of ``sitl_mock`` is imported."""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from companion.errors import LinkError
from companion.geometry import frames
from companion.io.link import CAN_HOLD_SIGNALS, INTERRUPT_SIGNALS
from companion.mission.model import Mission


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 free at the time of the call."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def mock_start_args(mission: Mission, altitude_m: float) -> list[str]:
    """The mock's start options: airborne at the mission's start (else the path's) at ``altitude_m``."""
    if mission.start is not None:
        x, y, heading = mission.start.x_m, mission.start.y_m, mission.start.heading_rad
    else:
        (x, y), heading = mission.path.start_xy_m, mission.path.start_heading_rad
    yaw_deg = math.degrees(frames.yaw_ned_from_enu(heading))
    return [f"--start-ned={y:.3f},{x:.3f}", "--start-alt-m", f"{altitude_m:g}",
            f"--start-yaw-deg={yaw_deg:.3f}", "--start-airborne"]


class MockProcess:
    """``python -m sitl_mock ...`` as a child process; ``ready`` when it prints ``sitl_mock ready``."""

    def __init__(self, args: list[str]):
        self.cmd = [sys.executable, "-m", "sitl_mock", *args]
        self.proc: subprocess.Popen | None = None
        self.lines: list[str] = []
        self._ready = threading.Event()

    def start(self, timeout_s: float = 30.0) -> None:
        env = dict(os.environ)
        src_root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = src_root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        try:
            self.proc = subprocess.Popen(self.cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                         text=True, env=env)
        except OSError as err:
            raise LinkError(f"cannot start the mock autopilot ({err})") from err
        threading.Thread(target=self._read, daemon=True).start()
        end = time.monotonic() + timeout_s
        while not self._ready.wait(0.05):
            if self.proc.poll() is not None or time.monotonic() > end:
                tail = " | ".join(self.lines[-5:]) or "no output"
                self.stop()
                raise LinkError(f"the mock autopilot did not start ({' '.join(self.cmd[1:])}): {tail}")

    def _read(self) -> None:
        assert self.proc is not None and self.proc.stdout is not None
        if CAN_HOLD_SIGNALS:  # Ctrl-C and SIGTERM are the main thread's (link.py)
            signal.pthread_sigmask(signal.SIG_BLOCK, INTERRUPT_SIGNALS)
        for line in self.proc.stdout:
            line = line.rstrip("\n")
            self.lines.append(line)
            del self.lines[:-200]
            if line.startswith("sitl_mock ready"):
                self._ready.set()

    def stop(self) -> None:
        if self.proc is None or self.proc.poll() is not None:
            return
        self.proc.terminate()
        try:
            self.proc.wait(5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5.0)
