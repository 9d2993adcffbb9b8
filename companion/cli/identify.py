"""``companion identify FLIGHT.tlog [--json] [-o vehicle.yaml] [--partial]``: fit the vehicle model.

Reads the velocity + yaw-rate setpoints (and any acceleration target) and the vehicle's response from a tlog
(:mod:`companion.io.idlog`), fits :mod:`companion.sim.identify`'s model, prints the parameters
with their standard errors and the fit quality, and writes a ``vehicle:`` block that missions
and ``sitl-mock --vehicle-model`` accept. When the log cannot identify a parameter (too little
excitation) it refuses with one line naming it (exit 2); ``--partial`` writes the block anyway,
with each such value marked as the fit's guess or the bound the log shows.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from companion.errors import CompanionError, LogError
from companion.guidance.types import ACCEL_FF_KEYS, VEHICLE_MODEL_KEYS

_DECIMALS = {"a_max_m_s2": 2, "delay_s": 3, "lag_s": 3, "accel_lag_s": 3, "tail_share": 3, "tail_tc_s": 3,
             "speed_sag_s": 3, "yaw_rate_max_deg_s": 1, "vel_bias_m_s": 4, "vel_bias_tc_s": 2,
             "vel_bias_jerk_s2": 4, "vel_bias_jerk_max_m_s3": 2, "vel_bias_smooth_s": 1, "vel_bias_loop_s": 3,
             "vel_offset_m_s": 4, "pos_delay_s": 3, "accel_ff_gain": 3, "accel_ff_lag_s": 3}
# Values a grid chooses or a bound the log shows: printed without a standard error.
_NO_ERROR = ("yaw_rate_max_deg_s", "vel_bias_jerk_max_m_s3", "vel_bias_smooth_s", "vel_bias_loop_s")


class IdentificationRefused(CompanionError):
    """The log does not identify every parameter."""


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "identify", help="fit the vehicle's response to velocity (and acceleration) setpoints from a tlog",
        description="Fit acceleration limit, delay, lag, speed sag, yaw-rate limit and velocity-estimate "
                    "bias of the vehicle, and the gain and lag of an acceleration target if the setpoints "
                    "carried one, from a tlog holding both directions of the link (docs/vehicle_model.md).")
    parser.add_argument("tlog", help="the flight log (companion, MAVProxy or QGroundControl tlog)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("-o", "--output", metavar="FILE", help="write the vehicle: block to FILE (YAML)")
    parser.add_argument("--partial", action="store_true",
                        help="write the block even when some parameter is not identified (marked in it)")
    parser.set_defaults(func=run)


def written_keys(accel_target: bool) -> tuple[str, ...]:
    """The keys a log identifies: the acceleration target's only if it flew one."""
    return tuple(k for k in VEHICLE_MODEL_KEYS if accel_target or k not in ACCEL_FF_KEYS)


def vehicle_block_text(model, unidentified: dict, source: str, accel_target: bool = True) -> str:
    """The ``vehicle:`` YAML block, one key per line with a comment on unidentified ones; without
    an acceleration target in the log, a comment in place of its keys (their defaults apply)."""
    values = model.as_dict()
    lines = [f"# identified by companion identify from {source}", "vehicle:"]
    if not accel_target:
        lines.append(f"  # {', '.join(ACCEL_FF_KEYS)}: no acceleration target in the log (defaults apply)")
    for key in written_keys(accel_target):
        note = f"  # not identified: {unidentified[key]}" if key in unidentified else ""
        lines.append(f"  {key}: {round(values[key], _DECIMALS[key])}{note}")
    return "\n".join(lines) + "\n"


def run(args) -> int:
    # Imported here, not at the top: every subcommand module is imported to register it, and the
    # fit's scipy.signal and scipy.optimize must not weigh on ``companion fly``.
    from companion.io.idlog import read_identification_samples
    from companion.sim.identify import IdentifyError, identify

    path = Path(args.tlog)
    if not path.is_file():
        raise LogError(f"{path}: no such file")
    samples = read_identification_samples(path)
    try:
        result = identify(samples)
    except IdentifyError as err:
        raise LogError(f"{path}: {err}") from None
    q = result.quality
    accel_target = result.excitation.get("accel_target_s", 0.0) > 0.0
    if args.json:
        from companion.bench.campaign import finite_json  # an infinite standard error is null: JSON has no inf

        print(json.dumps(finite_json({"vehicle": result.model.as_dict(), "std_errors": result.std_errors,
                                      "quality": q, "excitation": result.excitation,
                                      "unidentified": result.unidentified,
                                      "not_in_log": [] if accel_target else list(ACCEL_FF_KEYS)}),
                         indent=2, allow_nan=False))
    else:
        values = result.model.as_dict()
        print(f"{path.name}: {q['duration_s']:.0f} s of flight under velocity setpoints, "
              f"model: {q['model_structure']}")
        for key in written_keys(accel_target):
            se = result.std_errors.get(key)
            se_text = f" +- {se:.3g}" if se is not None and key not in _NO_ERROR else ""
            flag = "  (not identified)" if key in result.unidentified else ""
            print(f"  {key:20s} {values[key]:.{_DECIMALS[key]}f}{se_text}{flag}")
        print(f"  lateral acceleration: one-step prediction explains {q['vaf_one_step']:.1%} of its variance "
              f"(residual RMS {q['residual_rms_one_step_m_s2']:.3f} m/s^2); free run {q['vaf_free_run']:.1%} "
              f"(RMS {q['residual_rms_free_run_m_s2']:.3f} m/s^2)")
        if "vel_bias_jerk_fitted_s2" in q:
            print(f"  velocity bias growing with the jerk: {q['vel_bias_jerk_fitted_s2']:.4f} +- "
                  f"{q['vel_bias_jerk_se_s2']:.2g} s^2 up to {q['vel_bias_jerk_max_fitted_m_s3']:.2f} m/s^3, "
                  f"beside {q['vel_bias_still_m_s']:.4f} m/s ("
                  f"{'kept' if values['vel_bias_jerk_s2'] > 0 else 'not clear of zero: one level kept'})")
        if "vel_bias_fast_ratio" in q:
            print(f"  its drift's fast part (2-s moving average's rest) against its 1-s changes: "
                  f"{q['vel_bias_fast_ratio']:.3f}, the bias smoothed over {values['vel_bias_smooth_s']:.1f} s: "
                  f"{q['vel_bias_fast_ratio_model']:.3f}")
        if "vel_bias_across_m_s" in q:
            print(f"  velocity bias across the track (the part that moves a track): {q['vel_bias_across_m_s']:.3f} "
                  f"+- {q['vel_bias_across_se_m_s']:.3g} m/s over {q['vel_bias_across_tc_s']:.2f} s")
    if result.unidentified and not args.partial:
        name, why = next(iter(result.unidentified.items()))
        others = len(result.unidentified) - 1
        more = f" (and {others} more: {', '.join(list(result.unidentified)[1:])})" if others else ""
        raise IdentificationRefused(f"{path}: cannot identify vehicle.{name}: {why}{more}; "
                                    "--partial writes the block anyway")
    if args.output:
        try:
            Path(args.output).write_text(vehicle_block_text(result.model, result.unidentified, path.name,
                                                            accel_target))
        except OSError as err:
            raise LogError(f"{args.output}: cannot write: {err.strerror}") from None
        if not args.json:
            print(f"wrote {args.output}", file=sys.stderr)
    elif not args.json:
        print(vehicle_block_text(result.model, result.unidentified, path.name, accel_target), end="")
    return 0
