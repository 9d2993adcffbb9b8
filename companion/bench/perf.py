"""``companion bench perf``: is the companion fast enough for a small companion computer?

Every figure of one run, with its target and a pass/fail column (targets are medians on the
project's 2-core reference machine):

=============================  ===============================================  ==============
figure                         how it is measured                               target
=============================  ===============================================  ==============
guidance step, fixed-L1        every ``step`` of a simulated paper-sine flight  <= 50 us
guidance step, corrector       the ticks without a re-optimisation              <= 150 us
guidance step, corrector+reopt the ticks with one (``GuidanceOutput.reoptimised``)  (reported)
re-optimisation                ``GainOptimiser.optimise`` alone, timed inside   <= 20 ms
worst tick                     the longest corrector step of the flight         < 1 tick (20 ms)
loop latency p99, 50 Hz        LOCAL_POSITION_NED datagram readable -> its      <= 2 ms
                               setpoint sent, over loopback UDP with sitl_mock
                               streaming; the tick is the flight loop's own
                               ``compute_tick`` on the mission's guidance
CPU, 50 Hz                     ``companion fly`` against sitl_mock: CPU time    <= 10 % of a core
                               over wall time, from /proc, flight loop only
peak RSS                       the same process's ``VmHWM`` (/proc, since its   <= 120 MB
                               ``exec``; ``ru_maxrss`` without /proc)
replay throughput              a synthetic one-hour 50 Hz flight log            >= 60,000 msg/s
                               (``companion.replay.synthetic``), read and
                               replayed; messages / (read + replay time)
predictive, mean per tick      every ``step`` of ``predictive`` on the paper    <= 0.3 ms
                               sine under the lag model (0.3 s, 5 m/s^2),
                               re-optimising or not
predictive, re-opt ticks p99   the steps that re-optimised                      <= 5 ms
loop latency p99, predictive   as the loop latency, on                          <= 2 ms
                               ``missions/racetrack_predictive.yaml``
=============================  ===============================================  ==============

Also reported: the simulation's real-time factor (simulated seconds per wall second, corrector on
the paper sine), the paper bench's wall time (``companion bench paper``'s table), and the steps
of the other laws (ApL1, NPFG, pure pursuit, predictive) for comparison.

``--quick`` shortens every measurement (fewer samples, a 1-minute synthetic log, one paper
heading, short latency and CPU windows) so CI can run it in well under a minute; its figures are
noisier and the loop-latency/CPU parts are skipped when the mock cannot start.
"""

from __future__ import annotations

import gc
import json
import math
import os
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from companion.errors import CompanionError

TARGETS = {
    "fixed_l1_step_us": ("<=", 50.0),
    "corrector_step_us": ("<=", 150.0),
    "reoptimisation_ms": ("<=", 20.0),
    "worst_tick_ms": ("<", 20.0),
    "loop_latency_p99_ms_50hz": ("<=", 2.0),
    "cpu_percent_50hz": ("<=", 10.0),
    "rss_mb": ("<=", 120.0),
    "replay_msgs_per_s": (">=", 60000.0),
    "predictive_tick_mean_ms": ("<=", 0.3),
    "predictive_reopt_p99_ms": ("<=", 5.0),
    "loop_latency_p99_ms_50hz_predictive": ("<=", 2.0),
}
MISSIONS_DIR = Path(__file__).resolve().parents[2] / "missions"


def _stats_us(samples_s: list[float]) -> dict:
    if not samples_s:
        return {"median": None, "p99": None, "n": 0}
    a = np.asarray(samples_s) * 1e6
    return {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)), "n": int(a.size)}


class _TimedLaw:
    """Wraps a law and records the wall time of every ``step`` (and whether it re-optimised)."""

    def __init__(self, law):
        self.law = law
        self.durations_s: list[float] = []
        self.reoptimised: list[bool] = []

    def step(self, t_s, state):
        t0 = time.perf_counter()
        out = self.law.step(t_s, state)
        self.durations_s.append(time.perf_counter() - t0)
        self.reoptimised.append(bool(out.reoptimised))
        return out


class _TimedOptimiser:
    """Wraps ``GainOptimiser`` to time ``optimise`` alone."""

    def __init__(self, inner):
        self.inner = inner
        self.durations_s: list[float] = []

    def optimise(self, *args, **kwargs):
        t0 = time.perf_counter()
        out = self.inner.optimise(*args, **kwargs)
        self.durations_s.append(time.perf_counter() - t0)
        return out

    def __getattr__(self, name):
        return getattr(self.inner, name)


def _paper_path(x_end_m: float):
    from companion.geometry.paths import function_path

    return function_path(lambda x: 10.0 * np.sin(0.078 * x) + 20.0 * np.cos(0.082 * x), (-15.0, x_end_m))


def measure_guidance(quick: bool) -> dict:
    """Per-step timings of every law over a simulated paper-sine flight, and the sim's speed."""
    from companion.guidance.two_phase import TwoPhaseGuidance
    from companion.guidance.types import GuidanceParams, VehicleState
    from companion.sim.simulator import LagModel, simulate

    path = _paper_path(60.0 if quick else 300.0)
    start = VehicleState(-15.0, 0.0, math.radians(39.118), 5.0)
    out: dict = {}
    for method in ("fixed_l1", "corrector"):
        params = GuidanceParams(method=method, l1_m=10.0, speed_m_s=5.0, rate_hz=50.0, midcourse_trigger="off")
        guidance = TwoPhaseGuidance(path, params)
        opt = None
        if getattr(guidance, "_optimiser", None) is not None:
            opt = guidance._optimiser = _TimedOptimiser(guidance._optimiser)
        timed = _TimedLaw(guidance)
        t0 = time.perf_counter()
        res = simulate(path, timed, start, params)
        wall = time.perf_counter() - t0
        steps = np.asarray(timed.durations_s)
        reopt = np.asarray(timed.reoptimised)
        if method == "fixed_l1":
            out["fixed_l1"] = _stats_us(steps.tolist())
        else:
            out["corrector"] = _stats_us(steps[~reopt].tolist())
            out["corrector_reopt"] = _stats_us(steps[reopt].tolist())
            out["reoptimisation_ms"] = {k: (v / 1e3 if k != "n" and v is not None else v)
                                        for k, v in _stats_us(opt.durations_s if opt else []).items()}
            out["worst_tick_ms"] = float(steps.max() * 1e3) if steps.size else None
            sim_s = float(res.t_s[-1]) if res.t_s.size else 0.0
            # Simulated seconds per wall second, the law included (as in a real sweep).
            out["sim_realtime_factor"] = sim_s / wall if wall > 0 else None
    lag = LagModel(0.3, 5.0)
    params = GuidanceParams(speed_m_s=5.0, rate_hz=50.0)
    short = _paper_path(30.0 if quick else 120.0)
    for name in ("ap_l1", "npfg", "pure_pursuit", "predictive"):
        timed = _TimedLaw(_rebuild(name, short))
        simulate(short, timed, start, params, model=lag)
        steps = np.asarray(timed.durations_s)
        reopt = np.asarray(timed.reoptimised)
        if name == "predictive":
            out["predictive"] = _stats_us(steps[~reopt].tolist())
            out["predictive_reopt"] = _stats_us(steps[reopt].tolist())
            # Every tick, re-optimising or not: what the law costs a companion computer.
            out["predictive_tick_mean_ms"] = float(steps.mean() * 1e3) if steps.size else None
        else:
            out[name] = _stats_us(steps.tolist())
    return out


def _rebuild(name: str, path):
    from companion.guidance.baselines import ApL1Guidance, NpfgGuidance, PurePursuitGuidance
    from companion.guidance.predictive import PredictiveGuidance, PredictiveParams

    if name == "ap_l1":
        return ApL1Guidance(path)
    if name == "npfg":
        return NpfgGuidance(path)
    if name == "pure_pursuit":
        return PurePursuitGuidance(path)
    return PredictiveGuidance(path, PredictiveParams(lag_s=0.3, a_max_m_s2=5.0))


def measure_paper_bench(quick: bool) -> float:
    from companion.bench.paper import run_table

    t0 = time.perf_counter()
    run_table(headings_index=(4,) if quick else None)
    return time.perf_counter() - t0


def measure_replay(quick: bool) -> dict:
    from companion.replay.replay import replay_log
    from companion.replay.synthetic import RACETRACK_MISSION, write_synthetic_flight

    duration = 60.0 if quick else 3600.0
    with tempfile.TemporaryDirectory() as tmp:
        tlog = Path(tmp) / "synthetic.tlog"
        info = write_synthetic_flight(tlog, RACETRACK_MISSION, duration, 50.0)
        result = replay_log(tlog, progress=False)
    total = result.timing_s["total_s"]
    return {"duration_s": duration, "messages": info["records"], "total_s": total,
            "msgs_per_s": info["records"] / total if total > 0 else None,
            "within_tolerance": bool(result.within_tolerance)}


# ----------------------------------------------------------------------------- the live loop
def _mission_file(names: tuple[str, ...] = ("paper_sine.yaml", "racetrack.yaml")) -> Path:
    for name in names:
        p = MISSIONS_DIR / name
        if p.exists():
            return p
    raise CompanionError(f"bench perf: no mission file in {MISSIONS_DIR} (expected {names[0]})")


#: The mission of the predictive law's loop latency (the rest of the bench flies the paper sine).
PREDICTIVE_MISSION = ("racetrack_predictive.yaml",)


def _start_mock(mission, port: int, extra: list[str] | None = None):
    from companion.io.mock_process import MockProcess, mock_start_args

    mock = MockProcess(["--autopilot", "px4", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
                        *mock_start_args(mission, 15.0), "--quiet", *(extra or [])])
    mock.start()
    return mock


def measure_loop_latency(rate_hz: float, duration_s: float, mission_names: tuple[str, ...] | None = None) -> dict:
    """Datagram readable -> setpoint sent, for every LOCAL_POSITION_NED the mock streams, the
    guidance being the mission's (the paper sine's corrector unless ``mission_names`` says)."""
    from companion.io.mock_process import free_udp_port
    from companion.io.link import MSG_ID_LOCAL_POSITION_NED, MavLink
    from companion.loop.driver import make_guidance
    from companion.loop.tick import TickConfig, compute_tick
    from companion.mission import load_mission

    mission = load_mission(str(_mission_file(mission_names) if mission_names else _mission_file()))
    port = free_udp_port()
    mock = _start_mock(mission, port)
    link = None
    try:
        link = MavLink(f"udpin:127.0.0.1:{port}")
        link.wait_heartbeat(10.0)
        link.request_message_interval(MSG_ID_LOCAL_POSITION_NED, rate_hz)
        guidance = make_guidance(mission, rate_hz)
        config = TickConfig(speed_m_s=mission.speed_m_s, rate_hz=rate_hz, altitude_m=mission.altitude_m)
        fd = link.fileno()
        latencies: list[float] = []
        seen = link.state.positions
        tick = 0
        t_first = None
        prev_course = mission.path.start_heading_rad
        prev_cmd = None
        gc.collect()
        gc.freeze()  # as the flight loop does before its first tick (``FlightRunner.run``)
        end = time.monotonic() + duration_s
        while time.monotonic() < end:
            link.heartbeat_if_due()
            ready, _, _ = select.select([fd], [], [], 0.05)
            if not ready:
                continue
            t_arrival = time.perf_counter()
            link.poll(0.0)
            if link.state.positions == seen:
                continue  # not a position (heartbeat, ack, attitude ...)
            seen = link.state.positions
            now = time.monotonic()
            t_first = now if t_first is None else t_first
            result = compute_tick(guidance, tick, now - t_first, link.state.position, 0.0, config,
                                  yaw_ned_rad=link.state.yaw_ned_rad, prev_course_rad=prev_course,
                                  prev_course_cmd_rad=prev_cmd)
            prev_course, prev_cmd = result.course_rad, result.course_cmd_rad
            link.send_setpoint(result.setpoint)
            latencies.append(time.perf_counter() - t_arrival)
            tick += 1
        a = np.asarray(latencies) * 1e3
        if a.size == 0:
            return {"p50": None, "p99": None, "n": 0, "stream_hz": 0.0}
        return {"p50": float(np.median(a)), "p99": float(np.percentile(a, 99)), "max": float(a.max()),
                "n": int(a.size), "stream_hz": a.size / duration_s}
    finally:
        gc.unfreeze()
        if link is not None:
            link.close()
        mock.stop()


def _proc_cpu_s(pid: int) -> float | None:
    """utime + stime of a process from /proc (Linux), seconds."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    ticks = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / ticks


def measure_fly_cpu(duration_s: float, warmup_s: float) -> dict:
    """``companion fly`` at 50 Hz against sitl_mock: CPU share of its flight loop and peak RSS."""
    from companion.io.mock_process import free_udp_port
    from companion.mission import load_mission

    mission_path = _mission_file()
    mission = load_mission(str(mission_path))
    port = free_udp_port()
    mock = _start_mock(mission, port)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [sys.executable, "-m", "companion", "fly", str(mission_path), "--connect",
                   f"udpin:127.0.0.1:{port}", "--rate-hz", "50", "--quiet",
                   "--max-duration-s", f"{warmup_s + duration_s + 5.0:g}", "--tlog", str(Path(tmp) / "perf.tlog")]
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            time.sleep(warmup_s)  # imports, pairing, stream requests, mode switch
            c0, w0 = _proc_cpu_s(proc.pid), time.monotonic()
            time.sleep(duration_s)
            c1, w1 = _proc_cpu_s(proc.pid), time.monotonic()
            peak_mb = _proc_peak_rss_mb(proc.pid)
            proc.terminate()
            _, status, usage = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(status)
            err = proc.stderr.read() if proc.stderr else ""
    finally:
        mock.stop()
    rss_mb = peak_mb if peak_mb is not None else usage.ru_maxrss / 1024.0
    if c0 is None or c1 is None:
        return {"cpu_percent": None, "rss_mb": rss_mb, "note": "no /proc: CPU share not measured",
                "stderr_tail": err[-300:]}
    return {"cpu_percent": 100.0 * (c1 - c0) / (w1 - w0), "rss_mb": rss_mb, "window_s": w1 - w0,
            "stderr_tail": err[-300:]}


def _proc_peak_rss_mb(pid: int) -> float | None:
    """Peak RSS of a running process since its ``exec`` (``VmHWM`` in /proc, Linux), MB.

    ``wait4``'s ``ru_maxrss`` counts the forked child before its ``exec`` too, that is a copy of
    this process's own memory: once the bench had built a ``predictive`` law (numba and LLVM,
    about 100 MB) it reported 219 MB for a flight that peaked at 116 MB."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None


# ----------------------------------------------------------------------------- report
def _check(name: str, value) -> str:
    if value is None:
        return "n/a"
    op, target = TARGETS[name]
    ok = {"<=": value <= target, "<": value < target, ">=": value >= target}[op]
    return "pass" if ok else "FAIL"


def collect(quick: bool, skip_live: bool = False) -> dict:
    g = measure_guidance(quick)
    result = {
        "guidance_step_us": {k: {"median": g[k]["median"], "p99": g[k]["p99"]}
                             for k in ("fixed_l1", "corrector", "corrector_reopt", "ap_l1", "npfg",
                                       "pure_pursuit", "predictive", "predictive_reopt")},
        "reoptimisation_ms": {"median": g["reoptimisation_ms"]["median"], "p99": g["reoptimisation_ms"]["p99"]},
        "worst_tick_ms": g["worst_tick_ms"],
        "sim_realtime_factor": g["sim_realtime_factor"],
        "predictive_tick_mean_ms": g["predictive_tick_mean_ms"],
        "predictive_reopt_p99_ms": (g["predictive_reopt"]["p99"] / 1e3
                                    if g["predictive_reopt"]["p99"] is not None else None),
    }
    notes = []
    if skip_live:
        result["loop_latency_ms"] = {key: {"p50": None, "p99": None} for key in ("50hz", "200hz", "50hz_predictive")}
        result["cpu_percent_50hz"] = None
        result["rss_mb"] = None
        notes.append("live loop skipped (--no-live)")
    else:
        lat_s = 4.0 if quick else 20.0
        lat = {}
        for key, rate, names in (("50hz", 50, None), ("200hz", 200, None),
                                 ("50hz_predictive", 50, PREDICTIVE_MISSION)):
            try:
                lat[key] = measure_loop_latency(float(rate), lat_s, names)
            except CompanionError as err:
                lat[key] = {"p50": None, "p99": None}
                notes.append(f"loop latency {key}: {err}")
        result["loop_latency_ms"] = lat
        try:
            cpu = measure_fly_cpu(5.0 if quick else 20.0, 6.0)
            result["cpu_percent_50hz"] = cpu["cpu_percent"]
            result["rss_mb"] = cpu["rss_mb"]
            if cpu.get("note"):
                notes.append(cpu["note"])
        except CompanionError as err:
            result["cpu_percent_50hz"] = None
            result["rss_mb"] = None
            notes.append(f"cpu/rss: {err}")
    result["paper_bench_s"] = measure_paper_bench(quick)
    rep = measure_replay(quick)
    result["replay_msgs_per_s"] = rep["msgs_per_s"]
    result["replay"] = rep
    result["quick"] = quick
    result["pass"] = {
        "fixed_l1_step_us": _check("fixed_l1_step_us", result["guidance_step_us"]["fixed_l1"]["median"]),
        "corrector_step_us": _check("corrector_step_us", result["guidance_step_us"]["corrector"]["median"]),
        "reoptimisation_ms": _check("reoptimisation_ms", result["reoptimisation_ms"]["median"]),
        "worst_tick_ms": _check("worst_tick_ms", result["worst_tick_ms"]),
        "loop_latency_p99_ms_50hz": _check("loop_latency_p99_ms_50hz", result["loop_latency_ms"]["50hz"].get("p99")),
        "cpu_percent_50hz": _check("cpu_percent_50hz", result["cpu_percent_50hz"]),
        "rss_mb": _check("rss_mb", result["rss_mb"]),
        "replay_msgs_per_s": _check("replay_msgs_per_s", result["replay_msgs_per_s"]),
        "predictive_tick_mean_ms": _check("predictive_tick_mean_ms", result["predictive_tick_mean_ms"]),
        "predictive_reopt_p99_ms": _check("predictive_reopt_p99_ms", result["predictive_reopt_p99_ms"]),
        "loop_latency_p99_ms_50hz_predictive": _check(
            "loop_latency_p99_ms_50hz_predictive", result["loop_latency_ms"]["50hz_predictive"].get("p99")),
    }
    result["notes"] = notes
    return result


def _ms(us):
    return None if us is None else us / 1e3


def _f(v, nd=1) -> str:
    return "-" if v is None else f"{v:,.{nd}f}"


def format_report(r: dict) -> str:
    g = r["guidance_step_us"]
    p = r["pass"]
    lat = r["loop_latency_ms"]
    lines = [f"{'figure':34s} {'median':>10s} {'p99':>10s}  {'target':>16s}  result",
             f"{'guidance step fixed-L1 (us)':34s} {_f(g['fixed_l1']['median']):>10s} {_f(g['fixed_l1']['p99']):>10s}  {'<= 50':>16s}  {p['fixed_l1_step_us']}",
             f"{'guidance step corrector (us)':34s} {_f(g['corrector']['median']):>10s} {_f(g['corrector']['p99']):>10s}  {'<= 150':>16s}  {p['corrector_step_us']}",
             f"{'guidance step corrector+reopt (us)':34s} {_f(g['corrector_reopt']['median']):>10s} {_f(g['corrector_reopt']['p99']):>10s}  {'':>16s}",
             f"{'re-optimisation (ms)':34s} {_f(r['reoptimisation_ms']['median'], 2):>10s} {_f(r['reoptimisation_ms']['p99'], 2):>10s}  {'<= 20':>16s}  {p['reoptimisation_ms']}",
             f"{'worst tick (ms)':34s} {_f(r['worst_tick_ms'], 2):>10s} {'':>10s}  {'< 20 (1 tick)':>16s}  {p['worst_tick_ms']}",
             f"{'loop latency 50 Hz (ms)':34s} {_f(lat['50hz'].get('p50'), 3):>10s} {_f(lat['50hz'].get('p99'), 3):>10s}  {'p99 <= 2':>16s}  {p['loop_latency_p99_ms_50hz']}",
             f"{'loop latency 200 Hz (ms)':34s} {_f(lat['200hz'].get('p50'), 3):>10s} {_f(lat['200hz'].get('p99'), 3):>10s}  {'':>16s}",
             f"{'loop latency 50 Hz predictive (ms)':34s} {_f(lat['50hz_predictive'].get('p50'), 3):>10s} {_f(lat['50hz_predictive'].get('p99'), 3):>10s}  {'p99 <= 2':>16s}  {p['loop_latency_p99_ms_50hz_predictive']}",
             f"{'predictive, mean per tick (ms)':34s} {_f(r['predictive_tick_mean_ms'], 3):>10s} {'':>10s}  {'<= 0.3':>16s}  {p['predictive_tick_mean_ms']}",
             f"{'predictive, re-opt ticks (ms)':34s} {_f(_ms(g['predictive_reopt']['median']), 2):>10s} {_f(r['predictive_reopt_p99_ms'], 2):>10s}  {'p99 <= 5':>16s}  {p['predictive_reopt_p99_ms']}",
             f"{'CPU at 50 Hz (% of one core)':34s} {_f(r['cpu_percent_50hz']):>10s} {'':>10s}  {'<= 10':>16s}  {p['cpu_percent_50hz']}",
             f"{'peak RSS (MB)':34s} {_f(r['rss_mb']):>10s} {'':>10s}  {'<= 120':>16s}  {p['rss_mb']}",
             f"{'replay (messages/s)':34s} {_f(r['replay_msgs_per_s'], 0):>10s} {'':>10s}  {'>= 60,000':>16s}  {p['replay_msgs_per_s']}",
             f"{'simulation real-time factor':34s} {_f(r['sim_realtime_factor']):>10s}",
             f"{'paper bench wall time (s)':34s} {_f(r['paper_bench_s']):>10s}",
             "",
             "other laws, one step (us, lag model):"]
    for name in ("ap_l1", "npfg", "pure_pursuit", "predictive", "predictive_reopt"):
        lines.append(f"  {name:32s} {_f(g[name]['median']):>10s} {_f(g[name]['p99']):>10s}")
    if r.get("quick"):
        lines.append("\n(--quick: short measurements, noisier figures)")
    for n in r.get("notes", []):
        lines.append(f"note: {n}")
    return "\n".join(lines)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "perf", help="guidance step cost, loop latency, CPU, RSS, simulation and replay speed",
        description="Measure the guidance step and re-optimisation cost, the closed-loop latency over "
                    "loopback UDP with the mock autopilot, CPU and memory at 50 Hz, and the offline "
                    "simulation and replay throughput, each beside its target.")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--quick", action="store_true", help="short measurements for CI")
    parser.add_argument("--no-live", action="store_true", help="skip the parts that need the mock autopilot")
    parser.set_defaults(func=run)


def run(args) -> int:
    r = collect(args.quick, skip_live=args.no_live)
    if args.json:
        print(json.dumps(r, allow_nan=False))
    else:
        print(format_report(r))
    return 0
