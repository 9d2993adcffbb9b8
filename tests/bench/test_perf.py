"""``companion bench perf --quick``: the JSON keeps the documented shape and the figures are sane."""

from __future__ import annotations

import json
import os
import resource
import sys

import pytest

from companion.bench.perf import _check, _proc_peak_rss_mb, _stats_us
from companion.cli.main import main


def test_statistics_of_known_samples():
    s = _stats_us([1e-6 * v for v in range(1, 101)])  # 1..100 us
    assert s["median"] == 50.5 and s["n"] == 100
    assert 99.0 <= s["p99"] <= 100.0


def test_targets_pass_and_fail_on_the_right_side():
    assert _check("fixed_l1_step_us", 49.9) == "pass"
    assert _check("fixed_l1_step_us", 50.1) == "FAIL"
    assert _check("replay_msgs_per_s", 60000.0) == "pass"
    assert _check("replay_msgs_per_s", 59999.0) == "FAIL"
    assert _check("worst_tick_ms", 20.0) == "FAIL"  # a tick must end before its deadline
    assert _check("rss_mb", None) == "n/a"


def test_quick_perf_json_has_every_documented_key(capsys):
    assert main(["bench", "perf", "--quick", "--no-live", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    for law in ("fixed_l1", "corrector", "corrector_reopt"):
        step = r["guidance_step_us"][law]
        assert 0 < step["median"] <= step["p99"]
    assert 0 < r["reoptimisation_ms"]["median"] <= r["reoptimisation_ms"]["p99"]
    assert r["worst_tick_ms"] >= r["guidance_step_us"]["corrector_reopt"]["median"] / 1e3
    assert set(r["loop_latency_ms"]) == {"50hz", "200hz", "50hz_predictive"}
    assert set(r["loop_latency_ms"]["50hz"]) >= {"p50", "p99"}
    for key in ("cpu_percent_50hz", "rss_mb"):
        assert key in r
    assert r["sim_realtime_factor"] > 1.0
    assert r["paper_bench_s"] > 0
    assert r["replay_msgs_per_s"] > 0
    # predictive's mean over every tick lies between its ordinary and its re-optimising ticks
    g = r["guidance_step_us"]
    assert g["predictive"]["median"] / 1e3 < r["predictive_tick_mean_ms"] < g["predictive_reopt"]["p99"] / 1e3
    assert r["predictive_reopt_p99_ms"] == g["predictive_reopt"]["p99"] / 1e3
    assert set(r["pass"]) >= {"predictive_tick_mean_ms", "predictive_reopt_p99_ms", "loop_latency_p99_ms_50hz_predictive"}
    assert r["pass"]["loop_latency_p99_ms_50hz_predictive"] == "n/a"  # --no-live


def test_predictive_targets_are_the_documented_ones():
    assert _check("predictive_tick_mean_ms", 0.3) == "pass"
    assert _check("predictive_tick_mean_ms", 0.31) == "FAIL"
    assert _check("predictive_reopt_p99_ms", 5.01) == "FAIL"
    assert _check("loop_latency_p99_ms_50hz_predictive", 2.0) == "pass"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="VmHWM is read from Linux's /proc")
def test_peak_rss_of_a_process_since_its_exec():
    # ru_maxrss of this process (not a forked child) is its own peak: the same number.
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    assert _proc_peak_rss_mb(os.getpid()) == pytest.approx(own, rel=0.05)
    assert _proc_peak_rss_mb(2**22 + 12345) is None  # no such process
