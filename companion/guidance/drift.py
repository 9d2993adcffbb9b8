"""The autopilot's velocity-estimate drift, seen from its own position and velocity reports.

A copter's velocity loop holds its velocity *estimate* at the setpoint. When that estimate is
off by a slowly varying bias ``b`` (PX4 SIH: about 0.16-0.25 m/s wandering over about 4 s;
ArduCopter SITL: 0.03 m/s; docs/vehicle_model.md), the vehicle flies the setpoint plus ``b``,
and its reported position, which follows GPS, leaves the integral of its reported velocity at
the rate ``b``. A look-ahead law steering by the reported velocity then holds a steady offset
from the path, of about ``L b / V`` (look-ahead ``L``, speed ``V``), as in a crosswind it is not
told about.

:class:`DriftEstimator` measures ``b`` from the reports alone: over each interval between two
samples, the distance moved less the trapezoidal integral of the reported velocity, divided by
the interval, low-passed with time constant ``tc_s``. The flight loop adds it to the reported
velocity for the course the law is given and subtracts it from the velocity setpoint it sends
(``docs/flying.md``, "The velocity estimate's drift"), so that the vehicle's position moves
along the velocity the law asked for.

Frame-agnostic: any horizontal frame, the same for the positions and the velocities (the flight
loop uses NED). Pure: numbers in, numbers out; the sample times are the autopilot's.
"""

from __future__ import annotations

import math

#: Intervals longer than this (s) between two samples are not used: the estimate restarts from
#: the newer sample (a link gap or a hold; the trapezoid is no integral over it).
MAX_GAP_S = 0.5
#: The estimate's magnitude is bounded by this (m/s): a setpoint must never be unbounded, and a
#: drift faster than this is not an estimator's bias but a fault the health checks report.
MAX_DRIFT_M_S = 1.0


class DriftEstimator:
    """Low-passed rate at which the reported position leaves the integral of the reported velocity.

    Parameters
    ----------
    tc_s : time constant of the low pass (s), > 0. Shorter follows a wandering bias more closely
        and lets more of the position's noise through: with the reports' position noise
        ``sigma_p``, the estimate's noise is about ``sigma_p / tc_s``.
    max_gap_s : longest interval used (s); a longer one restarts the integral from the newer sample.
    max_drift_m_s : bound on the estimate's magnitude (m/s).

    Examples
    --------
    A constant drift of 0.2 m/s north, reported velocity 5 m/s east, 50 Hz: after ``t`` seconds
    the estimate is ``0.2 (1 - exp(-t / tc_s))``.

    >>> est = DriftEstimator(tc_s=1.0)
    >>> for k in range(101):
    ...     t = 0.02 * k
    ...     bx, by = est.update(t, 0.2 * t, 5.0 * t, 0.0, 5.0)
    >>> round(bx, 6), round(0.2 * (1 - math.exp(-2.0)), 6), abs(by) < 1e-12
    (0.172933, 0.172933, True)
    """

    def __init__(self, tc_s: float, max_gap_s: float = MAX_GAP_S, max_drift_m_s: float = MAX_DRIFT_M_S):
        for name, value in (("tc_s", tc_s), ("max_gap_s", max_gap_s), ("max_drift_m_s", max_drift_m_s)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value > 0):
                raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
        self.tc_s = float(tc_s)
        self.max_gap_s = float(max_gap_s)
        self.max_drift_m_s = float(max_drift_m_s)
        self.drift = (0.0, 0.0)  # the estimate (m/s), first and second axis
        self._last: tuple[float, float, float, float, float] | None = None  # t, x, y, vx, vy

    def update(self, t_s: float, x_m: float, y_m: float, vx_m_s: float, vy_m_s: float) -> tuple[float, float]:
        """Take one report (time, position, velocity) and return the estimate (m/s per axis).

        A report no newer than the last one (the same sample handed to a second tick) changes
        nothing; non-finite values are ignored.
        """
        values = (t_s, x_m, y_m, vx_m_s, vy_m_s)
        if not all(math.isfinite(v) for v in values):
            return self.drift
        last = self._last
        if last is not None and not t_s > last[0]:
            return self.drift
        self._last = (float(t_s), float(x_m), float(y_m), float(vx_m_s), float(vy_m_s))
        if last is None or t_s - last[0] > self.max_gap_s:
            return self.drift
        dt = t_s - last[0]
        # The distance moved beyond the reported velocity's trapezoidal integral, per second.
        rx = (x_m - last[1]) / dt - 0.5 * (vx_m_s + last[3])
        ry = (y_m - last[2]) / dt - 0.5 * (vy_m_s + last[4])
        k = 1.0 - math.exp(-dt / self.tc_s)
        bx = self.drift[0] + k * (rx - self.drift[0])
        by = self.drift[1] + k * (ry - self.drift[1])
        norm = math.hypot(bx, by)
        if norm > self.max_drift_m_s:
            bx, by = bx * self.max_drift_m_s / norm, by * self.max_drift_m_s / norm
        self.drift = (bx, by)
        return self.drift
