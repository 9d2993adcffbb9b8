"""What sim, demo and fly print: one metrics table and its names, plots on a core install."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from companion.cli.fly import format_metrics_table
from companion.cli.main import main
from companion.sim.metrics import tracking_metrics

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
NO_PLOT_LINE = ("no plot written: plots need matplotlib, the 'plot' extra "
                "(pip install 'companion[plot]')")


@pytest.fixture
def no_matplotlib(monkeypatch):
    """A core install: importing matplotlib fails."""
    for name in list(sys.modules):
        if name == "matplotlib" or name.startswith("matplotlib."):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)


def table_rows(text):
    return [line.split()[0] for line in text.splitlines()[1:]]


def test_sim_fly_and_demo_share_one_table_whose_first_row_is_overall(capsys):
    m = tracking_metrics([0.0, 1.0, 2.0], [1.0, 2.0, 2.0], [0.5, 0.0, 0.0],
                         ["midcourse", "close_range", "close_range"])
    assert table_rows(format_metrics_table(m)) == ["overall", "midcourse", "close_range"]
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--t-max-s", "3"])
    out = capsys.readouterr().out
    assert code == 0
    i = next(k for k, line in enumerate(out.splitlines()) if line.startswith("phase"))
    assert "\n".join(out.splitlines()[i:]) == format_metrics_table(
        json.loads(_sim_json(capsys)))


def _sim_json(capsys):
    assert main(["sim", str(MISSIONS / "paper_sine.yaml"), "--t-max-s", "3", "--json"]) == 0
    return capsys.readouterr().out


def test_sim_plot_on_a_core_install_prints_the_figures_then_one_line(no_matplotlib, tmp_path, capsys):
    png = tmp_path / "x.png"
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--t-max-s", "3", "--plot", str(png)])
    out, err = capsys.readouterr()
    assert code == 2
    assert "overall" in out and "d_rms_m" in out  # the figures are not lost
    assert err.strip() == f"companion: error: {NO_PLOT_LINE}"
    assert not png.exists()


def test_sim_json_plot_on_a_core_install_prints_the_json_first(no_matplotlib, tmp_path, capsys):
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--t-max-s", "3", "--json",
                 "--plot", str(tmp_path / "x.png")])
    out, err = capsys.readouterr()
    assert code == 2 and "d_rms_m" in json.loads(out)
    assert err.strip() == f"companion: error: {NO_PLOT_LINE}"


class _FakeMock:
    def __init__(self, args):
        pass

    def start(self):
        pass

    def stop(self):
        pass


class _FakeRunner:
    """Stands in for the flight: a finished flight with a short record."""

    def __init__(self, mission, options, status):
        self.tlog_path = Path(options.tlog_path)
        self.record = SimpleNamespace(t_s=[0.0, 1.0], x_m=[0.0, 5.0], y_m=[0.0, 0.0],
                                      crosstrack_m=[0.1, 0.2], a_cmd_m_s2=[0.0, 0.1],
                                      phase=["close_range", "close_range"])
        m = tracking_metrics(self.record.t_s, self.record.crosstrack_m, self.record.a_cmd_m_s2,
                             self.record.phase)
        self.summary = dict(m, ticks=2, tlog=str(self.tlog_path))

    def run(self):
        return self.summary


@pytest.fixture
def fake_flight(monkeypatch):
    import companion.cli.demo as demo
    import companion.loop.runner as runner

    monkeypatch.setattr(demo, "MockProcess", _FakeMock)
    monkeypatch.setattr(runner, "FlightRunner", _FakeRunner)


def test_demo_on_a_core_install_prints_the_figures_and_names_the_extra(no_matplotlib, fake_flight,
                                                                      tmp_path, capsys):
    code = main(["demo", "--tlog", str(tmp_path / "d.tlog"), "--quiet"])
    out, err = capsys.readouterr()
    assert code == 0  # the flight worked; only the default plot is missing
    assert "overall" in out and f"tlog: {tmp_path / 'd.tlog'}" in out
    assert err.strip() == f"companion: {NO_PLOT_LINE} (or pass --no-plot)"
    code = main(["demo", "--tlog", str(tmp_path / "e.tlog"), "--quiet", "--plot", str(tmp_path / "p.png")])
    out, err = capsys.readouterr()
    assert code == 2 and "overall" in out  # a plot asked for by name: exit 2, figures kept
    assert err.strip() == f"companion: error: {NO_PLOT_LINE}"


def test_long_sim_shows_progress_on_a_terminal(monkeypatch, capsys):
    pytest.importorskip("tqdm")
    import io

    import companion.replay.progress as progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(sys, "stderr", term)
    code = main(["sim", str(MISSIONS / "paper_sine.yaml"), "--t-max-s", "10"])
    assert code == 0
    text = term.getvalue()
    assert "sim paper-sine" in text and "/10.0 [" in text  # simulated seconds of the 10 s limit
    assert "overall" in capsys.readouterr().out


def test_sim_on_a_pipe_shows_no_progress(capsys):
    assert main(["sim", str(MISSIONS / "paper_sine.yaml"), "--t-max-s", "3"]) == 0
    assert capsys.readouterr().err == ""


class _InterruptedRunner(_FakeRunner):
    """A flight stopped by Ctrl-C: the runner summarises the flight so far, then re-raises."""

    def run(self):
        raise KeyboardInterrupt


@pytest.mark.parametrize("command", ["fly", "demo"])
def test_ctrl_c_prints_the_metrics_so_far_then_exits_130(monkeypatch, tmp_path, capsys, command):
    import companion.cli.demo as demo
    import companion.loop.runner as runner

    monkeypatch.setattr(runner, "FlightRunner", _InterruptedRunner)
    monkeypatch.setattr(demo, "MockProcess", _FakeMock)
    argv = {"fly": ["fly", str(MISSIONS / "racetrack.yaml"), "--connect", "udpin:127.0.0.1:9"],
            "demo": ["demo", "--no-plot"]}[command]
    assert main(argv + ["--tlog", str(tmp_path / "i.tlog"), "--quiet"]) == 130
    out, err = capsys.readouterr()
    assert table_rows(out.split("\nloop:")[0]) == ["overall", "close_range"]
    assert f"tlog: {tmp_path / 'i.tlog'}" in out
    assert err.strip() == "companion: interrupted"
    assert main(argv + ["--tlog", str(tmp_path / "j.tlog"), "--quiet", "--json"]) == 130
    out = json.loads(capsys.readouterr().out)
    assert out["error"] == "interrupted (Ctrl-C)" and out["samples"] == 2
