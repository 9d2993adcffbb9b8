"""``companion bench fronts BENCH.json ...``: ``predictive`` at the other laws' a_rms, read from flights.

    companion bench sitl missions/figure_eight.yaml --method pure_pursuit --px4 ... --json > pp.json
    companion bench sitl figure_eight_lambda1.yaml --px4 ... --json > l1.json   # lambda_s4: 1
    companion bench fronts pp.json l1.json ... [--side real|mock] [--json]

Each file is the output of ``companion bench sitl --json``: one mission flown by one law, on the
mock and on the real firmware. The flights of ``predictive`` (any ``lambda_s4``; the knob that
trades tracking for acceleration) make its front: the non-dominated (a_rms, close-range d_rms)
points (:func:`companion.bench.tracking.pareto_front`). Every other law's flight is one point,
and ``predictive``'s error at that law's a_rms is read off the front
(:func:`companion.bench.tracking.front_at`: the tightest point flown at or below that a_rms, or
the straight line between the two flown on either side of it). ``met`` is true where that
error is at most the law's; a law that flew less a_rms than any ``predictive`` flight cannot
be compared, and counts as not met. ``--a-tolerance SHARE`` reads the front at the law's a_rms
times ``1 + SHARE`` instead: flights whose a_rms differ by less than one law's spread from boot
to boot are then taken as equal.

Flights are compared only within a group: the same mission (by its name), autopilot, side (real
or mock), acceleration-target setting (``guidance.accel_feedforward``) and ``--fly-args``. The
bench records what it flew (``flown``); for a file written before it did, the mission file it
names is read again (and its fly options are unknown: give such files one configuration per
call).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from companion.bench.tracking import front_at, pareto_front
from companion.errors import CompanionError

SIDES = ("real", "mock")


def flown_config(mission_file: str, fly_args: list[str] | None, method: str | None = None) -> dict:
    """What a bench flight flew: the mission's name, its law (``method`` replacing the mission's,
    as ``bench sitl --method`` does; ``lambda_s4`` for ``predictive`` when the mission states it,
    else None: the flight's own default, :func:`companion.loop.limits.mission_for_tail`; and its
    ``course_tc_s`` when above 0, else None), its acceleration-target setting and the extra
    ``companion fly`` options (None: unknown)."""
    from companion.mission.loader import load_mission, mission_text_with_method, parse_mission

    m = load_mission(mission_file) if method is None else \
        parse_mission(mission_text_with_method(mission_file, method), str(mission_file))
    law = m.guidance.method
    return {"mission_name": m.name, "method": law,
            "lambda_s4": m.guidance.lambda_s4 if law == "predictive" and m.lambda_stated else None,
            "course_tc_s": m.guidance.course_tc_s if law == "predictive" and m.guidance.course_tc_s > 0 else None,
            "accel_feedforward": m.accel_feedforward, "fly_args": None if fly_args is None else list(fly_args)}


def _flown(result: dict, source: str) -> dict:
    """The ``flown`` record of a bench result, rebuilt from its mission file if it has none."""
    flown = result.get("flown")
    if flown is not None:
        args = flown.get("fly_args") if isinstance(flown, dict) else None
        if not (isinstance(flown, dict) and isinstance(flown.get("mission_name"), str)
                and isinstance(flown.get("method"), str) and flown.get("accel_feedforward") in (None, True, False)
                and (args is None or (isinstance(args, list) and all(isinstance(a, str) for a in args)))):
            raise CompanionError(f"{source}: 'flown': expected an object with the mission's name and the "
                                 "method, as companion bench sitl --json writes it")
        return flown
    mission = result.get("mission")
    if not isinstance(mission, str) or not Path(mission).is_file():
        raise CompanionError(f"{source}: no 'flown' record and its mission file {mission!r} is gone; "
                             "expected the output of companion bench sitl --json")
    return flown_config(mission, None, result.get("method"))


def points(results: list[tuple[str, dict]], side: str) -> list[dict]:
    """One point per (file, autopilot) flown on ``side``: its group, law and figures. Flights
    that failed or lack a figure are left out."""
    out = []
    for source, result in results:
        if not isinstance(result, dict) or not isinstance(result.get("autopilots"), dict):
            raise CompanionError(f"{source}: expected the output of companion bench sitl --json "
                                 "(an object with 'autopilots')")
        flown = _flown(result, source)
        for autopilot, entry in result["autopilots"].items():
            row = entry.get(side) if isinstance(entry, dict) else None
            row = row if isinstance(row, dict) else {}
            a, d = row.get("a_rms_m_s2"), row.get("d_rms_close_m")
            if "error" in row or not isinstance(a, (int, float)) or not isinstance(d, (int, float)):
                continue
            if not (math.isfinite(a) and math.isfinite(d)):
                continue
            args = flown.get("fly_args")
            group = (flown["mission_name"], autopilot, side, flown.get("accel_feedforward"),
                     None if args is None else " ".join(args))
            out.append({"group": group, "law": flown["method"], "lambda_s4": flown.get("lambda_s4"),
                        "course_tc_s": flown.get("course_tc_s"),
                        "a_rms_m_s2": float(a), "d_rms_close_m": float(d), "file": source})
    return out


def compare(pts: list[dict], a_tolerance: float = 0.0) -> list[dict]:
    """Per group: ``predictive``'s flights and front, and every other law's flight against it, read
    at the law's a_rms times ``1 + a_tolerance`` (0: strictly at or below it)."""
    groups: dict[tuple, list[dict]] = {}
    for p in pts:
        groups.setdefault(p["group"], []).append(p)
    out = []
    for key, members in groups.items():
        pred = sorted((p for p in members if p["law"] == "predictive"), key=lambda p: p["a_rms_m_s2"])
        front = pareto_front([(p["a_rms_m_s2"], p["d_rms_close_m"]) for p in pred])
        laws = []
        for p in sorted((p for p in members if p["law"] != "predictive"), key=lambda p: (p["law"], p["a_rms_m_s2"])):
            there = front_at(front, p["a_rms_m_s2"] * (1.0 + a_tolerance))
            laws.append({"law": p["law"], "a_rms_m_s2": p["a_rms_m_s2"], "d_rms_close_m": p["d_rms_close_m"],
                         "predictive_d_rms_close_m": there,
                         "law_over_predictive": None if not there else p["d_rms_close_m"] / there,
                         "met": there is not None and there <= p["d_rms_close_m"], "file": p["file"]})
        mission, autopilot, side, ff, args = key
        out.append({"mission_name": mission, "autopilot": autopilot, "side": side, "accel_feedforward": ff,
                    "fly_args": args,
                    "predictive": [{k: p[k] for k in ("lambda_s4", "course_tc_s", "a_rms_m_s2", "d_rms_close_m", "file")}
                                   for p in pred],
                    "laws": laws})
    return out


def _num(v, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def format_table(groups: list[dict]) -> str:
    lines = []
    for g in groups:
        ff = {None: "by default", True: "sent", False: "not sent"}[g["accel_feedforward"]]
        args = "unknown" if g["fly_args"] is None else (g["fly_args"] or "none")
        lines.append(f"{g['mission_name']} on {g['autopilot']} ({g['side']}), acceleration target {ff}, "
                     f"fly options: {args}")
        front = ", ".join(f"{p['d_rms_close_m']:.4f} @ {p['a_rms_m_s2']:.3f} (lambda {_num(p['lambda_s4'], 'g')}"
                          + ("" if p["course_tc_s"] is None else f", course observed over {p['course_tc_s']:g} s")
                          + ")" for p in g["predictive"])
        lines.append(f"  predictive: {front or 'not flown'}")
        for law in g["laws"]:
            verdict = "met" if law["met"] else (
                "not met" if law["predictive_d_rms_close_m"] is not None
                else "not met: less a_rms than any predictive flight" if g["predictive"]
                else "not met: no predictive flight to compare")
            lines.append(f"  {law['law']:14s} {law['d_rms_close_m']:.4f} @ {law['a_rms_m_s2']:.3f}   predictive there "
                         f"{_num(law['predictive_d_rms_close_m'], '.4f')}   law / predictive "
                         f"{_num(law['law_over_predictive'], '.2f')}   {verdict}")
    compared = [law for g in groups for law in g["laws"]]
    lines.append(f"met: {sum(law['met'] for law in compared)} of {len(compared)}")
    return "\n".join(lines)


def register(subparsers) -> None:
    p = subparsers.add_parser("fronts", help="predictive at the other laws' a_rms, from bench sitl results",
                              description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("files", nargs="+", metavar="BENCH.json", help="outputs of companion bench sitl --json")
    p.add_argument("--side", choices=SIDES, default="real", help="the real flights (default) or the mock's")
    p.add_argument("--a-tolerance", type=float, default=0.0, metavar="SHARE",
                   help="read predictive's front at each law's a_rms times 1 + SHARE (default 0: at or below "
                        "it); for a_rms that differ by less than one law's spread between flights")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    results = []
    for name in args.files:
        try:
            results.append((name, json.loads(Path(name).read_text())))
        except OSError as err:
            raise CompanionError(f"{name}: cannot read: {err.strerror or err}") from None
        except json.JSONDecodeError as err:
            raise CompanionError(f"{name}: not JSON (line {err.lineno}): expected the output of "
                                 "companion bench sitl --json") from None
    if not (math.isfinite(args.a_tolerance) and 0.0 <= args.a_tolerance < 1.0):
        raise CompanionError(f"bench fronts: --a-tolerance: expected a share in [0, 1), got {args.a_tolerance}")
    groups = compare(points(results, args.side), args.a_tolerance)
    if args.json:
        compared = [law for g in groups for law in g["laws"]]
        print(json.dumps({"side": args.side, "a_tolerance": args.a_tolerance, "groups": groups, "met": sum(law["met"] for law in compared),
                          "compared": len(compared)}, indent=2))
    else:
        print(format_table(groups))
    return 0
