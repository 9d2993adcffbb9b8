"""Read what vehicle identification needs from a tlog (the adapter of :mod:`companion.sim.identify`).

From any tlog holding both directions of the link (the companion's, MAVProxy's, QGroundControl's):

- the velocity setpoints: ``SET_POSITION_TARGET_LOCAL_NED`` in ``MAV_FRAME_LOCAL_NED`` whose
  type mask uses the velocity (the yaw rate too when it is not masked out), at their log time;
- the vehicle's response: ``LOCAL_POSITION_NED`` velocity (and position, for the velocity
  estimate's bias) and ``ATTITUDE`` yaw speed from the
  system the setpoints address (the source with the most samples when several components send).

The autopilot's ``time_boot_ms`` is mapped onto the log's clock by a straight line fitted to
(boot time, log time) and shifted to the lower envelope of the arrival times (the 2nd
percentile): the samples keep the autopilot's own spacing, without the link's jitter, and a
simulator running slightly slower than the wall clock (PX4 SIH: 1.3 %) is followed. The
measurements' own time stamps go along too: the velocity estimate's bias integrates the velocity
over the autopilot's seconds, in which the vehicle moved.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from companion.errors import LogError
from companion.io.logread import MSG_ID, TlogReader
from companion.io.setpoints import uses_accel_target
from companion.sim.identify import Samples, resample

MAV_FRAME_LOCAL_NED = 1
MASK_IGNORE_VEL = 0b111000  # bits 3..5: vx, vy, vz ignored
MASK_IGNORE_YAW_RATE = 1 << 11
ENVELOPE_PERCENTILE = 2.0

_IDS = {MSG_ID["SET_POSITION_TARGET_LOCAL_NED"], MSG_ID["LOCAL_POSITION_NED"], MSG_ID["ATTITUDE"]}


def _log_time(t_log_s: np.ndarray, t_boot_s: np.ndarray) -> np.ndarray:
    """Autopilot boot times mapped onto the log clock (module docstring)."""
    if len(t_log_s) < 3 or np.ptp(t_boot_s) <= 0:
        return t_log_s
    x = t_boot_s - t_boot_s[0]
    slope, offset = np.polyfit(x, t_log_s, 1)
    fitted = slope * x + offset
    return fitted + np.percentile(t_log_s - fitted, ENVELOPE_PERCENTILE)


def read_identification_samples(path: str | Path) -> Samples:
    """The commands and the response in a tlog, on the identification grid.

    Raises :class:`companion.errors.LogError` (one line naming the file and what is missing)
    when the file cannot be read or lacks either direction. An acceleration target sent with the
    velocity (a flight with ``guidance.accel_feedforward``) is kept with each command (zero where
    a setpoint's mask ignores it): the model fits the response to it too.
    """
    path = Path(path)
    setpoints = []
    lpn: dict[tuple[int, int], list] = {}
    att: dict[tuple[int, int], list] = {}
    for rec in TlogReader(path, decode_ids=_IDS):
        msg = rec.msg
        if msg is None:
            continue
        kind = msg.get_type()
        if kind == "SET_POSITION_TARGET_LOCAL_NED":
            if msg.coordinate_frame != MAV_FRAME_LOCAL_NED or msg.type_mask & MASK_IGNORE_VEL:
                continue
            yaw_rate = 0.0 if msg.type_mask & MASK_IGNORE_YAW_RATE else msg.yaw_rate
            afx, afy = (msg.afx, msg.afy) if uses_accel_target(msg.type_mask) else (0.0, 0.0)
            setpoints.append((rec.time_s, msg.vx, msg.vy, yaw_rate, afx, afy, msg.target_system))
        elif kind == "LOCAL_POSITION_NED":
            lpn.setdefault((rec.src_system, rec.src_component), []).append(
                (rec.time_s, msg.time_boot_ms * 1e-3, msg.vx, msg.vy, msg.x, msg.y))
        elif kind == "ATTITUDE":
            att.setdefault((rec.src_system, rec.src_component), []).append(
                (rec.time_s, msg.time_boot_ms * 1e-3, msg.yawspeed))
    if not setpoints:
        raise LogError(f"{path}: no SET_POSITION_TARGET_LOCAL_NED velocity setpoints in MAV_FRAME_LOCAL_NED; "
                       "expected a log holding the controller's side of the link")
    target = Counter(row[6] for row in setpoints).most_common(1)[0][0]

    def source(streams: dict) -> list:
        mine = {k: v for k, v in streams.items() if k[0] == target} or streams
        return max(mine.values(), key=len) if mine else []

    meas = source(lpn)
    if len(meas) < 10:
        raise LogError(f"{path}: no LOCAL_POSITION_NED from system {target}; expected the autopilot's side "
                       "of the link too")
    sp = np.asarray([row[:6] for row in setpoints], dtype=float)
    m = np.asarray(meas, dtype=float)
    yaw = np.asarray(source(att), dtype=float).reshape(-1, 3)
    t_yaw = _log_time(yaw[:, 0], yaw[:, 1]) if len(yaw) else np.zeros(0)
    try:
        return resample(t_cmd_s=sp[:, 0], vel_cmd_ne_m_s=sp[:, 1:3], yaw_rate_cmd_rad_s=sp[:, 3],
                        t_meas_s=_log_time(m[:, 0], m[:, 1]), vel_meas_ne_m_s=m[:, 2:4], pos_meas_ne_m=m[:, 4:6],
                        t_meas_autopilot_s=m[:, 1], acc_ff_ne_m_s2=sp[:, 4:6],
                        t_yaw_s=t_yaw, yaw_rate_meas_rad_s=yaw[:, 2] if len(yaw) else np.zeros(0))
    except ValueError as err:
        raise LogError(f"{path}: {err}") from None
