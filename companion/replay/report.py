"""Text report and CSV of a :class:`companion.replay.replay.ReplayResult`."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from companion.errors import LogError

CSV_COLUMNS = (
    "t_s", "tick", "phase_logged", "phase_replayed", "x_enu_m", "y_enu_m", "crosstrack_m",
    "a_logged_m_s2", "a_replayed_m_s2", "yaw_rate_logged_rad_s", "yaw_rate_replayed_rad_s",
    "vx_logged_m_s", "vy_logged_m_s", "vz_logged_m_s", "vx_replayed_m_s", "vy_replayed_m_s",
    "vz_replayed_m_s", "k1_logged", "k1_replayed", "k2_logged", "k2_replayed",
    "yaw_rate_diff_rad_s", "vel_diff_m_s", "roll_logged_rad", "roll_replayed_rad", "attitude_diff_rad",
    "compared",
)


def json_safe(value):
    """Copy of ``value`` with non-finite floats as None (JSON has no NaN) and numpy scalars as Python."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def _f(value, digits: int = 4, width: int = 10) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return f"{'-':>{width}}"
    if isinstance(value, str):
        return f"{value:>{width}}"
    return f"{value:>{width}.{digits}f}"


def format_report(result) -> str:
    """Human-readable replay report."""
    j = json_safe(result.to_json())
    tol = j["tolerance"]
    kind = ("companion guidance records" if j["kind"] == "companion"
            else "setpoints of another controller, paired with the newest position")
    lines = [
        f"replay of {j['file']} ({kind}); mission {j['mission']}",
        f"steps compared: {j['steps_compared']} of {j['ticks']} ticks",
    ]
    lines += [f"note: {n}" for n in j["notes"]]
    if j["warnings"]:
        lines.append(f"log damage: {len(j['warnings'])} unreadable stretches (see warnings above)")
    verdict = "WITHIN tolerance" if j["within_tolerance"] else "NOT within tolerance"
    attitude = any("attitude_max_rad" in p for p in j["per_phase"].values())
    lines += [
        f"tolerance: yaw rate {tol['yaw_rate_rad_s']} rad/s, velocity {tol['vel_m_s']} m/s, "
        f"attitude {tol['attitude_rad']} rad -> {verdict}",
        "",
        "difference logged vs replayed, per " + ("logged" if j["kind"] == "companion" else "replayed") + " phase:",
        f"  {'phase':<12} {'steps':>7} {'yaw max':>10} {'yaw rms':>10} {'vel max':>10} {'vel rms':>10}"
        + (f" {'att max':>10} {'att rms':>10}" if attitude else ""),
        f"  {'':<12} {'':>7} {'rad/s':>10} {'rad/s':>10} {'m/s':>10} {'m/s':>10}"
        + (f" {'rad':>10} {'rad':>10}" if attitude else ""),
    ]
    for name, p in j["per_phase"].items():
        line = (f"  {name:<12} {p['steps']:>7} {_f(p['yaw_rate_max_rad_s'])} {_f(p['yaw_rate_rms_rad_s'])} "
                f"{_f(p['vel_max_m_s'])} {_f(p['vel_rms_m_s'])}")
        if attitude:
            line += f" {_f(p.get('attitude_max_rad'))} {_f(p.get('attitude_rms_rad'))}"
        lines.append(line)
    fd = j["first_divergence"]
    lines.append("")
    if fd is None:
        lines.append("first divergence: none")
    else:
        where = f"coasting setpoint after tick {fd['tick']}" if fd.get("coast") else f"tick {fd['tick']}"
        att = fd["attitude_diff_rad"]
        lines.append(f"first divergence: {where} at t = {fd['time_s']:.3f} s "
                     f"({', '.join(fd['reasons'])}; yaw-rate diff {_f(fd['yaw_rate_diff_rad_s'], 5, 1).strip()} "
                     f"rad/s, velocity diff {_f(fd['vel_diff_m_s'], 4, 1).strip()} m/s"
                     + (f", attitude diff {att:.5f} rad" if att is not None else "") + ")")
        lines.append(f"  {'':<16} {'logged':>12} {'replayed':>12}")
        for key in ("vx_m_s", "vy_m_s", "vz_m_s", "yaw_rate_rad_s", "roll_rad", "a_cmd_m_s2", "phase", "k1", "k2"):
            if fd["logged"].get(key) is not None or fd["replayed"].get(key) is not None:
                lines.append(f"  {key:<16} {_f(fd['logged'].get(key), 5, 12)} {_f(fd['replayed'].get(key), 5, 12)}")
    lines += ["", "phase switches (tick time, s):"]
    for side in ("logged", "replayed"):
        sw = j["phase_switches"][side]
        if side == "logged" and j["kind"] != "companion":
            text = "(not recorded by this log)"
        else:
            text = ", ".join(f"{s['from']} -> {s['to']} at {s['time_s']:.3f}" for s in sw) or "none"
        lines.append(f"  {side:<9} {text}")
    lines += [
        "",
        "flight tracking (logged): d_rms_m {0} d_max_m {1} a_rms_m_s2 {2} a_max_m_s2 {3} duration_s {4}".format(
            *(_f(j[k], 3, 1).strip() for k in ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "duration_s"))),
    ]
    for name, m in j["phases"].items():
        lines.append(f"  {name:<12} d_rms_m {_f(m['d_rms_m'], 3, 7)}  a_rms_m_s2 {_f(m['a_rms_m_s2'], 3, 7)}  "
                     f"a_max_m_s2 {_f(m['a_max_m_s2'], 3, 7)}  samples {m['samples']}")
    return "\n".join(lines)


def write_csv(result, path: str | Path) -> None:
    """One row per tick with :data:`CSV_COLUMNS` (empty cells where a value does not apply)."""
    s = result.series
    n = s["t_s"].size
    try:
        with open(path, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(CSV_COLUMNS)
            for i in range(n):
                row = []
                for col in CSV_COLUMNS:
                    v = s[col][i]
                    if col in ("tick",):
                        row.append(int(v))
                    elif col == "compared":
                        row.append(int(bool(v)))
                    elif isinstance(v, str):
                        row.append(v)
                    else:
                        row.append(repr(float(v)) if math.isfinite(v) else "")
                writer.writerow(row)
    except OSError as err:
        raise LogError(f"{path}: cannot write the CSV ({err.strerror or err})") from err
