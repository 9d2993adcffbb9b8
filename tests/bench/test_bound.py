"""``companion bench bound``: the CLI end to end on one law, and its bad input."""

from __future__ import annotations

import json
import math

from companion.cli.main import main


def test_bound_on_the_s_turn_puts_every_run_on_or_above_the_front(capsys):
    assert main(["bench", "bound", "--scenario", "s_turn", "--law", "pure_pursuit", "--lambda", "0.1",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["scenario"] == "s_turn" and doc["model"] == "lag"
    (b,) = doc["bound"]
    assert b["lambda_s4"] == 0.1
    # The optimum is never worse than its starts, and respects the vehicle's limit.
    assert b["cost_m2"] <= min(b["warm_costs_m2"]) + 1e-12
    assert b["a_max_m_s2"] <= 5.0 + 1e-9
    assert len(doc["rows"]) == 6
    for r in doc["rows"]:
        assert r["law"] == "pure_pursuit"
        assert r["a_max_m_s2"] <= 5.0 + 1e-9  # flown, so saturated
        # J = D + lambda A of the run is never below J* (the run is a warm start candidate)...
        assert r["d_rms_m"] ** 2 + 0.1 * r["a_rms_m_s2"] ** 2 >= b["cost_m2"] - 1e-12
        # ... so no run lies below the bound, and the gap is the percent above it.
        assert r["d_rms_m"] >= r["bound_d_rms_m"] - 1e-12
        assert math.isclose(r["gap_pct"], 100.0 * (r["d_rms_m"] / r["bound_d_rms_m"] - 1.0), rel_tol=1e-9)
    assert doc["horizon_s"] == doc["ticks"] / 50.0


def test_unknown_scenario_is_a_one_line_error(capsys):
    assert main(["bench", "bound", "--scenario", "moon"]) == 2
    err = capsys.readouterr().err
    assert "--scenario" in err and "moon" in err and len(err.strip().splitlines()) == 1


def test_negative_lambda_is_a_one_line_error(capsys):
    assert main(["bench", "bound", "--scenario", "s_turn", "--lambda", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--lambda" in err and len(err.strip().splitlines()) == 1


def test_a_random_scenario_is_bounded_and_named_by_its_seed(capsys):
    # The random scenario of a seed (bench tracking --random 1 --seed S) through the same path:
    # its own speed, lag, limit and wind; every run on or above the front.
    from companion.bench.scenarios import random_spec

    spec = random_spec(1003)
    assert main(["bench", "bound", "--random-seed", "1003", "--law", "npfg", "--quick", "--lambda", "0.3",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["scenario"] == spec.name
    assert doc["wind_enu_m_s"] == list(spec.wind_enu_m_s)
    assert len(doc["rows"]) == 2
    for r in doc["rows"]:
        assert r["a_max_m_s2"] <= spec.a_max_m_s2 + 1e-9
        assert r["d_rms_m"] >= r["bound_d_rms_m"] - 1e-12
