"""The shared flight plot: phase runs, shading and the one-line error on an unwritable file."""

from __future__ import annotations

import pytest

from companion.errors import CompanionError
from companion.geometry.paths import function_path
from companion.plots import flight_figure, phase_spans, save_figure


def test_phase_runs_end_where_the_next_phase_starts():
    t = [0.0, 0.5, 1.0, 1.5, 2.0]
    phases = ["midcourse", "midcourse", "close_range", "hold", "close_range"]
    assert phase_spans(t, phases) == [
        (0.0, 1.0, "midcourse"), (1.0, 1.5, "close_range"), (1.5, 2.0, "hold"), (2.0, 2.0, "close_range")]


def test_phase_runs_reject_series_of_different_lengths():
    with pytest.raises(ValueError):
        phase_spans([0.0, 1.0], ["midcourse"])


def test_flight_figure_shades_each_phase_on_both_time_panels_and_writes_a_png(tmp_path):
    path = function_path(lambda x: 0.0 * x, (0.0, 50.0))
    t = [0.0, 1.0, 2.0, 3.0]
    fig = flight_figure(path, t, [0, 5, 10, 15], [3, 2, 1, 0], [3, 2, 1, 0], [0.5, 0.4, 0.1, 0.0],
                        ["midcourse", "midcourse", "close_range", "close_range"], "line",
                        a_compare=("replayed", [0.5, 0.4, 0.1, 0.0]), mark_t_s=("here", 2.0))
    _, ax_d, ax_a = fig.axes
    # Two phase runs -> two shaded spans on each time panel, spanning [0, 2] and [2, 3].
    for ax in (ax_d, ax_a):
        spans = sorted((p.get_x(), p.get_x() + p.get_width()) for p in ax.patches)
        assert spans == [(0.0, 2.0), (2.0, 3.0)]
    out = save_figure(fig, tmp_path / "sub" / "flight.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unwritable_plot_path_is_one_line_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    fig = flight_figure(None, [0.0], [0.0], [0.0], [0.0], [0.0], ["close_range"], "t")
    with pytest.raises(CompanionError) as err:
        save_figure(fig, blocker / "x.png")
    assert "cannot write the plot" in str(err.value) and "\n" not in str(err.value)
