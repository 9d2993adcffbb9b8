"""``companion mission check | import | show | schema``: mission files from the command line.

- ``check FILE``: every problem, one line each (``file: key.path: expected ...``), exit 2; warnings
  (e.g. curvature too tight for L1) are printed but the exit code stays 0.
- ``import FILE.plan|FILE.waypoints -o OUT.yaml``: QGroundControl plans to a mission file; notes
  on what was skipped go to stderr.
- ``show FILE [--plot out.png] [--json]``: the path's figures, and a plot of the path, its
  curvature along arc length, the start heading and the two initiation circles.
- ``schema``: print the JSON Schema generated from :mod:`companion.mission.schema`.
- ``random SEED... -o DIR``: the tracking bench's seeded random scenarios as mission files
  (:func:`companion.bench.scenarios.scenario_mission_yaml`), to fly or plot one on its own.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path as FilePath

import numpy as np

from companion.errors import CompanionError, MissionError


def register(subparsers) -> None:
    parser = subparsers.add_parser("mission", help="check, import and show mission files",
                                   description="Check, import and show mission files.")
    sub = parser.add_subparsers(dest="mission_command", metavar="ACTION")
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])

    check = sub.add_parser("check", help="validate a mission file (every problem, one line each)")
    check.add_argument("file", help="mission YAML file")
    check.add_argument("--json", action="store_true", help="print one JSON object")
    check.set_defaults(func=run_check)

    imp = sub.add_parser("import", help="convert a QGroundControl .plan or QGC WPL 110 file")
    imp.add_argument("file", help="FILE.plan (JSON) or FILE.waypoints (QGC WPL 110)")
    imp.add_argument("-o", "--output", required=True,
                     help="mission YAML to write ('-': standard output); an existing file is kept "
                          "unless --force")
    imp.add_argument("--force", action="store_true", help="overwrite the --output file if it exists")
    imp.add_argument("--name", help="mission name (default: the file's stem)")
    imp.add_argument("--speed-m-s", type=float, help="ground speed (default: from the plan)")
    imp.add_argument("--altitude-m", type=float,
                     help="flight height above home (default: the waypoints' common altitude)")
    imp.set_defaults(func=run_import)

    show = sub.add_parser("show", help="figures and a plot of a mission's path")
    show.add_argument("file", help="mission YAML file")
    show.add_argument("--plot", metavar="OUT.png", help="write a plot of the path and its curvature")
    show.add_argument("--json", action="store_true", help="print one JSON object")
    show.set_defaults(func=run_show)

    schema = sub.add_parser("schema", help="print the mission JSON Schema")
    schema.set_defaults(func=run_schema)

    rnd = sub.add_parser("random", help="write the tracking bench's random scenarios as mission files",
                         description="Write scenarios of `companion bench tracking --random N --seed S` "
                                     "(seeds S .. S+N-1) as mission files: path, speed, start, vehicle: "
                                     "lag model; their wind in a comment (missions carry none).")
    rnd.add_argument("seed", nargs="+", type=int, help="scenario seeds")
    rnd.add_argument("-o", "--output", required=True,
                     help="directory to write random_SEED.yaml into (created if missing; existing files "
                          "are kept unless --force), or '-': standard output (one seed)")
    rnd.add_argument("--force", action="store_true", help="overwrite existing files")
    rnd.add_argument("--json", action="store_true", help="print one JSON object")
    rnd.set_defaults(func=run_random)


def run(args) -> int:  # pragma: no cover - each action sets its own func
    return args.func(args)


# ------------------------------------------------------------------------------------- check
def run_check(args) -> int:
    from companion.mission import check_mission_text, read_mission_text

    try:
        text = read_mission_text(args.file)
        mission, problems, warnings = check_mission_text(text, str(args.file))
    except MissionError as err:
        mission, problems, warnings = None, err.problems, []
    if args.json:
        out = {"file": str(args.file), "ok": not problems, "problems": problems, "warnings": warnings}
        if mission is not None:
            out.update(_figures(mission))
        print(json.dumps(out, indent=2))
    else:
        for line in problems + warnings:
            print(line, file=sys.stderr)
        if mission is not None:
            print(f"{args.file}: ok: {mission.name!r}, {mission.path.length_m:.1f} m "
                  f"{'closed ' if mission.path.closed else ''}path, V = {mission.speed_m_s:g} m/s, "
                  f"L1 = {mission.guidance.l1_m:g} m"
                  + (f", {len(warnings)} warning(s)" if warnings else ""))
    return 2 if problems else 0


# ------------------------------------------------------------------------------------ import
def run_import(args) -> int:
    from companion.mission.qgc import import_file

    for name in ("speed_m_s", "altitude_m"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise MissionError(f"--{name.replace('_', '-')}: expected a finite number > 0, got {value!r}")
    refusal = _refusal(args.output, ", or -o - to print")
    if args.output != "-" and not args.force and FilePath(args.output).exists():
        raise CompanionError(refusal)  # before reading the plan: one line, nothing else
    result = import_file(args.file, name=args.name, speed_m_s=args.speed_m_s,
                         altitude_m=args.altitude_m)
    for note in result.notes:
        print(note, file=sys.stderr)
    what = (f"{len(result.points_enu_m)} waypoints about origin "
            f"{result.origin[0]:.7f}, {result.origin[1]:.7f}")
    if args.output == "-":  # the YAML alone on stdout (for a pipe); the note on stderr
        sys.stdout.write(result.yaml_text)
        sys.stdout.flush()
        print(f"<stdout>: wrote {what}", file=sys.stderr)
        return 0
    out = FilePath(args.output)
    _write_new(out, result.yaml_text, args.force, refusal)
    print(f"{out}: wrote {what}")
    return 0


def _refusal(path, more: str = "") -> str:
    """The one line that refuses to replace an existing file ``path``."""
    return f"{path}: already exists; not overwritten (pass --force to replace it{more})"


def _write_new(out: FilePath, text: str, force: bool, refusal: str) -> None:
    """Write ``text`` to ``out``; an existing file is kept (``refusal`` raised) unless ``force``."""
    try:
        # "x": refuse an existing file in the same system call that creates the new one.
        with open(out, "w" if force else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise CompanionError(refusal) from None
    except OSError as err:
        raise CompanionError(f"{out}: cannot write ({err.strerror})") from None


# ------------------------------------------------------------------------------------ random
def run_random(args) -> int:
    from companion.bench.scenarios import random_spec, scenario_mission_yaml

    if args.output == "-" and len(args.seed) != 1:
        raise CompanionError(f"mission random: -o -: one seed at a time on standard output, got {len(args.seed)}")
    if args.output == "-" and args.json:
        raise CompanionError("mission random: --json: not with -o - (the mission file itself goes to standard output)")
    specs = [random_spec(seed) for seed in args.seed]  # a bad seed: one line, before anything is written
    texts = [scenario_mission_yaml(spec) for spec in specs]
    if args.output == "-":
        sys.stdout.write(texts[0])
        return 0
    out_dir = FilePath(args.output)
    files = [out_dir / f"{spec.name}.yaml" for spec in specs]
    if not args.force:
        existing = [str(f) for f in files if f.exists()]
        if existing:
            raise CompanionError(_refusal(existing[0]) + (f" ({len(existing) - 1} more)" if len(existing) > 1 else ""))
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CompanionError(f"{out_dir}: cannot create the directory ({err.strerror})") from None
    for file, text in zip(files, texts):
        _write_new(file, text, args.force, _refusal(file))
    if args.json:
        print(json.dumps({"files": [{"file": str(f), "scenario": spec.summary()} for f, spec in zip(files, specs)]},
                         indent=2))
        return 0
    for file, spec in zip(files, specs):
        east, north = spec.wind_enu_m_s
        print(f"{file}: wrote {spec.category}, V {spec.speed_m_s:g} m/s, lag {spec.lag_s:g} s, "
              f"wind {east:g},{north:g} m/s (companion bench tracking --mission {file} --wind={east:g},{north:g})")
    return 0


# -------------------------------------------------------------------------------------- show
def _initiation_circles(mission) -> list[tuple[float, float]]:
    """Centres of the two circles of radius R tangent to the path at its start (left, right)."""
    x0, y0 = mission.path.start_xy_m
    h = mission.path.start_heading_rad
    r = mission.guidance.circle_radius_m
    nx, ny = -math.sin(h), math.cos(h)  # left normal
    return [(x0 + r * nx, y0 + r * ny), (x0 - r * nx, y0 - r * ny)]


def _figures(mission) -> dict:
    path = mission.path
    k = np.asarray(path.k_table_1_m)
    i = int(np.argmax(np.abs(k)))
    k_max = float(abs(k[i]))
    out = {
        "name": mission.name,
        "frame": mission.frame,
        "length_m": round(path.length_m, 4),
        "closed": path.closed,
        "speed_m_s": mission.speed_m_s,
        "altitude_m": mission.altitude_m,
        "on_finish": mission.on_finish,
        "l1_m": mission.guidance.l1_m,
        "method": mission.guidance.method,
        "start_xy_m": [round(v, 4) for v in path.start_xy_m],
        "start_heading_deg": round(math.degrees(path.start_heading_rad), 4),
        "end_xy_m": [round(v, 4) for v in path.end_xy_m],
        "curvature_max_1_m": round(k_max, 6),
        "radius_min_m": round(1.0 / k_max, 4) if k_max > 0 else None,
        "radius_min_at_s_m": round(float(path.s_table_m[i]), 3),
        "a_path_max_m_s2": round(mission.speed_m_s ** 2 * k_max, 4),
        "turn_accel_share": mission.profile_limits.turn_accel_share,
        "initiation_circles": [{"centre_xy_m": [round(c, 4) for c in centre],
                                "radius_m": mission.guidance.circle_radius_m}
                               for centre in _initiation_circles(mission)],
    }
    if mission.start is not None:
        out["vehicle_start"] = {"x_m": mission.start.x_m, "y_m": mission.start.y_m,
                                "heading_deg": round(math.degrees(mission.start.heading_rad), 4)}
    if mission.origin is not None:
        out["origin"] = {"lat_deg": mission.origin.lat_deg, "lon_deg": mission.origin.lon_deg,
                         "alt_m": mission.origin.alt_m}
    p = mission.profile
    if p is not None:
        climb = p.climb_table_m_s()
        lim = p.limits
        out["profile"] = {
            "altitude_min_m": round(float(p.alt_m.min()), 4),
            "altitude_max_m": round(float(p.alt_m.max()), 4),
            "altitude_end_m": round(p.end_altitude_m, 4),
            "speed_min_m_s": round(float(p.speed_m_s_table.min()), 4),
            "speed_max_m_s": round(float(p.speed_m_s_table.max()), 4),
            "climb_max_m_s": round(float(climb.max()), 4),
            "sink_max_m_s": round(float(-climb.min()), 4),
            "limits": {"climb_max_m_s": lim.climb_max_m_s, "sink_max_m_s": lim.sink_max_m_s,
                       "vertical_accel_max_m_s2": lim.vert_accel_max_m_s2,
                       "along_track_accel_max_m_s2": lim.along_accel_max_m_s2},
        }
        out["a_path_max_m_s2"] = round(float(np.max(np.interp(path.s_table_m, p.s_m, p.speed_m_s_table) ** 2
                                                    * np.abs(k))), 4)
    share = mission.profile_limits.turn_accel_share
    # a flight on a vehicle whose acceleration limit is below this is slower in the turns (docs/missions.md)
    out["turns_slowed_below_a_max_m_s2"] = round(out["a_path_max_m_s2"] / share, 4) if share > 0 else None
    return out


def run_show(args) -> int:
    from companion.mission import load_mission

    mission = load_mission(args.file)
    for line in mission.warnings:
        print(line, file=sys.stderr)
    figures = _figures(mission)
    if args.plot:
        _plot(mission, args.plot)
        figures["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(figures, indent=2))
        return 0
    print(f"mission {figures['name']!r} ({figures['frame']}), on_finish: {figures['on_finish']}")
    print(f"  path: {figures['length_m']:.1f} m, {'closed' if figures['closed'] else 'open'}, "
          f"from ({figures['start_xy_m'][0]:.2f}, {figures['start_xy_m'][1]:.2f}) heading "
          f"{figures['start_heading_deg']:.2f} deg to ({figures['end_xy_m'][0]:.2f}, "
          f"{figures['end_xy_m'][1]:.2f})")
    radius = figures["radius_min_m"]
    print(f"  tightest radius: {radius if radius is not None else math.inf:.2f} m at s = "
          f"{figures['radius_min_at_s_m']:.1f} m (V^2 k = {figures['a_path_max_m_s2']:.2f} m/s^2 at "
          + ("the local speed V(s), largest along the path)" if mission.profile is not None else f"V = {mission.speed_m_s:g} m/s)"))
    below = figures["turns_slowed_below_a_max_m_s2"]
    if below is not None:
        print(f"  in flight: slower in the turns on a vehicle whose acceleration limit is below {below:.2f} m/s^2 "
              f"(along_track.turn_accel_share {figures['turn_accel_share']:g})")
    print(f"  guidance: {figures['method']}, L1 = {figures['l1_m']:g} m, "
          f"{mission.guidance.rate_hz:g} Hz; altitude {mission.altitude_m:g} m")
    if "profile" in figures:
        pf = figures["profile"]
        print(f"  profile: altitude {pf['altitude_min_m']:g}..{pf['altitude_max_m']:g} m (end "
              f"{pf['altitude_end_m']:g} m), speed {pf['speed_min_m_s']:g}..{pf['speed_max_m_s']:g} m/s, "
              f"climb up to {pf['climb_max_m_s']:.2f} m/s, sink up to {pf['sink_max_m_s']:.2f} m/s "
              f"(limits {pf['limits']['climb_max_m_s']:g} / {pf['limits']['sink_max_m_s']:g} m/s)")
    for side, circle in zip(("left", "right"), figures["initiation_circles"]):
        cx, cy = circle["centre_xy_m"]
        print(f"  initiation circle ({side}): centre ({cx:.2f}, {cy:.2f}), R = {circle['radius_m']:g} m")
    if "vehicle_start" in figures:
        vs = figures["vehicle_start"]
        print(f"  vehicle start: ({vs['x_m']:g}, {vs['y_m']:g}) heading {vs['heading_deg']:g} deg")
    if args.plot:
        print(f"  plot: {args.plot}")
    return 0


def _plot(mission, out_png: str) -> None:
    from companion.plots import pyplot, save_figure

    plt = pyplot()
    path = mission.path
    s, x, y = path.sample(2000)
    k = path.curvature_array(s)
    if mission.profile is None:
        fig, (ax_xy, ax_k) = plt.subplots(2, 1, figsize=(8, 9), gridspec_kw={"height_ratios": [3, 1]})
    else:  # a third panel: altitude and speed along the path
        fig, (ax_xy, ax_k, ax_h) = plt.subplots(3, 1, figsize=(8, 11),
                                                gridspec_kw={"height_ratios": [3, 1, 1]})
        from companion.plots import profile_panel

        profile_panel(ax_h, mission.profile)
    ax_xy.plot(x, y, "-", color="tab:blue", lw=1.5, label="path")
    x0, y0 = path.start_xy_m
    h = path.start_heading_rad
    r = mission.guidance.circle_radius_m
    arrow = max(r, 0.05 * path.length_m)
    ax_xy.annotate("", xy=(x0 + arrow * math.cos(h), y0 + arrow * math.sin(h)), xytext=(x0, y0),
                   arrowprops={"arrowstyle": "->", "color": "tab:green", "lw": 2})
    ax_xy.plot([x0], [y0], "o", color="tab:green", label=f"start, heading {math.degrees(h):.1f} deg")
    t = np.linspace(0, 2 * math.pi, 200)
    for (cx, cy), style in zip(_initiation_circles(mission), ("--", ":")):
        ax_xy.plot(cx + r * np.cos(t), cy + r * np.sin(t), style, color="tab:orange", lw=1)
    ax_xy.plot([], [], "--", color="tab:orange", label=f"initiation circles, R = {r:g} m")
    if mission.start is not None:
        st = mission.start
        ax_xy.plot([st.x_m], [st.y_m], "s", color="tab:red", label="vehicle start")
        ax_xy.annotate("", xy=(st.x_m + arrow * math.cos(st.heading_rad),
                               st.y_m + arrow * math.sin(st.heading_rad)),
                       xytext=(st.x_m, st.y_m), arrowprops={"arrowstyle": "->", "color": "tab:red"})
    ax_xy.set_aspect("equal", adjustable="datalim")
    ax_xy.set_xlabel("x east (m)")
    ax_xy.set_ylabel("y north (m)")
    ax_xy.set_title(f"{mission.name}: {path.length_m:.1f} m, V = {mission.speed_m_s:g} m/s, "
                    f"L1 = {mission.guidance.l1_m:g} m")
    ax_xy.grid(True, alpha=0.3)
    ax_xy.legend(loc="best", fontsize=8)
    ax_k.plot(s, k, color="tab:purple", lw=1)
    limit = 2.0 / mission.guidance.l1_m
    ax_k.axhline(limit, color="tab:red", ls=":", lw=1, label="+/- 2/L1 (fixed-L1 limit)")
    ax_k.axhline(-limit, color="tab:red", ls=":", lw=1)
    ax_k.set_xlabel("arc length s (m)")
    ax_k.set_ylabel("curvature (1/m)")
    ax_k.grid(True, alpha=0.3)
    ax_k.legend(loc="best", fontsize=8)
    fig.tight_layout()
    save_figure(fig, out_png)


# ------------------------------------------------------------------------------------ schema
def run_schema(args) -> int:
    from companion.mission.schema import json_schema_text

    sys.stdout.write(json_schema_text())
    return 0
