"""A copter whose velocity estimate drifts, flown by the loop with and without the compensation.

The synthetic vehicle flies the reported velocity plus a steady 0.3 m/s across an east-bound
straight (as a PX4 whose estimate is off by that much). Fixed L1 steering by the reported
velocity then settles where the line to its L1 point runs along that velocity, which is turned
by ``asin(w / V)`` from the path: ``d = L1 w / V`` = 0.6 m (L1 10 m, V 5 m/s). With the
compensation the law steers by the course flown and the setpoint leaves out the drift.
"""

from __future__ import annotations

import numpy as np
import pytest

from companion.replay.flightlog import read_flight
from companion.replay.replay import replay_log
from companion.replay.synthetic import RACETRACK_MISSION, write_synthetic_flight

FIXED_L1 = RACETRACK_MISSION.replace("method: corrector", "method: fixed_l1")
DRIFT_N_M_S = 0.3


def crosstrack_on_the_straight(path):
    ticks = [t for t in read_flight(path).ticks if t.debug is not None]
    t = np.array([tk.debug_value("t_s") for tk in ticks])
    d = np.array([tk.debug_value("crosstrack_m") for tk in ticks])
    return d[(t > 12.0) & (t < 22.0)]  # the first straight (0-24 s), settled


@pytest.mark.parametrize("tc_s", [0.0, 1.0])
def test_the_drift_offset_is_the_closed_form_and_compensation_removes_it(tmp_path, tc_s):
    path = tmp_path / f"drift-{tc_s}.tlog"
    write_synthetic_flight(path, mission=FIXED_L1, duration_s=24.0, start_offset_m=(0.0, 0.0),
                           vehicle_lag_s=0.2, drift_en_m_s=(0.0, DRIFT_N_M_S), drift_tc_s=tc_s)
    d = crosstrack_on_the_straight(path)
    offset = 10.0 * DRIFT_N_M_S / 5.0
    if tc_s == 0.0:
        assert np.abs(d).mean() == pytest.approx(offset, rel=0.05)
    else:
        assert np.abs(d).max() < 0.05 * offset
    # Replay rebuilds the estimate from the logged samples and sends the same setpoints.
    j = replay_log(path).to_json()
    assert j["within_tolerance"] is True and j["first_divergence"] is None
