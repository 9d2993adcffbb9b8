"""``companion fly`` when the connection fails: one line on stderr, no Python exception text,
exit 2, and nothing left in ``logs/`` (the tlog and the mission copy are created only once an
autopilot has answered)."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from companion.cli.main import main
from companion.io.mock_process import free_udp_port

MISSION = str(Path(__file__).resolve().parents[2] / "missions" / "paper_sine.yaml")


def closed_tcp_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


@pytest.mark.parametrize("connect, words", [
    (lambda: f"tcp:127.0.0.1:{closed_tcp_port()}", "refused"),
    (lambda: "/dev/ttyACM0,abc", "baud"),
    (lambda: f"udpin:127.0.0.1:{free_udp_port()}", "no HEARTBEAT"),
    (lambda: f"udp:127.0.0.1:{free_udp_port()}", "no HEARTBEAT"),
    (lambda: "serial-port-nowhere:1", "unknown connection string"),
])
def test_a_failed_connection_is_one_line_and_leaves_no_file(connect, words, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = main(["fly", MISSION, "--connect", connect(), "--heartbeat-timeout-s", "0.5", "--quiet"])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2
    assert len(lines) == 1 and lines[0].startswith("companion: error:") and words in lines[0], err
    for noise in ("Traceback", "Errno", "Exception", "sleeping", "invalid literal"):
        assert noise not in err
    assert list(tmp_path.rglob("*")) == []  # no logs/, no empty tlog, no mission copy


def test_a_negative_drift_time_constant_is_one_line_before_any_connection(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = main(["fly", MISSION, "--connect", f"udpin:127.0.0.1:{free_udp_port()}", "--drift-tc-s", "-1",
               "--heartbeat-timeout-s", "0.5", "--quiet"])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "--drift-tc-s" in lines[0] and ">= 0" in lines[0], err
    assert list(tmp_path.rglob("*")) == []
