"""``companion bench tracking``: fronts of cross-track error against acceleration, per law.

A shorter look-ahead always tracks tighter and pays in acceleration, so one tuning per law proves
little. This bench sweeps each law over its main knob and compares the resulting curves of
``d_rms`` against ``a_rms`` (Pareto fronts), like a rate-distortion plot:

===============  =============================================  ============
law              source                                         knob
===============  =============================================  ============
``fixed_l1``     Park 2007 (two-phase, ``method: fixed_l1``)    L1 (m)
``corrector``    the paper (two-phase, ``method: corrector``)   L1 (m)
``ap_l1``        ArduPilot ``AP_L1_Control``                    period (s)
``npfg``         PX4 NPFG                                       period (s)
``pure_pursuit`` Coulter 1992                                   look-ahead (m)
``predictive``   ours (:mod:`companion.guidance.predictive`)    lambda (s^4)
===============  =============================================  ============

Scenarios (each a :class:`~companion.bench.scenarios.ScenarioSpec`, data a worker rebuilds): the
paper's sine from (-15, 0) at its 11 initial headings, a far start on the same sine, the
gallery's racetrack, figure-eight and lawnmower missions (each from its own far start), and a
tight S-turn; or any mission files (``--mission``: their start, speed and ``vehicle:`` block);
or seeded random scenarios (``--random N --seed S``, :mod:`companion.bench.scenarios`). Models:
``ideal`` (the paper's kinematics) and ``lag`` (the scenario's first-order inner loop, limit, dead
time and wind; for the named scenarios 0.3 s and |a| <= 5 m/s^2 as the mock copter, optional
steady wind ``--wind``).

Runs: every (scenario, model, law, setting) is one task of a campaign
(:mod:`companion.bench.campaign`) on a process pool, or on Dask with ``--dask``; ``--out FILE``
streams the rows to a file and resumes from it.

Measurement (the same for every law, from the simulated trajectory, not from what each law
reports): ``d`` is the signed distance to the closest path point. ``touch_s`` is the first time
``|d| <= REACH_TOL_M``; ``d_rms_m``, ``d_max_m``, ``a_rms_m_s2`` and ``a_max_m_s2``
(:func:`companion.sim.metrics.tracking_metrics`) cover the flight from that moment on, so an
overshoot after touching the path is charged to the tracking. ``reach_s`` is the first time from
which ``|d|`` stays within ``REACH_TOL_M`` for ``REACH_HOLD_S`` (or to the end of the flight): a
flight that crosses the path at an angle and swings out beyond it has touched it, not reached it.
A far start's approach is judged by ``reach_s`` and the tracking by the rest. Open paths end for
every law when the closest point is ``END_MARGIN_M`` from the path end (or when the law
finishes); closed paths are flown for the approach plus one lap.

Summary: per scenario and model, at the ``a_rms`` of the predictive law's default tuning, each
law's front is interpolated and the law with the lowest ``d_rms`` named, with its margin.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path as FilePath
from typing import Callable

import numpy as np

from companion.bench.campaign import RowFile, dask_executor, finite_json, pool_executor, run_campaign
from companion.bench.scenarios import (BENCH_A_MAX_M_S2, BENCH_LAG_S, BENCH_SPEED_M_S, ScenarioSpec, build_path,
                                       function_mission_text, random_specs, spec_from_mission, spec_id)
from companion.errors import CompanionError, MissionError

REACH_TOL_M = 1.0
REACH_HOLD_S = 2.0
#: The join: the first seconds of the measured window (from the first touch of the band), where
#: ``d_rms_join_m`` is counted; ``d_rms_after_join_m`` counts the rest (:func:`join_split`).
JOIN_S = 4.0
#: Bumped when what a row measures changes (2: ``reach_s`` entered to stay, ``touch_s``).
MEASUREMENT_VERSION = 2
END_MARGIN_M = 20.0
SPEED_M_S = BENCH_SPEED_M_S  # the named scenarios' speed
RATE_HZ = 50.0
LAG_TAU_S = BENCH_LAG_S  # the bench's lag model (a scenario without a vehicle: block)
LAG_A_MAX_M_S2 = BENCH_A_MAX_M_S2
SINE_X_END_M = 150.0  # the paper sine from x = -15 m to here (248 m of path)
PAPER_HEADINGS_DEG = tuple(-20.882 + 15.0 * k for k in range(11))
MISSIONS_DIR = FilePath(__file__).resolve().parents[2] / "missions"

LAW_ORDER = ("fixed_l1", "corrector", "ap_l1", "npfg", "pure_pursuit", "predictive")
KNOBS = {
    "fixed_l1": "l1_m", "corrector": "l1_m", "ap_l1": "period_s", "npfg": "period_s",
    "pure_pursuit": "lookahead_m", "predictive": "lambda_s4",
}
FULL_SETTINGS = {
    "fixed_l1": (4.0, 5.0, 7.0, 10.0, 14.0, 20.0),
    "corrector": (4.0, 5.0, 7.0, 10.0, 14.0, 20.0),
    "ap_l1": (3.0, 4.0, 6.0, 8.0, 12.0, 17.0),
    "npfg": (2.0, 3.0, 4.0, 6.0, 8.0, 10.0),
    "pure_pursuit": (3.0, 4.0, 5.0, 7.0, 10.0, 14.0),
    "predictive": (0.003, 0.01, 0.03, 0.1, 0.3, 1.0),
}
QUICK_SETTINGS = {
    "fixed_l1": (5.0, 10.0),
    "corrector": (5.0, 10.0),
    "ap_l1": (4.0, 8.0),
    "npfg": (3.0, 6.0),
    "pure_pursuit": (4.0, 7.0),
    "predictive": (0.03, 0.3),
}
#: The predictive law's default lambda: the summary compares the laws at its a_rms.
DEFAULT_LAMBDA_S4 = 0.03
QUICK_SCENARIOS = ("s_turn", "paper_sine_h05")


# ----------------------------------------------------------------------------- scenarios
PAPER_SINE_TEXT = function_mission_text("paper_sine", "10.0*sin(0.078*x) + 20.0*cos(0.082*x)", (-15.0, SINE_X_END_M))
# One full period of y = 12 sin(0.12 x): two opposite bends of 5.8 m minimum radius
# (V^2 / R = 4.3 m/s^2 at 5 m/s, within the 5 m/s^2 limit of the lag model).
S_TURN_TEXT = function_mission_text("s_turn", "12.0*sin(0.12*x)", (0.0, 2.0 * math.pi / 0.12 + 25.0))
GALLERY_FILES = {"racetrack": "racetrack.yaml", "figure_eight": "figure_eight.yaml",
                 "lawnmower": "survey_lawnmower.yaml"}


def scenario_names() -> list[str]:
    names = [f"paper_sine_h{k + 1:02d}" for k in range(len(PAPER_HEADINGS_DEG))]
    return names + ["far_start", "racetrack", "figure_eight", "lawnmower", "s_turn"]


def named_spec(name: str) -> ScenarioSpec | None:
    """The bench scenario of that name (None if its mission file is missing)."""
    if name.startswith("paper_sine_h") and name in scenario_names():
        k = int(name[len("paper_sine_h"):]) - 1
        return ScenarioSpec(name, PAPER_SINE_TEXT, -15.0, 0.0, math.radians(PAPER_HEADINGS_DEG[k]))
    if name == "far_start":
        return ScenarioSpec(name, PAPER_SINE_TEXT, -70.0, -50.0, math.radians(90.0))
    if name == "s_turn":
        return ScenarioSpec(name, S_TURN_TEXT, -5.0, -2.0, 0.3)
    if name in GALLERY_FILES:
        file = MISSIONS_DIR / GALLERY_FILES[name]
        if not file.exists():
            return None
        from companion.mission import load_mission

        return replace(spec_from_mission(load_mission(str(file)), name), category="bench")
    raise CompanionError(f"bench tracking: unknown scenario {name!r}; expected one of {', '.join(scenario_names())}")


def mission_specs(files: list[str]) -> list[ScenarioSpec]:
    """One scenario per mission file (named by the file as given); a bad file is one line."""
    from companion.mission import load_mission

    specs = []
    for file in files:
        try:
            mission = load_mission(file)
        except MissionError as err:
            problems = err.problems
            more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
            raise CompanionError(f"bench tracking: --mission: {problems[0]}{more}") from None
        specs.append(spec_from_mission(mission, str(file)))
    return specs


# ----------------------------------------------------------------------------- laws
@dataclass(frozen=True)
class ModelSpec:
    name: str  # "ideal" (the paper's kinematics) or "lag" (the scenario's lag model and wind)

    def sim_model(self, sc: ScenarioSpec):
        from companion.sim.simulator import LagModel

        if self.name == "ideal":
            return None
        return LagModel(tau_s=sc.lag_s, a_max_m_s2=sc.a_max_m_s2, wind_enu_m_s=sc.wind_enu_m_s, delay_s=sc.delay_s)


MODELS = (ModelSpec("ideal"), ModelSpec("lag"))


@dataclass(frozen=True)
class Task:
    """One run of the bench: a law at one setting, on one scenario, in one model."""

    spec: ScenarioSpec
    model: ModelSpec
    law: str
    setting: float


def task_id(task: Task) -> str:
    """Stable id of a run: the scenario's whole description, the model, the law and the setting,
    and the version of the measurement (a row measured otherwise is not resumed as this one)."""
    import hashlib

    text = json.dumps([spec_id(task.spec), task.model.name, task.law, task.setting, MEASUREMENT_VERSION])
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:20]


class _CommonEnd:
    """Ends every law at the same place on an open path: closest point END_MARGIN_M from the end."""

    def __init__(self, law, path):
        self.law = law
        self._end_s = path.length_m - END_MARGIN_M if not path.closed else math.inf

    def step(self, t_s, state):
        out = self.law.step(t_s, state)
        if out.phase != "finished" and out.phase != "midcourse" and out.s_proj_m >= self._end_s:
            from dataclasses import replace

            return replace(out, phase="finished")
        return out


def make_law(law: str, setting: float, sc: ScenarioSpec, model: ModelSpec):
    """A fresh guidance object for one run."""
    path = build_path(sc)
    wx, wy = sc.wind_enu_m_s if model.name == "lag" else (0.0, 0.0)
    if law in ("fixed_l1", "corrector"):
        from companion.guidance.two_phase import TwoPhaseGuidance
        from companion.guidance.types import GuidanceParams

        params = GuidanceParams(method=law, l1_m=setting, speed_m_s=sc.speed_m_s, rate_hz=RATE_HZ,
                                circle_radius_m=sc.circle_radius_m)
        return TwoPhaseGuidance(path, params)
    if law == "ap_l1":
        from companion.guidance.baselines import ApL1Guidance, ApL1Params

        return ApL1Guidance(path, ApL1Params(period_s=setting))
    if law == "npfg":
        from companion.guidance.baselines import NpfgGuidance, NpfgParams

        return NpfgGuidance(path, NpfgParams(period_s=setting, wind_x_m_s=wx, wind_y_m_s=wy))
    if law == "pure_pursuit":
        from companion.guidance.baselines import PurePursuitGuidance, PurePursuitParams

        return PurePursuitGuidance(path, PurePursuitParams(lookahead_m=setting))
    if law == "predictive":
        from companion.guidance.predictive import PredictiveGuidance, PredictiveParams

        if model.name == "ideal":
            params = PredictiveParams(lambda_s4=setting)
        else:
            # The rollouts' single lag stands for lag plus dead time (VehicleModel.rollout_tau_s).
            params = PredictiveParams(lambda_s4=setting, lag_s=sc.lag_s + sc.delay_s, a_max_m_s2=sc.a_max_m_s2,
                                      wind_x_m_s=wx, wind_y_m_s=wy)
        return PredictiveGuidance(path, params)
    raise CompanionError(f"bench tracking: unknown law {law!r}; expected one of {', '.join(LAW_ORDER)}")


# ----------------------------------------------------------------------------- one run
def true_crosstrack_m(path, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
    """Signed distance to the closest path point along a trajectory (projection kept continuous,
    the first one along the first step):
    :func:`companion.sim.optimal.crosstrack_sequential_m`, the one measurement the bound uses too."""
    from companion.sim.optimal import crosstrack_sequential_m

    return crosstrack_sequential_m(path, x_m, y_m)[0]


def fly_task(task: Task):
    """Fly one run as the bench flies it: the path and the simulated flight (``SimResult``).

    Every law ends at the same place (:class:`_CommonEnd`); a closed path is flown for the approach
    plus one lap. ``companion bench bound`` flies its runs through here too.
    """
    from companion.guidance.types import GuidanceParams, VehicleState
    from companion.sim.simulator import simulate

    sc = task.spec
    path = build_path(sc)
    start = VehicleState(sc.x_m, sc.y_m, sc.heading_rad, sc.speed_m_s)
    if path.closed:
        sx, sy = path.start_xy_m
        t_max = (math.hypot(sc.x_m - sx, sc.y_m - sy) + path.length_m) / sc.speed_m_s + 10.0
    else:
        t_max = None
    guidance = _CommonEnd(make_law(task.law, task.setting, sc, task.model), path)
    return path, simulate(path, guidance, start, GuidanceParams(speed_m_s=sc.speed_m_s, rate_hz=RATE_HZ),
                          model=task.model.sim_model(sc), t_max_s=t_max)


def first_stay_index(inside: np.ndarray, n_hold: int) -> int | None:
    """The first sample from which ``inside`` holds for ``n_hold`` samples, or to the end; None if never.

    >>> first_stay_index(np.array([0, 1, 1, 0, 1, 1, 1, 1], bool), 3)
    4
    >>> first_stay_index(np.array([0, 1, 0, 0, 1, 1], bool), 3)  # the last run lasts to the end
    4
    >>> first_stay_index(np.array([0, 0], bool), 1) is None
    True
    """
    edges = np.flatnonzero(np.diff(np.concatenate(([0], inside.astype(np.int8), [0]))))
    for start, stop in zip(edges[::2], edges[1::2]):  # runs of True: [start, stop)
        if stop - start >= n_hold or stop == inside.size:
            return int(start)
    return None


def join_split(t_s: np.ndarray, d_m: np.ndarray, join_s: float = JOIN_S) -> tuple[float, float]:
    """A window's d_rms split at ``join_s`` after its first sample, in quadrature: ``(join,
    after)``, each the root of its samples' sum of squares over the whole window's count, so
    that ``join^2 + after^2 = d_rms^2``. It says which part of a window's error is the join.

    >>> join_split(np.array([0.0, 1.0, 2.0, 3.0]), np.array([2.0, 2.0, 1.0, -1.0]), 2.0)
    (1.4142135623730951, 0.7071067811865476)
    """
    t, d = np.asarray(t_s, dtype=float), np.asarray(d_m, dtype=float)
    if d.size == 0:
        return math.nan, math.nan
    join = t < t[0] + join_s
    return (math.sqrt(float(np.sum(d[join] ** 2)) / d.size),
            math.sqrt(float(np.sum(d[~join] ** 2)) / d.size))


def run_one(task: Task) -> dict:
    """Simulate one (scenario, model, law, setting) and measure it; returns one row."""
    from companion.sim.metrics import tracking_metrics

    model, law, setting = task.model, task.law, task.setting
    scenario_name = task.spec.name
    t0 = time.perf_counter()
    path, res = fly_task(task)
    wall = time.perf_counter() - t0
    d = true_crosstrack_m(path, res.x_m, res.y_m)
    inside = np.abs(d) <= REACH_TOL_M
    touched = np.flatnonzero(inside)
    row = {"scenario": scenario_name, "model": model.name, "law": law, "setting": setting,
           "knob": KNOBS[law]}
    if touched.size == 0:
        row.update(d_rms_m=math.nan, d_max_m=math.nan, a_rms_m_s2=math.nan, a_max_m_s2=math.nan,
                   reach_s=math.nan, touch_s=math.nan, d_rms_join_m=math.nan, d_rms_after_join_m=math.nan)
    else:
        i0 = int(touched[0])
        m = tracking_metrics(res.t_s[i0:], d[i0:], res.a_achieved_m_s2[i0:])  # what the vehicle flew
        stay = first_stay_index(inside, int(round(REACH_HOLD_S * RATE_HZ)))
        join, after = join_split(res.t_s[i0:], d[i0:])
        row.update(d_rms_m=m["d_rms_m"], d_max_m=m["d_max_m"], a_rms_m_s2=m["a_rms_m_s2"],
                   a_max_m_s2=m["a_max_m_s2"], touch_s=float(res.t_s[i0]),
                   reach_s=float(res.t_s[stay]) if stay is not None else math.nan,
                   d_rms_join_m=join, d_rms_after_join_m=after)
    row["duration_s"] = float(res.t_s[-1]) if res.t_s.size else 0.0
    row["wall_s"] = wall
    return row


# ----------------------------------------------------------------------------- fronts
def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Non-dominated (a_rms, d_rms) points, sorted by a_rms (both to be minimised).

    A point is dominated when another has a_rms <= and d_rms <= with one strictly lower.
    """
    pts = sorted({(a, d) for a, d in points if math.isfinite(a) and math.isfinite(d)})
    front: list[tuple[float, float]] = []
    best_d = math.inf
    for a, d in pts:
        if d < best_d:
            front.append((a, d))
            best_d = d
    return front


def front_at(front: list[tuple[float, float]], a_rms: float) -> float | None:
    """d_rms of a front at a given a_rms: the best d of the points with a_rms <= the given one,
    linearly interpolated between neighbours; None below the front's smallest a_rms.

    (A law can always be detuned, so above its largest a_rms the front keeps its last value.)
    """
    if not front or a_rms < front[0][0]:
        return None
    for (a0, d0), (a1, d1) in zip(front, front[1:]):
        if a0 <= a_rms <= a1:
            return d0 + (d1 - d0) * (a_rms - a0) / (a1 - a0) if a1 > a0 else min(d0, d1)
    return front[-1][1]


def fronts_by_group(rows: list[dict]) -> dict:
    """``{(scenario, model): {law: front}}``."""
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["model"]), {}).setdefault(r["law"], []).append(
            (r["a_rms_m_s2"], r["d_rms_m"]))
    return {k: {law: pareto_front(p) for law, p in v.items()} for k, v in groups.items()}


def points_below_predictive(fronts: dict) -> list[dict]:
    """The other laws' front points that lie below the predictive front (``{law: front}``)."""
    pred_front = fronts.get("predictive", [])
    beaten = []
    for law, front in fronts.items():
        if law == "predictive":
            continue
        for a, d in front:
            dp = front_at(pred_front, a)
            if dp is not None and d < dp - 1e-9:
                beaten.append({"law": law, "a_rms_m_s2": a, "d_rms_m": d, "predictive_d_rms_m": dp})
    return beaten


def _compared_runs(rows: list[dict], point: dict) -> tuple[dict, dict] | None:
    """The run behind a baseline point below predictive's front (one of
    :func:`points_below_predictive`'s, ``rows`` its scenario's and model's) and ``predictive``'s
    run nearest the point's a_rms; None when either is missing."""
    base = [r for r in rows if r["law"] == point["law"] and r["a_rms_m_s2"] == point["a_rms_m_s2"]
            and r["d_rms_m"] == point["d_rms_m"]]
    pred = [r for r in rows if r["law"] == "predictive" and math.isfinite(r["a_rms_m_s2"])]
    if not base or not pred:
        return None
    return base[0], min(pred, key=lambda r: abs(r["a_rms_m_s2"] - point["a_rms_m_s2"]))


def where_lost(rows: list[dict], point: dict) -> str | None:
    """Where predictive loses to a baseline point below its front (:func:`_compared_runs`):
    ``"join"`` when most of the difference in the squared error, between predictive's run nearest
    the point's a_rms and the point's own run, lies in the join (:func:`join_split`), else
    ``"after"``; None without the split (rows from an older file)."""
    runs = _compared_runs(rows, point)
    if runs is None:
        return None
    parts = [(r.get("d_rms_join_m", math.nan), r.get("d_rms_after_join_m", math.nan)) for r in (runs[1], runs[0])]
    if not all(math.isfinite(v) for pair in parts for v in pair):
        return None
    (pj, pa), (bj, ba) = parts
    return "join" if pj * pj - bj * bj >= pa * pa - ba * ba else "after"


def measured_windows(rows: list[dict], point: dict) -> dict | None:
    """How long each of the two compared runs (:func:`_compared_runs`) was measured: from its
    first touch of the band to the common end (``window_s`` the point's run,
    ``predictive_window_s`` predictive's). A run's figures are RMS over its own window, so two
    laws that join the path at different places are averaged over different stretches of it (a
    fixed cost such as the join weighs less in the longer one). None when a run or its times are
    missing (rows from an older file)."""
    runs = _compared_runs(rows, point)
    if runs is None:
        return None
    base, pred = (r.get("duration_s", math.nan) - r.get("touch_s", math.nan) for r in runs)
    if not (math.isfinite(base) and math.isfinite(pred)):
        return None
    return {"window_s": base, "predictive_window_s": pred}


#: Two compared runs' windows (:func:`measured_windows`) this far apart, relative to the longer,
#: average over visibly different stretches of the path.
WINDOW_APART = 0.1


def windows_alike(point: dict) -> bool:
    """Whether a point below the front and predictive's run were measured over windows less than
    :data:`WINDOW_APART` apart (relative to the longer one)."""
    w, wp = point["window_s"], point["predictive_window_s"]
    return abs(w - wp) < WINDOW_APART * max(w, wp)


def summarise(rows: list[dict], default_lambda: float = DEFAULT_LAMBDA_S4) -> list[dict]:
    """Per scenario and model: which law tracks best at the a_rms of our default tuning.

    Also counts the other laws' front points that lie below the predictive front (``beaten_at``:
    points where a baseline has lower d_rms than predictive at equal a_rms).
    """
    out = []
    fronts = fronts_by_group(rows)
    by_group: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        by_group.setdefault((r["scenario"], r["model"]), []).append(r)
    for (scenario, model), laws in fronts.items():
        group = by_group[(scenario, model)]
        ref = [r for r in group if r["law"] == "predictive" and r["setting"] == default_lambda]
        entry = {"scenario": scenario, "model": model}
        if not ref or not math.isfinite(ref[0]["a_rms_m_s2"]):
            entry.update(a_rms_ref_m_s2=None, best_law=None, d_rms_by_law={})
            out.append(entry)
            continue
        a_ref = ref[0]["a_rms_m_s2"]
        at = {law: front_at(front, a_ref) for law, front in laws.items()}
        valid = {law: d for law, d in at.items() if d is not None}
        ranked = sorted(valid.items(), key=lambda kv: kv[1])
        best_law, best_d = ranked[0] if ranked else (None, None)
        runner = ranked[1] if len(ranked) > 1 else (None, None)
        beaten = points_below_predictive(laws)
        for point in beaten:
            point["lost_in"] = where_lost(group, point)
            point.update(measured_windows(group, point) or {})
        entry.update(
            a_rms_ref_m_s2=a_ref, best_law=best_law, best_d_rms_m=best_d,
            runner_up=runner[0], runner_up_d_rms_m=runner[1],
            margin_m=(runner[1] - best_d) if runner[0] else None,
            d_rms_by_law={law: valid.get(law) for law in LAW_ORDER if law in laws},
            predictive_beaten_at=beaten,
        )
        out.append(entry)
    return out


#: The smallest lambda (s^4) a refinement tries below the sweep's (``--refine``).
REFINE_LAMBDA_FLOOR_S4 = 1e-4


def refinement_settings(rows: list[dict]) -> dict[tuple[str, str], list[float]]:
    """The predictive settings to fly next so that its front is known at the a_rms of every
    baseline point that lies below it (``--refine``): ``{(scenario, model): [lambda, ...]}``.

    A front sampled at a few settings is drawn as straight lines between them; where it is curved
    a line lies above it, and a baseline point there can be "below the front" only because the
    front was not sampled there. For every such point, the lambda that should fly its a_rms is
    interpolated between the two predictive runs whose a_rms bracket it (linearly in log lambda,
    kept within the middle half of the bracket so that repeated rounds close in as a bisection
    does); above the a_rms of predictive's smallest lambda, a third of it (not below
    :data:`REFINE_LAMBDA_FLOOR_S4`). Settings already flown are not returned. Baseline points are
    taken as flown: they are what is compared.
    """
    out: dict[tuple[str, str], list[float]] = {}
    for key, fronts in fronts_by_group(rows).items():
        beaten = points_below_predictive(fronts)
        if not beaten:
            continue
        runs = sorted((r["setting"], r["a_rms_m_s2"]) for r in rows
                      if (r["scenario"], r["model"]) == key and r["law"] == "predictive"
                      and math.isfinite(r["a_rms_m_s2"]) and math.isfinite(r["d_rms_m"]))
        if not runs:
            continue
        flown = {f"{lam:.4g}" for lam, _ in runs}
        wanted: list[float] = []
        for point in beaten:
            a_b = point["a_rms_m_s2"]
            lam = None
            if a_b >= max(a for _, a in runs):
                lam = runs[0][0] / 3.0 if runs[0][0] / 3.0 >= REFINE_LAMBDA_FLOOR_S4 else None
            else:
                for (l0, a0), (l1, a1) in zip(runs, runs[1:]):  # lambda increasing
                    if min(a0, a1) <= a_b <= max(a0, a1) and a0 != a1:
                        f = min(max((a_b - a0) / (a1 - a0), 0.25), 0.75)
                        lam = math.exp(math.log(l0) + f * (math.log(l1) - math.log(l0)))
                        break
            if lam is not None and f"{lam:.4g}" not in flown:
                flown.add(f"{lam:.4g}")
                wanted.append(float(f"{lam:.4g}"))
        if wanted:
            out[key] = sorted(wanted)
    return out


# ----------------------------------------------------------------------------- output
def _fmt(v, nd=3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{nd}f}"


def render_tables(rows: list[dict], summary: list[dict]) -> str:
    lines = []
    by_group: dict = {}
    for r in rows:
        by_group.setdefault((r["scenario"], r["model"]), []).append(r)
    fronts = fronts_by_group(rows)
    for (scenario, model), group in by_group.items():
        lines.append(f"## {scenario} / {model}")
        lines.append(f"{'law':13s} {'knob':12s} {'setting':>8s} {'d_rms_m':>8s} {'d_max_m':>8s} "
                     f"{'a_rms':>7s} {'a_max':>7s} {'reach_s':>8s} front")
        for r in sorted(group, key=lambda r: (LAW_ORDER.index(r["law"]), r["setting"])):
            on_front = (r["a_rms_m_s2"], r["d_rms_m"]) in fronts[(scenario, model)].get(r["law"], [])
            lines.append(f"{r['law']:13s} {r['knob']:12s} {r['setting']:8g} {_fmt(r['d_rms_m']):>8s} "
                         f"{_fmt(r['d_max_m'], 2):>8s} {_fmt(r['a_rms_m_s2']):>7s} {_fmt(r['a_max_m_s2'], 2):>7s} "
                         f"{_fmt(r['reach_s'], 1):>8s} {'*' if on_front else ''}")
        lines.append("")
    lines.append("## summary (d_rms of each front at the a_rms of predictive, lambda = "
                 f"{DEFAULT_LAMBDA_S4:g})")
    head = f"{'scenario':18s} {'model':6s} {'a_ref':>6s} " + " ".join(f"{law:>12s}" for law in LAW_ORDER)
    lines.append(head + "  best (margin)  baseline points below predictive")
    for s in summary:
        cells = " ".join(f"{_fmt(s.get('d_rms_by_law', {}).get(law)):>12s}" for law in LAW_ORDER)
        best = s.get("best_law") or "-"
        margin = s.get("margin_m")
        beaten = s.get("predictive_beaten_at", [])
        beaten_txt = ", ".join(sorted({b["law"] for b in beaten})) or "none"
        in_join = sum(b.get("lost_in") == "join" for b in beaten)
        join_txt = f" ({in_join} lost in the join)" if in_join else ""
        apart = sum(not windows_alike(b) for b in beaten if "window_s" in b)
        join_txt += f" ({apart} measured over windows {WINDOW_APART:.0%} apart or more)" if apart else ""
        lines.append(f"{s['scenario']:18s} {s['model']:6s} {_fmt(s.get('a_rms_ref_m_s2'), 2):>6s} {cells}  "
                     f"{best} ({_fmt(margin)})  {len(beaten)}: {beaten_txt}{join_txt}")
    return "\n".join(lines)


def plot_fronts(rows: list[dict], out_dir: str) -> list[str]:
    """One PNG per model: a panel per scenario with every law's points and Pareto front."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise CompanionError("bench tracking --plot: matplotlib is not installed (pip install companion[plot])") from err
    os.makedirs(out_dir, exist_ok=True)
    written = []
    fronts = fronts_by_group(rows)
    for model in sorted({r["model"] for r in rows}):
        scenarios = [s for s in dict.fromkeys(r["scenario"] for r in rows if r["model"] == model)]
        n = len(scenarios)
        cols = min(4, n)
        nrows = math.ceil(n / cols)
        fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.4 * nrows), squeeze=False)
        for ax, scenario in zip(axes.flat, scenarios):
            for law in LAW_ORDER:
                pts = [(r["a_rms_m_s2"], r["d_rms_m"]) for r in rows
                       if r["model"] == model and r["scenario"] == scenario and r["law"] == law]
                if not pts:
                    continue
                a, d = zip(*pts)
                line = ax.plot(a, d, "o", ms=3, alpha=0.5)[0]
                front = fronts[(scenario, model)].get(law, [])
                if front:
                    fa, fd = zip(*front)
                    ax.plot(fa, fd, "-", color=line.get_color(), label=law,
                            lw=2.2 if law == "predictive" else 1.2)
            ax.set_title(scenario, fontsize=9)
            ax.set_xlabel("a_rms (m/s^2)", fontsize=8)
            ax.set_ylabel("d_rms (m)", fontsize=8)
            ax.set_yscale("log")
            ax.tick_params(labelsize=7)
        for ax in list(axes.flat)[n:]:
            ax.axis("off")
        axes.flat[0].legend(fontsize=7)
        fig.suptitle(f"tracking fronts, model: {model}")
        fig.tight_layout()
        name = os.path.join(out_dir, f"tracking_fronts_{model}.png")
        fig.savefig(name, dpi=110)
        plt.close(fig)
        written.append(name)
    return written


# ----------------------------------------------------------------------------- CLI
def parse_wind(text: str | None) -> tuple[float, float]:
    if not text:
        return (0.0, 0.0)
    try:
        east, north = (float(v) for v in text.split(","))
    except ValueError:
        raise CompanionError(f"bench tracking: --wind: expected 'EAST,NORTH' in m/s, got {text!r}") from None
    if not (math.isfinite(east) and math.isfinite(north)):
        raise CompanionError(f"bench tracking: --wind: expected finite numbers, got {text!r}")
    return east, north


def settings_for(law: str, spec: ScenarioSpec, quick: bool) -> tuple[float, ...]:
    """The settings swept: distance knobs (L1, look-ahead) scale with the scenario's speed
    (``setting * V / 5 m/s``, 4 significant digits) so they span the same look-ahead times at every
    speed; periods and lambda are the same everywhere. At the bench speed nothing changes."""
    base = (QUICK_SETTINGS if quick else FULL_SETTINGS)[law]
    if KNOBS[law] in ("l1_m", "lookahead_m") and spec.speed_m_s != SPEED_M_S:
        return tuple(float(f"{v * spec.speed_m_s / SPEED_M_S:.4g}") for v in base)
    return base


def build_tasks(specs: list[ScenarioSpec], laws, quick: bool, models=MODELS) -> list[Task]:
    return [Task(spec, model, law, setting) for spec in specs for model in models for law in laws
            for setting in settings_for(law, spec, quick)]


def run_tasks(tasks: list[Task], jobs: int, progress: Callable[[int, int], None] | None = None, *,
              executor=None, out: str | None = None) -> tuple[list[dict], dict]:
    """Rows in task order and the campaign's counts; on ``jobs`` processes unless another executor
    (:mod:`companion.bench.campaign`) is given, streamed to and resumed from ``out`` if given."""
    # Longest first (the predictive law's runs) keeps every worker busy to the end.
    order = sorted(range(len(tasks)), key=lambda i: tasks[i].law != "predictive")
    return run_campaign(tasks, run_one, [task_id(t) for t in tasks], executor=executor or pool_executor(jobs),
                        out=RowFile(out) if out else None, order=order, progress=progress)


def select_specs(args) -> tuple[list[ScenarioSpec], list[str]]:
    """The scenarios of the command line, and the named ones skipped (mission file missing)."""
    if args.wind and args.random:
        raise CompanionError("bench tracking: --wind: random scenarios draw their own wind; use --wind with "
                             "--scenario or --mission")
    if args.random is not None and args.random < 1:
        raise CompanionError(f"bench tracking: --random: expected a count >= 1, got {args.random}")
    if args.seed < 0:
        raise CompanionError(f"bench tracking: --seed: expected an integer >= 0, got {args.seed}")
    default = list(QUICK_SCENARIOS) if args.quick else scenario_names()
    names = args.scenario or ([] if (args.mission or args.random) else default)
    for name in names:
        if name not in scenario_names():
            raise CompanionError(f"bench tracking: --scenario: unknown {name!r}; expected one of {', '.join(scenario_names())}")
    named = {n: named_spec(n) for n in names}
    specs = [spec for spec in named.values() if spec is not None]
    missing = [n for n, spec in named.items() if spec is None]
    specs += mission_specs(args.mission or [])
    if args.wind:
        wind = parse_wind(args.wind)
        specs = [replace(spec, wind_enu_m_s=wind) for spec in specs]
    specs += random_specs(args.random, args.seed) if args.random else []
    seen: set[str] = set()
    for spec in specs:
        if spec.name in seen:
            raise CompanionError(f"bench tracking: scenario {spec.name!r} given twice")
        seen.add(spec.name)
    return specs, missing


def choose_executor(args):
    if args.dask:
        if args.workers < 1:
            raise CompanionError(f"bench tracking: --workers: expected a count >= 1, got {args.workers}")
        return dask_executor(args.workers, args.scheduler)
    if args.scheduler:
        raise CompanionError("bench tracking: --scheduler needs --dask")
    return pool_executor(max(1, args.jobs))


class _Progress:
    """A progress bar on stderr when it is a terminal (tqdm if installed, else a counter)."""

    def __init__(self) -> None:
        self.bar = None
        self.shown = sys.stderr.isatty()

    def __call__(self, done: int, total: int) -> None:
        if not self.shown:
            return
        try:
            from tqdm import tqdm
        except ImportError:
            print(f"\r{done}/{total} runs", end="", file=sys.stderr, flush=True)
            return
        if self.bar is not None and self.bar.total != total:  # a refinement round: a bar of its own
            self.bar.close()
            self.bar = None
        if self.bar is None:
            self.bar = tqdm(total=total, initial=done, unit="run", file=sys.stderr, dynamic_ncols=True)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.shown:
            print(file=sys.stderr)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "tracking", help="fronts of cross-track error against acceleration for every law",
        description="Sweep every guidance law over its main knob on the scenario gallery (or on mission "
                    "files, or on seeded random scenarios), in the ideal and the lag model, and compare "
                    "the Pareto fronts of d_rms against a_rms. docs/benchmarks.md.")
    parser.add_argument("--json", action="store_true", help="print one JSON object {rows, summary, scenarios}")
    parser.add_argument("--plot", metavar="DIR", help="write the fronts as PNG files into DIR")
    parser.add_argument("--quick", action="store_true", help="reduced form for CI (S-turn and one paper heading, two settings per law)")
    parser.add_argument("--scenario", action="append", metavar="NAME",
                        help=f"only these scenarios (repeatable): {', '.join(scenario_names())}")
    parser.add_argument("--mission", nargs="+", metavar="FILE", help="mission files as scenarios (their start, "
                        "speed and vehicle: block; the bench's lag model without one)")
    parser.add_argument("--random", type=int, metavar="N", help="N seeded random scenarios (seeds S .. S+N-1)")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="first seed of --random (default 0)")
    parser.add_argument("--law", action="append", metavar="LAW", choices=LAW_ORDER, help="only these laws (repeatable)")
    parser.add_argument("--model", action="append", choices=[m.name for m in MODELS],
                        help="only this vehicle model (repeatable; default ideal and lag)")
    parser.add_argument("--wind", metavar="EAST,NORTH", help="steady wind of the lag model, m/s (known to npfg and predictive)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes (default 2)")
    parser.add_argument("--dask", action="store_true", help="run every run as a Dask task (needs companion[campaign])")
    parser.add_argument("--workers", type=int, default=2, metavar="N", help="--dask: local cluster workers (default 2)")
    parser.add_argument("--scheduler", metavar="tcp://HOST:8786", help="--dask: a running scheduler instead of a local cluster")
    parser.add_argument("--out", metavar="FILE.jsonl", help="stream every finished row to FILE; a rerun with the "
                        "same FILE resumes (runs already there are not run again)")
    parser.add_argument("--refine", type=int, default=0, metavar="ROUNDS",
                        help="after the sweep, up to ROUNDS rounds of predictive runs at the lambda that flies "
                             "the a_rms of each baseline point below its front (default 0: the sweep alone)")
    parser.set_defaults(func=run)


def run(args) -> int:
    if args.refine < 0:
        raise CompanionError(f"bench tracking: --refine: expected a count >= 0, got {args.refine}")
    specs, missing = select_specs(args)
    laws = args.law or list(LAW_ORDER)
    models = [m for m in MODELS if m.name in args.model] if args.model else MODELS
    tasks = build_tasks(specs, laws, args.quick, models)
    executor = choose_executor(args)
    t0 = time.perf_counter()
    progress = _Progress()
    try:
        rows, counts = run_tasks(tasks, max(1, args.jobs), progress, executor=executor, out=args.out)
        by_key = {(spec.name, model.name): (spec, model) for spec in specs for model in models}
        refined = 0
        for _ in range(args.refine):
            more = [Task(*by_key[key], "predictive", lam) for key, lams in refinement_settings(rows).items()
                    for lam in lams if key in by_key]
            if not more:
                break
            extra, more_counts = run_tasks(more, max(1, args.jobs), progress, executor=executor, out=args.out)
            rows += extra
            refined += len(extra)
            counts = {k: counts[k] + more_counts[k] for k in counts}
    finally:
        progress.close()
    wall = time.perf_counter() - t0
    if args.out or args.dask:
        where = (f"the scheduler at {args.scheduler}" if args.scheduler else f"{args.workers} local workers") \
            if args.dask else f"{max(1, args.jobs)} processes"
        rate = counts["ran"] / wall if wall > 0 else math.nan
        found = f", {counts['from_file']} already in {args.out}" if args.out else ""
        print(f"campaign: {counts['runs']} runs{found}, {counts['ran']} run in {wall:.1f} s on {where} "
              f"({rate:.2f} runs/s)", file=sys.stderr)
    summary = summarise(rows)
    if args.plot:
        for name in plot_fronts(rows, args.plot):
            print(f"wrote {name}", file=sys.stderr)
    if args.json:
        print(json.dumps(finite_json({"rows": rows, "summary": summary, "missing_scenarios": missing,
                                      "scenarios": [spec.summary() for spec in specs], "wall_s": wall,
                                      "refined_runs": refined}),
                         allow_nan=False))
    else:
        print(render_tables(rows, summary))
        if missing:
            print(f"\nskipped (mission file missing): {', '.join(missing)}")
        print(f"\n{len(rows)} runs in {wall:.1f} s")
    return 0
