"""``companion bench sitl`` without real binaries: one clear line and exit 2 (the CI side of the
real-firmware tier, whose flights are in tests/sitl); its table and ratio from given rows."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

from companion.bench.sitl import arducopter_target, format_table, log_figures, median_row, mock_cmd, px4_target
from companion.cli.main import main
from companion.guidance.types import GuidanceOutput
from companion.io.state import PositionSample
from companion.loop.tick import TickConfig, compute_tick

from pymavlink import mavutil
from sitl_mock.cli import build_parser, config_from_args

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "replay"))
from replay_tlogtools import TlogBuilder  # noqa: E402


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


REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"


@pytest.mark.parametrize("log", ["ardupilot-copter-racetrack-predictive.tlog", "ardupilot-copter-figure-eight-corrector.tlog",
                                 "px4-sih-racetrack-predictive.tlog"])
def test_the_mock_starts_facing_where_the_real_sitl_starts(log):
    # The mid-course circles and the capture turn depend on the start heading: a mock facing north
    # chose another circle than the real ArduCopter, facing 353 deg, on the figure-eight.
    target = (arducopter_target("ac", None, 4, 14640, 1.0, None) if log.startswith("ardupilot")
              else px4_target("px4", "etc", None))
    argv = mock_cmd(target, 14999, 60.0)[3:]  # after "python -m sitl_mock"
    start_yaw_deg = config_from_args(build_parser().parse_args(argv)).start_yaw_deg
    conn = mavutil.mavlink_connection(str(REAL / log))
    first = conn.recv_match(type="ATTITUDE")  # on the ground, before take-off
    assert abs(math.remainder(math.degrees(first.yaw) - start_yaw_deg, 360.0)) < 3.0


def test_the_table_puts_mock_and_real_side_by_side():
    row = {"d_rms_m": 0.5, "d_max_m": 2.0, "a_rms_m_s2": 1.0, "a_max_m_s2": 2.4, "d_rms_close_m": 0.5,
           "sat_share": 0.0, "duration_s": 60.0}
    result = {"mission": "m.yaml", "method": "corrector", "max_duration_s": 60.0, "speedup": 1.0,
              "autopilots": {"ardupilot": {
                  "mock": row, "real": {**row, "d_rms_m": 0.6}, "d_rms_ratio_real_mock": 1.2}}}
    text = format_table(result)
    assert "d_rms_m                0.500           0.600" in text
    assert "d_rms real / mock: 1.20" in text


class Commanded:
    """A law commanding given accelerations, one per tick."""

    def __init__(self, a_m_s2):
        self.a = list(a_m_s2)

    def step(self, t_s, state):
        return GuidanceOutput(a_cmd_m_s2=self.a.pop(0), phase="close_range", crosstrack_m=0.1, s_proj_m=0.0)


def test_saturation_is_counted_over_the_flight_and_after_30_s_against_the_limit_read(tmp_path):
    # 40 ticks at 1 Hz; the autopilot says WPNAV_ACCEL 250 cm/s^2: 2.5 m/s^2. Saturated: ticks
    # 0-9 (a capture) and tick 35: 11 of 40 over the flight, 1 of the 10 from 30 s on.
    a = [2.5] * 10 + [1.0] * 20 + [-1.0] * 5 + [-2.5] + [0.5] * 4
    law = Commanded(a)
    log = TlogBuilder()
    ap, comp = log.sender(1, 1), log.sender(1, 191)
    log.add(0.0, 1, 1, ap.param_value_encode(b"WPNAV_ACCEL", 250.0, 9, 1, 0))
    config = TickConfig(speed_m_s=5.0, rate_hz=1.0, altitude_m=10.0)
    for k in range(40):
        t = float(k)
        ms = 1000 + 1000 * k
        v = 5.0 if k < 30 else 4.0 + 0.2 * (k % 2)  # from 30 s on: 4.0 and 4.2 in turn, 4.1 on average
        sample = PositionSample(ms, 0.0, 5.0 * t, -10.0, 0.0, v, 0.0)
        row = list(compute_tick(law, k, t, sample, 0.0, config, prev_course_rad=0.0).debug)
        row += [math.nan] * (58 - len(row))
        log.add(t + 0.5, 1, 1, ap.local_position_ned_encode(ms, 0.0, 5.0 * t, -10.0, 0.0, 5.0, 0.0))
        log.add(t + 0.501, 1, 191, comp.debug_float_array_encode(ms * 1000, b"guidance", 0, row))
    figures = log_figures(str(log.write(tmp_path / "f.tlog")), math.inf)
    assert figures["a_limit_m_s2"] == pytest.approx(2.5)
    assert figures["sat_share"] == pytest.approx(11 / 40)
    assert figures["sat_share_settled"] == pytest.approx(1 / 10)
    assert figures["d_rms_settled_m"] == pytest.approx(0.1)
    assert figures["speed_settled_m_s"] == pytest.approx(4.1)


def test_a_mock_flown_with_several_seeds_reports_each_metric_s_median_and_the_spread():
    rows = [{"d_rms_m": v, "d_max_m": 10 * v, "a_rms_m_s2": 1.0, "exit": "max duration"} for v in (0.3, 0.1, 0.2)]
    rows.append({"error": "companion fly exited 1"})
    median = median_row(rows)
    assert median["d_rms_m"] == 0.2 and median["d_max_m"] == 2.0 and median["a_rms_m_s2"] == 1.0
    assert median_row(rows[:2])["d_rms_m"] == pytest.approx(0.2)  # even count: the mean of the middle two
    assert median_row([{"error": "x"}]) == {"error": "x"}
    result = {"mission": "m.yaml", "method": "corrector", "max_duration_s": 60.0, "speedup": 1.0, "mock_seeds": 3,
              "autopilots": {"px4": {"mock": median, "real": {"d_rms_m": 0.25}, "d_rms_ratio_real_mock": 1.25,
                                     "mock_runs": rows}}}
    text = format_table(result)
    assert "mock (median of 3)" in text and "mock d_rms_m over its 3 seeds: 0.100 to 0.300" in text
    # the seed reaches the mock
    target = px4_target("px4", "etc", None)
    argv = mock_cmd(target, 14999, 60.0, seed=7)[3:]
    assert config_from_args(build_parser().parse_args(argv)).seed == 7


def test_several_real_flights_start_later_and_later_after_boot_and_report_their_medians(monkeypatch, tmp_path):
    # A SITL replays the same sensor noise after every boot: the further real flights start later
    # after their boot (by default the flight time and 30 s more), each from a fresh binary in a
    # directory of its own, and the real side is their median.
    from argparse import Namespace

    from companion.bench import sitl

    calls = []
    real_d = iter([0.5, 0.3, 0.4])

    def fake_fly_on(target, real, mission, opts, workdir, timeout_s, seed=0, later_s=0.0):
        calls.append((real, later_s, workdir))
        return {"d_rms_m": next(real_d) if real else 0.2, "exit": "max duration", "tlog": "unused"}

    monkeypatch.setattr(sitl, "fly_on", fake_fly_on)
    monkeypatch.setattr(sitl, "log_figures", lambda tlog, limit: {})
    args = Namespace(mission="missions/paper_sine.yaml", method=None, a_limit_m_s2=2.0, max_duration_s=60.0,
                     speedup=1.0, workdir=str(tmp_path), mock_seeds=1, real_runs=3, real_stagger_s=None)
    out = sitl.run_bench(args, [px4_target("px4", "etc", None)])
    reals = [c for c in calls if c[0]]
    assert [c[1] for c in reals] == [0.0, 90.0, 180.0]
    assert len({c[2] for c in reals}) == 3
    side = out["autopilots"]["px4"]
    assert side["real"]["d_rms_m"] == 0.4 and side["d_rms_ratio_real_mock"] == pytest.approx(2.0)
    assert side["real_later_s"] == [0.0, 90.0, 180.0] and len(side["real_runs"]) == 3
    text = format_table(out)
    assert "real px4 (median of 3)" in text and "real d_rms_m over its 3 flights: 0.300 to 0.500" in text
    # At twice real time the flight takes half the wall time; a given stagger is used as it is.
    args.speedup, calls[:] = 2.0, []
    real_d = iter([0.5, 0.3, 0.4])
    sitl.run_bench(args, [px4_target("px4", "etc", None)])
    assert [c[1] for c in calls if c[0]] == [0.0, 60.0, 120.0]
    args.speedup, args.real_stagger_s, calls[:] = 1.0, 5.0, []
    real_d = iter([0.5, 0.3, 0.4])
    sitl.run_bench(args, [px4_target("px4", "etc", None)])
    assert [c[1] for c in calls if c[0]] == [0.0, 5.0, 10.0]


def test_no_real_run_flies_the_mock_alone_and_starts_no_binary(monkeypatch, tmp_path):
    # --real-runs 0: the binary options only name the mock's personality; nothing real is started,
    # the real side is empty and there is no ratio.
    from argparse import Namespace

    from companion.bench import sitl

    calls, opts_seen = [], []

    def fake_fly_on(target, real, mission, opts, workdir, timeout_s, seed=0, later_s=0.0):
        calls.append((target.autopilot, real, seed))
        opts_seen.append(opts)
        return {"d_rms_m": 0.1 * (seed + 1), "exit": "max duration", "tlog": "unused"}

    monkeypatch.setattr(sitl, "fly_on", fake_fly_on)
    monkeypatch.setattr(sitl, "log_figures", lambda tlog, limit: {})
    args = Namespace(mission="missions/paper_sine.yaml", method=None, a_limit_m_s2=2.0, max_duration_s=60.0,
                     speedup=1.0, workdir=str(tmp_path), mock_seeds=3, real_runs=0, real_stagger_s=None,
                     fly_args="--speed-hold-tc-s 2 --drift-tc-s 0")
    out = sitl.run_bench(args, [px4_target("px4", "etc", None)])
    assert calls == [("px4", False, 0), ("px4", False, 1), ("px4", False, 2)]
    assert all(o[-4:] == ["--speed-hold-tc-s", "2", "--drift-tc-s", "0"] for o in opts_seen)  # every flight
    # ... and the result says what was flown (companion bench fronts groups by it)
    assert out["flown"] == {"mission_name": "paper-sine", "method": "corrector", "lambda_s4": None, "course_tc_s": None,
                            "accel_feedforward": None, "fly_args": ["--speed-hold-tc-s", "2", "--drift-tc-s", "0"]}
    side = out["autopilots"]["px4"]
    assert side["real"] == {} and side["d_rms_ratio_real_mock"] is None and "real_runs" not in side
    assert side["mock"]["d_rms_m"] == pytest.approx(0.2)
    text = format_table(out)
    assert "real px4: not flown" in text and "d_rms real / mock: -" in text


def test_a_later_real_flight_waits_that_much_longer_after_boot(monkeypatch, tmp_path):
    from companion.bench import sitl

    waits = []

    class Exited:  # a binary that has already exited: fly_on reports it after the wait
        def __init__(self, cmd, cwd, env=None):
            self.proc = type("P", (), {"poll": lambda self: 1, "returncode": 1})()

        def stop(self):
            pass

    monkeypatch.setattr(sitl, "Process", Exited)
    monkeypatch.setattr(sitl.time, "sleep", waits.append)
    row = sitl.fly_on(px4_target("px4", "etc", None), True, "m.yaml", [], tmp_path, 10.0, later_s=90.0)
    assert "exited 1 at start" in row["error"] and waits == [100.0]  # PX4's 10 s warm-up + 90 s


def test_no_mock_seed_flies_the_real_alone(monkeypatch, tmp_path):
    # --mock-seeds 0: the real flights only; the mock side is empty and there is no ratio.
    from argparse import Namespace

    from companion.bench import sitl

    calls = []

    def fake_fly_on(target, real, mission, opts, workdir, timeout_s, seed=0, later_s=0.0):
        calls.append(real)
        return {"d_rms_m": 0.3, "exit": "max duration", "tlog": "unused"}

    monkeypatch.setattr(sitl, "fly_on", fake_fly_on)
    monkeypatch.setattr(sitl, "log_figures", lambda tlog, limit: {})
    args = Namespace(mission="missions/paper_sine.yaml", method=None, a_limit_m_s2=2.0, max_duration_s=60.0,
                     speedup=1.0, workdir=str(tmp_path), mock_seeds=0, real_runs=1, real_stagger_s=None)
    out = sitl.run_bench(args, [px4_target("px4", "etc", None)])
    side = out["autopilots"]["px4"]
    assert calls == [True] and side["mock"] == {} and side["d_rms_ratio_real_mock"] is None
    assert side["real"]["d_rms_m"] == pytest.approx(0.3)
    text = format_table(out)
    assert "mock: not flown" in text and "d_rms real / mock: -" in text


@pytest.mark.parametrize("options", [["--real-runs", "-1"], ["--real-stagger-s", "-1"], ["--mock-seeds", "-1"],
                                     ["--mock-seeds", "0", "--real-runs", "0"]])
def test_bad_real_run_options_are_refused_with_one_line(capsys, options):
    assert main(["bench", "sitl", "missions/paper_sine.yaml", "--px4", sys.executable, "--px4-romfs", ".",
                 *options]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and options[0] in err[0]
