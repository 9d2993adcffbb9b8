"""Bench scenarios as data, and the random scenario generator: its invariants by independent arithmetic.

The paths are rebuilt from the specs by the mission loader (as a worker does) and measured here
with plain geometry on points along them: curvature from circles through three points, distances
by brute force, self-crossings by the orientation test.
"""

from __future__ import annotations

import collections
import json
import math
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from companion.bench.scenarios import (CATEGORIES, KAPPA_FRACTION, ScenarioError, ScenarioSpec, build_path,
                                       random_spec, random_specs, scenario_mission_yaml, spec_id)
from companion.bench.tracking import PAPER_HEADINGS_DEG, ModelSpec, Task, mission_specs, named_spec, run_one
from companion.cli.main import main
from companion.geometry.paths import function_path

# Two of every category: 2 x 14 seeds from the tuning range and the test range.
SEEDS = list(range(0, 14)) + list(range(1000, 1014))


@pytest.fixture(scope="module")
def drawn():
    return {seed: (spec, build_path(spec)) for seed in SEEDS for spec in [random_spec(seed)]}


def points(path, step_m=0.5):
    s = np.arange(0.0, path.length_m, step_m)
    return path.point_array(s)


def three_point_curvature(x, y):
    """1/R of the circle through each three consecutive points."""
    ax, ay, bx, by, cx, cy = x[:-2], y[:-2], x[1:-1], y[1:-1], x[2:], y[2:]
    cross = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return 2.0 * np.abs(cross) / (np.hypot(bx - ax, by - ay) * np.hypot(cx - bx, cy - by) * np.hypot(cx - ax, cy - ay))


def distance_to(path, x, y):
    px, py = points(path, 0.25)
    i = int(np.argmin(np.hypot(px - x, py - y)))
    return float(np.hypot(px[i] - x, py[i] - y)), px[i], py[i]


def crossings(x, y, closed):
    """Pairs of non-adjacent segments that intersect properly (the orientation test)."""
    n = x.size - 1
    i, j = np.triu_indices(n, k=2)
    if closed:
        keep = ~((i == 0) & (j == n - 1))
        i, j = i[keep], j[keep]

    def orient(ax, ay, bx, by, cx, cy):
        return np.sign((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))

    p, q, r, s = (x[i], y[i]), (x[i + 1], y[i + 1]), (x[j], y[j]), (x[j + 1], y[j + 1])
    hit = (orient(*p, *q, *r) != orient(*p, *q, *s)) & (orient(*r, *s, *p) != orient(*r, *s, *q))
    return int(np.count_nonzero(hit))


def test_every_path_is_flyable_its_curvature_within_the_bound(drawn):
    for seed, (spec, path) in drawn.items():
        x, y = points(path)
        kappa = float(np.max(three_point_curvature(x, y)))
        bound = KAPPA_FRACTION * spec.a_max_m_s2 / (spec.speed_m_s + math.hypot(*spec.wind_enu_m_s)) ** 2
        # The downwind turn of the tightest bend needs kappa (V + w)^2 <= 0.7 a_max.
        assert kappa <= bound * 1.01, (seed, kappa, bound)
        assert kappa * (spec.speed_m_s + math.hypot(*spec.wind_enu_m_s)) ** 2 <= 0.71 * spec.a_max_m_s2


def test_speed_lag_and_wind_are_within_their_ranges(drawn):
    for seed, (spec, _) in drawn.items():
        assert 3.0 <= spec.speed_m_s <= 15.0
        assert 0.1 <= spec.lag_s <= 0.6
        assert spec.delay_s == 0.0 and spec.a_max_m_s2 == 5.0
        assert math.hypot(*spec.wind_enu_m_s) <= 0.4 * spec.speed_m_s + 2e-3, seed
        assert spec.seed == seed and spec.name == f"random_{seed}"
    winds = [math.hypot(*s.wind_enu_m_s) / s.speed_m_s for s, _ in drawn.values()]
    assert max(winds) > 0.25  # the range is used, not just its bottom


def test_path_kinds_are_open_or_closed_and_cross_themselves_as_named(drawn):
    for seed, (spec, path) in drawn.items():
        kind = spec.category.split("/")[0]
        assert path.closed == kind.startswith("closed"), seed
        x, y = points(path, path.length_m / 700)
        if path.closed:  # the closing segment too
            x, y = np.append(x, x[0]), np.append(y, y[0])
        n = crossings(x, y, path.closed)
        if kind.endswith("crossing"):
            assert n >= 1, seed
        else:
            assert n == 0, seed


def test_starts_are_where_their_category_says(drawn):
    for seed, (spec, path) in drawn.items():
        start = spec.category.split("/")[1]
        d, px, py = distance_to(path, spec.x_m, spec.y_m)
        if start == "on_path":
            assert d < 0.15, seed
        elif start == "far":
            assert 0.7 * 20.0 - 0.2 <= d <= 60.0, (seed, d)
        elif start == "facing_away":
            assert 0.7 * 5.0 - 0.2 <= d <= 25.0, (seed, d)
            # Moving away: the heading has a positive component along (start - closest point).
            assert math.cos(spec.heading_rad) * (spec.x_m - px) + math.sin(spec.heading_rad) * (spec.y_m - py) > 0
        else:  # at the crossing: on the path at two places far apart along it
            s = np.arange(0.0, path.length_m, 0.05)
            qx, qy = path.point_array(s)
            near = s[np.hypot(qx - spec.x_m, qy - spec.y_m) < 0.1]
            assert near.size and near.max() - near.min() > 20.0, seed


def test_every_category_comes_up_equally_often_in_both_seed_ranges(drawn):
    # Any 14 consecutive seeds draw every category once (their geometry is checked above) ...
    counts = collections.Counter(spec.category for spec, _ in drawn.values())
    assert set(counts) == {f"{p}/{s}" for p, s in CATEGORIES} and set(counts.values()) == {2}
    assert len(CATEGORIES) == 14 and sum(1 for _, s in CATEGORIES if s == "crossing") == 2
    # ... so the tuning range 0-199 and the test range 1000-1199 hold 14 or 15 of each.
    for first in (0, 1000):
        per = collections.Counter(CATEGORIES[s % len(CATEGORIES)] for s in range(first, first + 200))
        assert set(per) == set(CATEGORIES) and set(per.values()) <= {14, 15}


def test_same_seed_gives_the_same_scenario_and_ranges_can_be_split():
    assert random_spec(1003) == random_spec(1003)
    assert random_specs(3, 1002) == [random_spec(1002), random_spec(1003), random_spec(1004)]
    assert random_spec(1003) != random_spec(1004)


def test_same_seed_gives_the_same_id_in_another_process():
    code = "from companion.bench.scenarios import random_spec, spec_id; print([spec_id(random_spec(s)) for s in (0, 9, 1013)])"
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.strip() == str([spec_id(random_spec(s)) for s in (0, 9, 1013)])


def test_a_spec_round_trips_through_json_and_rebuilds_the_same_path():
    spec = random_spec(1009)
    back = ScenarioSpec.from_dict(json.loads(json.dumps(spec.to_dict())))
    assert back == spec and spec_id(back) == spec_id(spec)
    a, b = build_path(spec), build_path(back)
    assert a.length_m == b.length_m and np.array_equal(a.x_table_m, b.x_table_m)
    with pytest.raises(ScenarioError, match="unknown keys colour"):
        ScenarioSpec.from_dict({**spec.to_dict(), "colour": "red"})
    with pytest.raises(ScenarioError, match="speed_m_s: expected a number > 0"):
        ScenarioSpec.from_dict({**spec.to_dict(), "speed_m_s": 0.0})
    broken = ScenarioSpec.from_dict({**spec.to_dict(), "mission_text": '{"name": "x", "speed_m_s": 5.0}'})
    with pytest.raises(ScenarioError, match="scenario random_1009: mission_text: path: missing"):
        build_path(broken)


def test_named_scenarios_are_the_bench_paths_they_always_were():
    spec = named_spec("paper_sine_h05")
    assert (spec.x_m, spec.y_m, spec.heading_rad) == (-15.0, 0.0, math.radians(PAPER_HEADINGS_DEG[4]))
    assert (spec.speed_m_s, spec.lag_s, spec.a_max_m_s2, spec.delay_s, spec.wind_enu_m_s) == (5.0, 0.3, 5.0, 0.0, (0.0, 0.0))
    old = function_path(lambda x: 10.0 * np.sin(0.078 * x) + 20.0 * np.cos(0.082 * x), (-15.0, 150.0))
    new = build_path(spec)
    for name in ("x_table_m", "y_table_m", "tx_table", "ty_table", "k_table_1_m"):
        assert np.array_equal(getattr(old, name), getattr(new, name)), name
    race = named_spec("racetrack")
    assert (race.x_m, race.y_m, race.heading_rad) == (-60.0, -50.0, math.radians(90.0)) and build_path(race).closed


MISSION = """
name: hook
speed_m_s: 7.0
path: {type: function, y_of_x: "8*sin(0.05*x)", x_range_m: [0, 200]}
start: {x_m: -10.0, y_m: 12.0, heading_deg: 0.0}
midcourse: {circle_radius_m: 15.0}
vehicle: {a_max_m_s2: 4.0, lag_s: 0.2, accel_lag_s: 0.05, delay_s: 0.04}
"""


def test_mission_files_run_as_scenarios_with_their_start_speed_and_vehicle(tmp_path, capsys):
    file = tmp_path / "hook.yaml"
    file.write_text(MISSION)
    plain = tmp_path / "plain.yaml"
    plain.write_text(MISSION.split("vehicle:")[0])
    argv = ["bench", "tracking", "--mission", str(file), str(plain), "--quick", "--law", "ap_l1", "--json", "--jobs", "1"]
    assert main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    specs = {s["name"]: s for s in doc["scenarios"]}
    hook = specs[str(file)]
    assert (hook["x_m"], hook["y_m"], hook["heading_rad"], hook["speed_m_s"]) == (-10.0, 12.0, 0.0, 7.0)
    assert hook["lag_s"] == pytest.approx(0.25) and hook["delay_s"] == 0.04 and hook["a_max_m_s2"] == 4.0
    assert hook["circle_radius_m"] == 15.0 and hook["category"] == "mission"
    assert (specs[str(plain)]["lag_s"], specs[str(plain)]["a_max_m_s2"]) == (0.3, 5.0)  # the bench default
    rows = doc["rows"]
    assert {(r["scenario"], r["model"]) for r in rows} == {(n, m) for n in specs for m in ("ideal", "lag")}
    lag = [r for r in rows if r["scenario"] == str(file) and r["model"] == "lag"]
    assert all(r["reach_s"] is not None and r["d_rms_m"] < 2.0 for r in lag)


def test_a_bad_mission_file_is_one_line_naming_it(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nspeed_m_s: -3\npath: {type: function, y_of_x: 'sin(', x_range_m: [0, 10]}\n")
    assert main(["bench", "tracking", "--mission", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "Traceback" not in err[0]
    assert main(["bench", "tracking", "--mission", str(tmp_path / "absent.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "absent.yaml: file not found" in err[0]


def test_random_scenarios_refuse_a_wind_of_their_own_and_a_bad_count(capsys):
    assert main(["bench", "tracking", "--random", "2", "--wind", "1,0"]) == 2
    assert "draw their own wind" in capsys.readouterr().err
    assert main(["bench", "tracking", "--random", "0"]) == 2
    assert "expected a count >= 1" in capsys.readouterr().err


def test_a_random_scenario_written_as_a_mission_file_is_the_same_scenario(tmp_path, capsys):
    # One seed of each category: the written file, loaded back (with the wind of its comment), is
    # the drawn scenario; and one law's run on it is the bench's run on the drawn one.
    seeds = list(range(1000, 1014))
    assert main(["mission", "random", *map(str, seeds), "-o", str(tmp_path / "out"), "--json"]) == 0
    files = [f["file"] for f in json.loads(capsys.readouterr().out)["files"]]
    assert files == [str(tmp_path / "out" / f"random_{s}.yaml") for s in seeds]
    for seed, file in zip(seeds, files):
        drawn = random_spec(seed)
        text = open(file).read()
        east, north = drawn.wind_enu_m_s
        assert f"--wind={east:g},{north:g}" in text.splitlines()[1]
        (back,) = mission_specs([file])
        assert (back.x_m, back.y_m, back.speed_m_s, back.lag_s, back.delay_s, back.a_max_m_s2,
                back.circle_radius_m) == (drawn.x_m, drawn.y_m, drawn.speed_m_s, drawn.lag_s, drawn.delay_s,
                                          drawn.a_max_m_s2, drawn.circle_radius_m)
        assert back.heading_rad == pytest.approx(drawn.heading_rad, abs=1e-12)
        a, b = build_path(drawn), build_path(back)
        assert a.closed == b.closed and np.array_equal(a.x_table_m, b.x_table_m)
    drawn = random_spec(1001)  # open, far start
    back = replace(mission_specs([files[1]])[0], wind_enu_m_s=drawn.wind_enu_m_s)
    rows = [run_one(Task(spec, ModelSpec("lag"), "npfg", 4.0)) for spec in (drawn, back)]
    assert rows[1]["d_rms_m"] == pytest.approx(rows[0]["d_rms_m"], rel=1e-6)
    assert rows[1]["a_rms_m_s2"] == pytest.approx(rows[0]["a_rms_m_s2"], rel=1e-6)
    with pytest.raises(ScenarioError, match="racetrack: only a scenario whose path is a JSON document"):
        scenario_mission_yaml(named_spec("racetrack"))  # a gallery file: written already


def test_mission_random_keeps_existing_files_and_refuses_bad_seeds_in_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["mission", "random", "7", "-o", str(out)]) == 0
    first = capsys.readouterr().out
    assert first.startswith(f"{out / 'random_7.yaml'}: wrote ") and "--wind=" in first
    (out / "random_7.yaml").write_text("kept\n")
    assert main(["mission", "random", "8", "7", "-o", str(out)]) == 2  # nothing written: 8 neither
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "random_7.yaml: already exists" in err[0]
    assert (out / "random_7.yaml").read_text() == "kept\n" and not (out / "random_8.yaml").exists()
    assert main(["mission", "random", "8", "7", "-o", str(out), "--force"]) == 0
    assert (out / "random_7.yaml").read_text().startswith("# random_7: ")
    capsys.readouterr()
    assert main(["mission", "random", "-o", str(out), "--", "-3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "seed: expected an integer >= 0, got -3" in err[0]
    assert main(["mission", "random", "5", "6", "-o", "-"]) == 2
    assert "one seed at a time" in capsys.readouterr().err
    assert main(["mission", "random", "5", "-o", "-", "--json"]) == 2
    assert "--json: not with -o -" in capsys.readouterr().err
    assert main(["mission", "random", "5", "-o", "-"]) == 0
    assert capsys.readouterr().out.startswith("# random_5: ")
