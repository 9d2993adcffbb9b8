"""``companion replay --plot``: the flight plot with a_cmd logged vs replayed.

Phases shaded are the logged ones on companion logs, the replayed ones otherwise; the first tick
beyond tolerance is marked. Drawn by the shared :func:`companion.plots.flight_figure`.
"""

from __future__ import annotations

from pathlib import Path

from companion.plots import flight_figure, save_figure


def plot_replay(result, out_path: str | Path) -> Path:
    """Write the replay figure to ``out_path`` (PNG, PDF or SVG by its suffix)."""
    s = result.series
    phases = s["phase_logged"] if result.flight.kind == "companion" else s["phase_replayed"]
    verdict = "within tolerance" if result.within_tolerance else "NOT within tolerance"
    fd = result.first_divergence
    fig = flight_figure(
        result.mission_path, s["t_s"], s["x_enu_m"], s["y_enu_m"], s["crosstrack_m"],
        s["a_logged_m_s2"], list(phases), f"{Path(result.flight.path).name}: {verdict}",
        a_compare=("a_cmd replayed", s["a_replayed_m_s2"]),
        mark_t_s=None if fd is None else ("first divergence", fd["time_s"]),
        track_label="logged track",
        altitude=(None if getattr(result, "mission_profile", None) is None
                  else (result.mission_profile, s["s_proj_m"], s["alt_m"])),
    )
    return save_figure(fig, out_path)
