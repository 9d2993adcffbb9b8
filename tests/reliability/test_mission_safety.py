"""Mission safety: ``companion fly`` refuses to start rather than send a vehicle somewhere wrong.

- A mission that fails validation is refused before any link is opened or log written.
- A vehicle farther than ``--max-start-distance-m`` from the path (a wrong origin or frame) is
  refused after its first position and before any mode change or setpoint: the autopilot's own
  log shows that nothing but the telemetry requests ever reached it.
"""

from __future__ import annotations

import math
import re
import time

from harness import LINE_MISSION, Companion, Mock, free_udp_port, read_tlog, write_mission

MAV_CMD_SET_MESSAGE_INTERVAL = 511


def test_invalid_mission_is_refused_before_the_link_is_opened(tmp_path):
    bad = write_mission(tmp_path, LINE_MISSION.replace("speed_m_s: 5.0", "speed_m_s: -5.0"), "bad.yaml")
    port = free_udp_port()
    t0 = time.monotonic()
    comp = Companion(bad, port, tmp_path / "c.tlog")
    rc, _ = comp.result(30)
    assert rc == 2
    assert time.monotonic() - t0 < 15  # no wait for an autopilot
    assert "companion: error:" in comp.stderr and "speed_m_s" in comp.stderr
    assert "Traceback" not in comp.stderr
    assert not (tmp_path / "c.tlog").exists()


def test_vehicle_farther_than_max_start_distance_is_refused_before_any_command(tmp_path):
    port = free_udp_port()
    mission = write_mission(tmp_path)
    # 250 m north of a path along the east axis from x = 0 to 400 m: 250 m from it exactly.
    comp = Companion(mission, port, tmp_path / "c.tlog", "--max-start-distance-m", "200")
    mock = Mock(f"udpout:127.0.0.1:{port}", "--start-ned", "250,100", tlog=tmp_path / "m.tlog")
    try:
        rc, summary = comp.result(60)
        time.sleep(0.3)
    finally:
        mock.stop()
    assert rc == 1, comp.stderr
    assert "not starting" in summary["exit"] and "--max-start-distance-m" in summary["exit"]
    reported = float(re.search(r"is (\d+) m from the path", summary["exit"]).group(1))
    assert math.isclose(reported, 250.0, abs_tol=1.0)
    assert summary["setpoints_sent"] == 0 and summary["ticks"] == 0
    # What reached the autopilot from the companion: heartbeats and SET_MESSAGE_INTERVAL only.
    from_companion = [m for m in read_tlog(tmp_path / "m.tlog") if m.get_srcComponent() == 191]
    kinds = {m.get_type() for m in from_companion}
    assert kinds <= {"HEARTBEAT", "COMMAND_LONG"}, kinds
    assert {int(m.command) for m in from_companion if m.get_type() == "COMMAND_LONG"} <= {MAV_CMD_SET_MESSAGE_INTERVAL}
