"""``companion bench sitl`` without real binaries: one clear line and exit 2 (the CI side of the
real-firmware tier, whose flights are in tests/sitl); its table and ratio from given rows."""

from __future__ import annotations

from companion.bench.sitl import arducopter_target, format_table, px4_target
from companion.cli.main import main


def test_no_binary_is_refused_with_one_line(capsys, tmp_path):
    assert main(["bench", "sitl", "missions/paper_sine.yaml"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--arducopter" in err[0]
    missing = str(tmp_path / "arducopter")
    assert main(["bench", "sitl", "missions/paper_sine.yaml", "--arducopter", missing]) == 2
    assert missing in capsys.readouterr().err


def test_the_binaries_start_as_the_sitl_scripts_start_them():
    t = arducopter_target("ac", "copter.parm", 4, 14640, 2.0, None)
    assert t.cmd == ["ac", "--model", "+", "--defaults", "copter.parm", "-w", "-I", "4", "--serial0",
                     "udpclient:127.0.0.1:14640", "--speedup", "2"]
    assert t.warmup_s == 25.0  # 50 s of simulated time at twice real time
    p = px4_target("px4", "etc", None)
    assert p.cmd[:5] == ["px4", "etc", "-s", "etc/init.d-posix/rcS", "-d"] and p.port == 14540
    assert p.env["PX4_SYS_AUTOSTART"] == "10040"


def test_the_table_puts_mock_and_real_side_by_side():
    row = {"d_rms_m": 0.5, "d_max_m": 2.0, "a_rms_m_s2": 1.0, "a_max_m_s2": 2.4, "d_rms_close_m": 0.5,
           "sat_share": 0.0, "duration_s": 60.0}
    result = {"mission": "m.yaml", "method": "corrector", "max_duration_s": 60.0, "speedup": 1.0,
              "autopilots": {"ardupilot": {
                  "mock": row, "real": {**row, "d_rms_m": 0.6}, "d_rms_ratio_real_mock": 1.2}}}
    text = format_table(result)
    assert "d_rms_m                0.500           0.600" in text
    assert "d_rms real / mock: 1.20" in text
