"""The point-mass model against closed forms: first-order lags, limits, coordinated turns, seeds."""

from __future__ import annotations

import math

import pytest

from sitl_mock.vehicle import GRAVITY_M_S2, VehicleModel, VehicleParams

DT_S = 1.0 / 400.0


def copter(**kw) -> VehicleModel:
    return VehicleModel(VehicleParams(kind="copter", **kw), (0.0, 0.0, -10.0), 0.0, airborne=True)


def run(model: VehicleModel, seconds: float, vel=(0.0, 0.0, 0.0), yaw_rate=0.0) -> None:
    for _ in range(round(seconds / DT_S)):
        model.step_multirotor(DT_S, vel, yaw_rate)


@pytest.mark.parametrize("tau_s", [0.1, 0.3, 0.8])
def test_yaw_rate_step_reaches_63_percent_after_one_time_constant(tau_s):
    model = copter(tau_yaw_rate_s=tau_s)
    command = math.radians(30.0)  # below the 90 deg/s limit
    run(model, tau_s, yaw_rate=command)
    assert model.state.yaw_rate_rad_s / command == pytest.approx(1.0 - math.exp(-1.0), abs=1e-6)
    run(model, 4 * tau_s, yaw_rate=command)
    assert model.state.yaw_rate_rad_s / command == pytest.approx(1.0 - math.exp(-5.0), abs=1e-6)


def test_velocity_step_below_the_acceleration_limit_follows_the_first_order_lag():
    # 1 m/s step with tau 0.3 s: the largest acceleration is 1/0.3 = 3.3 m/s^2 < 5 m/s^2.
    model = copter(tau_vel_s=0.3)
    run(model, 0.3, vel=(1.0, 0.0, 0.0))
    assert model.state.vel_ned_m_s[0] == pytest.approx(1.0 - math.exp(-1.0), abs=1e-6)
    # Position of a first-order lag step: x(t) = v (t - tau (1 - exp(-t/tau))).
    expected_x = 1.0 * (0.3 - 0.3 * (1.0 - math.exp(-1.0)))
    assert model.state.pos_ned_m[0] == pytest.approx(expected_x, abs=2e-4)


def test_large_velocity_step_is_acceleration_limited():
    model = copter(tau_vel_s=0.3, a_max_m_s2=2.0)
    speeds = []
    for _ in range(round(1.0 / DT_S)):
        model.step_multirotor(DT_S, (6.0, 8.0, 0.0), 0.0)  # 10 m/s, diagonal
        speeds.append(math.hypot(*model.state.vel_ned_m_s[:2]))
    accels = [(b - a) / DT_S for a, b in zip([0.0] + speeds, speeds)]
    assert max(accels) <= 2.0 + 1e-9
    # Saturated the whole second: exactly a_max * t, along the commanded direction.
    assert speeds[-1] == pytest.approx(2.0, abs=1e-9)
    assert model.state.vel_ned_m_s[1] / model.state.vel_ned_m_s[0] == pytest.approx(8.0 / 6.0)


def test_yaw_rate_command_is_clipped_to_the_limit():
    model = copter(yaw_rate_max_rad_s=math.radians(45.0), tau_yaw_rate_s=0.1)
    run(model, 2.0, yaw_rate=math.radians(400.0))
    assert model.state.yaw_rate_rad_s == pytest.approx(math.radians(45.0), rel=1e-6)


def test_yaw_stays_wrapped_to_plus_minus_pi():
    model = copter(tau_yaw_rate_s=0.0)
    run(model, 5.0, yaw_rate=math.radians(80.0))  # 400 degrees
    assert -math.pi < model.state.yaw_rad <= math.pi
    assert math.degrees(model.state.yaw_rad) == pytest.approx(40.0, abs=0.5)


def test_copter_lands_on_the_ground_and_stays_there():
    model = copter(tau_vel_s=0.1)
    run(model, 8.0, vel=(0.0, 0.0, 3.0))
    assert model.state.pos_ned_m[2] == 0.0
    assert model.state.on_ground
    assert model.state.vel_ned_m_s == [0.0, 0.0, 0.0]


def test_plane_turns_at_g_tan_roll_over_v_on_a_circle_of_radius_v2_over_g_tan_roll():
    params = VehicleParams(kind="plane", airspeed_cruise_m_s=15.0, tau_roll_s=0.0)
    model = VehicleModel(params, (0.0, 0.0, -100.0), 0.0, airborne=True)
    roll = math.radians(30.0)
    model.step_plane(DT_S, roll, 15.0, 0.0)
    expected_rate = GRAVITY_M_S2 * math.tan(roll) / 15.0
    assert model.state.yaw_rate_rad_s == pytest.approx(expected_rate, rel=1e-9)
    radius = 15.0 ** 2 / (GRAVITY_M_S2 * math.tan(roll))
    # Half a turn to the right from heading north: the plane ends 2R east of where it started.
    half_turn_s = math.pi / expected_rate
    for _ in range(round(half_turn_s / DT_S) - 1):
        model.step_plane(DT_S, roll, 15.0, 0.0)
    assert model.state.pos_ned_m[1] == pytest.approx(2.0 * radius, rel=2e-3)
    assert abs(model.state.pos_ned_m[0]) < 0.01 * radius


def test_plane_never_flies_below_its_minimum_airspeed():
    params = VehicleParams(kind="plane", airspeed_cruise_m_s=15.0, airspeed_min_m_s=11.0)
    model = VehicleModel(params, (0.0, 0.0, -100.0), 0.0, airborne=True)
    for _ in range(round(10.0 / DT_S)):
        model.step_plane(DT_S, 0.0, 0.0, 0.0)
    assert model.state.airspeed_m_s == pytest.approx(11.0)


def test_plane_bank_is_limited_and_lags_with_its_time_constant():
    params = VehicleParams(kind="plane", tau_roll_s=0.5, roll_max_rad=math.radians(35.0))
    model = VehicleModel(params, (0.0, 0.0, -100.0), 0.0, airborne=True)
    for _ in range(round(0.5 / DT_S)):
        model.step_plane(DT_S, math.radians(90.0), 15.0, 0.0)
    assert model.state.roll_rad == pytest.approx(math.radians(35.0) * (1 - math.exp(-1.0)), rel=1e-6)


def test_plane_drifts_with_the_wind():
    params = VehicleParams(kind="plane", wind_ned_m_s=(0.0, 5.0))
    model = VehicleModel(params, (0.0, 0.0, -100.0), 0.0, airborne=True)
    for _ in range(round(10.0 / DT_S)):
        model.step_plane(DT_S, 0.0, 15.0, 0.0)
    assert model.state.pos_ned_m[0] == pytest.approx(150.0, rel=1e-3)
    assert model.state.pos_ned_m[1] == pytest.approx(50.0, rel=1e-3)


def test_rover_stays_on_the_ground_and_points_along_its_track():
    model = VehicleModel(VehicleParams(kind="rover", a_max_m_s2=3.0), (0.0, 0.0, -5.0), 0.0, airborne=True)
    for _ in range(round(5.0 / DT_S)):
        model.step_multirotor(DT_S, (1.0, 1.0, -2.0), 0.0)
    assert model.state.pos_ned_m[2] == 0.0
    assert math.degrees(model.state.yaw_rad) == pytest.approx(45.0, abs=0.1)


def noisy_track(seed: int) -> list[tuple[float, float, float]]:
    model = VehicleModel(VehicleParams(kind="copter", pos_noise_m=0.5, seed=seed), (0.0, 0.0, -10.0), 0.0, True)
    track = []
    for i in range(400):
        model.step_multirotor(DT_S, (2.0, math.sin(i / 50.0), 0.0), 0.3)
        track.append(model.measured_pos_ned_m())
    return track


def test_same_seed_same_track_and_another_seed_another_track():
    assert noisy_track(7) == noisy_track(7)
    assert noisy_track(7) != noisy_track(8)


def test_noise_has_the_requested_spread():
    model = VehicleModel(VehicleParams(kind="copter", pos_noise_m=0.5, seed=3), (0.0, 0.0, 0.0), 0.0, False)
    samples = []
    for _ in range(4000):
        model.step_multirotor(DT_S, (0.0, 0.0, 0.0), 0.0, grounded=True)
        samples.append(model.measured_pos_ned_m()[0])
    mean = sum(samples) / len(samples)
    std = math.sqrt(sum((s - mean) ** 2 for s in samples) / len(samples))
    assert abs(mean) < 0.05
    assert std == pytest.approx(0.5, rel=0.05)


def test_invalid_parameters_are_refused_with_the_field_named():
    with pytest.raises(ValueError, match="a_max_m_s2"):
        VehicleParams(a_max_m_s2=-1.0)
    with pytest.raises(ValueError, match="vehicle kind"):
        VehicleParams(kind="boat")


# ------------------------------------------------------------------ the identified model's extras


def test_a_delayed_velocity_step_is_the_first_order_step_shifted_by_the_delay():
    model = copter(tau_vel_s=0.3, delay_s=0.2)
    run(model, 0.2 - DT_S, vel=(1.0, 0.0, 0.0))
    assert model.state.vel_ned_m_s[0] == 0.0  # nothing before the dead time has passed
    run(model, 0.3 + DT_S, vel=(1.0, 0.0, 0.0))
    assert model.state.vel_ned_m_s[0] == pytest.approx(1.0 - math.exp(-1.0), abs=1e-2)


def test_the_acceleration_feed_forward_waits_out_the_same_dead_time():
    # A hover asked to hold zero velocity and to accelerate north at 1 m/s^2: nothing happens for
    # the 0.2 s dead time, then the loop (tau 10 s: it barely pulls back) gathers about 1 m/s per second.
    model = copter(tau_vel_s=10.0, delay_s=0.2)
    for _ in range(round(0.2 / DT_S) - 1):
        model.step_multirotor(DT_S, (0.0, 0.0, 0.0), 0.0, (1.0, 0.0, 0.0))
    assert model.state.vel_ned_m_s[0] == 0.0
    for _ in range(round(0.5 / DT_S) + 1):
        model.step_multirotor(DT_S, (0.0, 0.0, 0.0), 0.0, (1.0, 0.0, 0.0))
    # v' = 1 - v / 10 from v = 0: v(0.5) = 10 (1 - exp(-0.05))
    assert model.state.vel_ned_m_s[0] == pytest.approx(10.0 * (1.0 - math.exp(-0.05)), abs=5e-3)


def test_a_second_acceleration_lag_gives_the_second_order_step_response():
    # The acceleration the loop asks for, (c - v) / t1, is followed through a lag t2:
    # t1 t2 v'' + t1 v' + v = c; for t1 = 0.3, t2 = 0.1 underdamped, s = -1/(2 t2) +- i w with
    # w = sqrt(1/(t1 t2) - 1/(4 t2^2)), and v(t) = 1 - exp(-t/(2 t2)) (cos wt + sin(wt) / (2 t2 w)).
    t1, t2, t = 0.3, 0.1, 0.5
    model = copter(tau_vel_s=t1, accel_lag_s=t2)
    run(model, t, vel=(1.0, 0.0, 0.0))
    w = math.sqrt(1.0 / (t1 * t2) - 1.0 / (4.0 * t2 * t2))
    expected = 1.0 - math.exp(-t / (2.0 * t2)) * (math.cos(w * t) + math.sin(w * t) / (2.0 * t2 * w))
    assert model.state.vel_ned_m_s[0] == pytest.approx(expected, abs=5e-3)


def test_speed_sag_slows_a_steady_turn_by_sag_times_lateral_acceleration():
    # Command a velocity rotating at w = 0.4 rad/s at 5 m/s (2 m/s^2 asked): in the steady turn
    # the speed V solves V = 5 - sag * V * w (no limit reached, lag small).
    sag, w = 0.2, 0.4
    model = copter(tau_vel_s=0.05, speed_sag_s=sag)
    course = 0.0
    for _ in range(round(20.0 / DT_S)):
        course += w * DT_S
        model.step_multirotor(DT_S, (5.0 * math.cos(course), 5.0 * math.sin(course), 0.0), 0.0)
    speed = math.hypot(*model.state.vel_ned_m_s[:2])
    # the lag alone rotates and shrinks the velocity by 1 / sqrt(1 + (w tau)^2): 0.02 % here
    assert speed == pytest.approx(5.0 / (1.0 + sag * w), rel=5e-3)


def test_a_slow_tail_gives_the_step_response_of_its_two_state_linear_system():
    # A 1 m/s step, below the limit. With w = c - v the velocity error and f its low-pass:
    #   w' = -(w - s f) / tau,  f' = (w - f) / T,  w(0) = 1, f(0) = 0,
    # so [w, f](t) = expm(A t) [1, 0], A = [[-1/tau, s/tau], [1/T, -1/T]] (scipy's expm, not the
    # mock's stepping). Fast at first (slope 1/tau), then slow: eigenvalues of A.
    from scipy.linalg import expm

    tau, share, tc = 0.45, 0.85, 1.0
    model = copter(tau_vel_s=tau, tail_share=share, tail_tc_s=tc, a_max_m_s2=10.0)
    a = [[-1.0 / tau, share / tau], [1.0 / tc, -1.0 / tc]]
    elapsed = 0.0
    for t in (0.45, 1.0, 3.0, 6.0):
        run(model, t - elapsed, vel=(1.0, 0.0, 0.0))
        elapsed = t
        w = expm([[x * t for x in row] for row in a])[0][0]
        assert model.state.vel_ned_m_s[0] == pytest.approx(1.0 - w, abs=0.005), t
    # The tail is what makes it slow: a first-order lag of 0.45 s is within 0.2 % after 3 s,
    # this one is still short by more than 10 %.
    assert 1.0 - math.exp(-3.0 / tau) > 0.998
    assert 1.0 - expm([[x * 3.0 for x in row] for row in a])[0][0] < 0.9


def run_with_target(model: VehicleModel, seconds: float, acc_ff) -> None:
    for _ in range(round(seconds / DT_S)):
        model.step_multirotor(DT_S, (0.0, 0.0, 0.0), 0.0, acc_ff)


@pytest.mark.parametrize("share, gain, ff_lag", [(0.0, 1.0, 0.0), (0.0, 1.3, 0.15), (0.85, 1.3, 0.15)])
def test_the_acceleration_target_joins_the_demand_before_the_slow_tail(share, gain, ff_lag):
    # Hovering, commanded to stay (c = 0) and given a constant target a0. The target through its
    # lag, q, joins the demand as the velocity error q tau that would ask for it, so with E the
    # whole error and f its low-pass:
    #   v' = (E - s f) / tau,  E = -v + q tau,  f' = (E - f) / T,  q' = (g a0 - q) / T_ff,
    # a linear system solved by scipy's expm (augmented with the constant input). With s = 0,
    # g = 1 and no lag it is the target added as sent: v = a0 tau (1 - exp(-t / tau)).
    import numpy as np
    from scipy.linalg import expm

    tau, tc, a0 = 0.45, 1.0, 1.0
    model = copter(tau_vel_s=tau, tail_share=share, tail_tc_s=tc, accel_ff_gain=gain, accel_ff_lag_s=ff_lag,
                   a_max_m_s2=10.0)
    # state [v, f, q, 1]
    q_rate = (-1.0 / ff_lag, gain * a0 / ff_lag) if ff_lag > 0 else None
    a = np.zeros((4, 4))
    a[0, :3] = (-1.0 / tau, -share / tau, 1.0)
    a[1, :3] = (-1.0 / tc, -1.0 / tc, tau / tc)
    x0 = np.array([0.0, 0.0, 0.0, 1.0])
    if q_rate is not None:
        a[2, 2], a[2, 3] = q_rate
    else:
        x0[2] = gain * a0  # no lag: the target is there from the start
    elapsed = 0.0
    for t in (0.2, 0.5, 1.0, 3.0):
        run_with_target(model, t - elapsed, (a0, 0.0, 0.0))
        elapsed = t
        v = (expm(a * t) @ x0)[0]
        # within 1 %, or the velocity one physics step of the target gives (the stepping leads the
        # continuous lag by half a step)
        assert model.state.vel_ned_m_s[0] == pytest.approx(v, abs=max(0.01 * abs(v), gain * a0 * DT_S)), t
    if share == 0.0 and gain == 1.0 and ff_lag == 0.0:
        assert model.state.vel_ned_m_s[0] == pytest.approx(a0 * tau * (1.0 - math.exp(-3.0 / tau)), rel=0.01)


def test_the_slow_tail_share_is_bounded():
    with pytest.raises(ValueError, match="tail_share"):
        VehicleParams(kind="copter", tail_share=0.99)
    with pytest.raises(ValueError, match="tail_tc_s"):
        VehicleParams(kind="copter", tail_share=0.5, tail_tc_s=0.0)


@pytest.mark.parametrize("smooth_s", [0.0, 3.0])
def test_velocity_estimate_bias_drifts_the_position_as_a_gauss_markov_process(smooth_s):
    # The loop holds its (biased) velocity estimate at the command, so the reported velocity stays
    # at 0 while the position drifts by the bias. For a first-order Gauss-Markov bias (sigma, tau)
    # the position change over T has the mean square 2 sigma^2 tau^2 (T/tau - 1 + exp(-T/tau))
    # per axis; 2000 s hold 500 independent windows of tau per axis, so the measured RMS lies
    # within 10 % of the closed form (about 3 standard errors at the longest lag). Flown through a
    # low-pass tau2, 2 sigma^2 tau / (tau^2 - tau2^2) (tau f(tau) - tau2 f(tau2)), f(c) = c T - c^2
    # (1 - exp(-T / c)) (the bias's autocovariance integrated twice).
    sigma, tau, dt, seconds = 0.25, 4.0, 0.02, 2000.0
    model = copter(vel_bias_m_s=sigma, vel_bias_tc_s=tau, vel_bias_smooth_s=smooth_s, seed=11)
    n = round(seconds / dt)
    north, east = [], []
    for _ in range(n):
        model.step_multirotor(dt, (0.0, 0.0, 0.0), 0.0)
        north.append(model.state.pos_ned_m[0])
        east.append(model.state.pos_ned_m[1])
    assert max(abs(v) for v in model.state.vel_ned_m_s) < 1e-12

    def f(c: float, lag_s: float) -> float:
        return c * lag_s - c * c * (1.0 - math.exp(-lag_s / c))

    for lag_s in (0.5, 1.0, 10.0):
        k = round(lag_s / dt)
        sq = [(a[i + k] - a[i]) ** 2 for a in (north, east) for i in range(n - k)]
        measured = math.sqrt(sum(sq) / len(sq))
        if smooth_s > 0.0:
            var = tau / (tau**2 - smooth_s**2) * (tau * f(tau, lag_s) - smooth_s * f(smooth_s, lag_s))
        else:
            var = f(tau, lag_s)
        expected = math.sqrt(2.0 * sigma**2 * var)
        assert measured == pytest.approx(expected, rel=0.1), (lag_s, measured, expected)


def test_a_bias_quicker_than_the_loop_shows_in_the_reported_velocity_and_the_rest_is_flown():
    # With vel_bias_loop_s = L the vehicle flies its bias b through a first-order lag L (f) and the
    # reported velocity carries f - b. b - f is b through the high-pass L s / (1 + L s): for a
    # first-order Gauss-Markov b (sigma, tau) its variance is sigma^2 L / (tau + L) (cov(b, f) =
    # var(f) = sigma^2 tau / (tau + L)). The position drifts by the flown part, whose change over
    # T has the smoothed bias's mean square with tau2 = L (the closed form of the test above).
    sigma, tau, loop, dt, seconds = 0.25, 4.0, 0.5, 0.02, 2000.0
    model = copter(vel_bias_m_s=sigma, vel_bias_tc_s=tau, vel_bias_loop_s=loop, seed=11)
    n = round(seconds / dt)
    north, east, reported = [], [], []
    for _ in range(n):
        model.step_multirotor(dt, (0.0, 0.0, 0.0), 0.0)
        north.append(model.state.pos_ned_m[0])
        east.append(model.state.pos_ned_m[1])
        reported.extend(model.reported_vel_ned_m_s()[:2])
    assert max(abs(v) for v in model.state.vel_ned_m_s) < 1e-12  # the loop's own velocity stays put
    measured = math.sqrt(sum(v * v for v in reported) / len(reported))
    assert measured == pytest.approx(sigma * math.sqrt(loop / (tau + loop)), rel=0.1)

    def f(c: float, lag_s: float) -> float:
        return c * lag_s - c * c * (1.0 - math.exp(-lag_s / c))

    for lag_s in (1.0, 10.0):
        k = round(lag_s / dt)
        sq = [(a[i + k] - a[i]) ** 2 for a in (north, east) for i in range(n - k)]
        var = tau / (tau**2 - loop**2) * (tau * f(tau, lag_s) - loop * f(loop, lag_s))
        assert math.sqrt(sum(sq) / len(sq)) == pytest.approx(math.sqrt(2.0 * sigma**2 * var), rel=0.1), lag_s
    smooth = copter(vel_bias_m_s=sigma, vel_bias_tc_s=tau, seed=11)  # without the key: nothing reported
    run(smooth, 10.0)
    assert smooth.reported_vel_ned_m_s() == tuple(smooth.state.vel_ned_m_s)
    model.state.on_ground = True  # landed: it reports standing still
    assert model.reported_vel_ned_m_s() == (0.0, 0.0, 0.0) and model._reported_rest_ne_m_s != (0.0, 0.0)


@pytest.mark.parametrize("radius_m, level", [(None, 0.01), (25.0, math.hypot(0.01, 0.04 * 0.2)),
                                               (5.0, math.hypot(0.01, 0.04 * 1.0))])
def test_the_bias_settles_to_the_level_the_manoeuvre_jerk_sets(radius_m, level):
    # A circle flown at v has a constant jerk v^3 / r^2 (the acceleration v^2 / r turning at v / r):
    # at 5 m/s, 0.2 m/s^3 on a 25 m circle and 5 m/s^3 on a 5 m one (capped at 1). Holding it,
    # the bias settles to sqrt(0.01^2 + (0.04 min(j, 1))^2) per axis; a hover (None) to 0.01.
    # 600 s hold about 370 correlation times per axis: the RMS of the bias lies within 12 % of
    # the level (about 3 standard errors).
    v, dt = 5.0, 0.01
    model = copter(vel_bias_m_s=0.01, vel_bias_tc_s=1.63, vel_bias_jerk_s2=0.04, vel_bias_jerk_max_m_s3=1.0,
                   tau_vel_s=0.05, seed=5)
    omega = 0.0 if radius_m is None else v / radius_m
    speed = 0.0 if radius_m is None else v
    squares = []
    for i in range(round(620.0 / dt)):
        course = omega * i * dt
        model.step_multirotor(dt, (speed * math.cos(course), speed * math.sin(course), 0.0), 0.0)
        if i * dt >= 20.0:  # past the start, the jerk's low-pass and the bias settled
            squares += [b * b for b in model._bias_ne_m_s]
    assert math.sqrt(sum(squares) / len(squares)) == pytest.approx(level, rel=0.12)


def test_a_velocity_offset_is_drawn_once_per_seed_and_flown_at_a_constant_rate():
    # Holding a zero velocity estimate, the copter moves at its offset: the same displacement in
    # every second, with the reported velocity at 0. Over 400 seeds the offsets on both axes (800
    # draws of N(0, 0.05)) have a standard deviation within 10 % of 0.05 (the estimate's own
    # spread is 2.5 %) and a mean within 3 standard errors (0.0053) of 0. The same seed draws the
    # same offset.
    sigma, dt = 0.05, 0.1
    rates = []
    for seed in range(400):
        model = copter(vel_offset_m_s=sigma, seed=seed)
        marks = []
        for _ in range(2):
            start = tuple(model.state.pos_ned_m[:2])
            run_at(model, 1.0, dt)
            marks.append((model.state.pos_ned_m[0] - start[0], model.state.pos_ned_m[1] - start[1]))
        assert marks[1] == pytest.approx(marks[0], abs=1e-12)
        assert max(abs(v) for v in model.state.vel_ned_m_s) < 1e-12
        rates.extend(marks[0])
    mean = sum(rates) / len(rates)
    spread = math.sqrt(sum((r - mean) ** 2 for r in rates) / (len(rates) - 1))
    assert spread == pytest.approx(sigma, rel=0.1)
    assert abs(mean) < 3.0 * sigma / math.sqrt(len(rates))
    again = copter(vel_offset_m_s=sigma, seed=0)
    run_at(again, 1.0, dt)
    assert tuple(again.state.pos_ned_m[:2]) == pytest.approx(tuple(rates[:2]), abs=1e-12)


def test_an_offset_beside_the_bias_leaves_the_bias_as_it_was():
    # The offset draws from its own stream: with it, the track is the bias's own track plus the
    # offset's constant rate (so adding one to a model does not change the other's flights).
    alone, both = copter(vel_bias_m_s=0.2, vel_bias_tc_s=2.0, seed=4), copter(vel_bias_m_s=0.2, vel_bias_tc_s=2.0,
                                                                          vel_offset_m_s=0.03, seed=4)
    offset_only = copter(vel_offset_m_s=0.03, seed=4)
    for model in (alone, both, offset_only):
        run_at(model, 20.0, 0.02)
    for axis in range(2):
        expected = alone.state.pos_ned_m[axis] + offset_only.state.pos_ned_m[axis]
        assert both.state.pos_ned_m[axis] == pytest.approx(expected, abs=1e-9)


def run_at(model: VehicleModel, seconds: float, dt: float, vel=(0.0, 0.0, 0.0)) -> None:
    for _ in range(round(seconds / dt)):
        model.step_multirotor(dt, vel, 0.0)


def test_velocity_estimate_bias_does_not_move_a_copter_on_the_ground():
    model = VehicleModel(VehicleParams(kind="copter", vel_bias_m_s=0.5, vel_bias_tc_s=1.0, vel_offset_m_s=0.5),
                         (0.0, 0.0, 0.0), 0.0, airborne=False)
    for _ in range(500):
        model.step_multirotor(0.02, (0.0, 0.0, 0.0), 0.0, grounded=True)
    for _ in range(500):
        model.step_multirotor(0.02, (0.0, 0.0, 0.0), 0.0)  # motors on, nothing asked: still on the ground
    assert model.state.pos_ned_m == [0.0, 0.0, 0.0]


def test_the_reported_position_is_pos_delay_s_old_and_the_velocity_current():
    # Flying north at a steady 4 m/s, a position reported 0.016 s late is 4 * 0.016 = 0.064 m
    # behind the true one; the velocity reported is the one flown now. Without the delay the
    # report is the true position.
    for delay in (0.0, 0.016):
        model = copter(pos_delay_s=delay, tau_vel_s=0.05)
        for _ in range(2000):  # 5 s at 400 Hz: the lag has settled
            model.step_multirotor(0.0025, (4.0, 0.0, 0.0), 0.0)
        true_n = model.state.pos_ned_m[0]
        assert model.state.vel_ned_m_s[0] == pytest.approx(4.0, abs=1e-9)
        assert model.measured_pos_ned_m()[0] == pytest.approx(true_n - 4.0 * delay, abs=1e-9)
        assert model.measured_pos_ned_m()[1:] == pytest.approx(tuple(model.state.pos_ned_m[1:]), abs=1e-12)
