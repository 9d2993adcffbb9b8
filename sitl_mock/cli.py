"""The ``sitl-mock`` command: parse options, build the mock, run it until stopped.

``main(argv) -> int`` is separate from :func:`entry_point` so tests can call it without a
subprocess. Exit codes: 0 after a clean stop (SIGINT, SIGTERM or ``--duration-s``), 2 for bad
options or a link / tlog / key file that cannot be opened (one line on stderr, no traceback).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading

from sitl_mock.autopilot import MockAutopilot, MockConfig
from sitl_mock.links import load_signing_key, parse_link
from sitl_mock.personality import VEHICLE_MODEL_KEYS, Personality
from sitl_mock.posctl import PosControlParams
from sitl_mock.vehicle import VehicleParams

# Keys of the vehicle: block a model must give (the others default as in a mission).
_REQUIRED_MODEL_KEYS = ("a_max_m_s2", "lag_s")
_MODEL_DEFAULTS = {"delay_s": 0.0, "accel_lag_s": 0.0, "tail_share": 0.0, "tail_tc_s": 1.0, "speed_sag_s": 0.0,
                   "yaw_rate_max_deg_s": 90.0, "vel_bias_m_s": 0.0, "vel_bias_tc_s": 3.0,
                   "vel_bias_jerk_s2": 0.0, "vel_bias_jerk_max_m_s3": 1.0, "vel_bias_smooth_s": 0.0,
                   "vel_bias_loop_s": 0.0, "vel_offset_m_s": 0.0, "pos_delay_s": 0.0, "accel_ff_gain": 1.0,
                   "accel_ff_lag_s": 0.0}


def load_vehicle_model(path: str) -> dict[str, float]:
    """The ``vehicle:`` block of a YAML file (``companion identify -o`` output or a mission), read
    here on the mock's side (the mock shares no code with the companion). ValueError, one line."""
    import yaml

    try:
        with open(path, encoding="utf-8") as handle:
            doc = yaml.safe_load(handle)
    except OSError as err:
        raise ValueError(f"--vehicle-model {path}: cannot read: {err.strerror}") from None
    except yaml.YAMLError as err:
        raise ValueError(f"--vehicle-model {path}: not YAML: {str(err).splitlines()[0]}") from None
    block = doc.get("vehicle") if isinstance(doc, dict) else None
    if not isinstance(block, dict):
        raise ValueError(f"--vehicle-model {path}: expected a mapping with a vehicle: block")
    unknown = sorted(set(block) - set(VEHICLE_MODEL_KEYS))
    if unknown:
        raise ValueError(f"--vehicle-model {path}: vehicle.{unknown[0]}: unknown key; expected one of "
                         f"{', '.join(VEHICLE_MODEL_KEYS)}")
    model = dict(_MODEL_DEFAULTS)
    for key in VEHICLE_MODEL_KEYS:
        if key not in block:
            if key in _REQUIRED_MODEL_KEYS:
                raise ValueError(f"--vehicle-model {path}: vehicle.{key}: missing; expected a number")
            continue
        value = block[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ValueError(f"--vehicle-model {path}: vehicle.{key}: expected a finite number >= 0, got {value!r}")
        model[key] = float(value)
    return model


def _floats(text: str, count: int, option: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"{option} {text!r}: expected {count} comma-separated numbers") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{option} {text!r}: expected {count} comma-separated finite numbers")
    return values


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sitl-mock",
        description="Mock PX4/ArduPilot autopilot speaking MAVLink 2 over UDP, with a point-mass vehicle.")
    add = parser.add_argument
    add("--autopilot", choices=("px4", "ardupilot"), default="px4",
        help="personality: modes, arming and failsafes of PX4 or ArduPilot (default px4)")
    add("--vehicle", choices=("copter", "plane", "rover"), default="copter",
        help="vehicle type in the heartbeat and its point-mass model (default copter)")
    add("--link", action="append", default=[], metavar="udpout:HOST:PORT|udpin:HOST:PORT",
        help="link string; repeat for several links (default udpout:127.0.0.1:14540)")
    add("--sysid", type=int, default=1, help="MAVLink system id of the autopilot (default 1)")
    add("--compid", type=int, default=1, help="MAVLink component id of the autopilot (default 1)")
    add("--speedup", type=float, default=1.0, help="simulated seconds per wall-clock second (default 1)")
    add("--physics-hz", type=float, default=400.0, help="vehicle model integration rate (default 400)")
    add("--seed", type=int, default=0, help="seed of the position noise")
    add("--start-ned", default="0,0", metavar="N,E", help="start position north,east (m) from the origin")
    add("--start-alt-m", type=float, default=0.0, help="start height above ground (m)")
    add("--start-yaw-deg", type=float, default=0.0, help="start yaw, degrees clockwise from north (default 0)")
    add("--start-airborne", action="store_true", help="start armed, flying, in the hold mode")
    add("--origin", default=None, metavar="LAT,LON,ALT", help="geodetic origin of the local frame")
    add("--no-ekf-origin", action="store_true",
        help="the estimator has no global origin: GPS_GLOBAL_ORIGIN is never sent (requests get nothing)")
    add("--pace-lead-s", type=float, default=None, metavar="S",
        help="hold simulated time while the setpoint client's newest time_boot_ms lags by more than S "
             "(faster-than-real-time runs on a busy machine; off by default)")
    add("--vehicle-model", default=None, metavar="FILE",
        help="YAML file with a vehicle: block (companion identify -o, or a mission): the copter's "
             "delay, lag, acceleration limit, speed sag, yaw-rate limit and velocity-estimate bias (default for a copter: the "
             "model identified from the chosen autopilot's real firmware, docs/vehicle_model.md)")
    add("--no-posctl", action="store_true",
        help="ArduPilot copter: fly GUIDED velocity targets through the vehicle model's own response instead of "
             "ArduCopter's position controller (emulated by default, unless --vehicle-model, --tau-vel-s or "
             "--a-max-m-s2 is given: docs/sitl_mock.md)")
    add("--tau-vel-s", type=float, default=None,
        help="velocity lag (default: the vehicle model's; 0.3 for planes and rovers)")
    add("--tau-yaw-rate-s", type=float, default=0.3,
        help="yaw-rate response time constant, s (copter, rover) (default 0.3)")
    add("--tau-roll-s", type=float, default=0.5, help="plane roll time constant")
    add("--a-max-m-s2", type=float, default=None, help="acceleration limit (default copter 5, rover 3, plane 5)")
    add("--yaw-rate-max-deg-s", type=float, default=None, help="yaw-rate limit (default copter 90, rover 120)")
    add("--roll-max-deg", type=float, default=45.0, help="plane bank-angle limit")
    add("--airspeed-m-s", type=float, default=15.0, help="plane cruise airspeed")
    add("--airspeed-min-m-s", type=float, default=10.0,
        help="plane minimum airspeed, the floor of DO_CHANGE_SPEED (default 10)")
    add("--wind-ned-m-s", default="0,0", metavar="N,E",
        help="steady wind north,east (m/s) the plane drifts with (default 0,0)")
    add("--vel-bias-m-s", type=float, default=None,
        help="standard deviation of the velocity estimate's bias the copter drifts by, m/s per horizontal axis, "
             "one level throughout, flown as it is (default: the vehicle model's, which may grow while "
             "manoeuvring and be smoothed; 0: none)")
    add("--vel-offset-m-s", type=float, default=None,
        help="standard deviation of the velocity estimate's constant offset, drawn once per flight (seeded), "
             "m/s per horizontal axis (default: the vehicle model's; 0: none)")
    add("--pos-noise-m", type=float, default=0.0,
        help="standard deviation of the noise on each reported position axis, m (default 0)")
    add("--offboard-loss-s", type=float, default=0.5, help="PX4 COM_OF_LOSS_T")
    add("--guided-timeout-s", type=float, default=3.0, help="ArduPilot GUID_TIMEOUT")
    add("--signing-key-file", default=None, metavar="F", help="64 hex characters, or a passphrase")
    add("--tlog", default=None, metavar="FILE", help="record both directions of every link to this tlog")
    add("--duration-s", type=float, default=None, help="stop after this much simulated time")
    add("--quiet", action="store_true", help="no event log on stderr (the ready and summary lines stay)")
    return parser


def config_from_args(args: argparse.Namespace) -> MockConfig:
    """Turn parsed options into a validated :class:`MockConfig` (ValueError with a one-line message)."""
    links = tuple(parse_link(text) for text in (args.link or ["udpout:127.0.0.1:14540"]))
    start_ned = _floats(args.start_ned, 2, "--start-ned")
    wind = _floats(args.wind_ned_m_s, 2, "--wind-ned-m-s")
    origin = _floats(args.origin, 3, "--origin") if args.origin else None
    if args.vehicle_model is not None:
        model = load_vehicle_model(args.vehicle_model)
    else:
        model = Personality(args.autopilot, args.vehicle).default_vehicle_model
    if model is None:  # plane, rover: the generic model
        model = {**_MODEL_DEFAULTS, "a_max_m_s2": 3.0 if args.vehicle == "rover" else 5.0, "lag_s": 0.3,
                 "yaw_rate_max_deg_s": 120.0 if args.vehicle == "rover" else 90.0}
    # An explicit option overrides the model's value.
    a_max = args.a_max_m_s2 if args.a_max_m_s2 is not None else model["a_max_m_s2"]
    yaw_max = args.yaw_rate_max_deg_s if args.yaw_rate_max_deg_s is not None else model["yaw_rate_max_deg_s"]
    tau_vel = args.tau_vel_s if args.tau_vel_s is not None else model["lag_s"]
    vel_bias = args.vel_bias_m_s if args.vel_bias_m_s is not None else model["vel_bias_m_s"]
    vel_offset = args.vel_offset_m_s if args.vel_offset_m_s is not None else model["vel_offset_m_s"]
    try:
        vehicle = VehicleParams(
            kind=args.vehicle, tau_vel_s=tau_vel, tau_yaw_rate_s=args.tau_yaw_rate_s, a_max_m_s2=a_max,
            delay_s=model["delay_s"], accel_lag_s=model["accel_lag_s"], tail_share=model["tail_share"],
            tail_tc_s=model["tail_tc_s"], speed_sag_s=model["speed_sag_s"],
            accel_ff_gain=model["accel_ff_gain"], accel_ff_lag_s=model["accel_ff_lag_s"],
            yaw_rate_max_rad_s=math.radians(yaw_max), v_max_m_s=5.0 if args.vehicle == "rover" else 12.0,
            airspeed_cruise_m_s=args.airspeed_m_s, airspeed_min_m_s=args.airspeed_min_m_s,
            airspeed_max_m_s=max(25.0, args.airspeed_m_s), tau_roll_s=args.tau_roll_s,
            roll_max_rad=math.radians(args.roll_max_deg), wind_ned_m_s=wind, pos_noise_m=args.pos_noise_m,
            vel_bias_m_s=vel_bias, vel_bias_tc_s=model["vel_bias_tc_s"],
            vel_bias_jerk_s2=model["vel_bias_jerk_s2"] if args.vel_bias_m_s is None else 0.0,
            vel_bias_jerk_max_m_s3=model["vel_bias_jerk_max_m_s3"],
            vel_bias_smooth_s=model["vel_bias_smooth_s"] if args.vel_bias_m_s is None else 0.0,
            vel_bias_loop_s=model["vel_bias_loop_s"] if args.vel_bias_m_s is None else 0.0,
            vel_offset_m_s=vel_offset, pos_delay_s=model["pos_delay_s"],
            seed=args.seed)
    except ValueError as err:
        raise ValueError(f"vehicle parameters: {err}") from None
    # A real ArduCopter flies GUIDED velocity targets through its position controller; a model given
    # explicitly (file or options) is flown as it is.
    explicit_model = args.vehicle_model is not None or args.tau_vel_s is not None or args.a_max_m_s2 is not None
    emulate = (args.autopilot, args.vehicle) == ("ardupilot", "copter") and not (args.no_posctl or explicit_model)
    key = load_signing_key(args.signing_key_file) if args.signing_key_file else None
    return MockConfig(
        autopilot=args.autopilot, vehicle=args.vehicle, links=links, sysid=args.sysid, compid=args.compid,
        speedup=args.speedup, physics_hz=args.physics_hz, seed=args.seed, start_ned_m=start_ned,
        start_alt_m=args.start_alt_m, start_yaw_deg=args.start_yaw_deg, start_airborne=args.start_airborne,
        origin=origin, ekf_origin=not args.no_ekf_origin, pace_lead_s=args.pace_lead_s, vehicle_params=vehicle,
        posctl=PosControlParams() if emulate else None, offboard_loss_s=args.offboard_loss_s,
        guided_timeout_s=args.guided_timeout_s, signing_key=key, tlog_path=args.tlog, duration_s=args.duration_s,
        quiet=args.quiet)


def main(argv: list[str] | None = None, stop_event: threading.Event | None = None) -> int:
    """Run the mock; returns the exit code.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default ``sys.argv[1:]``).
    stop_event : threading.Event, optional
        Set it to stop the mock from another thread (signals are only installed in the main thread).
    """
    args = build_parser().parse_args(argv)
    try:
        config = config_from_args(args)
        mock = MockAutopilot(config)
    except ValueError as err:
        print(f"sitl-mock: error: {err}", file=sys.stderr)
        return 2
    if stop_event is not None:
        mock.stop_event = stop_event
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, mock.request_stop)
        signal.signal(signal.SIGTERM, mock.request_stop)
    mock.announce()
    try:
        code = mock.run()
    except BrokenPipeError:
        code = 1
    print(mock.summary(), file=sys.stderr, flush=True)
    return code


def entry_point() -> None:
    sys.exit(main())
