"""``companion fly MISSION --connect LINK``: fly a mission path on a real or simulated autopilot."""

from __future__ import annotations

import json
import math
import sys

from companion.errors import CompanionError
from companion.loop.tick import DEFAULT_DRIFT_TC_S, DEFAULT_STALE_S


def add_flight_options(parser, *, connect_required: bool = True, tlog_prefix: str = "flight") -> None:
    """Options shared by ``fly`` and ``demo`` (the demo fills in the connection itself).

    ``tlog_prefix`` is the default log's file name prefix (``logs/<prefix>-<UTC time>.tlog``).
    """
    if connect_required:
        parser.add_argument("--connect", required=True, metavar="LINK",
                            help="udpin:0.0.0.0:14540 or udp:0.0.0.0:14540 (listen: PX4 SITL), tcp:127.0.0.1:5760 (ArduPilot SITL), "
                                 "udpout:HOST:PORT, or /dev/ttyACM0,921600")
        parser.add_argument("--autopilot", choices=("auto", "px4", "ardupilot"), default="auto",
                            help="expected autopilot (default: detect from its heartbeat)")
    parser.add_argument("--rate-hz", type=float, default=None,
                        help="guidance loop rate (default: the mission's guidance rate_hz, 50 unless set)")
    parser.add_argument("--stale-s", type=float, default=DEFAULT_STALE_S,
                        help="position older than this -> hold (zero velocity, zero yaw rate); "
                             f"default {DEFAULT_STALE_S:g}")
    parser.add_argument("--link-timeout-s", type=float, default=5.0,
                        help="no autopilot heartbeat for this long -> stop sending and exit (default 5: "
                             "five missed 1 Hz heartbeats, the usual MAVLink link-loss rule)")
    parser.add_argument("--clock", choices=("wall", "autopilot"), default="wall",
                        help="tick on the wall clock, or on the autopilot's time_boot_ms (simulators "
                             "running faster than real time)")
    parser.add_argument("--on-finish", choices=("hold", "loiter", "rtl", "land"), default=None,
                        help="action at the end of the path (default: the mission's on_finish)")
    parser.add_argument("--output", choices=("auto", "velocity", "attitude"), default="auto",
                        help="setpoint type: velocity + yaw rate (copter, rover) or attitude (plane)")
    parser.add_argument("--max-bank-deg", type=float, default=35.0, help="fixed-wing bank limit (default 35)")
    parser.add_argument("--drift-tc-s", type=float, default=DEFAULT_DRIFT_TC_S,
                        help="velocity output: estimate the autopilot's velocity-estimate drift (its position "
                             "leaving the integral of its velocity), low-passed over this long, and compensate "
                             f"it; 0 turns it off (default {DEFAULT_DRIFT_TC_S:g}; docs/flying.md)")
    parser.add_argument("--speed-hold-tc-s", type=float, default=0.0,
                        help="velocity output: lengthen the velocity setpoint by the integral of the ground-speed "
                             "error over this integral time (s), so that a vehicle that flies slower than asked "
                             "(PX4 SIH: 4.3 m/s for 5) flies the mission's speed; 0: off (default; docs/flying.md)")
    parser.add_argument("--tlog", default=None, help=f"flight log path (default logs/{tlog_prefix}-<UTC time>.tlog)")
    parser.add_argument("--signing-key-file", default=None,
                        help="MAVLink 2 signing key: 64 hex characters or a passphrase (SHA-256)")
    parser.add_argument("--max-duration-s", type=float, default=None, help="stop after this flight time")
    add_health_options(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON summary object on stdout")
    parser.add_argument("--quiet", action="store_true", help="no status lines")


def add_health_options(parser) -> None:
    """The flight-health failsafes' flags (companion.loop.health; 0 turns a check off)."""
    from companion.loop.health import HealthOptions

    d = HealthOptions()
    g = parser.add_argument_group("flight-health failsafes (docs/failsafes.md; 0 turns a check off)")
    g.add_argument("--no-progress-s", type=float, default=d.no_progress_s,
                   help="stop (exit 3) if the vehicle covers less than a fifth of the mission speed's "
                        f"distance in this long: not moving, on the ground (default {d.no_progress_s:g})")
    g.add_argument("--max-xtrack-m", type=float, default=d.max_xtrack_m,
                   help="hold if the distance to the path grows this much beyond its closest approach "
                        f"(default {d.max_xtrack_m:g})")
    g.add_argument("--xtrack-hold-s", type=float, default=d.xtrack_hold_s,
                   help="stop (exit 3) if still beyond --max-xtrack-m after holding this long "
                        f"(default {d.xtrack_hold_s:g})")
    g.add_argument("--clock-tolerance", type=float, default=d.clock_tolerance,
                   help="warn if the autopilot's time runs faster or slower than the loop's clock by "
                        f"more than this fraction: use --clock autopilot (default {d.clock_tolerance:g})")


def health_options_from_args(args):
    """The :class:`~companion.loop.health.HealthOptions` of the parsed flags (validated)."""
    from companion.loop.health import HealthOptions

    d = HealthOptions()
    return HealthOptions(
        no_progress_s=getattr(args, "no_progress_s", d.no_progress_s),
        max_xtrack_m=getattr(args, "max_xtrack_m", d.max_xtrack_m),
        xtrack_hold_s=getattr(args, "xtrack_hold_s", d.xtrack_hold_s),
        clock_tolerance=getattr(args, "clock_tolerance", d.clock_tolerance),
    )


def register(subparsers) -> None:
    p = subparsers.add_parser("fly", help="fly a mission on PX4/ArduPilot over MAVLink",
                              description="Fly a mission path on a real or simulated autopilot.")
    p.add_argument("mission", help="mission YAML file")
    add_flight_options(p)
    p.add_argument("--arm", action="store_true", help="arm the vehicle (retries until --arm-timeout-s)")
    p.add_argument("--arm-timeout-s", type=float, default=90.0, help="give up arming after this (default 90)")
    p.add_argument("--takeoff-alt-m", type=float, default=None,
                   help="ArduPilot NAV_TAKEOFF altitude after arming (default: the mission altitude)")
    p.add_argument("--resume", action="store_true",
                   help="after a pilot override, wait for OFFBOARD/GUIDED to be selected again and continue")
    p.add_argument("--max-start-distance-m", type=float, default=300.0,
                   help="refuse to start farther than this from the path (default 300)")
    p.add_argument("--source-system", type=int, default=1, help="the companion's system id (default 1)")
    p.add_argument("--source-component", type=int, default=191, help="the companion's component id (default 191)")
    p.add_argument("--target-system", type=int, default=None, help="pair only with this autopilot system id")
    p.add_argument("--heartbeat-timeout-s", type=float, default=15.0,
                   help="wait this long for the autopilot's first heartbeat (default 15)")
    p.add_argument("--position-timeout-s", type=float, default=90.0,
                   help="wait this long for the autopilot's position estimate, showing what it says "
                        "(GPS, EKF, its messages); a cold-started ArduCopter needs about 40 s (default 90)")
    p.add_argument("--origin-timeout-s", type=float, default=10.0,
                   help="geodetic missions: wait this long for the autopilot's GPS_GLOBAL_ORIGIN, "
                        "else refuse to fly (default 10)")
    p.set_defaults(func=run)


def options_from_args(args, mission, **overrides):
    from companion.io.link import load_signing_key
    from companion.loop.runner import FlyOptions

    key = load_signing_key(args.signing_key_file) if getattr(args, "signing_key_file", None) else None
    kw = dict(
        connect=getattr(args, "connect", None),
        autopilot=getattr(args, "autopilot", "auto"),
        rate_hz=args.rate_hz if args.rate_hz is not None else mission.guidance.rate_hz,
        stale_s=args.stale_s,
        link_timeout_s=args.link_timeout_s,
        clock=args.clock,
        on_finish=args.on_finish,
        output=args.output,
        max_bank_deg=args.max_bank_deg,
        tlog_path=args.tlog,
        signing_key=key,
        max_duration_s=args.max_duration_s,
        arm=getattr(args, "arm", False),
        arm_timeout_s=getattr(args, "arm_timeout_s", 90.0),
        takeoff_alt_m=getattr(args, "takeoff_alt_m", None),
        resume=getattr(args, "resume", False),
        max_start_distance_m=getattr(args, "max_start_distance_m", 300.0),
        source_system=getattr(args, "source_system", 1),
        source_component=getattr(args, "source_component", 191),
        target_system=getattr(args, "target_system", None),
        heartbeat_timeout_s=getattr(args, "heartbeat_timeout_s", 15.0),
        origin_timeout_s=getattr(args, "origin_timeout_s", 10.0),
        position_timeout_s=getattr(args, "position_timeout_s", 90.0),
        drift_tc_s=getattr(args, "drift_tc_s", DEFAULT_DRIFT_TC_S),
        speed_hold_tc_s=getattr(args, "speed_hold_tc_s", 0.0),
        health=health_options_from_args(args),
    )
    kw.update(overrides)
    return FlyOptions(**kw)


def json_safe(obj):
    """NaN/inf -> None so that the summary is strict JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    return obj


def format_metrics_table(summary: dict) -> str:
    """The per-phase metrics table of sim, fly and demo: ``overall``, then one row per phase."""
    from companion.sim.metrics import OVERALL_ROW

    rows = [(OVERALL_ROW, summary)] + list(summary.get("phases", {}).items())
    lines = [f"{'phase':<12} {'d_rms_m':>9} {'d_max_m':>9} {'a_rms_m_s2':>11} {'a_max_m_s2':>11} "
             f"{'duration_s':>11}"]
    for name, m in rows:
        def f(key, width, fmt="{:.3f}", m=m):
            v = m.get(key)
            return (fmt.format(v) if isinstance(v, (int, float)) and math.isfinite(v) else "n/a").rjust(width)
        lines.append(f"{name:<12} {f('d_rms_m', 9)} {f('d_max_m', 9)} {f('a_rms_m_s2', 11)} "
                     f"{f('a_max_m_s2', 11)} {f('duration_s', 11, '{:.2f}')}")
    return "\n".join(lines)


def format_loop_line(summary: dict) -> str:
    tick = summary.get("tick_ms", {}) or {}
    link = summary.get("link", {}) or {}
    rej = link.get("rejected", {}) or {}
    rej_text = ", ".join(f"{k} {v}" for k, v in rej.items() if v) or "none"
    def num(v, fmt):
        return fmt.format(v) if isinstance(v, (int, float)) and math.isfinite(v) else "n/a"
    return (f"loop: {num(summary.get('rate_hz_achieved'), '{:.1f}')} Hz achieved, tick "
            f"p50 {num(tick.get('p50'), '{:.2f}')} ms p99 {num(tick.get('p99'), '{:.2f}')} ms, "
            f"{summary.get('ticks', 0)} guidance ticks ({summary.get('hold_ticks', 0)} hold, "
            f"{summary.get('coast_ticks', 0)} coasted), "
            f"{summary.get('setpoints_sent', 0)} setpoints sent; rejected packets: {rej_text}")


def fly_keeping_error(runner) -> tuple[dict, BaseException | None]:
    """Run the flight; on a :class:`CompanionError` or Ctrl-C keep it and the summary so far (the
    runner has closed the tlog and summarised the flight: the caller prints the metrics, writes
    the plot, then lets the error, or Ctrl-C with exit 130, go on to the one place that reports it)."""
    try:
        return runner.run(), None
    except (CompanionError, KeyboardInterrupt) as err:
        return runner.summary, err


def run(args) -> int:
    from companion.loop.runner import FlightRunner, Status
    from companion.mission import load_mission

    mission = load_mission(args.mission)
    health_options_from_args(args)  # bad thresholds: one line, exit 2, before anything opens
    options = options_from_args(args, mission)
    runner = FlightRunner(mission, options, Status(quiet=args.quiet))
    summary, error = fly_keeping_error(runner)
    print_flight_summary(summary, args.json, error)
    if error is not None:
        raise error
    return 0


def print_flight_summary(summary: dict, as_json: bool, error: BaseException | None = None,
                         extra_lines: tuple[str, ...] = ()) -> None:
    """The end of a flight on stdout, also after a failure or Ctrl-C: the metrics so far."""
    if as_json:
        out = dict(summary)
        out.setdefault("plot", None)
        if isinstance(error, KeyboardInterrupt):
            out["error"] = "interrupted (Ctrl-C)"
        elif error is not None:
            out["error"] = str(error)
        print(json.dumps(json_safe(out), indent=2))
    elif summary.get("ticks"):
        print(format_metrics_table(summary))
        print(format_loop_line(summary))
        print(f"tlog: {summary.get('tlog')}")
        for line in extra_lines:
            print(line)
    sys.stdout.flush()
