import math

import pytest

from companion.sim.metrics import tracking_metrics


def test_metrics_match_hand_arithmetic_per_phase():
    t = [0.0, 0.5, 1.0, 1.5]
    d = [3.0, -4.0, 0.0, 2.0]
    a = [1.0, -1.0, 2.0, -2.0]
    m = tracking_metrics(t, d, a, ["midcourse", "midcourse", "close_range", "close_range"])
    assert m["d_rms_m"] == pytest.approx(math.sqrt((9 + 16 + 0 + 4) / 4))
    assert m["d_max_m"] == 4.0
    assert m["a_rms_m_s2"] == pytest.approx(math.sqrt(10 / 4))
    assert m["a_max_m_s2"] == 2.0
    assert m["duration_s"] == 1.5
    assert list(m["phases"]) == ["midcourse", "close_range"]
    assert m["phases"]["midcourse"]["d_rms_m"] == pytest.approx(math.sqrt(12.5))
    assert m["phases"]["close_range"]["duration_s"] == 0.5


def test_metrics_reject_mismatched_series():
    with pytest.raises(ValueError):
        tracking_metrics([0.0, 1.0], [0.0], [0.0, 0.0])
