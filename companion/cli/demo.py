"""``companion demo``: fly ``missions/paper_far_start.yaml`` on the mock autopilot, end to end.

Starts ``sitl_mock`` as a subprocess (``python -m sitl_mock``) on a free local UDP port, flies the
mission over MAVLink faster than real time (the loop ticks on the autopilot's clock), then prints
the metrics table, the loop statistics, the tlog path and writes a PNG plot.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from companion.cli.fly import (
    add_flight_options,
    fly_keeping_error,
    health_options_from_args,
    options_from_args,
    print_flight_summary,
)
from companion.errors import CompanionError
from companion.io.mock_process import MockProcess, free_udp_port, mock_start_args

DEFAULT_MISSION = "missions/paper_far_start.yaml"


def register(subparsers) -> None:
    p = subparsers.add_parser("demo", help="fly the paper's far-start mission on the mock autopilot",
                              description="Start the mock autopilot, fly a mission end to end over UDP "
                                          "faster than real time, print metrics, write a tlog and a plot.")
    p.add_argument("--mission", default=None, help=f"mission file (default {DEFAULT_MISSION})")
    p.add_argument("--autopilot", choices=("px4", "ardupilot"), default="px4",
                   help="personality of the mock autopilot (default px4)")
    p.add_argument("--vehicle", choices=("copter", "rover", "plane"), default="copter")
    p.add_argument("--speedup", type=float, default=3.0, help="simulated time per wall second (default 3)")
    p.add_argument("--tau-vel-s", type=float, default=0.3, help="mock velocity-loop time constant (default 0.3)")
    p.add_argument("--a-max-m-s2", type=float, default=10.0, help="mock acceleration limit (default 10)")
    p.add_argument("--plot", default=None, help="PNG path (default: beside the tlog)")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG")
    p.add_argument("--seed", type=int, default=1)
    add_flight_options(p, connect_required=False, tlog_prefix="demo")
    # The demo ticks on the autopilot's clock unless told otherwise (parser defaults win).
    p.set_defaults(func=run, clock="autopilot")


def find_mission(path: str | None) -> Path:
    """The mission file: as given, else ``missions/paper_far_start.yaml`` here or in the source tree."""
    if path:
        return Path(path)
    here = Path(DEFAULT_MISSION)
    if here.exists():
        return here
    tree = Path(__file__).resolve().parents[2] / DEFAULT_MISSION
    return tree if tree.exists() else here


def mock_args(mission, args, port: int) -> list[str]:
    out = [
        "--autopilot", args.autopilot, "--vehicle", args.vehicle,
        "--link", f"udpout:127.0.0.1:{port}",
        "--speedup", f"{args.speedup:g}",
        *mock_start_args(mission, mission.altitude_m),
        "--tau-vel-s", f"{args.tau_vel_s:g}", "--a-max-m-s2", f"{args.a_max_m_s2:g}",
        "--seed", str(args.seed), "--quiet",
        # Keep the real autopilots' wall-clock margins: a pause of w wall seconds in the companion
        # is w * speedup simulated seconds to the mock (PX4 COM_OF_LOSS_T 1 s, ArduPilot 3 s).
        "--offboard-loss-s", f"{1.0 * max(1.0, args.speedup):g}",
        "--guided-timeout-s", f"{3.0 * max(1.0, args.speedup):g}",
    ]
    if args.signing_key_file:
        out += ["--signing-key-file", args.signing_key_file]
    return out


def write_plot(path: Path, mission, record, title: str) -> Path:
    """Path vs track, cross-track error and a_cmd over time, phases shaded."""
    from companion.plots import flight_figure, save_figure

    altitude = None
    if getattr(mission, "profile", None) is not None:
        altitude = (mission.profile, record.s_proj_m, record.alt_m)
    fig = flight_figure(mission.path, record.t_s, record.x_m, record.y_m, record.crosstrack_m,
                        record.a_cmd_m_s2, list(record.phase), title, altitude=altitude)
    return save_figure(fig, path)


def run(args) -> int:
    from companion.io.tlog import default_tlog_path
    from companion.loop.runner import FlightRunner, Status
    from companion.mission import load_mission

    mission = load_mission(find_mission(args.mission))
    health_options_from_args(args)  # bad thresholds: one line, exit 2, before the mock starts
    if not args.tlog:
        p = default_tlog_path()
        args.tlog = str(p.with_name(p.name.replace("flight-", "demo-")))
    if not (math.isfinite(args.speedup) and args.speedup > 0):
        raise CompanionError(f"--speedup: expected a number > 0, got {args.speedup!r}")
    port = free_udp_port()
    expected_s = mission.path.length_m / mission.speed_m_s
    max_duration = args.max_duration_s if args.max_duration_s is not None else 3.0 * expected_s + 60.0
    options = options_from_args(args, mission, connect=f"udpin:127.0.0.1:{port}", autopilot=args.autopilot,
                                max_duration_s=max_duration, heartbeat_timeout_s=20.0)
    status = Status(quiet=args.quiet)
    mock = MockProcess(mock_args(mission, args, port))
    wall0 = time.monotonic()
    mock.start()
    status.event(f"mock autopilot started ({args.autopilot} {args.vehicle}, speedup {args.speedup:g}) "
                 f"on udp port {port}")
    runner = FlightRunner(mission, options, status)
    try:
        summary, error = fly_keeping_error(runner)
    finally:
        mock.stop()
    wall_s = time.monotonic() - wall0
    plot_path = None
    plot_error: CompanionError | None = None
    if not args.no_plot and runner.record.t_s:
        plot_path = Path(args.plot) if args.plot else Path(str(runner.tlog_path) + ".png")
        title = f"{mission.name}: {args.autopilot} {args.vehicle} mock, x{args.speedup:g}"
        try:
            write_plot(plot_path, mission, runner.record, title)
        except CompanionError as err:  # a core install without matplotlib: keep the figures
            plot_error, plot_path = err, None
    summary = dict(summary)
    summary["plot"] = str(plot_path) if plot_path else None
    if plot_error is not None:
        summary["plot_error"] = str(plot_error)
    summary["wall_s"] = wall_s
    summary["speedup"] = args.speedup
    print_flight_summary(summary, args.json, error,
                         extra_lines=((f"plot: {plot_path}",) if plot_path else ()) + (f"wall time: {wall_s:.1f} s",))
    if error is not None:
        raise error
    if plot_error is not None:
        if args.plot:  # asked for by name: the command did not do what it was told
            raise plot_error
        print(f"companion: {plot_error} (or pass --no-plot)", file=sys.stderr)
    return 0
