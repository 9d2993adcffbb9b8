"""``companion mission check | show | schema`` through ``companion.cli.main.main``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from companion.cli.main import main

STRAIGHT = """\
name: straight
speed_m_s: 4
path: {type: waypoints, points_m: [[0, 0], [100, 0]]}
start: {x_m: -30, y_m: -40, heading_deg: 90}
"""
TIGHT = """\
name: tight
speed_m_s: 6
path: {type: parametric, x_of_s: "3*cos(s)", y_of_s: "3*sin(s)", s_range: [0, 2*pi], closed: true}
guidance: {method: fixed_l1, l1_m: 12}
"""


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_check_clean_file_exits_0_with_a_summary(tmp_path, capsys):
    path = write(tmp_path, "straight.yaml", STRAIGHT)
    assert main(["mission", "check", str(path)]) == 0
    out, err = capsys.readouterr()
    assert err == "" and out.strip() == f"{path}: ok: 'straight', 100.0 m path, V = 4 m/s, L1 = 10 m"


def test_check_warns_about_curvature_tighter_than_l1_allows_but_exits_0(tmp_path, capsys):
    path = write(tmp_path, "tight.yaml", TIGHT)
    assert main(["mission", "check", str(path)]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1
    # Radius 3 m < L1/2 = 6 m; V^2/R = 36/3 = 12 m/s^2 > 2 V^2/L1 = 72/12 = 6 m/s^2.
    assert lines[0].startswith(f"{path}: path: warning: curvature radius 3 m")
    assert "needs V^2/R = 12 m/s^2, more than fixed-L1 can command (2 V^2/L1 = 6 m/s^2)" in lines[0]
    assert "1 warning(s)" in out


def test_check_json_lists_problems_and_warnings(tmp_path, capsys):
    path = write(tmp_path, "bad.yaml", "name: b\nspeed_m_s: 0\npath: {type: waypoints, points_m: [[0, 0], [1, 0]]}\n")
    assert main(["mission", "check", "--json", str(path)]) == 2
    doc = json.loads(capsys.readouterr().out)
    assert doc["ok"] is False and doc["warnings"] == []
    assert doc["problems"] == [f"{path}: speed_m_s: expected a finite number > 0 and <= 100, got 0"]


def test_show_json_gives_hand_checked_figures(tmp_path, capsys):
    path = write(tmp_path, "straight.yaml", STRAIGHT)
    assert main(["mission", "show", "--json", str(path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["length_m"] == pytest.approx(100.0, abs=1e-6)
    assert doc["start_heading_deg"] == pytest.approx(0.0, abs=1e-6)
    assert doc["radius_min_m"] is None or doc["radius_min_m"] > 1e6
    # Start (0, 0) heading east, R = 10 m: circle centres 10 m to the left (north) and right (south).
    centres = [c["centre_xy_m"] for c in doc["initiation_circles"]]
    assert centres[0] == pytest.approx([0.0, 10.0], abs=1e-6)
    assert centres[1] == pytest.approx([0.0, -10.0], abs=1e-6)
    assert doc["vehicle_start"] == {"x_m": -30.0, "y_m": -40.0, "heading_deg": 90.0}


def test_show_plot_writes_a_png(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    path = write(tmp_path, "tight.yaml", TIGHT)
    png = tmp_path / "out.png"
    assert main(["mission", "show", str(path), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "tightest radius: 3.00 m" in out and f"plot: {png}" in out


def test_show_circle_radius_on_the_paper_sine_start(tmp_path, capsys):
    text = ("name: s\nspeed_m_s: 5\npath: {type: function, y_of_x: \"10*sin(0.078*x) + 20*cos(0.082*x)\","
            " x_range_m: [-15, 300]}\nmidcourse: {circle_radius_m: 12}\n")
    assert main(["mission", "show", "--json", str(write(tmp_path, "s.yaml", text))]) == 0
    doc = json.loads(capsys.readouterr().out)
    x0 = -15.0
    y0 = 10 * math.sin(0.078 * x0) + 20 * math.cos(0.082 * x0)
    h = math.atan(10 * 0.078 * math.cos(0.078 * x0) - 20 * 0.082 * math.sin(0.082 * x0))
    left = [x0 - 12 * math.sin(h), y0 + 12 * math.cos(h)]
    assert doc["initiation_circles"][0]["centre_xy_m"] == pytest.approx(left, abs=1e-3)


def test_schema_action_prints_the_committed_schema(capsys):
    assert main(["mission", "schema"]) == 0
    committed = (Path(__file__).resolve().parents[2] / "companion/mission/mission.schema.json").read_text()
    assert capsys.readouterr().out == committed


def test_import_rejects_a_negative_speed_option(tmp_path, capsys):
    src = tmp_path / "x.plan"
    src.write_text("{}")
    assert main(["mission", "import", str(src), "-o", str(tmp_path / "o.yaml"), "--speed-m-s", "-3"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "companion: error: --speed-m-s: expected a finite number > 0, got -3.0"


PLAN = Path(__file__).resolve().parents[2] / "missions" / "qgc_inspection.plan"


def test_import_keeps_an_existing_output_unless_forced(tmp_path, capsys):
    out = tmp_path / "o.yaml"
    out.write_text("mine\n")
    assert main(["mission", "import", str(PLAN), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (f"companion: error: {out}: already exists; not overwritten "
                           "(pass --force to replace it, or -o - to print)")
    assert out.read_text() == "mine\n"
    assert main(["mission", "import", str(PLAN), "-o", str(out), "--force"]) == 0
    assert out.read_text().startswith("#") or "path:" in out.read_text()
    assert out.read_text() != "mine\n"


def test_import_to_stdout_prints_only_the_yaml(tmp_path, capsys):
    assert main(["mission", "import", str(PLAN), "-o", "-"]) == 0
    captured = capsys.readouterr()
    assert not (tmp_path / "-").exists() and not Path("-").exists()
    doc = tmp_path / "from_stdout.yaml"
    doc.write_text(captured.out)
    assert main(["mission", "check", str(doc)]) == 0  # stdout alone is a valid mission
    assert "<stdout>: wrote" in captured.err


def test_show_says_below_which_vehicle_limit_a_flight_slows_in_the_turns(tmp_path, capsys):
    # A 20 m circle at 6 m/s asks V^2 / R = 1.8 m/s^2: slowed on a vehicle below 1.8 / 0.5 = 3.6 m/s^2.
    text = ("name: circle\nspeed_m_s: 6.0\nalong_track: {turn_accel_share: 0.5}\n"
            "path: {type: parametric, x_of_s: '20*cos(s)', y_of_s: '20*sin(s)', s_range: [0, 6.283185307179586], "
            "closed: true}\n")
    assert main(["mission", "show", "--json", str(write(tmp_path, "c.yaml", text))]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["a_path_max_m_s2"] == pytest.approx(1.8, rel=1e-3)
    assert doc["turns_slowed_below_a_max_m_s2"] == pytest.approx(3.6, rel=1e-3)
    assert main(["mission", "show", str(write(tmp_path, "c.yaml", text))]) == 0
    assert "slower in the turns on a vehicle whose acceleration limit is below 3.60 m/s^2" in capsys.readouterr().out
