"""``companion bench sitl MISSION``: one mission flown on the mock and on the real firmware, side by side.

    companion bench sitl missions/racetrack.yaml --method corrector \\
        --arducopter /tmp/sitl/ardupilot/build/sitl/bin/arducopter \\
        --arducopter-defaults /tmp/sitl/ardupilot/Tools/autotest/default_params/copter.parm --json
    companion bench sitl missions/paper_sine.yaml --px4 /tmp/sitl/px4/build/px4_sitl_default/bin/px4 \\
        --px4-romfs /tmp/sitl/px4/build/px4_sitl_default/etc

For each autopilot given, the bench starts the mock with that autopilot's personality (its
copter flies the model identified from that firmware, docs/vehicle_model.md) and then the real
SITL binary, and runs ``companion fly MISSION --arm`` against each, from the ground at the local
origin, for the same flight time. The mock's copter flies a random velocity-estimate bias, as the
real PX4's does: ``--mock-seeds N`` flies it N times (seeds 0..N-1) and reports each metric's
median, with the spread of ``d_rms_m``. It prints the shared metric names of each flight
(``d_rms_m``, ``d_max_m``, ``a_rms_m_s2``, ``a_max_m_s2`` over the whole flight, capture
included; ``d_rms_close_m`` over the close-range phase; ``d_rms_settled_m`` from 30 s of guidance
on, and ``speed_settled_m_s`` the mean ground speed flown there; ``sat_share``: the share of ticks
whose command reaches the acceleration limit, the mission's or else the one the flight read from
the autopilot, ``a_limit_m_s2``; ``sat_share_settled`` the same from 30 s on) and the ratio
real / mock of ``d_rms_m``. The result records what was flown (``flown``: the mission's name, the
law, ``lambda_s4``, the acceleration-target setting and the extra fly options), so that
``companion bench fronts`` can put several results side by side.

The binaries are started as ``../shared/tools/sitl/run-*.sh`` start them (nothing of the firmware
is part of this project): ArduCopter ``--model + --defaults PARM -w -I INSTANCE --serial0
udpclient:127.0.0.1:PORT`` (``--speedup N`` when asked; the companion then ticks on the
autopilot's clock), PX4 ``px4 ROMFS -s etc/init.d-posix/rcS -w WORKDIR -d`` with the SIH
quadrotor (airframe 10040), which sends to UDP 14540. ArduCopter's position estimate needs about
40 s (simulated) after boot: the bench waits ``--warmup-s`` before starting the companion.
"""

from __future__ import annotations

import json
import math
import os
import shlex
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from companion.bench.fronts import flown_config
from companion.errors import CompanionError

METRICS = ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "d_rms_close_m", "d_rms_settled_m", "sat_share",
           "sat_share_settled", "speed_settled_m_s", "a_limit_m_s2", "duration_s")
SETTLED_AFTER_S = 30.0  # take-off, climb and capture are over by then on the gallery missions
PX4_PORT = 14540  # the SIH build's offboard link sends here
DEFAULT_INSTANCE = 4
DEFAULT_PORT = 14640


@dataclass
class Target:
    """One real autopilot to compare with the mock: how to start it and where it talks."""

    autopilot: str  # "ardupilot" or "px4"
    cmd: list[str]
    port: int
    warmup_s: float
    env: dict[str, str] = field(default_factory=dict)
    # The heading the simulated vehicle starts with (degrees clockwise from north); the mock is
    # started with the same, so that both begin the flight pointing the same way.
    start_yaw_deg: float = 0.0


#: ArduPilot SITL's start heading without ``--home``: ``SIM_OPOS_HDG``, 353 deg by default
#: (``libraries/SITL/SITL.cpp``; its start position is CMAC's). PX4's SIH starts facing north.
ARDUCOPTER_START_YAW_DEG = 353.0


def arducopter_target(binary: str, defaults: str | None, instance: int, port: int, speedup: float,
                      warmup_s: float | None) -> Target:
    """ArduCopter SITL as ``run-ardupilot-copter.sh`` starts it (plus ``--speedup``)."""
    cmd = [binary, "--model", "+", "-w", "-I", str(instance), "--serial0", f"udpclient:127.0.0.1:{port}"]
    if defaults:
        cmd[3:3] = ["--defaults", defaults]
    if speedup != 1.0:
        cmd += ["--speedup", f"{speedup:g}"]
    return Target("ardupilot", cmd, port, 50.0 / speedup if warmup_s is None else warmup_s,
                  start_yaw_deg=ARDUCOPTER_START_YAW_DEG)


def px4_target(binary: str, romfs: str, warmup_s: float | None) -> Target:
    """PX4 SITL with its SIH quadrotor as ``run-px4-sih.sh`` starts it (the working dir is added)."""
    env = {"PX4_SYS_AUTOSTART": "10040", "PX4_SIMULATOR": "sihsim", "PX4_SIM_MODEL": "sihsim_quadx"}
    cmd = [binary, romfs, "-s", "etc/init.d-posix/rcS", "-d"]
    return Target("px4", cmd, PX4_PORT, 10.0 if warmup_s is None else warmup_s, env)


def check_binaries(args) -> list[Target]:
    """The targets the options name, each checked to exist (exit 2 with one line otherwise)."""
    targets = []
    if args.arducopter:
        _need_file(args.arducopter, "--arducopter", executable=True)
        if args.arducopter_defaults:
            _need_file(args.arducopter_defaults, "--arducopter-defaults")
        targets.append(arducopter_target(args.arducopter, args.arducopter_defaults, args.instance,
                                         args.port, args.speedup, args.warmup_s))
    if args.px4:
        _need_file(args.px4, "--px4", executable=True)
        if not args.px4_romfs or not Path(args.px4_romfs).is_dir():
            raise CompanionError(f"--px4-romfs: expected PX4's ROMFS directory (build/px4_sitl_default/etc), "
                                 f"got {args.px4_romfs!r}")
        targets.append(px4_target(args.px4, args.px4_romfs, args.warmup_s))
    if not targets:
        raise CompanionError("bench sitl: expected --arducopter BIN and/or --px4 BIN (the real SITL binaries)")
    return targets


def _need_file(path: str, option: str, executable: bool = False) -> None:
    p = Path(path)
    if not p.is_file() or (executable and not os.access(p, os.X_OK)):
        raise CompanionError(f"{option}: expected an existing {'executable ' if executable else ''}file, got {path!r}")


def fly(mission: str, connect: str, workdir: Path, opts: list[str], timeout_s: float) -> dict:
    """``companion fly MISSION --arm --json`` against ``connect``; its JSON summary and tlog path."""
    tlog = workdir / "flight.tlog"
    cmd = [sys.executable, "-m", "companion", "fly", mission, "--connect", connect, "--arm", "--json",
           "--quiet", "--tlog", str(tlog), *opts]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return {"error": f"companion fly did not end within {timeout_s:.0f} s"}
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["no message"])[-1]
        return {"error": f"companion fly exited {out.returncode}: {last}"}
    summary = json.loads(out.stdout)
    summary["tlog"] = str(tlog)
    return summary


def log_figures(tlog: str, a_limit_m_s2: float) -> dict:
    """From the flight's recorded guidance rows: ``sat_share``, the share of ticks whose |a_cmd|
    reaches the limit (the given one, else the one the flight read from the autopilot's parameters;
    None without either), ``sat_share_settled`` the same from ``SETTLED_AFTER_S`` on, and
    ``d_rms_settled_m``, the cross-track RMS from ``SETTLED_AFTER_S`` on, and ``speed_settled_m_s``, the
    mean ground speed the autopilot reported over the same ticks (PX4 SIH flies slower than asked)."""
    from companion.loop.limits import limit_from_params
    from companion.replay.flightlog import read_flight

    flight = read_flight(tlog, progress=False)
    if not math.isfinite(a_limit_m_s2):
        read = limit_from_params(flight.params)
        a_limit_m_s2 = read.a_max_m_s2 if read is not None else math.nan
    rows = [(tk.debug_value("t_s"), tk.debug_value("a_cmd_m_s2"), tk.debug_value("crosstrack_m"),
             tk.debug_value("ground_speed_m_s")) for tk in flight.ticks]

    def share(after_s: float) -> float | None:
        a = [abs(v) for t, v, _, _ in rows if t >= after_s and math.isfinite(v)]
        if not a or not math.isfinite(a_limit_m_s2):
            return None
        return sum(v >= a_limit_m_s2 * (1.0 - 1e-3) for v in a) / len(a)

    d = [x for t, _, x, _ in rows if t >= SETTLED_AFTER_S and math.isfinite(x)]
    settled = math.sqrt(sum(x * x for x in d) / len(d)) if d else None
    v = [x for t, _, _, x in rows if t >= SETTLED_AFTER_S and math.isfinite(x)]
    return {"sat_share": share(-math.inf), "sat_share_settled": share(SETTLED_AFTER_S), "d_rms_settled_m": settled,
            "speed_settled_m_s": sum(v) / len(v) if v else None,
            "a_limit_m_s2": a_limit_m_s2 if math.isfinite(a_limit_m_s2) else None}


def flight_row(summary: dict, a_limit_m_s2: float) -> dict:
    """The bench's metrics of one ``companion fly --json`` summary."""
    if "error" in summary:
        return {"error": summary["error"]}
    row = {k: summary.get(k) for k in ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "duration_s")}
    row["d_rms_close_m"] = summary.get("phases", {}).get("close_range", {}).get("d_rms_m")
    row.update(log_figures(summary["tlog"], a_limit_m_s2))
    row["exit"] = summary.get("exit")
    return row


class Process:
    """A child process (the mock or a SITL binary) stopped by its own id, never by name."""

    def __init__(self, cmd: list[str], cwd: Path, env: dict[str, str] | None = None):
        log = open(cwd / "process.log", "w")  # noqa: SIM115 (closed in stop)
        self._log = log
        self.proc = subprocess.Popen(cmd, cwd=cwd, stdout=log, stderr=subprocess.STDOUT,
                                     env={**os.environ, **(env or {})}, start_new_session=True)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self._log.close()


def mock_cmd(target: Target, port: int, duration_s: float, seed: int = 0) -> list[str]:
    """The mock standing in for ``target``: its autopilot's copter personality (which flies the model
    identified from that firmware, its velocity-estimate bias drawn with ``seed``), on the ground,
    facing where the real SITL's vehicle starts."""
    return [sys.executable, "-m", "sitl_mock", "--autopilot", target.autopilot, "--vehicle", "copter",
            "--link", f"udpout:127.0.0.1:{port}", "--quiet", "--duration-s", f"{duration_s:.0f}",
            f"--start-yaw-deg={target.start_yaw_deg:g}", "--seed", str(seed)]


def median_row(rows: list[dict]) -> dict:
    """Each metric's median over the flights that ran (the mock flown with several seeds); the
    first failure when none ran."""
    ran = [r for r in rows if "error" not in r]
    if not ran:
        return rows[0]
    out: dict = {}
    for key in METRICS:
        values = [r[key] for r in ran if r.get(key) is not None]
        if values:
            out[key] = statistics.median(values)
    out["exit"] = ran[0].get("exit")
    return out


def fly_on(target: Target, real: bool, mission: str, fly_opts: list[str], workdir: Path, timeout_s: float,
           seed: int = 0, later_s: float = 0.0) -> dict:
    """Start the mock (``real`` False) or the binary, wait for it (a binary ``later_s`` longer than
    its warm-up), fly the mission, stop it."""
    workdir.mkdir(parents=True, exist_ok=True)
    if real:
        cmd, env, warmup_s, port = target.cmd, target.env, target.warmup_s + later_s, target.port
        if target.autopilot == "px4":
            cmd = [*cmd, "-w", str(workdir)]
    else:
        port = _free_port()
        cmd = mock_cmd(target, port, timeout_s + 30.0, seed)
        env, warmup_s = {"PYTHONPATH": str(Path(__file__).resolve().parents[2])}, 1.0
    proc = Process(cmd, workdir, env)
    try:
        time.sleep(warmup_s)
        if proc.proc.poll() is not None:
            return {"error": f"{cmd[0]} exited {proc.proc.returncode} at start (log: {workdir / 'process.log'})"}
        return fly(mission, f"udpin:127.0.0.1:{port}", workdir, fly_opts, timeout_s)
    finally:
        proc.stop()


def _free_port() -> int:
    from companion.io.mock_process import free_udp_port

    return free_udp_port()


def vehicle_limit_m_s2(mission_file: str) -> float:
    """The acceleration limit the mission's law plans with: its ``vehicle:`` block's, else guidance's."""
    from companion.mission import load_mission

    m = load_mission(mission_file)
    if m.vehicle is not None:
        return float(m.vehicle.a_max_m_s2)
    return float(m.guidance.a_max_m_s2)


def run_bench(args, targets: list[Target]) -> dict:
    """Every target flown on the mock and for real; the comparison as one JSON-ready dict."""
    mission = _mission_for(args)
    limit = args.a_limit_m_s2 if args.a_limit_m_s2 is not None else vehicle_limit_m_s2(mission)
    opts = ["--max-duration-s", f"{args.max_duration_s:g}", "--arm-timeout-s", "120",
            "--origin-timeout-s", "60"]
    if args.speedup != 1.0:
        opts += ["--clock", "autopilot"]
    extra = shlex.split(getattr(args, "fly_args", None) or "")
    opts += extra
    timeout_s = args.max_duration_s / args.speedup + 240.0
    root = Path(args.workdir or tempfile.mkdtemp(prefix="bench-sitl-"))
    out: dict = {"mission": args.mission, "method": args.method,
                 "max_duration_s": args.max_duration_s, "speedup": args.speedup, "autopilots": {},
                 "flown": flown_config(mission, extra)}
    seeds = range(args.mock_seeds)
    out["mock_seeds"] = args.mock_seeds
    stagger_s = real_stagger_s(args)
    out["real_runs"] = args.real_runs
    for t in targets:
        runs = [flight_row(fly_on(t, False, mission, opts, root / f"{t.autopilot}-mock" / f"seed-{k}", timeout_s, k),
                           limit) for k in seeds]
        mock = median_row(runs) if runs else {}  # --mock-seeds 0: the real alone
        real_dir = root / f"{t.autopilot}-real"
        real_runs = [flight_row(fly_on(t, True, mission, opts, real_dir / f"run-{k}" if args.real_runs > 1 else real_dir,
                                       timeout_s, later_s=k * stagger_s), limit) for k in range(args.real_runs)]
        real = median_row(real_runs) if real_runs else {}  # --real-runs 0: the mock alone
        ratio = None
        if mock.get("d_rms_m") and real.get("d_rms_m") is not None:
            ratio = real["d_rms_m"] / mock["d_rms_m"]
        entry = {"mock": mock, "real": real, "d_rms_ratio_real_mock": ratio}
        if len(runs) > 1:
            entry["mock_runs"] = runs
        if len(real_runs) > 1:
            entry["real_runs"] = real_runs
            entry["real_later_s"] = [k * stagger_s for k in range(args.real_runs)]
        out["autopilots"][t.autopilot] = entry
    return out


def real_stagger_s(args) -> float:
    """How much later each further real flight starts after its binary's boot (``--real-stagger-s``).

    A SITL binary replays the same sensor noise after every boot: PX4 SIH's simulated sensors draw
    from the C library's ``rand()``, never seeded, so on a quiet machine two flights of a mission
    begun the same time after boot are the same flight, and so are the drifts of its velocity
    estimate (docs/real_firmware.md). Started later, a flight meets another stretch of that noise;
    by default later by the whole flight and half a minute, so that no stretch is flown twice.
    """
    if args.real_stagger_s is not None:
        return float(args.real_stagger_s)
    return args.max_duration_s / args.speedup + 30.0


def _mission_for(args) -> str:
    """The mission file to fly: the given one, or a copy with ``guidance.method`` replaced."""
    if args.method is None:
        return args.mission
    from companion.mission.loader import mission_text_with_method

    text = mission_text_with_method(args.mission, args.method)
    fd, name = tempfile.mkstemp(prefix="bench-sitl-", suffix=".yaml")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    return name


def format_table(result: dict) -> str:
    """The two flights of each autopilot side by side."""
    lines = [f"mission {result['mission']} (method {result['method'] or 'as in the mission'}), "
             f"{result['max_duration_s']:g} s, speed-up {result['speedup']:g}"]
    seeds, reals = result.get("mock_seeds", 1), result.get("real_runs", 1)
    for ap, r in result["autopilots"].items():
        real_head = {0: f"real {ap}: not flown", 1: f"real {ap}"}.get(reals, f"real {ap} (median of {reals})")
        mock_head = {0: "mock: not flown", 1: "mock"}.get(seeds, f"mock (median of {seeds})")
        lines.append(f"{'':16s}{mock_head:>12s}{real_head:>16s}")
        for k in METRICS:
            lines.append(f"{k:16s}{_cell(r['mock'], k):>12s}{_cell(r['real'], k):>16s}")
        for side in ("mock", "real"):
            if "error" in r[side]:
                lines.append(f"{side}: {r[side]['error']}")
        ratio = r["d_rms_ratio_real_mock"]
        lines.append(f"d_rms real / mock: {'-' if ratio is None else f'{ratio:.2f}'}")
        runs = [x["d_rms_m"] for x in r.get("mock_runs", []) if x.get("d_rms_m") is not None]
        if runs:
            lines.append(f"mock d_rms_m over its {len(runs)} seeds: {min(runs):.3f} to {max(runs):.3f}")
        runs = [x["d_rms_m"] for x in r.get("real_runs", []) if x.get("d_rms_m") is not None]
        if runs:
            lines.append(f"real d_rms_m over its {len(runs)} flights: {min(runs):.3f} to {max(runs):.3f}")
    return "\n".join(lines)


def _cell(row: dict, key: str) -> str:
    v = row.get(key)
    return "-" if v is None else f"{v:.3f}"


def register(subparsers) -> None:
    from companion.guidance.types import METHODS

    p = subparsers.add_parser("sitl", help="a mission on the mock and on a real SITL, side by side",
                              description=__doc__.split("\n\n")[0].strip("`"))
    p.add_argument("mission", help="mission YAML file")
    p.add_argument("--method", choices=METHODS, help="override the mission's guidance method")
    p.add_argument("--arducopter", metavar="BIN", help="the ArduCopter SITL binary (build/sitl/bin/arducopter)")
    p.add_argument("--arducopter-defaults", metavar="PARM", help="its defaults file (Tools/autotest/default_params/copter.parm)")
    p.add_argument("--instance", type=int, default=DEFAULT_INSTANCE, help="ArduCopter -I instance (default 4)")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help="UDP port ArduCopter sends to (default 14640)")
    p.add_argument("--speedup", type=float, default=1.0, help="ArduCopter --speedup (>1: autopilot clock)")
    p.add_argument("--px4", metavar="BIN", help="the PX4 SITL binary (build/px4_sitl_default/bin/px4)")
    p.add_argument("--px4-romfs", metavar="DIR", help="PX4's ROMFS directory (build/px4_sitl_default/etc)")
    p.add_argument("--max-duration-s", type=float, default=90.0, help="flight time of each flight (default 90)")
    p.add_argument("--warmup-s", type=float, help="wait after starting a binary (default: 50 / speed-up ArduCopter, 10 PX4)")
    p.add_argument("--a-limit-m-s2", type=float, help="limit for sat_share (default: the mission's vehicle/guidance limit)")
    p.add_argument("--mock-seeds", type=int, default=1, metavar="N",
                   help="fly the mock N times, with seeds 0..N-1 of its velocity-estimate bias, and report "
                        "each metric's median (default 1; 0: the real alone)")
    p.add_argument("--real-runs", type=int, default=1, metavar="N",
                   help="fly the real binary N times, each started afresh and flown --real-stagger-s later "
                        "after its boot than the one before, and report each metric's median (default 1; "
                        "0: the mock alone, its personality named by --arducopter / --px4)")
    p.add_argument("--real-stagger-s", type=float, metavar="S",
                   help="how much later each further real flight starts (default: the flight time + 30 s, "
                        "so that none meets the sensor noise another flew; a SITL replays the same noise "
                        "after every boot)")
    p.add_argument("--fly-args", metavar="ARGS",
                   help="more options for every `companion fly` of the bench, as one string "
                        "(e.g. \"--speed-hold-tc-s 2\"), the mock's and the real's alike")
    p.add_argument("--workdir", help="where the flights' logs go (default: a new temporary directory)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    if not (args.max_duration_s > 0 and args.speedup > 0):
        raise CompanionError("bench sitl: --max-duration-s and --speedup: expected numbers > 0")
    if args.mock_seeds < 0:
        raise CompanionError(f"bench sitl: --mock-seeds: expected an integer >= 0, got {args.mock_seeds}")
    if args.real_runs < 0:
        raise CompanionError(f"bench sitl: --real-runs: expected an integer >= 0, got {args.real_runs}")
    if args.mock_seeds == 0 and args.real_runs == 0:
        raise CompanionError("bench sitl: --mock-seeds 0 and --real-runs 0: nothing to fly (expected at least one "
                             "flight)")
    if args.real_stagger_s is not None and not (math.isfinite(args.real_stagger_s) and args.real_stagger_s >= 0):
        raise CompanionError(f"bench sitl: --real-stagger-s: expected a number >= 0, got {args.real_stagger_s}")
    targets = check_binaries(args)
    result = run_bench(args, targets)
    print(json.dumps(result, indent=2) if args.json else format_table(result))
    failed = any("error" in r[s] for r in result["autopilots"].values() for s in ("mock", "real"))
    return 1 if failed else 0
