"""``companion log summary``: duration, senders, rates, modes and gaps, checked by hand."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.cli.main import main
from companion.replay.summary import summarise_log
from replay_tlogtools import TlogBuilder, heartbeat, local_position

COPTER_LOG = Path("/work/shared/data/ardupilot-copter-sitl-sine.tlog")

PX4 = mavlink.MAV_AUTOPILOT_PX4
QUAD = mavlink.MAV_TYPE_QUADROTOR


def px4_flight_with_a_pause() -> TlogBuilder:
    """PX4 at 50 Hz for 4 s, silent from 2.00 s to 3.50 s; POSCTL -> OFFBOARD (armed) -> LOITER."""
    b = TlogBuilder()
    t = 0.0
    i = 0
    while t < 4.0 - 1e-9:
        if not (2.0 < t < 3.5):
            b.add(t, 1, 1, local_position(i * 20, 0.0, 0.0, -5.0, 0, 0, 0))
        i += 1
        t = i * 0.02
    for t_hb, mode, armed in [(0.0, 3 << 16, False), (1.0, 6 << 16, True), (3.5, (4 << 16) | (3 << 24), True)]:
        b.add(t_hb + 0.001, 1, 1, heartbeat(QUAD, PX4, mode, armed))
    b.add(0.005, 1, 191, heartbeat(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID))
    b.records.sort(key=lambda r: r[0])
    return b


def test_px4_modes_rates_and_one_gap_by_hand(tmp_path):
    path = px4_flight_with_a_pause().write(tmp_path / "px4.tlog")
    s = summarise_log(path)
    assert s["duration_s"] == pytest.approx(3.98, abs=1e-6)  # first record 0.00, last 3.98
    assert [(m["time_s"], m["mode"], m["armed"]) for m in s["modes"]] == [
        (pytest.approx(0.001, abs=1e-6), "POSCTL", False),
        (pytest.approx(1.001, abs=1e-6), "OFFBOARD", True),
        (pytest.approx(3.501, abs=1e-6), "LOITER", True),
    ]
    lpn = [m for m in s["messages"] if m["type"] == "LOCAL_POSITION_NED"]
    # 0.00..2.00 (101 samples) and 3.50..3.98 (25 samples) -> 126 over 3.98 s
    assert lpn[0]["count"] == 126
    assert lpn[0]["rate_hz"] == pytest.approx(125 / 3.98)
    gaps = [(g["system"], g["component"], g["start_s"], g["duration_s"]) for g in s["link_gaps"]]
    assert gaps == [(1, 1, pytest.approx(2.0, abs=1e-6), pytest.approx(1.5, abs=1e-6))]
    systems = {(x["system"], x["component"]): x for x in s["systems"]}
    assert systems[(1, 1)]["type"] == "MAV_TYPE_QUADROTOR"
    assert systems[(1, 1)]["autopilot"] == "MAV_AUTOPILOT_PX4"
    assert systems[(1, 191)]["sparse"] is True  # one heartbeat: not searched for gaps


def test_summary_cli_json_on_the_copter_log(capsys):
    assert main(["log", "summary", str(COPTER_LOG), "--json"]) == 0
    out, err = capsys.readouterr()
    s = json.loads(out)
    assert "byte " in err  # the damaged stretches are warned about, with offsets
    assert 85.0 < s["duration_s"] < 95.0
    systems = {(x["system"], x["component"]): (x["type"], x["autopilot"]) for x in s["systems"]}
    assert systems[(1, 1)] == ("MAV_TYPE_QUADROTOR", "MAV_AUTOPILOT_ARDUPILOTMEGA")
    assert systems[(1, 191)] == ("MAV_TYPE_ONBOARD_CONTROLLER", "MAV_AUTOPILOT_INVALID")
    rates = {(m["system"], m["component"], m["type"]): m["rate_hz"] for m in s["messages"]}
    assert rates[(1, 1, "LOCAL_POSITION_NED")] == pytest.approx(50.0, rel=0.02)  # requested 20000 us
    assert rates[(1, 1, "ATTITUDE")] == pytest.approx(20.0, rel=0.02)  # requested 50000 us
    assert rates[(1, 1, "GLOBAL_POSITION_INT")] == pytest.approx(10.0, rel=0.02)  # requested 100000 us
    modes = [(m["mode"], m["armed"]) for m in s["modes"] if m["component"] == 1]
    assert modes[-1] == ("GUIDED", True)  # "ends still in GUIDED"
    armed_at = next(m["time_s"] for m in s["modes"] if m["armed"])
    assert 40.0 < armed_at < 48.0  # arm refused for about 44 s


def test_summary_cli_text_names_modes_and_senders(capsys):
    assert main(["log", "summary", str(COPTER_LOG)]) == 0
    out = capsys.readouterr().out
    assert "MAV_TYPE_QUADROTOR MAV_AUTOPILOT_ARDUPILOTMEGA" in out
    assert "GUIDED" in out and "armed" in out
    assert "SET_POSITION_TARGET_LOCAL_NED" in out


def test_unreadable_file_exits_2_with_one_line_and_no_traceback(tmp_path, capsys):
    path = tmp_path / "notalog.tlog"
    path.write_bytes(b"this is not a telemetry log\n" * 50)
    assert main(["log", "summary", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "no MAVLink records" in err
    assert main(["log", "summary", str(tmp_path / "missing.tlog")]) == 2
    assert "cannot read" in capsys.readouterr().err


@pytest.mark.parametrize("threshold, header, gaps", [
    (None, "link gaps longer than 0.5 s (per sender):", 1),
    ("2", "link gaps longer than 2 s (per sender):", 0),  # the 1.5 s pause is below 2 s
    ("1.25", "link gaps longer than 1.25 s (per sender):", 1),
])
def test_gap_threshold_changes_the_header_it_reports_under(tmp_path, capsys, threshold, header, gaps):
    path = px4_flight_with_a_pause().write(tmp_path / "px4.tlog")
    argv = ["log", "summary", str(path)] + (["--gap-threshold", threshold] if threshold else [])
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert header in text.splitlines()
    assert text.count("gaps, longest") == gaps
    assert main(argv + ["--json"]) == 0
    assert json.loads(capsys.readouterr().out)["gap_threshold_s"] == float(threshold or 0.5)
