"""``companion bench fronts``: predictive's error at the other laws' a_rms, read from bench results.

The fronts here are drawn by hand, and every read-off is checked against the straight line
between the two flown points computed in the test.
"""

from __future__ import annotations

import json

import pytest

from companion.bench import fronts
from companion.cli.main import main
from companion.errors import CompanionError


def result(law: str, a_rms: float, d_rms: float, lambda_s4: float | None = None, fly_args=(),
           ff=None, side: str = "real", mission: str = "figure-eight") -> dict:
    """A ``bench sitl --json`` result of one flight on PX4 (the other side failed)."""
    row = {"a_rms_m_s2": a_rms, "d_rms_close_m": d_rms, "d_rms_m": d_rms + 1.0}
    other = "mock" if side == "real" else "real"
    return {"mission": "gone.yaml", "method": None,
            "flown": {"mission_name": mission, "method": law, "lambda_s4": lambda_s4, "accel_feedforward": ff,
                      "fly_args": list(fly_args)},
            "autopilots": {"px4": {side: row, other: {"error": "companion fly exited 2: no heartbeat"}}}}


def write(tmp_path, results: list[dict]) -> list[str]:
    names = []
    for k, r in enumerate(results):
        f = tmp_path / f"r{k}.json"
        f.write_text(json.dumps(r))
        names.append(str(f))
    return names


def by_law(group: dict) -> dict:
    return {law["law"]: law for law in group["laws"]}


def test_each_law_is_read_against_the_straight_line_between_predictive_s_flights():
    rs = [("a", result("predictive", 0.70, 0.30, 1.0)), ("b", result("predictive", 0.80, 0.10, 0.03)),
          ("c", result("predictive", 0.75, 0.40, 3.0)),  # dominated by the line: not on the front
          ("d", result("pure_pursuit", 0.75, 0.25)), ("e", result("npfg", 0.65, 0.05)),
          ("f", result("ap_l1", 0.90, 0.05))]
    [group] = fronts.compare(fronts.points(rs, "real"))
    laws = by_law(group)
    # at 0.75, halfway between (0.70, 0.30) and (0.80, 0.10): 0.20, below pure pursuit's 0.25
    assert laws["pure_pursuit"]["predictive_d_rms_close_m"] == pytest.approx(0.20)
    assert laws["pure_pursuit"]["law_over_predictive"] == pytest.approx(1.25) and laws["pure_pursuit"]["met"]
    # less a_rms than any predictive flight: nothing to read, not met
    assert laws["npfg"]["predictive_d_rms_close_m"] is None and not laws["npfg"]["met"]
    # beyond the last flight the front keeps its tightest error (0.10), which ArduPilot's L1 beats
    assert laws["ap_l1"]["predictive_d_rms_close_m"] == pytest.approx(0.10) and not laws["ap_l1"]["met"]
    assert [p["lambda_s4"] for p in group["predictive"]] == [1.0, 3.0, 0.03]  # all flights listed, by a_rms
    text = fronts.format_table([group])
    assert "met: 1 of 3" in text and "less a_rms than any predictive flight" in text


def test_flights_of_other_settings_sides_or_missions_are_not_compared():
    rs = [("a", result("predictive", 0.70, 0.30, 1.0)),
          ("b", result("pure_pursuit", 0.75, 0.25, fly_args=["--speed-hold-tc-s", "1"])),
          ("c", result("pure_pursuit", 0.75, 0.25, ff=True)),
          ("d", result("pure_pursuit", 0.75, 0.25, side="mock")),
          ("e", result("pure_pursuit", 0.75, 0.25, mission="racetrack")),
          ("f", result("npfg", 0.75, 0.35))]
    groups = fronts.compare(fronts.points(rs, "real"))
    assert len(groups) == 4  # the mock's flight is not on the real side at all
    [same] = [g for g in groups if g["predictive"]]
    assert [law["law"] for law in same["laws"]] == ["npfg"] and same["laws"][0]["met"]
    assert all(not g["predictive"] and all(law["predictive_d_rms_close_m"] is None for law in g["laws"])
               for g in groups if g is not same)
    assert fronts.format_table(groups).count("not met: no predictive flight to compare") == 3
    [mock] = fronts.compare(fronts.points(rs, "mock"))
    assert mock["side"] == "mock" and [law["law"] for law in mock["laws"]] == ["pure_pursuit"]


def test_an_older_result_is_described_by_its_mission_file_and_the_method_it_replaced():
    old = {"mission": "missions/figure_eight.yaml", "method": "pure_pursuit",
           "autopilots": {"px4": {"real": {"a_rms_m_s2": 0.8, "d_rms_close_m": 0.2}, "mock": {}}}}
    [p] = fronts.points([("old.json", old)], "real")
    assert p["law"] == "pure_pursuit" and p["group"] == ("figure-eight", "px4", "real", None, None)
    old["method"] = None  # the mission's own method
    assert fronts.points([("old.json", old)], "real")[0]["law"] == "corrector"
    old["mission"] = "missions/no_such_mission.yaml"
    with pytest.raises(CompanionError, match=r"old\.json: no 'flown' record and its mission file"):
        fronts.points([("old.json", old)], "real")


def test_the_command_prints_json_and_refuses_a_file_that_is_not_a_result(tmp_path, capsys):
    names = write(tmp_path, [result("predictive", 0.70, 0.30, 1.0), result("predictive", 0.80, 0.10, 0.03),
                             result("pure_pursuit", 0.75, 0.25)])
    assert main(["bench", "fronts", *names, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["side"] == "real" and out["met"] == 1 and out["compared"] == 1
    assert out["groups"][0]["laws"][0]["predictive_d_rms_close_m"] == pytest.approx(0.20)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["bench", "fronts", str(bad)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json: not JSON" in err[0] and "Traceback" not in err[0]
    bad.write_text("[1, 2]")
    assert main(["bench", "fronts", str(bad)]) != 0
    assert "expected the output of companion bench sitl --json" in capsys.readouterr().err
    broken = result("pure_pursuit", 0.75, 0.25)
    del broken["flown"]["method"]
    bad.write_text(json.dumps(broken))
    assert main(["bench", "fronts", str(bad)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json: 'flown': expected an object with the mission's name and the method" in err[0]
    broken = result("pure_pursuit", 0.75, 0.25)
    broken["flown"]["fly_args"] = 3
    bad.write_text(json.dumps(broken))
    assert main(["bench", "fronts", str(bad)]) != 0
    assert "bad.json: 'flown': expected an object" in capsys.readouterr().err


def test_a_tolerance_reads_the_front_that_much_further_right():
    # pure pursuit flew 0.05 % less a_rms than predictive's least (a tie within any boot's spread):
    # strictly nothing to read; with 0.1 % the front is read at 0.7004: 0.29920, under its 0.2995.
    rs = [("a", result("predictive", 0.7000, 0.30, 1.0)), ("b", result("predictive", 0.8000, 0.10, 0.03)),
          ("c", result("pure_pursuit", 0.6997, 0.2995))]
    [strict] = fronts.compare(fronts.points(rs, "real"))
    assert strict["laws"][0]["predictive_d_rms_close_m"] is None and not strict["laws"][0]["met"]
    [tol] = fronts.compare(fronts.points(rs, "real"), a_tolerance=0.001)
    a = 0.6997 * 1.001
    assert tol["laws"][0]["predictive_d_rms_close_m"] == pytest.approx(0.30 - 0.20 * (a - 0.70) / 0.10)
    assert tol["laws"][0]["met"]
    assert main(["bench", "fronts", "x.json", "--a-tolerance", "-0.1"]) != 0


def test_a_predictive_flight_with_its_course_observed_says_so(tmp_path):
    # flown_config records the observer's time constant of a predictive mission that states one
    # (None otherwise), and the front's line names it beside the lambda.
    base = "{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], [50, 0]]}, guidance: {method: %s}}"
    observed, plain = tmp_path / "observed.yaml", tmp_path / "plain.yaml"
    observed.write_text(base % "predictive, course_tc_s: 0.3")
    plain.write_text(base % "predictive")
    assert fronts.flown_config(str(observed), [])["course_tc_s"] == 0.3
    assert fronts.flown_config(str(plain), [])["course_tc_s"] is None
    assert fronts.flown_config(str(observed), [], method="pure_pursuit")["course_tc_s"] is None
    r = result("predictive", 0.70, 0.30, 0.3)
    r["flown"]["course_tc_s"] = 0.3
    [group] = fronts.compare(fronts.points([("a", r), ("b", result("pure_pursuit", 0.75, 0.25))], "real"))
    text = fronts.format_table([group])
    assert "0.3000 @ 0.700 (lambda 0.3, course observed over 0.3 s)" in text
