"""ArduCopter's position controller as the mock emulates it (sitl_mock.posctl).

The pieces are checked against closed forms of the firmware's formulas; the whole chain against
the real ArduCopter SITL's flights in ../shared/data/real (its identification flight is what the
dead time was fitted on; the mission flights were not used to fit anything).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.io.idlog import read_identification_samples
from companion.sim.identify import simulate, smoothed
from sitl_mock import flight as fl
from sitl_mock.personality import IDENTIFIED_COPTER_MODELS
from sitl_mock.posctl import (CORNER_ACCELERATION_RATIO, NEPositionController, PosControlParams, corner_limited,
                              cross_first_limited, sqrt_controller)

from test_flight_rules import DT_S, advance, make, vel_setpoint

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


def test_sqrt_controller_is_linear_near_zero_then_stops_at_the_limit():
    p, limit = 2.0, 5.0  # the shaper's own: jerk / accel_max and the jerk
    linear = limit / p**2  # 1.25: where the two branches meet
    assert sqrt_controller(0.5, p, limit, 0.0) == pytest.approx(1.0)
    assert sqrt_controller(3.0, p, limit, 0.0) == pytest.approx(math.sqrt(2 * 5.0 * (3.0 - 0.625)))
    assert sqrt_controller(-3.0, p, limit, 0.0) == pytest.approx(-math.sqrt(2 * 5.0 * (3.0 - 0.625)))
    below, above = sqrt_controller(linear - 1e-9, p, limit, 0.0), sqrt_controller(linear + 1e-9, p, limit, 0.0)
    assert below == pytest.approx(above, abs=1e-6) == pytest.approx(p * linear)
    assert sqrt_controller(0.01, 20.0, 0.0, 0.1) == pytest.approx(0.01 / 0.1)  # never overshoots in one step


def test_corner_rule_keeps_cross_acceleration_to_one_over_root_two_when_the_along_part_dominates():
    # along (1, 0), limit 2.5: cross 1 under 2.5/sqrt(2) is kept, the along part gets the rest
    an, ae = corner_limited(3.0, 1.0, 1.0, 0.0, 2.5)
    assert (an, ae) == pytest.approx((math.sqrt(2.5**2 - 1.0), 1.0))
    an, ae = corner_limited(3.0, 2.0, 1.0, 0.0, 2.5)  # cross 2 above 1.77: held there
    cross = CORNER_ACCELERATION_RATIO * 2.5
    assert (an, ae) == pytest.approx((math.sqrt(2.5**2 - cross**2), cross))
    assert corner_limited(1.0, 3.0, 1.0, 0.0, 2.5) == pytest.approx((2.5 / math.hypot(1, 3), 7.5 / math.hypot(1, 3)))
    assert corner_limited(1.0, 0.5, 1.0, 0.0, 2.5) == (1.0, 0.5)  # within the limit: untouched


def test_lean_limit_gives_the_cross_track_part_priority():
    assert cross_first_limited(3.0, 6.0, 1.0, 0.0, 5.0) == pytest.approx((0.0, 5.0))
    assert cross_first_limited(5.0, 3.0, 1.0, 0.0, 5.0) == pytest.approx((4.0, 3.0))
    assert cross_first_limited(3.0, 3.0, 1.0, 0.0, 5.0) == (3.0, 3.0)


def _trajectory(params: PosControlParams, target: tuple[float, float], seconds: float, dt: float = 0.0025):
    """The controller flown by an ideal airframe from a hover at the origin; (t, desired acc, desired vel)."""
    ctl = NEPositionController(params)
    ctl.reset((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    pos, vel = [0.0, 0.0], [0.0, 0.0]
    rows = []
    for k in range(round(seconds / dt)):
        a = ctl.update(dt, target, tuple(pos), tuple(vel))
        for i in range(2):
            pos[i] += vel[i] * dt + 0.5 * a[i] * dt * dt
            vel[i] += a[i] * dt
        rows.append(((k + 1) * dt, ctl.desired_acc_ne_m_s2[0], ctl.desired_vel_ne_m_s[0], vel[0], pos[0],
                     ctl.desired_pos_ne_m[0]))
    return np.array(rows)


def test_the_trajectory_leaves_a_hover_at_the_jerk_limit_then_at_the_acceleration_limit():
    # From rest toward 5 m/s: the acceleration ramps at PSC_JERK_XY = 5 m/s^3 to WPNAV_ACCEL = 2.5
    # (0.5 s, 0.625 m/s gained), holds 2.5 until the square-root branch asks for less (velocity
    # error 1.25 m/s, i.e. at 3.75 m/s, t = 0.5 + 3.125 / 2.5 = 1.75 s), then closes without overshoot.
    rows = _trajectory(PosControlParams(input_delay_s=0.0), (5.0, 0.0), 8.0)
    t, acc, vel = rows[:, 0], rows[:, 1], rows[:, 2]
    at = lambda x, col: col[np.searchsorted(t, x - 1e-9)]  # noqa: E731
    assert at(0.25, acc) == pytest.approx(1.25, abs=0.02)
    assert at(0.5, acc) == pytest.approx(2.5, abs=0.02)
    assert at(0.5, vel) == pytest.approx(0.625, abs=0.01)
    assert at(1.5, vel) == pytest.approx(0.625 + 2.5 * 1.0, abs=0.01)
    assert acc.max() <= 2.5 + 1e-9
    assert vel.max() <= 5.0 + 1e-9
    assert vel[-1] == pytest.approx(5.0, abs=1e-3)


def test_the_vehicle_catches_the_trajectory_and_holds_its_position():
    # The position loop ties the vehicle to the trajectory: in the steady state no velocity or
    # position error is left (the integrator takes nothing once the error is gone).
    rows = _trajectory(PosControlParams(), (3.0, 0.0), 20.0)
    vel, pos, desired_pos = rows[:, 3], rows[:, 4], rows[:, 5]
    assert vel[-1] == pytest.approx(3.0, abs=1e-3)
    assert pos[-1] == pytest.approx(desired_pos[-1], abs=0.01)


def test_velocity_control_starts_from_the_acceleration_the_vehicle_flies():
    # init_NE_controller: the trajectory's acceleration starts at zero and the velocity loop's
    # integrator takes what the airframe pushes with (the acceleration flown plus the drag at
    # 3 m/s: 0.243 x 3 + 0.0316 x 9 = 1.0134 m/s^2), so the first command carries it on.
    ctl = NEPositionController(PosControlParams(input_delay_s=0.0, airframe_lag_s=0.0))
    ctl.reset((0.0, 0.0), (3.0, 0.0), (1.0, 0.5))
    assert ctl.desired_acc_ne_m_s2 == (0.0, 0.0)
    assert ctl._integrator == pytest.approx((1.0 + 0.243 * 3 + 0.0316 * 9, 0.5))
    # after one step the vehicle lags the trajectory by 3 m/s x 2.5 ms: 2 (1/s) x 1 (1/s) x 7.5 mm
    assert ctl.update(0.0025, (3.0, 0.0), (0.0, 0.0), (3.0, 0.0)) == pytest.approx((1.0 + 0.015, 0.5), abs=2e-3)
    # behind the airframe's lag the flown acceleration moves by that step times 1 - exp(-dt / lag)
    lagged = NEPositionController(PosControlParams(input_delay_s=0.0))
    lagged.reset((0.0, 0.0), (3.0, 0.0), (1.0, 0.5))
    k = 1.0 - math.exp(-0.0025 / 0.18)
    assert lagged.update(0.0025, (3.0, 0.0), (0.0, 0.0), (3.0, 0.0)) == pytest.approx((1.0 + 0.015 * k, 0.5), abs=1e-4)


def test_the_velocity_loop_integrator_holds_the_drag_at_a_steady_speed():
    # At a steady 5 m/s the trajectory's acceleration is zero, so all of what the airframe pushes
    # with comes from the integrator, and it must equal the drag: 0.243 x 5 + 0.0316 x 25 = 2.005
    # m/s^2 (ArduCopter SITL's copter leans atan(2.005 / 9.80665) = 11.6 deg; its flights show 11.3-11.8).
    ctl = NEPositionController(PosControlParams())
    ctl.reset((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    pos, vel = [0.0, 0.0], [0.0, 0.0]
    for _ in range(16000):  # 40 s at 400 Hz
        a = ctl.update(0.0025, (5.0, 0.0), tuple(pos), tuple(vel))
        pos[0] += vel[0] * 0.0025 + 0.5 * a[0] * 0.0025**2
        vel[0] += a[0] * 0.0025
    assert vel[0] == pytest.approx(5.0, abs=1e-3)  # the vehicle's speed
    assert ctl._integrator[0] == pytest.approx(0.243 * 5 + 0.0316 * 25, rel=1e-3)
    assert ctl.drag_ne_m_s2((3.0, 4.0)) == pytest.approx(((0.243 + 0.0316 * 5) * 3, (0.243 + 0.0316 * 5) * 4))


def test_the_input_delay_shifts_the_response():
    dt = 0.0025
    early = _trajectory(PosControlParams(input_delay_s=0.0), (5.0, 0.0), 3.0, dt)
    late = _trajectory(PosControlParams(input_delay_s=0.1), (5.0, 0.0), 3.1, dt)
    shift = round(0.1 / dt)
    assert np.allclose(late[shift:, 1], early[: len(late) - shift, 1], atol=1e-9)
    assert np.all(late[: shift - 1, 1] == 0.0)


def _free_run(s, params: PosControlParams) -> tuple[np.ndarray, np.ndarray]:
    """The chain driven by a real flight's own velocity targets from its first one on (free run:
    the model's state is its own); (measured, emulated) velocities on the flight's grid from there."""
    k0 = int(np.argmax(s.valid))
    t, measured = s.t_s[k0:], smoothed(s)[k0:]
    dt = 0.0025
    grid = np.arange(t[0], t[-1], dt)
    cmd = np.column_stack([np.interp(grid, s.t_cmd_s, s.vel_cmd_raw_ne_m_s[:, i]) for i in range(2)])
    ctl = NEPositionController(params)
    pos, vel = np.zeros(2), measured[0].copy()
    ctl.reset(tuple(pos), tuple(vel), (0.0, 0.0))
    flown = np.zeros_like(cmd)
    for k in range(len(grid)):
        a = np.array(ctl.update(dt, tuple(cmd[k]), tuple(pos), tuple(vel)))
        pos += vel * dt + 0.5 * a * dt * dt
        vel += a * dt
        flown[k] = vel
    return measured, np.column_stack([np.interp(t, grid, flown[:, i]) for i in range(2)])


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


SHARED_AP_FLIGHTS = ["ardupilot-copter-id.tlog", "ardupilot-copter-racetrack-predictive.tlog",
                     "ardupilot-copter-figure-eight-corrector.tlog"]


@pytest.mark.parametrize("name", SHARED_AP_FLIGHTS)
def test_the_emulated_controller_predicts_the_real_arducopter_better_than_a_first_order_lag(name):
    # The emulated chain's velocity stays closer to what the real ArduCopter SITL flew than the
    # first-order model identified from the same identification flight (docs/vehicle_model.md).
    s = read_identification_samples(REAL / name)
    measured, emulated = _free_run(s, PosControlParams())
    k0 = int(np.argmax(s.valid))
    t = s.t_s[k0:]

    m = IDENTIFIED_COPTER_MODELS["ardupilot"]
    theta = (m["delay_s"], m["lag_s"], m["a_max_m_s2"], m["speed_sag_s"], m["accel_lag_s"])
    window = s.__class__(**{**s.__dict__, "t_s": t, "vel_ne_m_s": s.vel_ne_m_s[k0:],
                            "valid": np.ones(len(t), bool), "pos_ne_m": None})
    acc, _ = simulate(window, theta)
    first_order = measured[0] + np.vstack([np.zeros(2), np.cumsum(acc[:-1] * np.diff(t)[:, None], axis=0)])

    assert _rms(emulated, measured) < 0.1
    assert _rms(emulated, measured) < 0.6 * _rms(first_order, measured)


@pytest.mark.parametrize("name", SHARED_AP_FLIGHTS)
def test_the_airframe_with_drag_predicts_the_real_arducopter_better_than_a_dead_time_alone(name):
    # The chain behind a dead time alone (0.13 s, the best dead time without drag or lag on the
    # identification flight) against the chain with the airframe's drag and lag: the drag was
    # measured, the dead time and lag fitted, on the identification flight only; the two mission
    # flights were used for neither.
    s = read_identification_samples(REAL / name)
    measured, with_drag = _free_run(s, PosControlParams())
    _, dead_time = _free_run(s, PosControlParams(input_delay_s=0.13, airframe_lag_s=0.0, drag_linear_1_s=0.0,
                                                 drag_quadratic_1_m=0.0))
    assert _rms(with_drag, measured) < 0.85 * _rms(dead_time, measured)


def test_the_mock_arducopter_flies_guided_velocity_targets_through_its_position_controller():
    # From a hover, 5 m/s north: the trajectory's dead time, then the jerk ramp and 2.5 m/s^2;
    # 1.5 s after the target the trajectory is at 0.625 + 2.5 (1.5 - 0.02 - 0.5) = 3.075 m/s and
    # the vehicle, behind the airframe's lag (0.18 s x 2.5 m/s^2 = 0.45 m/s) and pulled along by
    # the position loop, between 2.6 m/s and that. It then overshoots while it catches up with
    # its trajectory (the real SITL's launches peak at 5.07 m/s about 5 s after the target) and
    # holds 5 m/s 12 s after it, its integrator then holding the drag.
    f = make("ardupilot", posctl=PosControlParams())
    assert f.set_mode(f.pers.mode_named("GUIDED")) == fl.MAV_RESULT_ACCEPTED
    advance(f, 1.5, vel_setpoint(5.0, 0.0))
    assert 2.6 < f.model.state.vel_ned_m_s[0] < 3.075
    advance(f, 3.5, vel_setpoint(5.0, 0.0))
    assert 5.0 < f.model.state.vel_ned_m_s[0] < 5.15
    advance(f, 7.0, vel_setpoint(5.0, 0.0))
    st = f.model.state
    assert st.vel_ned_m_s[0] == pytest.approx(5.0, abs=0.01)
    # cruising, it leans into the drag as the real does: its attitude's thrust points 0.243 x 5
    # + 0.0316 x 25 = 2.005 m/s^2 north (pitch 11.6 deg when facing north)
    a_fwd, a_right = -9.80665 * math.tan(st.pitch_rad), 9.80665 * math.tan(st.roll_rad)
    cy, sy = math.cos(st.yaw_rad), math.sin(st.yaw_rad)
    assert (cy * a_fwd - sy * a_right, sy * a_fwd + cy * a_right) == pytest.approx((2.005, 0.0), abs=0.02)
    # a position target leaves it; the next velocity target starts a new trajectory from the vehicle
    advance(f, 2.0, (fl.MAV_FRAME_LOCAL_NED, 0b0000_1111_1111_1000, tuple(f.model.state.pos_ned_m),
                     (0, 0, 0), (0, 0, 0), 0.0, 0.0))
    assert not f._posctl_flying
    advance(f, DT_S, vel_setpoint(0.0, 3.0))
    assert f._posctl_flying
    assert f.posctl.desired_vel_ne_m_s == pytest.approx(tuple(f.model.state.vel_ned_m_s[:2]), abs=0.05)


def test_the_drag_is_what_the_real_arducopter_leans_against_at_steady_speeds():
    # Independent of the chain: in the shared identification flight, at a steady speed (measured
    # acceleration under 0.15 m/s^2) the thrust's horizontal part, g tan(tilt) from ATTITUDE, holds
    # the drag. Its median along the velocity at 3, 5 and 8 m/s is the drag the mock's airframe has,
    # within 5 %.
    from scipy.signal import savgol_filter

    from companion.io.logread import TlogReader

    att, lpn = [], []
    for rec in TlogReader(REAL / "ardupilot-copter-id.tlog"):
        msg = rec.msg
        if msg is not None and msg.get_type() == "ATTITUDE":
            att.append((msg.time_boot_ms * 1e-3, msg.roll, msg.pitch, msg.yaw))
        elif msg is not None and msg.get_type() == "LOCAL_POSITION_NED":
            lpn.append((msg.time_boot_ms * 1e-3, msg.vx, msg.vy))
    a, m = np.array(att), np.array(lpn)
    t, v = m[:, 0], m[:, 1:3]
    acc = savgol_filter(np.gradient(v, t, axis=0), 11, 2, axis=0)
    roll, pitch, yaw = (np.interp(t, a[:, 0], np.unwrap(a[:, i])) for i in (1, 2, 3))
    # the body z axis in NED (third column of the body-to-NED rotation), thrust along -z
    zn = np.cos(yaw) * np.sin(pitch) * np.cos(roll) + np.sin(yaw) * np.sin(roll)
    ze = np.sin(yaw) * np.sin(pitch) * np.cos(roll) - np.cos(yaw) * np.sin(roll)
    zd = np.cos(pitch) * np.cos(roll)
    speed = np.hypot(v[:, 0], v[:, 1])
    u = v / np.maximum(speed, 1e-6)[:, None]
    thrust_along = -9.80665 * (zn * u[:, 0] + ze * u[:, 1]) / zd
    drag = thrust_along - (acc[:, 0] * u[:, 0] + acc[:, 1] * u[:, 1])
    steady = np.hypot(acc[:, 0], acc[:, 1]) < 0.15
    ctl = NEPositionController(PosControlParams())
    for target in (3.0, 5.0, 8.0):
        near = steady & (np.abs(speed - target) < 0.5)
        assert near.sum() > 200
        measured = float(np.median(drag[near]))
        model = math.hypot(*ctl.drag_ne_m_s2((float(np.mean(speed[near])), 0.0)))
        assert model == pytest.approx(measured, rel=0.05)


def _circle_lag_m_s(feed_forward: bool, v_m_s: float = 5.0, a_m_s2: float = 2.0) -> float:
    """The shaped trajectory's steady velocity lag behind a target turning at ``a / V``, the target
    sent afresh at 50 Hz (with its centripetal acceleration when ``feed_forward``)."""
    ctl = NEPositionController(PosControlParams(input_delay_s=0.0))
    omega, dt = a_m_s2 / v_m_s, 0.0025
    ctl.reset((0.0, 0.0), (v_m_s, 0.0), (0.0, 0.0))
    sent = 0.0
    for k in range(int(20.0 / dt)):
        t = k * dt
        if t >= sent + 0.02 - 1e-9 or k == 0:
            sent = t
        c, s = math.cos(omega * sent), math.sin(omega * sent)
        acc = (-a_m_s2 * s, a_m_s2 * c) if feed_forward else (0.0, 0.0)
        ctl.update(dt, (v_m_s * c, v_m_s * s), ctl.desired_pos_ne_m, ctl.desired_vel_ne_m_s, acc, sent)
    t = 20.0
    target = (v_m_s * math.cos(omega * t), v_m_s * math.sin(omega * t))
    return math.hypot(target[0] - ctl.desired_vel_ne_m_s[0], target[1] - ctl.desired_vel_ne_m_s[1])


def test_without_feed_forward_the_trajectory_lags_a_turning_target_by_v_omega_over_kpa():
    # shape_vel_accel_xy closes the velocity error with KPa = jerk / accel = 2 1/s (linear below
    # 5 / 2^2 = 1.25 m/s): to turn at V omega = 2 m/s^2 it needs an error of 2 / 2 = 1 m/s.
    assert _circle_lag_m_s(False) == pytest.approx(1.0, rel=0.03)


def test_with_the_acceleration_target_the_trajectory_turns_with_the_target():
    # The target acceleration is added after the correction's limit and moves GUIDED's own target
    # on between setpoints: the correction has nothing steady left to do (what is left is the
    # chord of one 20 ms hold, V omega dt / 2 = 0.02 m/s).
    assert _circle_lag_m_s(True) < 0.03
