"""Figures: the one flight plot every command draws, and the matplotlib plumbing around it.

``companion sim --plot``, ``companion demo`` / ``fly`` and ``companion replay --plot`` all show a
flight the same way (:func:`flight_figure`): the path against the track in the local ENU frame,
then the cross-track error and the lateral-acceleration command over time with the guidance
phases shaded. matplotlib is an optional dependency (``pip install 'companion[plot]'``): it is
imported only when a plot is asked for, with the file-writing ``Agg`` backend.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from companion.errors import CompanionError

PHASE_COLOURS = {
    "midcourse": "#fde2b8",
    "close_range": "#d4ecd4",
    "finished": "#dddddd",
    "hold": "#f6c6c6",
}


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend, or a one-line error naming the install extra."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise CompanionError("no plot written: plots need matplotlib, the 'plot' extra "
                             "(pip install 'companion[plot]')") from None
    return plt


def save_figure(fig, out_path: str | Path) -> Path:
    """Write ``fig`` (format from the suffix), creating the folder; always closes the figure."""
    out = Path(out_path)
    plt = pyplot()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=110)
    except OSError as err:
        raise CompanionError(f"{out}: cannot write the plot ({err.strerror or err})") from None
    finally:
        plt.close(fig)
    return out


def phase_spans(t_s: Sequence[float], phases: Sequence[str]) -> list[tuple[float, float, str]]:
    """Runs of equal phase as ``(t_start_s, t_end_s, name)``; a run ends where the next starts.

    >>> phase_spans([0.0, 1.0, 2.0, 3.0], ["midcourse", "midcourse", "close_range", "close_range"])
    [(0.0, 2.0, 'midcourse'), (2.0, 3.0, 'close_range')]
    """
    t = np.asarray(t_s, dtype=float)
    names = list(phases)
    if len(names) != t.size:
        raise ValueError(f"phases ({len(names)}) and times ({t.size}) differ in length")
    spans = []
    start = 0
    for i in range(1, len(names) + 1):
        if i == len(names) or names[i] != names[start]:
            end = t[i] if i < len(names) else t[-1]
            spans.append((float(t[start]), float(end), str(names[start])))
            start = i
    return spans


def flight_figure(
    path,
    t_s: Sequence[float],
    x_m: Sequence[float],
    y_m: Sequence[float],
    crosstrack_m: Sequence[float],
    a_cmd_m_s2: Sequence[float],
    phases: Sequence[str],
    title: str,
    *,
    a_compare: tuple[str, Sequence[float]] | None = None,
    mark_t_s: tuple[str, float] | None = None,
    track_label: str = "flown track",
    altitude: tuple | None = None,
):
    """The flight plot: path vs track (ENU), cross-track error and a_cmd over time, phases shaded.

    Parameters
    ----------
    path : the mission's :class:`companion.geometry.paths.Path` (None to draw the track only).
    t_s, x_m, y_m, crosstrack_m, a_cmd_m_s2, phases : one entry per guidance tick.
    title : figure title.
    a_compare : optional ``(label, series)`` drawn dashed over a_cmd (replay: the re-computed command).
    mark_t_s : optional ``(label, t_s)`` marked by a vertical line on both time panels.
    altitude : optional ``(profile, s_m, alt_m)`` for a mission with an altitude / speed profile:
        a panel below the path with the profile's height (and speed) along the arc length and the
        flown heights at each tick's projection ``s_m``. Without it the figure is the 2-D one.

    Returns the matplotlib figure; write it with :func:`save_figure`.
    """
    plt = pyplot()
    t = np.asarray(t_s, dtype=float)
    fig = plt.figure(figsize=(12, 7) if altitude is None else (12, 9.5))
    ax_xy = fig.add_subplot(1, 2, 1) if altitude is None else fig.add_subplot(3, 2, (1, 3))
    _track_panel(ax_xy, path, np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float), title,
                 track_label)
    if altitude is None:
        ax_d = fig.add_subplot(2, 2, 2)
        ax_a = fig.add_subplot(2, 2, 4, sharex=ax_d)
    else:
        ax_d = fig.add_subplot(3, 2, (2, 4))
        ax_a = fig.add_subplot(3, 2, 6, sharex=ax_d)
        profile, s_m, alt_m = altitude
        profile_panel(fig.add_subplot(3, 2, 5), profile, s_m, alt_m)
    if t.size:
        _shade_phases((ax_d, ax_a), t, phases)
    ax_d.plot(t, np.asarray(crosstrack_m, dtype=float), "b-", lw=1)
    ax_d.set_ylabel("cross-track error (m, left +)")
    ax_a.plot(t, np.asarray(a_cmd_m_s2, dtype=float), "r-", lw=1.2, label="a_cmd")
    if a_compare is not None:
        label, series = a_compare
        ax_a.plot(t, np.asarray(series, dtype=float), "k--", lw=1, label=label)
    if mark_t_s is not None:
        label, when = mark_t_s
        for ax in (ax_d, ax_a):
            ax.axvline(when, color="tab:red", lw=1, ls=":")
        ax_a.annotate(label, (when, 0.0), color="tab:red", fontsize=8)
    ax_a.set_ylabel("a_cmd (m/s², left +)")
    ax_a.set_xlabel("t (s)")
    ax_d.legend(loc="best", fontsize=8)
    if a_compare is not None:
        ax_a.legend(loc="best", fontsize=8)
    for ax in (ax_d, ax_a):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def _track_panel(ax_xy, path, x: np.ndarray, y: np.ndarray, title: str, track_label: str) -> None:
    """The path (when given) and the track in the ENU plane, the start marked."""
    if path is not None:
        _, px, py = path.sample(1000)
        ax_xy.plot(px, py, "k--", lw=1, label="path")
    ax_xy.plot(x, y, "b-", lw=1.5, label=track_label)
    if x.size:
        ax_xy.plot(x[0], y[0], "go", label="start")
    ax_xy.set_xlabel("x east (m)")
    ax_xy.set_ylabel("y north (m)")
    ax_xy.set_aspect("equal", adjustable="datalim")
    ax_xy.legend(loc="best", fontsize=8)
    ax_xy.set_title(title, fontsize=10)


def _shade_phases(axes, t: np.ndarray, phases: Sequence[str]) -> None:
    """Each guidance phase shaded on the time panels; its name in the first panel's legend once."""
    seen: set[str] = set()
    for t0, t1, name in phase_spans(t, phases):
        for ax in axes:
            ax.axvspan(t0, t1, color=PHASE_COLOURS.get(name, "#eeeeee"), lw=0,
                       label=name if (ax is axes[0] and name not in seen) else None)
        seen.add(name)


def profile_panel(ax, profile, s_m: Sequence[float] | None = None, alt_m: Sequence[float] | None = None):
    """Altitude along the path (and the speed on a second axis): the profile's tables, the flown
    heights at their projections when given. ``profile`` is a
    :class:`companion.geometry.profile.PathProfile`."""
    ax.plot(profile.s_m, profile.alt_m, "k-", lw=1.2, label="altitude profile h(s)")
    if s_m is not None and alt_m is not None:
        ax.plot(np.asarray(s_m, dtype=float), np.asarray(alt_m, dtype=float), "b.", ms=1.5,
                label="flown altitude")
    ax.set_xlabel("arc length s (m)")
    ax.set_ylabel("altitude (m)")
    ax.grid(True, alpha=0.3)
    ax_v = ax.twinx()
    ax_v.plot(profile.s_m, profile.speed_m_s_table, "-", color="tab:orange", lw=1,
              label="speed V(s), m/s (right axis)")
    ax_v.tick_params(axis="y", colors="tab:orange")
    lines = ax.get_legend_handles_labels()
    more = ax_v.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], loc="best", fontsize=8)
    return ax
