"""``companion sim`` end to end through ``main(argv)``."""

from __future__ import annotations

import json
from pathlib import Path

from companion.cli.main import main

MISSIONS = Path(__file__).resolve().parents[2] / "missions"


def test_sim_json_has_the_shared_metric_names_and_the_midcourse_phase(capsys):
    code = main(["sim", str(MISSIONS / "paper_far_start.yaml"), "--method", "fixed_l1", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("d_rms_m", "a_rms_m_s2", "a_max_m_s2", "duration_s", "phases"):
        assert key in out
    assert set(out["phases"]) == {"midcourse", "close_range"}
    assert out["finished"] is True
    assert out["phases"]["close_range"]["d_rms_m"] < 1.0
    assert out["a_max_m_s2"] <= 5.0 + 1e-9


def test_sim_overrides_start_and_heading_and_prints_a_table(capsys):
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--method", "fixed_l1", "--start=-15,0",
                 "--heading-deg", "24.118", "--t-max-s", "20"])
    assert code == 0
    text = capsys.readouterr().out
    assert "heading 24.118 deg" in text
    assert "time limit reached" in text
    assert "close_range" in text


def test_sim_plot_writes_a_png(tmp_path, capsys):
    out = tmp_path / "far.png"
    code = main(["sim", str(MISSIONS / "paper_far_start.yaml"), "--method", "fixed_l1", "--t-max-s", "40",
                 "--plot", str(out)])
    assert code == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_sim_on_a_missing_mission_fails_with_one_line_and_exit_2(tmp_path, capsys):
    code = main(["sim", str(tmp_path / "nope.yaml")])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("companion: error:")


def test_sim_flies_the_predictive_method_on_a_gallery_mission(capsys):
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--method", "predictive", "--t-max-s", "30",
                 "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "predictive"
    # 30 s at 5 m/s from a 39 deg start on the sine: captured within a metre, then tracked closely.
    assert out["d_max_m"] < 1.5 and out["phases"]["close_range"]["d_rms_m"] < 0.3
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--method", "predictive", "--t-max-s", "2"])
    assert code == 0 and "lambda 0.03 s^4" in capsys.readouterr().out
