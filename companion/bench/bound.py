"""``companion bench bound``: every law's distance to the physical limit on a bench scenario.

For one scenario of ``companion bench tracking`` and its lag model, this flies every law at its
settings (the tracking bench's laws, sweeps and end rule), solves the offline optimum
``J*(lambda)`` of :mod:`companion.sim.optimal` at a grid of ``lambda``, warm-started from the
laws' own commands (the best runs at that ``lambda``) and from the neighbouring ``lambda``'s
optimum, and reports each run's gap: percent of its ``d_rms`` above the lower-bound front at its
``a_rms``.

Horizon and windowing: the bound is over a fixed horizon from the start, so every figure here is
a *whole-flight* figure over the same horizon: the shortest of the laws' runs on the scenario
(whole ticks), each run's first ``N`` commands replayed through the same model
(:func:`companion.sim.optimal.whole_flight_metrics`), ``a`` the flown acceleration. The tracking
bench's ``d_rms_m`` / ``a_rms_m_s2`` start at the first touch of the path instead; for a start on
the path the two nearly coincide (docs/benchmarks.md, "The physical limit").
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from companion.errors import CompanionError

#: The lambda grid of the bound (s^4): the predictive law's sweep widened by a decade each way
#: (the laws' fronts reach a_rms that only those lambdas' optima cover).
DEFAULT_LAMBDAS_S4 = (0.0003, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0)
#: Warm starts per lambda: this many of the laws' runs with the lowest J(lambda) (distinct laws),
#: plus the optimum at the previous lambda.
WARM_LAWS = 2


def law_run(spec: Any, law: str, setting: float) -> Any:
    """One law's simulated run on a scenario in the lag model (its ``SimResult``), as the tracking
    bench flies it (:func:`companion.bench.tracking.fly_task`)."""
    from companion.bench.tracking import ModelSpec, Task, fly_task

    return fly_task(Task(spec, ModelSpec("lag"), law, setting))[1]


def bound_scenario(spec: Any, *, lambdas_s4: Sequence[float] = DEFAULT_LAMBDAS_S4,
                   laws: Sequence[str] | None = None, quick: bool = False,
                   progress: Any = None) -> dict[str, Any]:
    """The bound and every run's gap on one scenario (a :class:`~companion.bench.scenarios.ScenarioSpec`)
    in the lag model (its own lag, limit and wind), as one JSON-ready dict. The laws are flown at
    the tracking bench's settings for the scenario (``settings_for``; ``quick``: the short sweep)."""
    from companion.bench.scenarios import build_path
    from companion.bench.tracking import LAW_ORDER, RATE_HZ, ModelSpec, settings_for
    from companion.guidance.types import VehicleState
    from companion.sim.optimal import BoundFront, OptimalProblem, gap_pct, solve_optimal, whole_flight_metrics

    laws = list(laws or LAW_ORDER)
    runs = []
    for law in laws:
        for setting in settings_for(law, spec, quick):
            res = law_run(spec, law, setting)
            runs.append({"law": law, "setting": setting, "a_cmd": np.asarray(res.a_cmd_m_s2, dtype=float)})
            if progress:
                progress(f"flew {law} {setting:g}")
    n_ticks = min(r["a_cmd"].size for r in runs)
    start = VehicleState(spec.x_m, spec.y_m, spec.heading_rad, spec.speed_m_s)
    problem = OptimalProblem.build(build_path(spec), start, rate_hz=RATE_HZ, horizon_s=n_ticks / RATE_HZ,
                                   model=ModelSpec("lag").sim_model(spec))
    rows = []
    for r in runs:
        m = whole_flight_metrics(problem, r["a_cmd"])
        rows.append({"law": r["law"], "setting": r["setting"], **m})
    solutions, solve_s = [], []
    previous: np.ndarray | None = None
    for lam in sorted(lambdas_s4):
        order = sorted(range(len(runs)), key=lambda i: rows[i]["d_rms_m"] ** 2 + lam * rows[i]["a_rms_m_s2"] ** 2)
        starts, used = [], set()
        for i in order:
            if runs[i]["law"] in used:
                continue
            used.add(runs[i]["law"])
            starts.append(runs[i]["a_cmd"][:n_ticks])
            if len(starts) == WARM_LAWS:
                break
        if previous is not None:
            starts.append(previous)
        t0 = time.perf_counter()
        sol = solve_optimal(problem, lam, starts)
        solve_s.append(time.perf_counter() - t0)
        previous = sol.a_cmd_m_s2
        solutions.append(sol)
        if progress:
            progress(f"lambda {lam:g}: J* {sol.cost:.6g} in {solve_s[-1]:.1f} s")
    front = BoundFront.from_solutions(solutions)
    a_lo = min(s.a_rms_m_s2 for s in solutions)
    a_hi = max(s.a_rms_m_s2 for s in solutions)
    for row in rows:
        row["bound_d_rms_m"] = front.d_rms_m(row["a_rms_m_s2"])
        row["gap_pct"] = gap_pct(row["d_rms_m"], row["a_rms_m_s2"], front)
        # Between the optima's own a_rms the front is tight up to the lambda grid; outside it the
        # bound still holds but is loose (the nearest lambda's line), and the gap an upper estimate.
        row["in_range"] = a_lo <= row["a_rms_m_s2"] <= a_hi
    return {
        "scenario": spec.name, "model": "lag", "wind_enu_m_s": list(spec.wind_enu_m_s),
        "horizon_s": problem.horizon_s, "ticks": problem.n_ticks,
        "bound": [{"lambda_s4": s.lambda_s4, "cost_m2": s.cost, "d_rms_m": s.d_rms_m, "a_rms_m_s2": s.a_rms_m_s2,
                   "a_max_m_s2": float(np.max(np.abs(s.a_cmd_m_s2))), "solve_s": t,
                   "iterations": s.iterations, "evaluations": s.evaluations, "converged": s.converged,
                   "costs_by_start_m2": list(s.costs_by_start), "warm_costs_m2": list(s.warm_costs)}
                  for s, t in zip(solutions, solve_s)],
        "rows": rows,
        "median_gap_pct_by_law": {law: float(np.median([r["gap_pct"] for r in rows if r["law"] == law]))
                                  for law in laws},
        "min_gap_pct_by_law": {law: float(np.min([r["gap_pct"] for r in rows if r["law"] == law]))
                               for law in laws},
    }


def render(result: dict[str, Any]) -> str:
    lines = [f"## {result['scenario']} / {result['model']}: horizon {result['horizon_s']:.2f} s "
             f"({result['ticks']} ticks)",
             f"{'lambda_s4':>9s} {'J*_m2':>10s} {'d_rms_m':>8s} {'a_rms':>7s} {'a_max':>6s} {'solve_s':>8s} "
             "starts (J by start)"]
    for b in result["bound"]:
        starts = ", ".join(f"{c:.5g}" for c in b["costs_by_start_m2"])
        lines.append(f"{b['lambda_s4']:9g} {b['cost_m2']:10.5g} {b['d_rms_m']:8.4f} {b['a_rms_m_s2']:7.3f} "
                     f"{b['a_max_m_s2']:6.2f} {b['solve_s']:8.1f} {starts}")
    lines.append("")
    lines.append(f"{'law':13s} {'setting':>8s} {'d_rms_m':>8s} {'a_rms':>7s} {'bound_m':>8s} {'gap_%':>7s}")
    for r in result["rows"]:
        outside = "" if r.get("in_range", True) else "  (outside the optima's a_rms range: loose)"
        lines.append(f"{r['law']:13s} {r['setting']:8g} {r['d_rms_m']:8.4f} {r['a_rms_m_s2']:7.3f} "
                     f"{r['bound_d_rms_m']:8.4f} {r['gap_pct']:7.1f}{outside}")
    lines.append("")
    lines.append("median gap by law: " + ", ".join(f"{k} {v:.1f} %" for k, v in result["median_gap_pct_by_law"].items()))
    if "min_gap_pct_by_law" in result:
        lines.append("smallest gap by law: " + ", ".join(f"{k} {v:.1f} %" for k, v in result["min_gap_pct_by_law"].items()))
    return "\n".join(lines)


def register(subparsers: Any) -> None:
    from companion.bench.tracking import LAW_ORDER

    parser = subparsers.add_parser(
        "bound", help="every law's gap to the offline optimal bound on one tracking scenario",
        description="Fly every law of the tracking bench on one scenario in the lag model, solve the "
                    "offline optimum of mean(d^2 + lambda a^2) at a grid of lambda, and report each run's "
                    "percent of d_rms above the lower-bound front at its a_rms (whole-flight figures).")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--scenario", metavar="NAME", help="a named tracking-bench scenario")
    which.add_argument("--mission", metavar="FILE", help="a mission file (its start, speed and vehicle: block)")
    which.add_argument("--random-seed", type=int, metavar="S",
                       help="the random scenario of that seed (as bench tracking --random 1 --seed S)")
    parser.add_argument("--quick", action="store_true", help="the laws at the short sweep (two settings each)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--law", action="append", metavar="LAW", choices=LAW_ORDER, help="only these laws (repeatable)")
    parser.add_argument("--lambda", dest="lambdas", action="append", type=float, metavar="S4",
                        help=f"lambda grid, s^4 (repeatable; default {' '.join(f'{x:g}' for x in DEFAULT_LAMBDAS_S4)})")
    parser.add_argument("--wind", metavar="EAST,NORTH", help="steady wind of the lag model, m/s")
    parser.set_defaults(func=run)


def run(args: Any) -> int:
    from companion.bench.scenarios import random_spec
    from companion.bench.campaign import finite_json
    from companion.bench.tracking import mission_specs, named_spec, parse_wind, scenario_names

    if args.scenario is not None:
        if args.scenario not in scenario_names():
            raise CompanionError(f"bench bound: --scenario: unknown {args.scenario!r}; expected one of "
                                 f"{', '.join(scenario_names())}")
        spec = named_spec(args.scenario)
        if spec is None:
            raise CompanionError(f"bench bound: scenario {args.scenario!r}: its mission file is missing")
    elif args.mission is not None:
        spec = mission_specs([args.mission])[0]
    else:
        if args.random_seed < 0:
            raise CompanionError(f"bench bound: --random-seed: expected an integer >= 0, got {args.random_seed}")
        if args.wind:
            raise CompanionError("bench bound: --wind: a random scenario draws its own wind")
        spec = random_spec(args.random_seed)
    if args.wind:
        spec = replace(spec, wind_enu_m_s=parse_wind(args.wind))
    lambdas = args.lambdas or list(DEFAULT_LAMBDAS_S4)
    if not all(math.isfinite(x) and x >= 0 for x in lambdas):
        raise CompanionError(f"bench bound: --lambda: expected finite numbers >= 0, got {lambdas!r}")
    t0 = time.perf_counter()

    def progress(text: str) -> None:
        if not args.json and sys.stderr.isatty():
            print(text, file=sys.stderr, flush=True)

    result = bound_scenario(spec, lambdas_s4=lambdas, laws=args.law, quick=args.quick, progress=progress)
    result["wall_s"] = time.perf_counter() - t0
    if args.json:
        print(json.dumps(finite_json(result), allow_nan=False))
    else:
        print(render(result))
        print(f"\n{len(result['rows'])} runs and {len(result['bound'])} solves in {result['wall_s']:.1f} s")
    return 0
