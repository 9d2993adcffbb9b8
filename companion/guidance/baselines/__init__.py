"""Baseline path-following laws that users would otherwise fly, for the tracking benchmark.

Each law is a class built from a :class:`companion.geometry.paths.Path` and a frozen parameter
dataclass, with the same ``step(t_s, VehicleState) -> GuidanceOutput`` method as
:class:`companion.guidance.two_phase.TwoPhaseGuidance`, so the simulator flies any of them:

- :class:`ApL1Guidance` (``ap_l1.py``): ArduPilot's ``AP_L1_Control`` (period, damping, capture
  angle, cross-track integrator), applied to a curved path through its look-ahead point;
- :class:`NpfgGuidance` (``npfg.py``): PX4's nonlinear path following guidance (track-error
  bound, look-ahead angle, curvature feed-forward, bearing feasibility, wind triangle);
- :class:`PurePursuitGuidance` (``pure_pursuit.py``): pure pursuit of a goal point at a look-ahead
  distance (Coulter 1992).

Commands are lateral accelerations in the local ENU frame, positive = turn left.
"""

from companion.guidance.baselines.ap_l1 import ApL1Guidance, ApL1Params
from companion.guidance.baselines.npfg import NpfgGuidance, NpfgParams
from companion.guidance.baselines.pure_pursuit import PurePursuitGuidance, PurePursuitParams

__all__ = [
    "ApL1Guidance",
    "ApL1Params",
    "NpfgGuidance",
    "NpfgParams",
    "PurePursuitGuidance",
    "PurePursuitParams",
]
