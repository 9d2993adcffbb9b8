"""``companion sim MISSION``: fly a mission offline on the paper's kinematics and print the metrics.

    companion sim missions/paper_sine.yaml
    companion sim missions/paper_sine.yaml --method fixed_l1 --heading-deg 24.118 --json
    companion sim missions/paper_far_start.yaml --plot far.png
    companion sim missions/racetrack.yaml --method predictive

The start is the mission's ``start:`` unless ``--start X,Y`` / ``--heading-deg H`` override it;
with neither, the vehicle starts on the path start with the path's heading.
"""

from __future__ import annotations

import json
import math

from companion.cli.fly import format_metrics_table
from companion.errors import MissionError
from companion.guidance.types import METHODS, VehicleState


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sim", help="simulate a mission offline (paper kinematics) and print tracking metrics",
        description="Fly a mission offline with the unicycle model of the paper and print "
                    "d_rms_m, a_rms_m_s2, a_max_m_s2, duration_s and the per-phase figures.")
    parser.add_argument("mission", help="mission YAML file")
    parser.add_argument("--method", choices=METHODS, help="override the mission's guidance method")
    parser.add_argument("--heading-deg", type=float, help="initial heading, degrees anticlockwise from east")
    parser.add_argument("--start", type=_parse_xy, metavar="X,Y", help="initial position, local ENU metres (write --start=-15,0 when X is negative)")
    parser.add_argument("--t-max-s", type=float, help="time limit of the simulation")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", metavar="OUT.png", help="save a plot of the path, track, error and command")
    parser.set_defaults(func=run)


def _parse_xy(text: str) -> tuple[float, float]:
    import argparse

    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y in metres (e.g. -15,0), got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise argparse.ArgumentTypeError(f"expected finite X,Y, got {text!r}")
    return x, y


def run(args) -> int:
    import dataclasses

    from companion.guidance.factory import make_law
    from companion.mission import load_mission
    from companion.guidance.profiled import ProfiledGuidance
    from companion.sim.simulator import LagModel, simulate

    mission = load_mission(args.mission)
    params = mission.guidance
    if args.method:
        params = dataclasses.replace(params, method=args.method)
    path = mission.path
    if mission.start is not None:
        x0, y0, h0 = mission.start.x_m, mission.start.y_m, mission.start.heading_rad
    else:
        (x0, y0), h0 = path.start_xy_m, path.start_heading_rad
    if args.start is not None:
        x0, y0 = args.start
    if args.heading_deg is not None:
        if not math.isfinite(args.heading_deg):
            raise MissionError(f"--heading-deg: expected a finite number, got {args.heading_deg}")
        h0 = math.radians(args.heading_deg)
    if args.t_max_s is not None and not args.t_max_s > 0:
        raise MissionError(f"--t-max-s: expected a number > 0, got {args.t_max_s}")
    start = VehicleState(x0, y0, h0, mission.speed_m_s)
    law = make_law(path, params, params.rate_hz, mission.speed_m_s)
    profile = mission.profile if mission.profile is not None and not mission.profile.constant_speed else None
    flown = ProfiledGuidance(law, profile) if profile else law
    model = LagModel.from_vehicle(mission.vehicle) if mission.vehicle is not None else None
    with SimProgress(_expected_s(path, start, args.t_max_s), f"sim {mission.name}") as progress:
        result = simulate(path, _Reporting(flown, progress), start, params, model=model,
                          t_max_s=args.t_max_s, profile=profile)
    metrics = result.metrics
    summary = {
        "mission": mission.name, "method": params.method,
        "start": {"x_m": x0, "y_m": y0, "heading_deg": math.degrees(h0)},
        "finished": result.finished,
        **{k: _finite_or_none(v) for k, v in metrics.items() if k != "phases"},
        "phases": {name: {k: _finite_or_none(v) for k, v in m.items()}
                   for name, m in metrics["phases"].items()},
    }
    plan = getattr(law, "midcourse_plan", None)  # the baselines have no mid-course phase
    if plan is not None:
        summary["midcourse"] = {"case": plan.case, "rule": plan.rule, "circle": plan.chosen.circle.name,
                                "contact_xy_m": list(plan.chosen.contact_xy_m),
                                "a_cmd_m_s2": plan.chosen.a_cmd_m_s2}
    if args.json:
        print(json.dumps(summary, indent=2))
        if args.plot:
            _plot(args.plot, mission, path, result)
        return 0
    if params.method == "predictive":  # chooses its own look-ahead: show its tuning instead of L1
        tuning = (f"lambda {params.lambda_s4:g} s^4, lag {params.rollout_tau_s:g} s, "
                  f"a_max {params.a_max_m_s2:g} m/s^2")
    else:
        tuning = _baseline_tuning(params) or f"L1 {params.l1_m:g} m"
    print(f"mission {mission.name}: method {params.method}, start ({x0:.3f}, {y0:.3f}) m, "
          f"heading {math.degrees(h0):.3f} deg, V {mission.speed_m_s:g} m/s, {tuning}")
    end = "path end reached" if result.finished else "time limit reached"
    print(f"{end} after {metrics['duration_s']:.2f} s ({metrics['samples']} ticks at {params.rate_hz:g} Hz)")
    if plan is not None:
        c = plan.chosen
        print(f"mid-course: case {plan.case}, {c.circle.name} initiation circle, contact point "
              f"({c.contact_xy_m[0]:.2f}, {c.contact_xy_m[1]:.2f}) m, constant command {c.a_cmd_m_s2:.3f} m/s^2")
    print(format_metrics_table(metrics))
    if args.plot:
        _plot(args.plot, mission, path, result)
        print(f"plot written to {args.plot}")
    return 0


def _baseline_tuning(params) -> str | None:
    """What tunes a baseline law (None for the two-phase laws)."""
    if params.method in ("ap_l1", "npfg"):
        default = "17" if params.method == "ap_l1" else "10"
        return f"period {params.period_s:g} s" if params.period_s is not None else f"period {default} s (default)"
    if params.method == "pure_pursuit":
        return f"look-ahead {params.lookahead_m if params.lookahead_m is not None else 10.0:g} m"
    return None


class SimProgress:
    """Progress of a simulation in simulated seconds: a tqdm bar on stderr (the ``progress``
    extra), shown only on a terminal and only once the run has taken a second of wall time, so
    a short run and a redirected output stay clean."""

    def __init__(self, total_s: float, description: str, enabled: bool | None = None):
        from companion.replay.progress import ByteProgress

        self._bar = ByteProgress(total_s, description, enabled=enabled, unit="s")

    def update_to(self, t_s: float) -> None:
        self._bar.update_to(t_s)

    def __enter__(self) -> "SimProgress":
        return self

    def __exit__(self, *exc) -> None:
        self._bar.__exit__(*exc)


class _Reporting:
    """The guidance law, reporting each step's simulated time to a progress bar."""

    def __init__(self, law, progress: SimProgress):
        self._law = law
        self._progress = progress

    def step(self, t_s, state):
        self._progress.update_to(t_s)
        return self._law.step(t_s, state)

    def __getattr__(self, name):
        return getattr(self._law, name)


def _expected_s(path, start, t_max_s) -> float:
    """The nominal flight time (reach the path start, then fly it), capped by the time limit."""
    from companion.sim.simulator import default_t_max_s

    sx, sy = path.start_xy_m
    nominal_s = (path.length_m + math.hypot(start.x_m - sx, start.y_m - sy)) / start.speed_m_s
    limit_s = t_max_s if t_max_s is not None else default_t_max_s(path, start)
    return round(min(nominal_s, limit_s), 1)


def _finite_or_none(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _plot(out_path: str, mission, path, result) -> None:
    """Written after the figures are printed: without matplotlib (a core install) the figures
    are on stdout and one line on stderr names the ``plot`` extra (exit code 2)."""
    from companion.plots import flight_figure, save_figure

    fig = flight_figure(path, result.t_s, result.x_m, result.y_m, result.crosstrack_m,
                        result.a_cmd_m_s2, list(result.phase), f"{mission.name}: offline simulation",
                        track_label="simulated track", a_compare=("a flown", result.a_achieved_m_s2))
    save_figure(fig, out_path)
