"""``companion replay --plot``: path vs track, cross-track error, a_cmd logged vs replayed.

Three panels, phases shaded in the two time panels (logged phases on companion logs, replayed
phases otherwise). matplotlib is an optional dependency (``pip install companion[plot]``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from companion.errors import CompanionError, LogError

PHASE_COLOURS = {"midcourse": "#f4d03f", "close_range": "#aed6f1", "finished": "#d5dbdb",
                 "hold": "#f5b7b1", "unknown": "#ffffff"}


def _segments(t_s: np.ndarray, phases) -> list[tuple[float, float, str]]:
    out = []
    start = 0
    for i in range(1, len(phases) + 1):
        if i == len(phases) or phases[i] != phases[start]:
            end_t = t_s[i] if i < len(phases) else t_s[-1]
            out.append((float(t_s[start]), float(end_t), str(phases[start])))
            start = i
    return out


def plot_replay(result, out_path: str | Path, path_samples: int = 1000) -> None:
    """Write the replay figure to ``out_path`` (PNG, PDF or SVG by its suffix)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as err:
        raise CompanionError("--plot needs matplotlib (pip install companion[plot])") from err

    s = result.series
    t = s["t_s"]
    phases = s["phase_logged"] if result.flight.kind == "companion" else s["phase_replayed"]
    fig, (ax_xy, ax_d, ax_a) = plt.subplots(3, 1, figsize=(9, 12), constrained_layout=True,
                                           gridspec_kw={"height_ratios": [2, 1, 1]})
    mission_path = result.mission_path
    if mission_path is not None:
        _, px, py = mission_path.sample(path_samples)
        ax_xy.plot(px, py, "k--", lw=1, label="mission path")
    ax_xy.plot(s["x_enu_m"], s["y_enu_m"], "C0", lw=1.5, label="logged track")
    ax_xy.set_xlabel("x east (m)")
    ax_xy.set_ylabel("y north (m)")
    ax_xy.set_aspect("equal", adjustable="datalim")
    ax_xy.legend(loc="best")
    ax_xy.set_title(f"{Path(result.flight.path).name}: "
                    + ("within tolerance" if result.within_tolerance else "NOT within tolerance"))

    ax_d.plot(t, s["crosstrack_m"], "C0", lw=1)
    ax_d.set_ylabel("cross-track error (m, left +)")
    ax_a.plot(t, s["a_logged_m_s2"], "C0", lw=1.5, label="a_cmd logged")
    ax_a.plot(t, s["a_replayed_m_s2"], "C3", lw=1, ls="--", label="a_cmd replayed")
    ax_a.set_ylabel("lateral acceleration (m/s², left +)")
    ax_a.set_xlabel("tick time (s)")
    fd = result.first_divergence
    if fd is not None:
        for ax in (ax_d, ax_a):
            ax.axvline(fd["time_s"], color="C3", lw=1, ls=":")
        ax_a.annotate("first divergence", (fd["time_s"], 0), color="C3", fontsize=8)
    seen = set()
    for t0, t1, name in _segments(t, phases):
        for ax in (ax_d, ax_a):
            ax.axvspan(t0, t1, color=PHASE_COLOURS.get(name, "#eeeeee"), alpha=0.5, lw=0,
                       label=name if (ax is ax_d and name not in seen) else None)
        seen.add(name)
    ax_d.legend(loc="best", fontsize=8)
    ax_a.legend(loc="best", fontsize=8)
    for ax in (ax_d, ax_a):
        ax.grid(True, alpha=0.3)
    try:
        fig.savefig(out_path, dpi=110)
    except OSError as err:
        raise LogError(f"{out_path}: cannot write the plot ({err.strerror or err})") from err
    finally:
        plt.close(fig)
