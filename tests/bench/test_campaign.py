"""Campaigns: rows streamed to a file, resumed with no run lost or repeated, on Dask as on one core.

The counts are checked by reading the file back line by line here, independently of the code
that wrote it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from companion.bench import campaign
from companion.bench.campaign import RowFile, dask_executor, run_campaign, serial_executor
from companion.bench.tracking import build_tasks, named_spec, run_one, run_tasks, task_id
from companion.cli.main import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# 2 models x 3 laws x 2 settings = 12 short runs of the S-turn.
SMALL = ["--scenario", "s_turn", "--quick", "--law", "pure_pursuit", "--law", "ap_l1", "--law", "npfg"]


def square(task):
    return {"task": task, "value": task * task, "d_rms_m": float("nan") if task == 3 else float(task)}


def file_ids(path):
    """Task ids of the file's lines, counted here from the raw text."""
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line)["task_id"] for line in fh.read().splitlines() if line.strip()]


def without_wall(rows):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


@pytest.fixture(scope="module")
def small_tasks():
    return build_tasks([named_spec("s_turn")], ["pure_pursuit", "ap_l1", "npfg"], quick=True)


@pytest.fixture(scope="module")
def serial_rows(small_tasks):
    return [run_one(t) for t in small_tasks]


def test_an_interrupted_campaign_resumes_with_no_run_lost_or_repeated(tmp_path):
    tasks = list(range(10))
    ids = [f"t{t}" for t in tasks]
    out = tmp_path / "rows.jsonl"

    def stops_after_four(run, tasks_, order, ids_):
        for n, i in enumerate(order):
            if n == 4:
                raise KeyboardInterrupt
            yield i, run(tasks_[i])

    with pytest.raises(KeyboardInterrupt):
        run_campaign(tasks, square, ids, executor=stops_after_four, out=RowFile(str(out)))
    assert file_ids(out) == ["t0", "t1", "t2", "t3"]
    # A kill in the middle of a write leaves half a line: it is dropped and that run done again.
    with open(out, "a", encoding="utf-8") as fh:
        fh.write('{"task_id": "t4", "task": 4, "val')
    rows, counts = run_campaign(tasks, square, ids, out=RowFile(str(out)))
    assert counts == {"runs": 10, "from_file": 4, "ran": 6}
    ids_in_file = file_ids(out)
    assert sorted(ids_in_file) == sorted(ids) and len(ids_in_file) == len(set(ids_in_file)) == 10
    clean, _ = run_campaign(tasks, square, ids)
    assert [r["value"] for r in rows] == [t * t for t in tasks]
    assert json.dumps(rows[:3] + rows[4:]) == json.dumps(clean[:3] + clean[4:])
    assert rows[3]["d_rms_m"] != rows[3]["d_rms_m"]  # NaN, written as null, read back as NaN
    # A third run finds everything in the file and runs nothing.
    _, counts = run_campaign(tasks, square, ids, out=RowFile(str(out)))
    assert counts == {"runs": 10, "from_file": 10, "ran": 0} and len(file_ids(out)) == 10


def test_a_damaged_line_stops_the_campaign_and_keeps_the_file(tmp_path):
    out = tmp_path / "rows.jsonl"
    out.write_text('{"task_id": "t0", "task": 0}\nnot json\n{"task_id": "t1", "task": 1}\n')
    before = out.read_bytes()
    with pytest.raises(campaign.CampaignError, match="line 2: expected a JSON row with a task_id"):
        run_campaign([0, 1], square, ["t0", "t1"], out=RowFile(str(out)))
    assert out.read_bytes() == before


def test_a_second_campaign_on_the_same_file_is_refused(tmp_path):
    first = RowFile(str(tmp_path / "rows.jsonl"))
    first.open()
    try:
        with pytest.raises(campaign.CampaignError, match="another campaign is writing this file"):
            RowFile(str(tmp_path / "rows.jsonl")).open()
    finally:
        first.close()


def test_task_ids_are_stable_and_name_the_whole_run(small_tasks):
    ids = [task_id(t) for t in small_tasks]
    assert len(set(ids)) == len(ids) == 12
    again = build_tasks([named_spec("s_turn")], ["pure_pursuit", "ap_l1", "npfg"], quick=True)
    assert [task_id(t) for t in again] == ids


def test_a_small_campaign_on_a_local_dask_cluster_gives_the_serial_rows(small_tasks, serial_rows, tmp_path):
    out = tmp_path / "rows.jsonl"
    rows, counts = run_tasks(small_tasks, 1, executor=dask_executor(workers=2, processes=False), out=str(out))
    assert counts["ran"] == 12 and without_wall(rows) == without_wall(serial_rows)
    assert sorted(file_ids(out)) == sorted(task_id(t) for t in small_tasks)


def test_the_dask_campaign_prints_the_same_json_as_the_default_runner(tmp_path, capsys):
    assert main(["bench", "tracking", *SMALL, "--json", "--jobs", "1"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main(["bench", "tracking", *SMALL, "--json", "--dask", "--workers", "1",
                 "--out", str(tmp_path / "c.jsonl")]) == 0
    captured = capsys.readouterr()
    on_dask = json.loads(captured.out)
    assert set(on_dask) == set(plain) and on_dask["summary"] == plain["summary"]
    assert without_wall(on_dask["rows"]) == without_wall(plain["rows"])
    assert "campaign: 12 runs, 0 already in" in captured.err and "1 local workers" in captured.err


def test_killed_and_restarted_the_campaign_runs_every_run_once(tmp_path, serial_rows, small_tasks, capsys):
    out = tmp_path / "campaign.jsonl"
    cmd = [sys.executable, "-m", "companion", "bench", "tracking", *SMALL, "--dask", "--workers", "1",
           "--out", str(out), "--json"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            if out.exists() and len(out.read_bytes().splitlines()) >= 3:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the campaign ended before it could be killed"
        os.killpg(proc.pid, signal.SIGKILL)  # the client, its scheduler and its workers at once
    finally:
        proc.wait(timeout=60)
    killed_at = len(file_ids(out))
    assert 3 <= killed_at < 12
    assert main(["bench", "tracking", *SMALL, "--dask", "--workers", "1", "--out", str(out), "--json"]) == 0
    captured = capsys.readouterr()
    assert f"campaign: 12 runs, {killed_at} already in" in captured.err
    ids = file_ids(out)
    assert len(ids) == 12 and sorted(ids) == sorted(task_id(t) for t in small_tasks)
    assert without_wall(json.loads(captured.out)["rows"]) == without_wall(serial_rows)


def test_without_the_extra_dask_is_one_line_exit_2(monkeypatch, capsys):
    monkeypatch.setattr(campaign, "dask_available", lambda: False)
    assert main(["bench", "tracking", *SMALL, "--dask"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "install companion[campaign]" in err[0]


def test_the_serial_executor_runs_in_the_order_given():
    seen = []
    list(serial_executor(lambda t: seen.append(t) or {}, ["a", "b", "c"], [2, 0, 1], ["x", "y", "z"]))
    assert seen == ["c", "a", "b"]
