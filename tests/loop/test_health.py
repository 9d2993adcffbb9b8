"""Flight-health failsafes (companion/loop/health.py) on synthetic trajectories, fake clock.

Every expected time below is hand arithmetic from the defaults: progress expected over the
window = 0.2 * speed * window (5 m in 5 s at 5 m/s, 2.5 m in the half window); cross-track
bound 25 m beyond the closest approach, stop 3 s after the hold began; clock band 1 +- 0.25
measured over 2 s.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from companion.errors import CompanionError
from companion.loop.health import (
    EXIT_HEALTH_STOP,
    HealthMonitor,
    HealthOptions,
    HealthSample,
    turn_allowance_m,
)
from companion.loop.scheduler import FakeClock, FixedRateScheduler

RATE_HZ = 10.0


def ticks(duration_s: float, rate_hz: float = RATE_HZ):
    """Tick times from the loop's own scheduler on a fake clock: 0, 0.1, 0.2, ..."""
    sched = FixedRateScheduler(rate_hz, FakeClock())
    while True:
        t = sched.wait_next().deadline_s
        if t > duration_s + 1e-9:
            return
        yield t
        sched.done()


def fly(monitor, trajectory, duration_s, rate_hz=RATE_HZ):
    """Feed ``trajectory(t) -> HealthSample`` to the monitor; return [(t, verdict)]."""
    return [(t, monitor.update(trajectory(t))) for t in ticks(duration_s, rate_hz)]


def first(verdicts, level):
    return next((t for t, v in verdicts if v.level == level), None)


def on_path(speed_m_s):
    """Flying along a straight path (the x axis) at ``speed_m_s``, on it."""
    return lambda t: HealthSample(t_s=t, x_enu_m=speed_m_s * t, y_enu_m=0.0, s_m=speed_m_s * t,
                                  crosstrack_m=0.0, autopilot_time_s=100.0 + t)


# ------------------------------------------------------------------ no progress


def test_stationary_vehicle_warns_at_half_the_window_and_stops_at_the_window():
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=0.0, y_enu_m=0.0, s_m=0.0,
                                          crosstrack_m=0.0, ground_speed_m_s=0.0), 6.0)
    assert first(out, "warn") == pytest.approx(2.5)
    assert first(out, "stop") == pytest.approx(5.0)
    stop = next(v for _, v in out if v.level == "stop")
    assert stop.check == "progress" and stop.exit_code == EXIT_HEALTH_STOP == 3
    assert "0.0 m in 5 s" in stop.reason and "expected >= 5.0 m" in stop.reason
    assert "\n" not in stop.reason


def test_plane_on_the_ground_stops_within_ten_seconds_at_its_mission_speed():
    # A plane's mission at 18 m/s sitting still: stop at the 5 s window, whatever the speed.
    mon = HealthMonitor(HealthOptions(), speed_m_s=18.0)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=3.0, y_enu_m=-2.0, s_m=0.0,
                                          crosstrack_m=2.0), 10.0, rate_hz=50.0)
    assert first(out, "stop") == pytest.approx(5.0)


@pytest.mark.parametrize("speed_m_s, stops", [(0.9, True), (1.1, False)])
def test_creeping_vehicle_is_judged_against_a_fifth_of_the_mission_speed(speed_m_s, stops):
    # 5 m/s mission: 5 m expected in 5 s. 0.9 m/s covers 4.5 m (stop), 1.1 m/s 5.5 m (ok).
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, on_path(speed_m_s), 12.0)
    assert (first(out, "stop") is not None) == stops
    if stops:
        assert first(out, "stop") == pytest.approx(5.0)
        assert first(out, "warn") == pytest.approx(2.5)  # 2.25 m < 2.5 m in the half window


def test_vehicle_flying_the_path_is_ok_throughout():
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, on_path(5.0), 30.0)
    assert {v.level for _, v in out} == {"ok"}


def test_midcourse_approach_counts_as_progress_though_s_stays_at_the_start():
    # 80 m south of the path start, flying north at 5 m/s: projection s = 0 all along.
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=0.0, y_enu_m=-80.0 + 5.0 * t, s_m=0.0,
                                          crosstrack_m=80.0 - 5.0 * t, phase="midcourse"), 15.0)
    assert {v.level for _, v in out} == {"ok"}


def test_orbiting_on_the_spot_is_no_progress():
    # Radius 2 m at 5 m/s: 2.5 rad/s, so 12.5 rad in 5 s: chord 4 |sin 6.25| = 0.13 m < 5 m.
    r, w = 2.0, 2.5
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=r * math.cos(w * t), y_enu_m=r * math.sin(w * t),
                                          s_m=0.0, crosstrack_m=1.0), 6.0)
    assert first(out, "stop") == pytest.approx(5.0)
    assert 4 * abs(math.sin(6.25)) == pytest.approx(0.133, abs=1e-3)


def test_stale_data_holds_restart_the_progress_window():
    # Holding on stale data for the first 3 s: the 5 s window starts after it -> stop at 8 s.
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=0.0, y_enu_m=0.0, s_m=0.0, crosstrack_m=0.0,
                                          hold=t < 3.0 - 1e-9), 9.0)
    assert first(out, "stop") == pytest.approx(8.0)


def test_progress_along_a_closed_path_that_wraps_is_still_progress():
    # A 100 m loop flown at 5 m/s: s wraps from 100 to 0 at t = 20 s; the vehicle moved.
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    rad = 100.0 / (2 * math.pi)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=rad * math.cos(5 * t / rad),
                                          y_enu_m=rad * math.sin(5 * t / rad), s_m=(5 * t) % 100.0,
                                          crosstrack_m=0.0), 30.0)
    assert {v.level for _, v in out} == {"ok"}


# ------------------------------------------------------------------ cross-track runaway


def runaway(start_s=2.0, rate_m_s=10.0):
    """Along the path at 5 m/s; from ``start_s`` drifting off sideways at ``rate_m_s``."""
    def traj(t):
        d = max(0.0, rate_m_s * (t - start_s))
        return HealthSample(t_s=t, x_enu_m=5.0 * t, y_enu_m=d, s_m=5.0 * t, crosstrack_m=d)
    return traj


def test_runaway_warns_at_half_the_bound_holds_at_the_bound_and_stops_three_seconds_later():
    # d = 10 (t - 2): 12.5 m at t = 3.25 (warn from 3.3), 25 m at t = 4.5 (hold from 4.6: the
    # bound itself is still allowed), stop 3 s into the hold: 7.6 s, within 10 s of the start.
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, runaway(), 10.0)
    assert first(out, "warn") == pytest.approx(3.3)
    assert first(out, "hold") == pytest.approx(4.6)
    assert first(out, "stop") == pytest.approx(7.6)
    stop = next(v for _, v in out if v.level == "stop")
    assert stop.check == "crosstrack" and stop.exit_code == 3
    assert "runaway" in stop.reason and "--max-xtrack-m 25" in stop.reason
    hold = next(v for _, v in out if v.level == "hold")
    assert hold.exit_code == 0 and "holding" in hold.reason


def test_runaway_that_comes_back_during_the_hold_resumes():
    # Off by 30 m from t = 2 s to t = 3 s (a position glitch), then back on the path.
    def traj(t):
        d = 30.0 if 2.0 <= t < 3.0 else 0.0
        return HealthSample(t_s=t, x_enu_m=5.0 * t, y_enu_m=d, s_m=5.0 * t, crosstrack_m=d)
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, traj, 12.0)
    assert first(out, "hold") == pytest.approx(2.0)
    assert first(out, "stop") is None
    assert out[-1][1].level == "ok"


def test_held_vehicle_is_not_also_stopped_for_no_progress():
    # The runner holds on a cross-track hold, so the vehicle stops: the hold lasts its 3 s, and
    # the stop, when it comes, is the cross-track one, not the progress one.
    def traj(t):
        if t < 2.0:
            return HealthSample(t_s=t, x_enu_m=5.0 * t, y_enu_m=0.0, s_m=5.0 * t, crosstrack_m=0.0)
        return HealthSample(t_s=t, x_enu_m=10.0, y_enu_m=40.0, s_m=10.0, crosstrack_m=40.0)
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, traj, 6.0)
    stop_t = first(out, "stop")
    assert stop_t == pytest.approx(5.0)
    assert next(v for _, v in out if v.level == "stop").check == "crosstrack"


def test_far_start_is_measured_from_the_closest_approach():
    # Starts 80 m off, approaches to 40 m (t = 8 s), then drifts away at 5 m/s: the bound is
    # 40 + 25 = 65 m, reached at t = 8 + 25 / 5 = 13 s (hold from 13.1), stop at 16.1 s. It also
    # moves east at 5 m/s (turning back on the spot would be no progress: 4 m from 5.1 to 10.1 s).
    def traj(t):
        d = 80.0 - 5.0 * t if t <= 8.0 else 40.0 + 5.0 * (t - 8.0)
        return HealthSample(t_s=t, x_enu_m=5.0 * t, y_enu_m=-d, s_m=0.0, crosstrack_m=-d, phase="midcourse")
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, traj, 17.0)
    assert first(out, "hold") == pytest.approx(13.1)
    assert first(out, "stop") == pytest.approx(16.1)


def test_midcourse_turn_allowance_lets_a_plane_turn_round():
    # A plane heading away first: 80 m -> 120 m (40 m growth) in the mid-course phase. With the
    # allowance 2 v^2 / a for 18 m/s and a = g tan 35 deg (6.87 m/s2): 94 m -> no hold.
    allowance = turn_allowance_m(10.0, 18.0, 9.80665 * math.tan(math.radians(35.0)))
    assert allowance == pytest.approx(2 * 18.0 ** 2 / 6.8668, abs=0.05) == pytest.approx(94.3, abs=0.1)

    def traj(t):
        d = 80.0 + 40.0 * math.sin(math.pi * t / 10.0)  # out to 120 m at t = 5, back by t = 10
        return HealthSample(t_s=t, x_enu_m=18.0 * t, y_enu_m=d, s_m=0.0, crosstrack_m=d, phase="midcourse")
    with_allowance = fly(HealthMonitor(HealthOptions(), 18.0, turn_allowance_m=allowance), traj, 10.0)
    assert first(with_allowance, "hold") is None
    without = fly(HealthMonitor(HealthOptions(), 18.0), traj, 10.0)
    # 80 + 40 sin(pi t / 10) > 105 from t = 10/pi * asin(25/40) = 2.15 s: hold from 2.2 s.
    assert first(without, "hold") == pytest.approx(2.2)


def plane_turning_round(d0_m: float, v_m_s: float, radius_m: float):
    """A plane ``d0_m`` from a straight path (the x axis, vehicle above it), heading straight
    away from it, turning round at its tightest radius ``R``, then flying back and along the
    path (no mid-course phase: close range from the first tick). The centre of the turn is at
    (R, d0), so the distance to the path is ``d0 + R sin(v t / R)`` during the half turn: out to
    ``d0 + R`` at a quarter turn, back to ``d0`` after half a turn, then straight down at ``v``
    to the path and along it."""
    half_turn_s = math.pi * radius_m / v_m_s

    def traj(t):
        if t <= half_turn_s:
            th = v_m_s * t / radius_m
            x, d = radius_m * (1.0 - math.cos(th)), d0_m + radius_m * math.sin(th)
        else:
            d = max(0.0, d0_m - v_m_s * (t - half_turn_s))
            x = 2.0 * radius_m + v_m_s * max(0.0, t - half_turn_s - d0_m / v_m_s)
        return HealthSample(t_s=t, x_enu_m=x, y_enu_m=d, s_m=max(x, 0.0), crosstrack_m=d)
    return traj


def test_a_plane_turning_round_towards_the_path_before_reaching_it_is_no_runaway():
    # The plane of the fixed-wing mission (15 m/s, 35 deg bank: R = 225 / 6.87 = 32.8 m), 22 m
    # from the path and pointing away when the close-range law takes over: the turn round
    # takes it 32.8 m beyond its closest approach (22 m), past the 25 m bound. That is the
    # turn, not a runaway: until the vehicle has first come within half the bound (12.5 m) of
    # the path the bound is widened by the tightest turn's diameter, 2 R = 65.5 m, in every
    # phase, not only the mid-course one.
    a_max = 9.80665 * math.tan(math.radians(35.0))
    radius = 15.0 ** 2 / a_max
    assert radius == pytest.approx(32.77, abs=0.01)
    allowance = turn_allowance_m(0.0, 15.0, a_max)
    assert allowance == pytest.approx(2 * radius)
    traj = plane_turning_round(22.0, 15.0, radius)
    assert max(traj(t).crosstrack_m for t in ticks(20.0)) == pytest.approx(22.0 + radius, abs=0.1)
    out = fly(HealthMonitor(HealthOptions(), 15.0, turn_allowance_m=allowance), traj, 20.0)
    assert {v.level for _, v in out} <= {"ok", "warn"}
    # Without the allowance: beyond 22 + 25 = 47 m from sin(th) > 25 / R, th = 0.8676 rad at
    # t = th R / v = 1.8955 s: hold from the next tick, 1.9 s.
    out = fly(HealthMonitor(HealthOptions(), 15.0), traj, 20.0)
    assert first(out, "hold") == pytest.approx(1.9)


def test_once_on_the_path_the_turn_allowance_no_longer_applies():
    # Flying along the path, then drifting away at 5 m/s from t = 2 s (a runaway): having been
    # on the path, the bound is 25 m whatever the allowance, so hold from 7.1 s as without one.
    def traj(t):
        d = 0.0 if t <= 2.0 else 5.0 * (t - 2.0)
        return HealthSample(t_s=t, x_enu_m=15.0 * t, y_enu_m=d, s_m=15.0 * t, crosstrack_m=d)
    out = fly(HealthMonitor(HealthOptions(), 15.0, turn_allowance_m=65.5), traj, 12.0)
    assert first(out, "hold") == pytest.approx(7.1)
    assert first(out, "stop") == pytest.approx(10.1)


# ------------------------------------------------------------------ clock mismatch


def speedup(factor):
    return lambda t: HealthSample(t_s=1000.0 + t, x_enu_m=5.0 * t, y_enu_m=0.0, s_m=5.0 * t,
                                  crosstrack_m=0.0, autopilot_time_s=30.0 + factor * t)


def test_five_times_speedup_warns_two_seconds_in_and_suggests_the_autopilot_clock():
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, speedup(5.0), 5.0)
    assert first(out, "warn") == pytest.approx(2.0)  # within 5 s of the start
    warn = next(v for _, v in out if v.level == "warn")
    assert warn.check == "clock" and "5.00x the wall clock" in warn.reason
    assert "--clock autopilot" in warn.reason and "faster" in warn.reason
    assert first(out, "stop") is None and warn.exit_code == 0


@pytest.mark.parametrize("factor, warns", [(0.5, True), (0.74, True), (0.8, False), (1.0, False),
                                           (1.2, False), (1.3, True)])
def test_clock_band_is_one_plus_or_minus_a_quarter(factor, warns):
    out = fly(HealthMonitor(HealthOptions(), speed_m_s=5.0), speedup(factor), 4.0)
    assert (first(out, "warn") is not None) == warns
    if factor == 0.5:
        assert "0.50x" in next(v for _, v in out if v.level == "warn").reason
        assert "slower" in next(v for _, v in out if v.level == "warn").reason


def test_clock_check_is_off_on_the_autopilot_clock():
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0, clock="autopilot")
    assert first(fly(mon, speedup(5.0), 5.0), "warn") is None


def test_autopilot_restart_starts_a_new_clock_series():
    # Real time for 3 s, restart (time_boot_ms back to 0) at 3 s, real time again: no warning.
    def traj(t):
        ap = 50.0 + t if t < 3.0 else t - 3.0
        return HealthSample(t_s=t, x_enu_m=5.0 * t, y_enu_m=0.0, s_m=5.0 * t, crosstrack_m=0.0,
                            autopilot_time_s=ap)
    assert first(fly(HealthMonitor(HealthOptions(), 5.0), traj, 8.0), "warn") is None


# ------------------------------------------------------------------ verdicts and options


def test_changed_is_set_only_on_transitions():
    mon = HealthMonitor(HealthOptions(), speed_m_s=5.0)
    out = fly(mon, lambda t: HealthSample(t_s=t, x_enu_m=0.0, y_enu_m=0.0, s_m=0.0, crosstrack_m=0.0), 6.0)
    changes = [(t, v.level) for t, v in out if v.changed]
    assert changes == [(pytest.approx(2.5), "warn"), (pytest.approx(5.0), "stop")]


def test_zero_turns_each_check_off():
    off = HealthOptions(no_progress_s=0, max_xtrack_m=0, clock_tolerance=0)
    still = lambda t: HealthSample(t_s=t, x_enu_m=0.0, y_enu_m=500.0, s_m=0.0,  # noqa: E731
                                   crosstrack_m=500.0 * min(t, 1.0), autopilot_time_s=5 * t)
    assert {v.level for _, v in fly(HealthMonitor(off, 5.0), still, 10.0)} == {"ok"}


@pytest.mark.parametrize("field, value", [("no_progress_s", -1.0), ("max_xtrack_m", math.nan),
                                          ("clock_tolerance", math.inf), ("clock_window_s", 0.0),
                                          ("min_progress_fraction", 1.0)])
def test_bad_options_are_one_line_errors(field, value):
    with pytest.raises(CompanionError) as err:
        HealthOptions(**{field: value})
    assert "\n" not in str(err.value) and field.split("_")[0] in str(err.value)


# ------------------------------------------------------------------ command line


def test_fly_flags_reach_the_monitor_options():
    from companion.cli.fly import health_options_from_args
    from companion.cli.main import build_parser

    args = build_parser().parse_args(["fly", "m.yaml", "--connect", "udpin:0.0.0.0:14540",
                                      "--no-progress-s", "7", "--max-xtrack-m", "40",
                                      "--xtrack-hold-s", "1.5", "--clock-tolerance", "0"])
    assert health_options_from_args(args) == HealthOptions(no_progress_s=7.0, max_xtrack_m=40.0,
                                                           xtrack_hold_s=1.5, clock_tolerance=0.0)
    defaults = build_parser().parse_args(["demo"])
    assert health_options_from_args(defaults) == HealthOptions()


def test_bad_threshold_is_refused_before_anything_opens(tmp_path, capsys, monkeypatch):
    from companion.cli.main import main

    monkeypatch.chdir(tmp_path)
    mission = Path(__file__).resolve().parents[2] / "missions" / "racetrack.yaml"
    code = main(["fly", str(mission), "--connect", "udpin:127.0.0.1:9", "--no-progress-s", "-2"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip() == "companion: error: --no-progress-s: expected a number >= 0, got -2.0"
    assert not (tmp_path / "logs").exists()


def test_demo_help_names_the_demo_log():
    from companion.cli.main import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    demo_help = sub["demo"].format_help()
    fly_help = sub["fly"].format_help()
    assert "logs/demo-<UTC time>.tlog" in " ".join(demo_help.split())
    assert "logs/flight-<UTC time>.tlog" in " ".join(fly_help.split())


# ------------------------------------------------------------------ fed from the loop's tick


def test_sample_from_a_tick_takes_enu_position_speed_and_the_guidance_figures():
    from companion.guidance.types import GuidanceOutput
    from companion.io.state import PositionSample
    from companion.loop.health import sample_from_tick
    from companion.loop.tick import TickConfig, compute_tick

    class Straight:
        def step(self, t_s, state):
            return GuidanceOutput(a_cmd_m_s2=0.0, phase="close_range", crosstrack_m=-1.5, s_proj_m=42.0)

    cfg = TickConfig(speed_m_s=5.0, rate_hz=50.0, altitude_m=10.0, stale_s=0.3)
    pos = PositionSample(2000, 4.0, 3.0, -10.0, 3.0, 4.0, 0.0, received_s=0.0)  # NED: north 4, east 3
    fresh = sample_from_tick(compute_tick(Straight(), 0, 1.0, pos, 0.01, cfg), 7.0, 2.0)
    assert (fresh.x_enu_m, fresh.y_enu_m, fresh.s_m, fresh.crosstrack_m) == (3.0, 4.0, 42.0, -1.5)
    assert (fresh.t_s, fresh.autopilot_time_s, fresh.ground_speed_m_s) == (7.0, 2.0, 5.0)  # 3-4-5
    assert not fresh.hold and fresh.phase == "close_range"
    stale = sample_from_tick(compute_tick(Straight(), 1, 1.0, pos, 0.5, cfg), 7.5)
    assert stale.hold and math.isnan(stale.s_m) and math.isnan(stale.crosstrack_m)
    assert (stale.x_enu_m, stale.y_enu_m) == (3.0, 4.0)


# ------------------------------------------------------------------ no false alarm on healthy flights


@pytest.mark.parametrize("mission", ["paper_far_start", "qgc_inspection", "racetrack", "survey_lawnmower",
                                     "paper_sine"])
def test_healthy_simulated_flights_of_the_gallery_raise_nothing(mission):
    # The offline simulator with a lagging inner loop (0.3 s, 5 m/s2) flies each mission from
    # its start; on the far starts the mid-course swing round the initiation circle moves the
    # vehicle up to 18.4 m farther from the path than its closest approach, inside 25 + 2 R.
    from companion.guidance.two_phase import TwoPhaseGuidance
    from companion.guidance.types import VehicleState
    from companion.mission import load_mission
    from companion.sim.simulator import LagModel, simulate

    m = load_mission(Path(__file__).resolve().parents[2] / "missions" / f"{mission}.yaml")
    p = m.path
    if m.start is not None:
        start = VehicleState(m.start.x_m, m.start.y_m, m.start.heading_rad, m.speed_m_s)
    else:
        start = VehicleState(*p.start_xy_m, p.start_heading_rad, m.speed_m_s)
    r = simulate(p, TwoPhaseGuidance(p, m.guidance), start, m.guidance, model=LagModel(0.3, 5.0),
                 keep_outputs=True)
    mon = HealthMonitor(HealthOptions(), m.speed_m_s,
                        turn_allowance_m=turn_allowance_m(m.guidance.circle_radius_m, m.speed_m_s))
    levels = set()
    for i, t in enumerate(r.t_s):
        o = r.outputs[i]
        levels.add(mon.update(HealthSample(t_s=float(t), x_enu_m=float(r.x_m[i]), y_enu_m=float(r.y_m[i]),
                                           s_m=o.s_proj_m, crosstrack_m=o.crosstrack_m,
                                           autopilot_time_s=50.0 + float(t), phase=o.phase)).level)
    assert levels == {"ok"}  # (the racetrack is a closed loop: it ends at the time limit)
