"""``companion bench tracking``: the front arithmetic by hand, and the CI form end to end."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench_scenes import LinePath
from companion.bench.tracking import (JOIN_S, REFINE_LAMBDA_FLOOR_S4, ModelSpec, Task, fly_task, front_at,
                                      join_split, named_spec, pareto_front, refinement_settings, run_one,
                                      render_tables, summarise, true_crosstrack_m, where_lost,
                                      windows_alike)
from companion.cli.main import main


def test_pareto_front_drops_dominated_points_and_sorts_by_acceleration():
    pts = [(1.0, 0.5), (0.8, 0.9), (1.2, 0.2), (1.1, 0.6), (0.9, 0.95), (1.3, 0.25), (float("nan"), 0.1)]
    # (1.1, 0.6) is beaten by (1.0, 0.5); (0.9, 0.95) by (0.8, 0.9); (1.3, 0.25) by (1.2, 0.2).
    assert pareto_front(pts) == [(0.8, 0.9), (1.0, 0.5), (1.2, 0.2)]


def test_front_is_interpolated_between_points_and_flat_beyond_the_last():
    front = [(1.0, 0.6), (2.0, 0.2)]
    assert front_at(front, 1.5) == pytest.approx(0.4)
    assert front_at(front, 3.0) == pytest.approx(0.2)
    assert front_at(front, 0.5) is None


def test_summary_names_the_law_with_the_lowest_front_at_our_acceleration():
    rows = []
    for law, pts in {"predictive": [(0.03, 1.5, 0.30), (0.3, 1.0, 0.8)],
                     "npfg": [(3.0, 1.4, 0.50), (6.0, 1.6, 0.2)],
                     "pure_pursuit": [(4.0, 1.5, 0.35)]}.items():
        for setting, a, d in pts:
            rows.append({"scenario": "s", "model": "lag", "law": law, "setting": setting,
                         "a_rms_m_s2": a, "d_rms_m": d})
    (s,) = summarise(rows, default_lambda=0.03)
    assert s["a_rms_ref_m_s2"] == 1.5
    # npfg's front at a = 1.5: halfway between (1.4, 0.5) and (1.6, 0.2) -> 0.35.
    assert s["d_rms_by_law"]["npfg"] == pytest.approx(0.35)
    assert s["best_law"] == "predictive" and s["best_d_rms_m"] == pytest.approx(0.30)
    assert s["margin_m"] == pytest.approx(0.05)
    # npfg's (1.6, 0.2) lies below predictive's front there (0.30): reported honestly.
    assert [(b["law"], b["a_rms_m_s2"]) for b in s["predictive_beaten_at"]] == [("npfg", 1.6)]


def _rows(points: dict) -> list[dict]:
    return [{"scenario": "s", "model": "lag", "law": law, "setting": setting, "a_rms_m_s2": a, "d_rms_m": d}
            for law, pts in points.items() for setting, a, d in pts]


def test_refinement_asks_for_the_lambda_between_the_runs_that_bracket_a_beaten_point():
    # predictive: lambda 0.01 flies a_rms 1.2, lambda 1 flies 1.0; the chord at 1.05 is 0.55 - npfg's
    # (1.05, 0.5) lies below it. a_rms 1.05 is a quarter of the way from 1.0 to 1.2, i.e. 3/4 of the
    # way from lambda 0.01 to 1 in log lambda (within the middle half): 10^(-2 + 0.75 * 2) = 0.3162.
    rows = _rows({"predictive": [(0.01, 1.2, 0.3), (1.0, 1.0, 0.7)], "npfg": [(3.0, 1.05, 0.5)]})
    assert refinement_settings(rows) == {("s", "lag"): [0.3162]}
    # Nearer one end than the middle half allows: clamped to a quarter of the bracket (bisection-like).
    rows = _rows({"predictive": [(0.01, 1.2, 0.3), (1.0, 1.0, 0.7)], "npfg": [(3.0, 1.01, 0.6)]})
    assert refinement_settings(rows) == {("s", "lag"): [float(f"{10 ** (-2 + 0.75 * 2):.4g}")]}
    rows = _rows({"predictive": [(0.01, 1.2, 0.3), (1.0, 1.0, 0.7)], "npfg": [(3.0, 1.19, 0.25)]})
    assert refinement_settings(rows) == {("s", "lag"): [float(f"{10 ** (-2 + 0.25 * 2):.4g}")]}


def test_refinement_extends_the_front_past_its_smallest_lambda_down_to_a_floor():
    # npfg spends more than predictive's tightest setting and tracks tighter: try a third of it.
    rows = _rows({"predictive": [(0.003, 1.2, 0.3), (0.3, 1.0, 0.7)], "npfg": [(2.0, 1.3, 0.2)]})
    assert refinement_settings(rows) == {("s", "lag"): [0.001]}
    rows = _rows({"predictive": [(REFINE_LAMBDA_FLOOR_S4 * 2, 1.2, 0.3), (0.3, 1.0, 0.7)],
                  "npfg": [(2.0, 1.3, 0.2)]})
    assert refinement_settings(rows) == {}  # a third would be below the floor


def test_refinement_asks_nothing_already_flown_nor_where_no_point_is_below():
    rows = _rows({"predictive": [(0.01, 1.2, 0.3), (0.3162, 1.05, 0.52), (1.0, 1.0, 0.7)],
                  "npfg": [(3.0, 1.05, 0.5)]})
    # (1.05, 0.5) is still below (0.52), but its lambda has been flown: the next one brackets closer.
    (lams,) = refinement_settings(rows).values()
    assert lams and all(0.3162 < lam < 1.0 or 0.01 < lam < 0.3162 for lam in lams) and 0.3162 not in lams
    rows = _rows({"predictive": [(0.01, 1.2, 0.3), (1.0, 1.0, 0.7)], "npfg": [(3.0, 1.05, 0.6)]})
    assert refinement_settings(rows) == {}


def test_crosstrack_is_measured_from_the_trajectory_with_sign():
    x = np.array([0.0, 10.0, 20.0])
    y = np.array([3.0, -2.0, 0.5])
    assert np.allclose(true_crosstrack_m(LinePath(x0=-10.0), x, y), [3.0, -2.0, 0.5])


def test_quick_bench_runs_every_law_in_both_models(capsys):
    assert main(["bench", "tracking", "--quick", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    rows = doc["rows"]
    laws = ("fixed_l1", "corrector", "ap_l1", "npfg", "pure_pursuit", "predictive")
    assert {(r["model"], r["law"]) for r in rows} == {(m, law) for m in ("ideal", "lag") for law in laws}
    assert len(rows) == 2 * 2 * len(laws) * 2  # scenarios x models x laws x settings
    assert {r["scenario"] for r in rows} == {"s_turn", "paper_sine_h05"}
    for r in rows:
        for key in ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "reach_s"):
            assert r[key] is not None and math.isfinite(r[key]), (r, key)
        assert r["d_rms_m"] <= r["d_max_m"] and r["a_rms_m_s2"] <= r["a_max_m_s2"] + 1e-12
        if r["model"] == "lag":
            assert r["a_max_m_s2"] <= 5.0 + 1e-9  # every law charged what it flies: within the limit
    assert {(s["scenario"], s["model"]) for s in doc["summary"]} == {
        (sc, m) for sc in ("s_turn", "paper_sine_h05") for m in ("ideal", "lag")}


def test_model_option_runs_only_that_model(capsys):
    assert main(["bench", "tracking", "--scenario", "s_turn", "--law", "npfg", "--quick", "--model", "lag",
                 "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [(r["model"], r["setting"]) for r in rows] == [("lag", 3.0), ("lag", 6.0)]


def test_unknown_scenario_is_a_one_line_error(capsys):
    assert main(["bench", "tracking", "--scenario", "moon"]) == 2
    err = capsys.readouterr().err
    assert "unknown 'moon'" in err and "Traceback" not in err


def test_refine_flies_predictive_at_the_contested_accelerations(capsys, tmp_path):
    # random_1003 (an open self-crossing path started at its crossing, 9 m/s, wind): in the short
    # sweep npfg's period-3 point lies below predictive's two-point front.
    args = ["bench", "tracking", "--random", "1", "--seed", "1003", "--model", "lag", "--quick", "--jobs", "1",
            "--law", "npfg", "--law", "predictive", "--json"]
    assert main(args) == 0
    plain = json.loads(capsys.readouterr().out)
    assert plain["summary"][0]["predictive_beaten_at"] and plain["refined_runs"] == 0
    out = tmp_path / "rows.jsonl"
    assert main(args + ["--refine", "2", "--out", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    lams = sorted(r["setting"] for r in doc["rows"] if r["law"] == "predictive")
    assert doc["refined_runs"] == len(lams) - 2 >= 1
    assert len(out.read_text().splitlines()) == len(doc["rows"])  # the refinement's rows are streamed too
    # every refined lambda was asked for by a point below the front of the runs before it
    assert all(REFINE_LAMBDA_FLOOR_S4 <= lam <= 0.3 for lam in lams)
    assert main(["bench", "tracking", "--refine", "-1"]) == 2


def test_reach_is_where_a_flight_enters_the_band_to_stay_touch_where_it_first_enters():
    # From the far start, fixed L1 at 5 m swings through the path and out again (its mid-course
    # hands over at an angle); ArduPilot's L1 at 3 s and predictive come in. For every run: the
    # tracking window starts at touch_s, the first sample within 1 m; reach_s is the first
    # sample from which |d| stays within 1 m for 2 s. Checked against the flown track.
    sc = named_spec("far_start")
    seen_swing = False
    for law, setting in (("fixed_l1", 5.0), ("ap_l1", 3.0), ("predictive", 0.03)):
        task = Task(sc, ModelSpec("lag"), law, setting)
        row = run_one(task)
        path, res = fly_task(task)
        d = np.abs(true_crosstrack_m(path, res.x_m, res.y_m))
        t = res.t_s
        assert row["touch_s"] == pytest.approx(t[np.flatnonzero(d <= 1.0)[0]])
        assert row["reach_s"] >= row["touch_s"]
        stay = (t >= row["reach_s"] - 1e-9) & (t <= row["reach_s"] + 2.0 - 1e-9)
        assert np.all(d[stay] <= 1.0)
        between = (t >= row["touch_s"]) & (t < row["reach_s"] - 1e-9)
        if row["reach_s"] > row["touch_s"]:
            seen_swing = True
            assert np.max(d[between]) > 1.0  # it left the band in between
            # and no earlier 2 s stay: every start before reach_s leaves the band within 2 s
            for i in np.flatnonzero(between & (d <= 1.0))[::25]:
                assert np.any(d[(t >= t[i]) & (t <= t[i] + 2.0 - 1e-9)] > 1.0)
        else:
            assert row["d_max_m"] <= 1.0 or np.all(d[(t >= row["touch_s"]) & (t <= row["touch_s"] + 2.0 - 1e-9)] <= 1.0)
    assert seen_swing


def test_join_split_counts_the_first_seconds_apart_in_quadrature():
    # 10 s at 50 Hz from t = 3 s: 1 m for the first 4 s (200 samples), 0.1 m after (300).
    t = 3.0 + np.arange(500) * 0.02
    d = np.where(t < 7.0, 1.0, -0.1)
    join, after = join_split(t, d, 4.0)
    assert join == pytest.approx(math.sqrt(200 * 1.0 / 500))
    assert after == pytest.approx(math.sqrt(300 * 0.01 / 500))
    assert join ** 2 + after ** 2 == pytest.approx(float(np.mean(d ** 2)))
    assert all(math.isnan(v) for v in join_split(np.zeros(0), np.zeros(0)))


def test_bench_rows_split_their_error_at_the_join():
    # The far start's predictive flight: its window's d_rms is the join's and the rest's in
    # quadrature, the join counted over the JOIN_S seconds after the first touch of the band.
    task = Task(named_spec("far_start"), ModelSpec("lag"), "predictive", 0.03)
    row = run_one(task)
    path, res = fly_task(task)
    d = true_crosstrack_m(path, res.x_m, res.y_m)
    window = res.t_s >= row["touch_s"] - 1e-9
    join = window & (res.t_s < row["touch_s"] + JOIN_S)
    assert row["d_rms_join_m"] == pytest.approx(math.sqrt(np.sum(d[join] ** 2) / np.sum(window)))
    assert row["d_rms_join_m"] ** 2 + row["d_rms_after_join_m"] ** 2 == pytest.approx(row["d_rms_m"] ** 2)


def test_a_point_below_the_front_says_whether_predictive_lost_it_in_the_join():
    def rows(pred_parts, base_parts):
        out = []
        for law, setting, a, (j, r) in (("predictive", 0.03, 1.0, pred_parts), ("npfg", 6.0, 1.0, base_parts)):
            out.append({"scenario": "s", "model": "lag", "law": law, "setting": setting, "a_rms_m_s2": a,
                        "d_rms_m": math.hypot(j, r), "d_rms_join_m": j, "d_rms_after_join_m": r})
        return out

    # predictive 0.30 m in the join, 0.01 after; npfg 0.10 and 0.05: lost in the join.
    (s,) = summarise(rows((0.30, 0.01), (0.10, 0.05)), default_lambda=0.03)
    assert [b["lost_in"] for b in s["predictive_beaten_at"]] == ["join"]
    # predictive 0.05 in the join, 0.30 after; npfg 0.10 and 0.10: lost after it.
    (s,) = summarise(rows((0.05, 0.30), (0.10, 0.10)), default_lambda=0.03)
    assert [b["lost_in"] for b in s["predictive_beaten_at"]] == ["after"]
    # rows without the split (an older campaign file): not said.
    old = [{k: v for k, v in r.items() if "join" not in k} for r in rows((0.30, 0.01), (0.10, 0.05))]
    point = {"law": "npfg", "a_rms_m_s2": 1.0, "d_rms_m": old[1]["d_rms_m"]}
    assert where_lost(old, point) is None


def test_a_point_below_the_front_says_over_which_windows_the_two_runs_were_measured():
    # npfg joined the path at 8 s and flew to the end at 40 s (a 32 s window); predictive joined
    # at 8 s too but further along the path, and reached the end at 30 s (22 s): 31 % apart.
    def rows(pred_end_s):
        return [{"scenario": "s", "model": "lag", "law": law, "setting": setting, "knob": "k", "a_rms_m_s2": a,
                 "d_rms_m": d, "a_max_m_s2": 2.0, "d_max_m": 1.0, "reach_s": 8.0, "touch_s": 8.0, "duration_s": end}
                for law, setting, a, d, end in (("predictive", 0.03, 0.56, 0.089, pred_end_s),
                                                ("npfg", 3.0, 0.56, 0.074, 40.0))]

    (s,) = summarise(rows(30.0), default_lambda=0.03)
    (b,) = s["predictive_beaten_at"]
    assert (b["window_s"], b["predictive_window_s"]) == (32.0, 22.0)
    assert not windows_alike(b)  # |32 - 22| = 10 s >= 10 % of 32 s
    assert "1 measured over windows 10% apart or more" in render_tables(rows(30.0), [s])
    (s,) = summarise(rows(38.0), default_lambda=0.03)  # 30 s against 32 s: 6 % apart
    assert windows_alike(s["predictive_beaten_at"][0])
    assert "windows" not in render_tables(rows(38.0), [s])
    # rows without their times (an older campaign file): not said.
    old = [{k: v for k, v in r.items() if k != "duration_s"} for r in rows(30.0)]
    (s,) = summarise(old, default_lambda=0.03)
    assert "window_s" not in s["predictive_beaten_at"][0]
