"""The gallery in ``missions/``: every file loads, and each mission flies in the offline simulator
with the corrector method from its far start, reaches the path and completes it (open paths: the
guidance reports the end; closed paths: one full lap of arc length after reaching the path).

Run this file directly to print the table of ``docs/missions.md``::

    .venv/bin/python tests/mission/test_mission_gallery.py
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from companion.mission import load_mission
from companion.sim.metrics import tracking_metrics

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
GALLERY = ["racetrack.yaml", "figure_eight.yaml", "survey_lawnmower.yaml", "qgc_inspection.yaml",
           "survey_terrain_steps.yaml"]
REACHED_M = 1.0  # "on the path": cross-track error below this
STAYS_WITHIN_M = 2.0  # after reaching it, the vehicle never strays further


def fly(mission) -> dict:
    """Fly ``mission`` with the corrector from its start; figures for one run (one lap if closed)."""
    from companion.guidance.two_phase import TwoPhaseGuidance
    from companion.guidance.types import VehicleState
    from companion.sim.simulator import simulate

    params = dataclasses.replace(mission.guidance, method="corrector")
    path, start = mission.path, mission.start
    state = VehicleState(start.x_m, start.y_m, start.heading_rad, mission.speed_m_s)
    approach_m = math.hypot(start.x_m - path.start_xy_m[0], start.y_m - path.start_xy_m[1])
    # Enough time to approach (allowing a detour of 3x the distance plus turns) and fly the path.
    t_max_s = (3.0 * approach_m + 1.2 * path.length_m) / mission.speed_m_s + 60.0
    law = TwoPhaseGuidance(path, params)
    profile = mission.profile if mission.profile is not None and not mission.profile.constant_speed else None
    if profile is not None:  # fly the speed profile: every law at the local speed
        from companion.guidance.profiled import ProfiledGuidance

        law = ProfiledGuidance(law, profile)
    result = simulate(path, law, state, params, t_max_s=t_max_s, keep_outputs=True, profile=profile)
    d = np.abs(result.crosstrack_m)
    on_path = np.flatnonzero((d < REACHED_M) & (np.array(result.phase) == "close_range"))
    reached = on_path.size > 0
    end = len(result.t_s)
    completed = result.finished
    if reached and path.closed:
        # Unwrapped progress of the projection along the loop, from the tick the path is reached.
        s = np.array([o.s_proj_m for o in result.outputs[on_path[0]:]])
        step = np.diff(s)
        step = np.where(step < -0.5 * path.length_m, step + path.length_m, step)
        step = np.where(step > 0.5 * path.length_m, step - path.length_m, step)
        progress = np.concatenate(([0.0], np.cumsum(step)))
        lap = np.flatnonzero(progress >= path.length_m)
        completed = lap.size > 0
        if completed:
            end = on_path[0] + int(lap[0]) + 1
    i0 = int(on_path[0]) if reached else end
    after = d[i0:end]
    metrics = tracking_metrics(result.t_s[:end], result.crosstrack_m[:end], result.a_cmd_m_s2[:end],
                               result.phase[:end])
    close = metrics["phases"].get("close_range", {})
    return {
        "name": mission.name,
        "closed": path.closed,
        "length_m": path.length_m,
        "approach_m": approach_m,
        "reached": reached,
        "completed": bool(completed),
        "t_reach_s": float(result.t_s[i0]) if reached else math.nan,
        "max_d_after_reach_m": float(after.max()) if after.size else math.nan,
        "close_range": close,
        "metrics": metrics,
    }


@pytest.mark.parametrize("name", GALLERY)
def test_gallery_mission_loads_with_a_far_start(name):
    mission = load_mission(MISSIONS / name)
    assert mission.start is not None
    sx, sy = mission.path.start_xy_m
    assert math.hypot(mission.start.x_m - sx, mission.start.y_m - sy) > 2 * mission.guidance.circle_radius_m
    assert not mission.warnings


@pytest.mark.parametrize("name", GALLERY)
def test_gallery_mission_flies_to_the_path_and_completes_it(name):
    pytest.importorskip("companion.sim.simulator")
    figures = fly(load_mission(MISSIONS / name))
    assert figures["reached"], f"{name}: never came within {REACHED_M} m of the path"
    assert figures["completed"], f"{name}: did not complete the path (one lap if closed)"
    assert figures["max_d_after_reach_m"] < STAYS_WITHIN_M
    assert figures["close_range"]["d_rms_m"] < 0.5


def test_every_yaml_in_missions_loads():
    names = sorted(MISSIONS.glob("*.yaml"))
    assert len(names) >= 4
    for path in names:
        load_mission(path)


def table() -> str:  # pragma: no cover - documentation helper
    rows = ["| mission | path | approach | reached at | close-range d_rms / d_max | "
            "close-range a_rms / a_max | total time | completed |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name in GALLERY:
        f = fly(load_mission(MISSIONS / name))
        c = f["close_range"]
        rows.append(
            f"| `{name}` | {f['length_m']:.1f} m {'closed' if f['closed'] else 'open'} | "
            f"{f['approach_m']:.1f} m | {f['t_reach_s']:.1f} s | {c['d_rms_m']:.3f} / {c['d_max_m']:.3f} m | "
            f"{c['a_rms_m_s2']:.3f} / {c['a_max_m_s2']:.3f} m/s^2 | {f['metrics']['duration_s']:.1f} s | "
            f"{'one lap' if f['closed'] and f['completed'] else 'end reached' if f['completed'] else 'NO'} |")
    return "\n".join(rows)


if __name__ == "__main__":  # pragma: no cover
    print(table())
