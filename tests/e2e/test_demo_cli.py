"""The commands as a user runs them: ``companion demo --json`` and ``companion fly`` + SIGTERM."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

from pymavlink import mavutil

from companion.io.mock_process import MockProcess, free_udp_port
from companion.cli.main import main

ROOT = Path(__file__).resolve().parents[2]

SHORT = """\
name: demo-short
frame: local_enu
speed_m_s: 5.0
altitude_m: 10.0
path:
  type: function
  y_of_x: "10*sin(0.078*x) + 20*cos(0.082*x)"
  x_range_m: [-15, 60]
guidance: {l1_m: 10.0, method: corrector, rate_hz: 50}
midcourse: {circle_radius_m: 10.0, trigger: auto}
start: {x_m: -40.0, y_m: -25.0, heading_deg: 0.0}
"""


def test_demo_json_reports_the_shared_metric_names_a_tlog_and_a_plot(tmp_path, capsys):
    mission = tmp_path / "short.yaml"
    mission.write_text(SHORT)
    tlog = tmp_path / "demo.tlog"
    code = main(["demo", "--mission", str(mission), "--speedup", "5", "--json", "--quiet",
                 "--tlog", str(tlog)])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    for key in ("d_rms_m", "a_rms_m_s2", "a_max_m_s2", "duration_s", "phases", "rate_hz_achieved",
                "tick_ms", "tlog", "plot"):
        assert key in out, key
    assert set(out["tick_ms"]) >= {"p50", "p99"}
    assert set(out["phases"]) >= {"midcourse", "close_range"}
    for phase in out["phases"].values():
        assert {"d_rms_m", "a_rms_m_s2", "a_max_m_s2"} <= set(phase)
    assert out["exit"] == "finished"
    assert Path(out["tlog"]) == tlog and tlog.stat().st_size > 0
    assert Path(out["plot"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "demo.tlog.mission.yaml").read_text() == SHORT
    assert math.isfinite(out["d_rms_m"]) and out["d_rms_m"] > 0


def test_sigterm_mid_flight_leaves_a_complete_readable_tlog(tmp_path):
    mission = tmp_path / "short.yaml"
    mission.write_text(SHORT)
    port = free_udp_port()
    mock = MockProcess(["--autopilot", "px4", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                        "--speedup", "1", "--start-ned=-25,-40", "--start-alt-m", "10", "--start-airborne",
                        "--quiet"])
    mock.start(timeout_s=60.0)
    tlog = tmp_path / "f.tlog"
    proc = subprocess.Popen([sys.executable, "-m", "companion", "fly", str(mission), "--connect",
                             f"udpin:127.0.0.1:{port}", "--tlog", str(tlog), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:  # wait until it is flying (guidance records present)
            time.sleep(0.5)
            if tlog.exists() and b"guidance" in tlog.read_bytes():
                break
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20.0)
    finally:
        if proc.poll() is None:
            proc.kill()
        mock.stop()
    assert proc.returncode == 1
    assert "SIGTERM" in err and "Traceback" not in err
    data = tlog.read_bytes()
    conn = mavutil.mavlink_connection(str(tlog))
    n = 0
    last = None
    while (msg := conn.recv_match()) is not None:
        assert msg.get_type() != "BAD_DATA"
        n += 1
        last = msg
    assert n > 100 and last is not None
    # Every record is whole: the file ends exactly at the end of the last packet.
    assert data.endswith(bytes(last.get_msgbuf()))
