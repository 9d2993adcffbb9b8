"""End to end: a geodetic mission is flown on the autopilot's own EKF origin (GPS_GLOBAL_ORIGIN).

The mock's local frame is centred on its ``--origin``. The mission's origin is placed 40 m east
and 25 m north of it, so the mission's path, written in ENU about its own origin, must be flown
40 m east and 25 m north of where the same numbers would put it in the mock's frame.

The expected offset is computed here independently of ``companion.geometry.geodetic``: the
mission origin's latitude/longitude come from the WGS-84 meridian and prime-vertical radii of
curvature at the mock's latitude (Δlat = north / M, Δlon = east / (N cos lat)); over 47 m that
local-radius arithmetic is exact to well below a millimetre (the radii change by ~1e-6 relative
over that distance).
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from companion.io.mock_process import MockProcess, free_udp_port
from companion.errors import LinkError
from companion.loop.runner import FlightRunner, FlyOptions, Status
from companion.mission import parse_mission

MOCK_LAT_DEG, MOCK_LON_DEG, MOCK_ALT_M = 47.397742, 8.545594, 488.0
EAST_M, NORTH_M = 40.0, 25.0
SPEEDUP = 5.0

A_M = 6378137.0
E2 = (1.0 / 298.257223563) * (2.0 - 1.0 / 298.257223563)


def mission_origin_deg(alt_m: float) -> tuple[float, float]:
    """Latitude/longitude EAST_M east and NORTH_M north of the mock's origin (local radii, WGS-84)."""
    phi = math.radians(MOCK_LAT_DEG)
    w = math.sqrt(1.0 - E2 * math.sin(phi) ** 2)
    m_m = A_M * (1.0 - E2) / w ** 3 + alt_m  # meridian radius of curvature
    n_m = A_M / w + alt_m  # prime-vertical radius of curvature
    return (MOCK_LAT_DEG + math.degrees(NORTH_M / m_m),
            MOCK_LON_DEG + math.degrees(EAST_M / (n_m * math.cos(phi))))


def geodetic_mission():
    # The mission origin is given on the ellipsoid at the mock's altitude; the path is flown
    # 10 m above it (the radii above include that height).
    lat, lon = mission_origin_deg(MOCK_ALT_M + 10.0)
    text = f"""\
name: e2e-geodetic-line
frame: geodetic
origin: {{lat_deg: {lat:.10f}, lon_deg: {lon:.10f}, alt_m: {MOCK_ALT_M}}}
speed_m_s: 5.0
altitude_m: 10.0
path:
  type: function
  y_of_x: "5*sin(0.06*x)"
  x_range_m: [0, 90]
guidance: {{l1_m: 10.0, method: corrector, rate_hz: 50}}
midcourse: {{circle_radius_m: 10.0, trigger: auto}}
"""
    return parse_mission(text, "geodetic.yaml")


def start_mock(port, start_ned, extra=()):
    mock = MockProcess([
        "--autopilot", "px4", "--vehicle", "copter", "--link", f"udpout:127.0.0.1:{port}",
        "--speedup", f"{SPEEDUP:g}", f"--start-ned={start_ned[0]},{start_ned[1]}",
        "--start-alt-m", "10", "--start-yaw-deg=90", "--start-airborne",
        "--origin", f"{MOCK_LAT_DEG},{MOCK_LON_DEG},{MOCK_ALT_M}", "--quiet",
        "--offboard-loss-s", str(SPEEDUP), "--pace-lead-s", "0.04",
        "--vel-bias-m-s", "0", "--vel-offset-m-s", "0",  # the frames are the subject here: no estimator drift in the track
        *extra,
    ])
    mock.start(timeout_s=60.0)
    return mock


def fly(m, tmp_path, start_ned, extra_mock=(), **kw):
    port = free_udp_port()
    mock = start_mock(port, start_ned, extra_mock)
    opts = dict(connect=f"udpin:127.0.0.1:{port}", rate_hz=50.0, clock="autopilot",
                tlog_path=str(tmp_path / "flight.tlog"), heartbeat_timeout_s=30.0,
                link_timeout_s=10.0, max_duration_s=120.0)
    opts.update(kw)
    runner = FlightRunner(m, FlyOptions(**opts), Status(quiet=True))
    try:
        runner.run()
    finally:
        mock.stop()
    return runner


def distance_to_polyline_m(px, py, xs, ys):
    """Distance from each point (px, py) to the polyline (xs, ys) (exact segment distances)."""
    ax, ay = xs[:-1], ys[:-1]
    dx, dy = np.diff(xs), np.diff(ys)
    len2 = dx * dx + dy * dy
    out = []
    for x, y in zip(px, py):
        t = np.clip(((x - ax) * dx + (y - ay) * dy) / len2, 0.0, 1.0)
        out.append(float(np.min(np.hypot(ax + t * dx - x, ay + t * dy - y))))
    return np.array(out)


@pytest.fixture(scope="module")
def geodetic_flight(tmp_path_factory):
    # Start 3 m south of the path's first point as the autopilot sees it (mission (0, 0) is at
    # ENU (40, 25) in the mock's frame): north 22, east 40. Unshifted, that start would be 47 m away.
    tmp_path = tmp_path_factory.mktemp("geodetic")
    return fly(geodetic_mission(), tmp_path, start_ned=(NORTH_M - 3.0, EAST_M)), tmp_path / "flight.tlog"


def test_a_geodetic_mission_is_flown_on_the_autopilots_origin(geodetic_flight):
    runner, _ = geodetic_flight
    s = runner.summary
    assert s["exit"] == "finished", runner.events
    east, north = s["origin_offset_enu_m"]
    assert east == pytest.approx(EAST_M, abs=0.005)
    assert north == pytest.approx(NORTH_M, abs=0.005)
    # Over a 90 m path 47 m from the EKF origin the translation is exact to a millimetre or so.
    assert s["origin_translation_error_m"] < 0.002
    # The flown track (the autopilot's LOCAL_POSITION_NED, as ENU) against the mission's path
    # moved by the independently computed offset: on it once converged (close range).
    xs = np.linspace(0.0, 90.0, 3001)
    ys = 5.0 * np.sin(0.06 * xs)
    r = runner.record
    close = [i for i, ph in enumerate(r.phase) if ph == "close_range" and math.isfinite(r.x_m[i])]
    assert len(close) > 200
    px = np.array([r.x_m[i] for i in close])
    py = np.array([r.y_m[i] for i in close])
    # Converged: beyond the first third of the path (the start was 3 m off it).
    later = px - EAST_M >= 30.0
    assert later.sum() > 100
    on_path = distance_to_polyline_m(px[later], py[later], xs + EAST_M, ys + NORTH_M)
    assert float(np.sqrt(np.mean(on_path ** 2))) < 0.3, on_path.max()
    assert float(np.max(on_path)) < 0.6
    # ... and not on the path read in the mock's own frame (the bug this guards against).
    off_path = distance_to_polyline_m(px, py, xs, ys)
    assert float(np.min(off_path)) > 15.0


def test_the_geodetic_flight_replays_within_tolerance_on_the_recorded_origin(geodetic_flight):
    """Replay places the geodetic mission with the GPS_GLOBAL_ORIGIN recorded in the tlog."""
    from companion.replay.replay import replay_log

    _, tlog = geodetic_flight
    result = replay_log(tlog, progress=False)  # the mission recorded beside the log
    assert result.within_tolerance, result.first_divergence
    assert result.steps_compared > 500
    # The path replay used starts where the flight flew it: the mission's (0, 0) moved by the
    # independently computed offset.
    x0, y0 = result.mission_path.start_xy_m
    assert x0 == pytest.approx(EAST_M, abs=0.005) and y0 == pytest.approx(NORTH_M, abs=0.005)


def test_a_geodetic_log_without_the_autopilots_origin_cannot_be_replayed(geodetic_flight, tmp_path):
    from companion.errors import LogError
    from companion.io.logread import TlogReader
    from companion.replay.replay import replay_log

    _, tlog = geodetic_flight
    # Copy the log without its GPS_GLOBAL_ORIGIN records (id 49): the flight's frame is unknown.
    stripped = tmp_path / "stripped.tlog"
    data = tlog.read_bytes()
    records = list(TlogReader(tlog))
    ends = [r.offset for r in records[1:]] + [len(data)]  # an undamaged log: records are contiguous
    kept = [data[r.offset:end] for r, end in zip(records, ends) if r.msg_id != 49]
    assert len(kept) < len(records)
    stripped.write_bytes(b"".join(kept))
    (tmp_path / "stripped.tlog.mission.yaml").write_text(geodetic_mission().source_text, encoding="utf-8")
    with pytest.raises(LogError, match="GPS_GLOBAL_ORIGIN"):
        replay_log(stripped, progress=False)


def test_a_geodetic_mission_without_an_autopilot_origin_is_refused(tmp_path):
    m = geodetic_mission()
    with pytest.raises(LinkError, match="GPS_GLOBAL_ORIGIN"):
        fly(m, tmp_path, start_ned=(NORTH_M - 3.0, EAST_M), extra_mock=("--no-ekf-origin",),
            origin_timeout_s=2.0)


def test_the_cli_refuses_a_geodetic_mission_without_origin_with_exit_2(tmp_path):
    m_path = tmp_path / "geo.yaml"
    m_path.write_text(geodetic_mission().source_text, encoding="utf-8")
    port = free_udp_port()
    mock = start_mock(port, (NORTH_M - 3.0, EAST_M), ("--no-ekf-origin",))
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "companion", "fly", str(m_path), "--connect", f"udpin:127.0.0.1:{port}",
             "--clock", "autopilot", "--origin-timeout-s", "2", "--tlog", str(tmp_path / "f.tlog"), "--quiet"],
            capture_output=True, text=True, timeout=120)
    finally:
        mock.stop()
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert any("GPS_GLOBAL_ORIGIN" in ln for ln in lines), proc.stderr
    assert "Traceback" not in proc.stderr
