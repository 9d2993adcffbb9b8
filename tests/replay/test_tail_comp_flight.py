"""A copter whose velocity loop has PX4's slow tail, flown by the loop with and without the
compensation, and copters whose tail is not the one compensated.

Compensated, the tail's vehicle must fly the racetrack as the same vehicle without a tail does
(a first-order loop of the same lag): the invariant of companion.guidance.tail_comp. Not
compensated, it flies its turns wide. Replay rebuilds the compensation from the logged samples.
"""

from __future__ import annotations

import numpy as np
import pytest

from companion.replay.flightlog import read_flight, recorded_tail
from companion.replay.replay import replay_log
from companion.replay.synthetic import RACETRACK_MISSION, write_synthetic_flight

PURE_PURSUIT = RACETRACK_MISSION.replace("method: corrector", "method: pure_pursuit")
TAIL = (0.857, 0.958)  # PX4 SIH's
LAG_S = 0.437


def _fly(tmp_path, name: str, **kw) -> tuple[np.ndarray, list]:
    path = tmp_path / f"{name}.tlog"
    write_synthetic_flight(path, mission=PURE_PURSUIT, duration_s=45.0, start_offset_m=(0.0, 0.0),
                           vehicle_lag_s=LAG_S, **kw)
    ticks = [tk for tk in read_flight(path).ticks if tk.debug is not None]
    return np.array([tk.debug_value("crosstrack_m") for tk in ticks]), ticks


def test_the_compensated_tail_flies_as_a_first_order_loop_and_replays(tmp_path):
    assert "method: pure_pursuit" in PURE_PURSUIT
    first_order, _ = _fly(tmp_path, "no-tail")
    tail, ticks_tail = _fly(tmp_path, "tail", vehicle_tail=TAIL)
    comp, ticks_comp = _fly(tmp_path, "comp", vehicle_tail=TAIL, compensated_tail=TAIL)
    n = min(len(first_order), len(tail), len(comp))
    rms = lambda d: float(np.sqrt(np.mean(d[:n] ** 2)))  # noqa: E731
    # the tail's vehicle, not compensated, flies the turns wide; compensated, as the tail-less one
    assert rms(tail - first_order) > 0.2 * rms(first_order)
    assert rms(comp - first_order) < 0.05 * rms(first_order)
    assert rms(comp) < rms(tail)
    assert recorded_tail(ticks_tail) == (0.0, 0.0)
    assert recorded_tail(ticks_comp) == pytest.approx(TAIL)
    n_comp = np.array([tk.debug_value("tail_comp_n_m_s") for tk in ticks_comp])
    assert np.all(np.isfinite(n_comp[5:])) and np.max(np.abs(n_comp)) > 0.05
    j = replay_log(tmp_path / "comp.tlog").to_json()
    assert j["within_tolerance"] is True and j["first_divergence"] is None


@pytest.mark.parametrize("vehicle_tail", [(0.0, 1.0), (0.857, 2 * 0.958), (0.857, 0.958 / 2)],
                         ids=["no tail", "tail twice as slow", "tail twice as fast"])
def test_a_tail_compensated_wrongly_stays_stable(tmp_path, vehicle_tail):
    """Compensating PX4's tail on a vehicle whose loop differs. With no tail at all the loop is
    ``v' = (c0 + s f - v) / lag``, ``f' = (c0 + s f - v - f) / tc``: its determinant is
    ``1 / (lag tc)`` > 0 and its trace negative, stable for every share, and ``f`` -> 0. Flown:
    no limit cycle, settled on the straight, and at most twice the error of the same vehicle not
    compensated (1.6 times with no tail: the compensation then leads the loop); with a tail of
    another time it still helps."""
    plain, _ = _fly(tmp_path, "plain", vehicle_tail=vehicle_tail)
    comp, _ = _fly(tmp_path, "wrong", vehicle_tail=vehicle_tail, compensated_tail=TAIL)
    rms = lambda d: float(np.sqrt(np.mean(d ** 2)))  # noqa: E731
    assert np.all(np.isfinite(comp))
    assert rms(comp) <= 2.0 * rms(plain)
    last = comp[-500:]  # the last 10 s: on the racetrack's straight, settled
    assert np.max(np.abs(last)) < 0.1
    if vehicle_tail[0] > 0:
        assert rms(comp) < rms(plain)


def test_predictive_flies_the_tail_compensated_lambda_unless_the_mission_states_one(tmp_path):
    """A flight that compensates the tail flies ``predictive`` at TAIL_COMPENSATED_LAMBDA_S4 when
    the mission states no lambda: the same track as a mission stating that lambda, another than
    one stating the default; replay makes the same choice from the tail the log records."""
    from companion.guidance.types import DEFAULT_LAMBDA_S4, TAIL_COMPENSATED_LAMBDA_S4
    from companion.mission import parse_mission

    predictive = RACETRACK_MISSION.replace("method: corrector", "method: predictive")
    assert "lambda_s4" not in predictive and "method: predictive" in predictive

    def fly(name: str, text: str) -> np.ndarray:
        path = tmp_path / f"{name}.tlog"
        write_synthetic_flight(path, mission=text, duration_s=20.0, start_offset_m=(0.0, 0.0),
                               vehicle_lag_s=LAG_S, vehicle_tail=TAIL, compensated_tail=TAIL)
        return np.array([tk.debug_value("crosstrack_m") for tk in read_flight(path).ticks if tk.debug is not None])

    unstated = fly("unstated", predictive)
    stated = lambda lam: predictive.replace("method: predictive", f"method: predictive, lambda_s4: {lam}")  # noqa: E731
    assert np.array_equal(unstated, fly("tail-lambda", stated(TAIL_COMPENSATED_LAMBDA_S4)))
    assert not np.allclose(unstated, fly("default-lambda", stated(DEFAULT_LAMBDA_S4)), atol=1e-3)
    assert replay_log(tmp_path / "unstated.tlog").to_json()["within_tolerance"] is True
    # replayed with the default lambda stated, the same log diverges
    j = replay_log(tmp_path / "unstated.tlog", parse_mission(stated(DEFAULT_LAMBDA_S4), "stated.yaml")).to_json()
    assert j["within_tolerance"] is False
