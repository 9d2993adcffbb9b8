"""Run the real processes for the reliability tests: ``python -m sitl_mock`` and ``companion fly``.

Everything talks over loopback UDP on free ports. Each helper has a generous timeout so that a
loaded two-core machine slows the tests down instead of failing them.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from pymavlink import mavutil

from companion.io.mock_process import free_udp_port  # noqa: F401 - the tests take it from here

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable

#: A straight 400 m path east from the origin: the mock starts on it, heading east.
LINE_MISSION = """\
version: 1
name: line
frame: local_enu
speed_m_s: 5.0
altitude_m: 10.0
path:
  type: segments
  start_m: [0.0, 0.0]
  start_heading_deg: 0.0
  segments:
    - {type: line, length_m: 400.0}
guidance: {method: corrector, l1_m: 10.0, rate_hz: 50}
on_finish: hold
"""

MSG_LOCAL_POSITION_NED = 32
MSG_SET_POSITION_TARGET_LOCAL_NED = 84
PHASE_HOLD = 3



def write_mission(directory: Path, text: str = LINE_MISSION, name: str = "line.yaml") -> Path:
    path = Path(directory) / name
    path.write_text(text, encoding="utf-8")
    return path


def default_sigint() -> None:
    """In the child before exec: SIGINT back to its default action.

    A shell without job control starts background commands (``pytest ... &``) with SIGINT
    ignored, and children inherit that; a Python child that starts with SIGINT ignored never
    raises KeyboardInterrupt, so a Ctrl-C test would wait for nothing. With the default action
    restored, the child's interpreter installs its own handler as it would from a terminal.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class Proc:
    """A child process whose stdout and stderr are collected by reader threads."""

    def __init__(self, argv: list[str], cwd: Path = REPO):
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.argv = argv
        self.p = subprocess.Popen(argv, cwd=str(cwd), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True, env=env, preexec_fn=default_sigint)
        self.out: list[str] = []
        self.err: list[str] = []
        self._threads = [threading.Thread(target=self._read, args=(self.p.stdout, self.out), daemon=True),
                         threading.Thread(target=self._read, args=(self.p.stderr, self.err), daemon=True)]
        for t in self._threads:
            t.start()

    @staticmethod
    def _read(stream, sink: list[str]) -> None:
        for line in stream:
            sink.append(line)

    def wait_for(self, pattern: str, timeout_s: float, stream: str = "out") -> re.Match:
        """Wait for a line matching ``pattern``; AssertionError with the output on timeout/exit."""
        rx = re.compile(pattern)
        sink = self.out if stream == "out" else self.err
        end = time.monotonic() + timeout_s
        seen = 0
        while time.monotonic() < end:
            while seen < len(sink):
                m = rx.search(sink[seen])
                if m:
                    return m
                seen += 1
            if self.p.poll() is not None and seen >= len(sink):
                time.sleep(0.1)
                if seen >= len(sink):
                    break
            time.sleep(0.02)
        raise AssertionError(f"{pattern!r} not seen from {self.argv[2:4]} (rc {self.p.poll()}):\n"
                             + "".join(self.out[-20:]) + "".join(self.err[-20:]))

    def signal(self, sig: int) -> None:
        if self.p.poll() is None:
            self.p.send_signal(sig)

    def wait(self, timeout_s: float) -> int:
        try:
            rc = self.p.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.p.wait(timeout=10)
            raise AssertionError(f"{self.argv[2:4]} did not exit within {timeout_s} s (stalled?):\n"
                                 + "".join(self.err[-30:]))
        for t in self._threads:
            t.join(timeout=5)
        return rc

    def kill(self) -> None:
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait(timeout=10)

    @property
    def stdout(self) -> str:
        return "".join(self.out)

    @property
    def stderr(self) -> str:
        return "".join(self.err)


class Mock(Proc):
    """``python -m sitl_mock`` (PX4 copter, airborne at 10 m, heading east at the origin, no velocity-estimate
    bias, by default)."""

    def __init__(self, link: str, *extra: str, tlog: Path | None = None, sysid: int = 1,
                 autopilot: str = "px4"):
        argv = [PY, "-m", "sitl_mock", "--autopilot", autopilot, "--vehicle", "copter", "--link", link,
                "--sysid", str(sysid), "--speedup", "1", "--start-airborne", "--start-alt-m", "10",
                "--start-yaw-deg", "90", "--physics-hz", "200",
                # The link is the subject here: no velocity-estimate drift (a random walk of the
                # track, 0.18 m/s on the PX4 model) to blur the error bounds. It has its own tests
                # (tests/sim/test_identify.py, tests/e2e/test_climb_hold.py).
                "--vel-bias-m-s", "0", "--vel-offset-m-s", "0",
                "--duration-s", "180"]  # a backstop: no mock outlives a failed test by long
        if tlog is not None:
            argv += ["--tlog", str(tlog)]
        super().__init__(argv + list(extra))
        self.wait_for(r"sitl_mock ready", 30.0)

    def stop(self, timeout_s: float = 20.0) -> dict:
        """SIGTERM, wait, and return the summary line's ``key=value`` fields."""
        self.signal(signal.SIGTERM)
        self.wait(timeout_s)
        return self.summary()

    def summary(self) -> dict:
        for line in reversed(self.err):
            if line.startswith("sitl_mock summary"):
                return {k: _num(v) for k, v in re.findall(r"(\w+)=(\S+)", line)}
        raise AssertionError("no sitl_mock summary line:\n" + self.stderr[-2000:])


def _num(text: str):
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            return text


class Companion(Proc):
    """``companion fly MISSION --connect udpin:127.0.0.1:PORT --json --quiet ...``."""

    def __init__(self, mission: Path, port: int, tlog: Path, *extra: str):
        argv = [PY, "-m", "companion", "fly", str(mission), "--connect", f"udpin:127.0.0.1:{port}",
                "--tlog", str(tlog), "--json", "--heartbeat-timeout-s", "20"] + list(extra)
        super().__init__(argv)

    def result(self, timeout_s: float = 60.0) -> tuple[int, dict | None]:
        rc = self.wait(timeout_s)
        text = self.stdout.strip()
        return rc, (json.loads(text) if text.startswith("{") else None)

    def wait_flying(self, timeout_s: float = 30.0) -> None:
        """Until the status says the guidance loop runs (needs no --quiet)."""
        self.wait_for(r"companion: flying ", timeout_s, stream="err")


def read_tlog(path: Path) -> list:
    """Every message of a tlog, each with ``_timestamp`` (unix seconds), in file order."""
    conn = mavutil.mavlink_connection(str(path), robust_parsing=True)
    out = []
    while True:
        m = conn.recv_msg()
        if m is None:
            break
        out.append(m)
    conn.close()
    return out


def mavlogdump(path: Path, *extra: str) -> subprocess.CompletedProcess:
    """Run pymavlink's ``mavlogdump.py`` on a tlog (the external reader the logs must satisfy)."""
    tool = Path(PY).parent / "mavlogdump.py"
    return subprocess.run([PY, str(tool), *extra, str(path)], capture_output=True, text=True, timeout=120)


def guidance_records(msgs: list) -> list:
    """The companion's per-tick DEBUG_FLOAT_ARRAY "guidance" records."""
    out = []
    for m in msgs:
        if m.get_type() == "DEBUG_FLOAT_ARRAY":
            name = m.name.decode() if isinstance(m.name, bytes) else m.name
            if name.rstrip("\x00") == "guidance":
                out.append(m)
    return out
