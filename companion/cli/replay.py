"""``companion replay FLIGHT.tlog``: re-run the guidance on a logged flight, report differences.

Exit codes: 0 every compared setpoint within tolerance, 1 not, 2 a file that cannot be used
(no setpoints, no mission, unreadable). Damaged stretches of the log are warned about on stderr
with their byte offset and the replay covers what could be read.
"""

from __future__ import annotations

import json
import sys

from companion.replay.replay import Tolerance, replay_log


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "replay",
        help="re-run the guidance on a logged flight and report where it differs",
        description="Rebuild the guidance from the mission, feed it the logged LOCAL_POSITION_NED "
                    "samples at the ticks the flight used, and compare every re-computed setpoint "
                    "with the logged one. Exit 0 within tolerance, 1 not, 2 unusable file.",
    )
    parser.add_argument("tlog", help="the flight's tlog")
    parser.add_argument("--mission", metavar="M.yaml",
                        help="mission file (default: <tlog>.mission.yaml recorded beside the log)")
    parser.add_argument("--tolerance-yaw-rate", type=float, default=0.01, metavar="RAD_S",
                        help="largest accepted yaw-rate difference, rad/s (default 0.01)")
    parser.add_argument("--tolerance-vel", type=float, default=0.05, metavar="M_S",
                        help="largest accepted velocity difference (norm of vx, vy, vz), m/s (default 0.05)")
    parser.add_argument("--tolerance-attitude", type=float, default=0.01, metavar="RAD",
                        help="fixed-wing (SET_ATTITUDE_TARGET) flights: largest accepted rotation between "
                             "logged and replayed attitude, rad (default 0.01)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--plot", metavar="OUT.png",
                        help="plot path vs track, cross-track error, a_cmd logged vs replayed, phases")
    parser.add_argument("--csv", metavar="OUT.csv", help="write the per-tick comparison as CSV")
    parser.set_defaults(func=run)


def run(args) -> int:
    tolerance = _tolerance(args)
    result = replay_log(
        args.tlog, args.mission, tolerance,
        on_warning=lambda w: print(f"companion: warning: {args.tlog}: {w}", file=sys.stderr),
    )
    if args.csv:
        from companion.replay.report import write_csv

        write_csv(result, args.csv)
    if args.plot:
        from companion.replay.plot import plot_replay

        plot_replay(result, args.plot)
    events = companion_events(args.tlog)
    if args.json:
        out = result.to_json()
        out["events"] = events
        print(json.dumps(out, indent=2, allow_nan=False))
    else:
        from companion.replay.report import format_report

        print(format_report(result))
        print(format_events(events))
    return result.exit_code


def companion_events(tlog: str) -> list[dict]:
    """The companion's own events recorded in the flight's tlog (STATUSTEXT from a sender whose
    HEARTBEAT says onboard controller, component 191 by default), as ``companion log summary``
    lists them: ``time_s`` since the start of the log, ``severity``, ``text``."""
    from companion.replay.summary import summarise_log

    summary = summarise_log(tlog, progress=False)
    ours = {(s["system"], s["component"]) for s in summary["systems"] if "ONBOARD_CONTROLLER" in str(s["type"])}
    return [{"time_s": e["time_s"], "severity": str(e["severity"]).removeprefix("MAV_SEVERITY_"), "text": e["text"]}
            for e in summary["statustext"]
            if (e["system"], e["component"]) in ours or (not ours and e["component"] == 191)]


def format_events(events: list[dict]) -> str:
    """The events as text lines (time since the start of the log, severity, text)."""
    lines = ["", "companion events (time since start, severity, text):"]
    lines += [f"  {e['time_s']:8.2f} s  {e['severity']:<9} {e['text']}" for e in events] or ["  (none)"]
    return "\n".join(lines)


def _tolerance(args) -> Tolerance:
    from companion.errors import CompanionError

    try:
        return Tolerance(args.tolerance_yaw_rate, args.tolerance_vel, args.tolerance_attitude)
    except ValueError as err:
        raise CompanionError(f"--tolerance: {err}") from None

