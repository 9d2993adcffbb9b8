"""``companion log summary FLIGHT.tlog [--json]``: what a flight log contains.

Unreadable stretches of the file are reported on stderr as warnings with their byte offset;
the summary covers everything that could be read. Exit 0 on success, 2 when no MAVLink record
can be read at all.
"""

from __future__ import annotations

import json
import sys

from companion.replay.summary import GAP_THRESHOLD_S, format_summary, summarise_log


def register(subparsers) -> None:
    parser = subparsers.add_parser("log", help="inspect flight logs (tlogs)")
    log_sub = parser.add_subparsers(dest="log_command", metavar="ACTION")
    summary = log_sub.add_parser(
        "summary",
        help="duration, systems, message rates, modes and link gaps of a tlog",
        description="Summarise a tlog: duration, systems/components seen (heartbeat type and "
                    "autopilot), message counts and rates, flight modes over time and link gaps.",
    )
    summary.add_argument("tlog", help="the tlog file (companion, MAVProxy or QGroundControl)")
    summary.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    summary.add_argument("--gap-threshold", type=float, default=GAP_THRESHOLD_S, metavar="S",
                         help=f"shortest silence reported as a link gap, seconds (default {GAP_THRESHOLD_S})")
    summary.set_defaults(func=run)
    parser.set_defaults(func=lambda args: parser.print_help() or 2)


def print_warning(path, warning) -> None:
    print(f"companion: warning: {path}: {warning}", file=sys.stderr)


def run(args) -> int:
    summary = summarise_log(args.tlog, gap_threshold_s=args.gap_threshold,
                            on_warning=lambda w: print_warning(args.tlog, w))
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    return 0
