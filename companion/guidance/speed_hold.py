"""A ground-speed hold: raise the velocity setpoint's magnitude until the vehicle flies the
mission's speed.

PX4 SIH in OFFBOARD flies a 5 m/s velocity setpoint at 4.0-4.8 m/s, least in the turns
(docs/real_firmware.md, "`predictive` at the other laws' a_rms"). The model identified from it
closes a fresh velocity error fast and the last part of a lasting one slowly (the "slow tail" of
docs/vehicle_model.md), and a setpoint that keeps turning keeps such an error open, which would
explain it. The guidance and its rollouts
assume the vehicle moves at the mission's speed ``V``. :class:`SpeedHold` integrates the speed
error and adds it to the magnitude of the velocity setpoint:

    c[k+1] = clip(c[k] + (V - |v|) dt / tc_s,  -low V,  +high V)

with ``dt`` the time between two position reports (the autopilot's clock) and ``|v|`` the
vehicle's ground speed (the reported velocity, with the drift compensated). The setpoint still
turns at ``a / V``: only its length changes. Off by default (``fly --speed-hold-tc-s``).

Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math

#: Intervals longer than this (s) between two reports are not integrated (a link gap or a hold).
MAX_GAP_S = 0.5
#: The correction is held within ``-LOW_SHARE V`` and ``+HIGH_SHARE V``: a setpoint is never
#: unbounded, and a vehicle that needs more than 1.4 V asked to fly V has a fault to report,
#: not a speed to hold.
LOW_SHARE = 0.2
HIGH_SHARE = 0.4


class SpeedHold:
    """Integral of the ground-speed error, added to the velocity setpoint's magnitude.

    Parameters
    ----------
    tc_s : integral time (s), > 0: a steady error ``e`` moves the correction by ``e`` in ``tc_s``.

    Examples
    --------
    A vehicle flying 4 m/s for 5 asked, reported at 50 Hz, ``tc_s`` 2 s: after 1 s (50 intervals)
    the correction is ``1 m/s * 1 s / 2 s``.

    >>> hold = SpeedHold(tc_s=2.0)
    >>> for k in range(51):
    ...     c = hold.update(0.02 * k, 5.0, 4.0, 0.0)
    >>> round(c, 9)
    0.5
    """

    def __init__(self, tc_s: float):
        if isinstance(tc_s, bool) or not isinstance(tc_s, (int, float)) or not (math.isfinite(tc_s) and tc_s > 0):
            raise ValueError(f"tc_s: expected a finite number > 0, got {tc_s!r}")
        self.tc_s = float(tc_s)
        self.correction_m_s = 0.0
        self._last_t_s: float | None = None

    def update(self, t_s: float, speed_m_s: float, vx_m_s: float, vy_m_s: float) -> float:
        """Take one report (its time, the speed asked, the ground velocity on two horizontal axes)
        and return the correction (m/s) to add to the setpoint's magnitude.

        A report no newer than the last one changes nothing, nor does a non-finite value; the
        first report, and one after a gap longer than ``MAX_GAP_S``, only start the clock.
        """
        if not all(math.isfinite(v) for v in (t_s, speed_m_s, vx_m_s, vy_m_s)) or speed_m_s <= 0:
            return self.correction_m_s
        last = self._last_t_s
        if last is not None and not t_s > last:
            return self.correction_m_s
        self._last_t_s = float(t_s)
        if last is None or t_s - last > MAX_GAP_S:
            return self.correction_m_s
        error = speed_m_s - math.hypot(vx_m_s, vy_m_s)
        c = self.correction_m_s + error * (t_s - last) / self.tc_s
        self.correction_m_s = min(HIGH_SHARE * speed_m_s, max(-LOW_SHARE * speed_m_s, c))
        return self.correction_m_s

    def pause(self) -> float:
        """Hold the correction and restart the clock (the vehicle is gathering speed or holding):
        the next report only starts it again. Returns the correction."""
        self._last_t_s = None
        return self.correction_m_s
