"""The slow tail of a velocity loop, compensated from outside it.

The velocity loop identified from PX4 SIH in OFFBOARD (docs/vehicle_model.md, "The slow tail")
asks for

    a = (e - s f) / lag,     f' = (e - f) / tc

with ``e`` the horizontal velocity error (setpoint less the reported velocity), ``s`` the tail's
share (``vehicle.tail_share``, PX4 SIH: 0.857) and ``tc`` its time (``vehicle.tail_tc_s``, 0.958 s).
A fresh error is closed at ``1 / lag``; once it has lasted about ``tc`` only at ``(1 - s) / lag``,
a seventh of that on PX4. A setpoint that keeps turning keeps such an error open: the vehicle
answers a ramp of the command ``lag / (1 - s)`` late (3.1 s on PX4, where the laws plan with
0.44 s) and flies 10-20 % slower than asked in the turns (docs/real_firmware.md).

:class:`TailCompensator` runs the loop's ``f`` beside it, from the setpoints it sent and the
velocities reported, and adds ``s f`` to the next setpoint:

    c = c0 + s f,     f <- f + (c_sent - v - f) (1 - exp(-dt / tc))

over each interval ``dt`` between two reports, ``v`` the reported velocity over it (trapezoid).
The vehicle then sees ``e = c0 + s f - v``, and with its ``f`` equal to ours it asks
``(c0 - v) / lag``: a first-order loop, the one the laws' rollouts assume. With the vehicle
standing still (``v`` held) ``f`` settles at ``(c0 - v) / (1 - s)`` with time constant
``tc / (1 - s)`` (6.7 s on PX4): stable, and bounded by ``MAX_SHARE`` of the speed besides.

Frame-agnostic: any horizontal frame, the same for setpoints and velocities (the flight loop
uses NED). The velocity is the reported one (the vehicle's own estimate: its loop closes on it),
not the drift-compensated ground velocity. Pure: numbers in, numbers out; the report times are
the autopilot's.
"""

from __future__ import annotations

import math

from companion.guidance.types import MAX_TAIL_SHARE

#: Intervals longer than this (s) between two reports restart the compensation from zero (a link
#: gap or a hold: what the vehicle's loop did meanwhile is not known).
MAX_GAP_S = 0.5
#: The correction is held within this share of the mission's speed: a setpoint is never
#: unbounded, and a loop that needs more than that is not the one identified.
MAX_SHARE = 0.6


class TailCompensator:
    """The velocity loop's slow tail, run beside it and added to the setpoint.

    Parameters
    ----------
    share : the tail's share ``s`` of the error, ``0 < share <= MAX_TAIL_SHARE`` (0.95).
    tc_s : the tail's time ``tc`` (s), > 0.

    Examples
    --------
    A vehicle held at 4 m/s north for a setpoint of 5 north (PX4's tail), reported at 50 Hz: the
    correction grows towards ``s (5 - 4) / (1 - s)`` = 5.99 m/s, held at ``MAX_SHARE`` of 5.

    >>> comp = TailCompensator(share=0.857, tc_s=0.958)
    >>> for k in range(2000):
    ...     n, e = comp.correction(0.02 * k, 5.0, 4.0, 0.0)
    ...     _ = comp.sent(5.0 + n, 0.0 + e)
    >>> round(n, 9), e
    (3.0, 0.0)
    """

    def __init__(self, share: float, tc_s: float):
        for name, value, upper in (("share", share, MAX_TAIL_SHARE), ("tc_s", tc_s, math.inf)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 < value <= upper):
                raise ValueError(f"{name}: expected a number in (0, {upper:g}], got {value!r}")
        self.share = float(share)
        self.tc_s = float(tc_s)
        self.f_m_s = (0.0, 0.0)  # the loop's low-passed error, as we run it
        self._sent: tuple[float, float] | None = None  # the horizontal setpoint on the wire
        self._last: tuple[float, float, float] | None = None  # the last report: t, v1, v2

    def correction(self, t_s: float, speed_m_s: float, v1_m_s: float, v2_m_s: float) -> tuple[float, float]:
        """Take one report (its time, the mission's speed, the reported horizontal velocity) and
        return the correction ``s f`` (two axes, m/s) to add to the next setpoint.

        A report no newer than the last one, or with a non-finite value, changes nothing; the
        first report, and one after a gap longer than ``MAX_GAP_S`` (or with no setpoint sent
        since), only start the clock from a correction of zero.
        """
        if not all(math.isfinite(x) for x in (t_s, speed_m_s, v1_m_s, v2_m_s)) or speed_m_s <= 0:
            return self._scaled(speed_m_s)
        last = self._last
        if last is not None and not t_s > last[0]:
            return self._scaled(speed_m_s)
        self._last = (float(t_s), float(v1_m_s), float(v2_m_s))
        if last is None or t_s - last[0] > MAX_GAP_S or self._sent is None:
            self.f_m_s = (0.0, 0.0)
            return self._scaled(speed_m_s)
        k = 1.0 - math.exp(-(t_s - last[0]) / self.tc_s)
        (c1, c2), (f1, f2) = self._sent, self.f_m_s
        e1, e2 = c1 - 0.5 * (last[1] + v1_m_s), c2 - 0.5 * (last[2] + v2_m_s)
        self.f_m_s = (f1 + (e1 - f1) * k, f2 + (e2 - f2) * k)
        return self._scaled(speed_m_s)

    def sent(self, c1_m_s: float, c2_m_s: float) -> None:
        """The horizontal setpoint that went on the wire after the last report."""
        self._sent = (float(c1_m_s), float(c2_m_s))

    def reset(self) -> None:
        """Start again from zero (a hold: the setpoint is no longer ours to compensate)."""
        self.f_m_s = (0.0, 0.0)
        self._sent = None
        self._last = None

    def _scaled(self, speed_m_s: float) -> tuple[float, float]:
        """``s f``, held within ``MAX_SHARE`` of the speed (its direction kept)."""
        c1, c2 = self.share * self.f_m_s[0], self.share * self.f_m_s[1]
        size = math.hypot(c1, c2)
        limit = MAX_SHARE * speed_m_s if math.isfinite(speed_m_s) and speed_m_s > 0 else 0.0
        if size > limit:  # then size > 0
            c1, c2 = c1 * limit / size, c2 * limit / size
        return c1, c2
