"""The acceleration limit the autopilot's own parameters put on its velocity controller, read at start-up.

Which parameter bounds the horizontal acceleration of the velocity controller that flies our
velocity + yaw-rate setpoints (found in the firmware sources):

- **ArduCopter, GUIDED** (velocity / velocity-acceleration sub-mode): ``ModeGuided::pva_control_start``
  (``ArduCopter/mode_guided.cpp``) sets the position controller's horizontal limits with
  ``pos_control->set_max_speed_accel_NE_cm(..., wp_nav->get_wp_acceleration_cmss())``, i.e.
  ``WPNAV_ACCEL`` in cm/s^2 (``AC_WPNav``; 0 or less falls back to 250 cm/s^2). The identified
  2.43 m/s^2 of the default build (docs/vehicle_model.md) is this 250 cm/s^2.
- **PX4, OFFBOARD** (velocity setpoints): the setpoint goes straight to ``PositionControl``, whose
  velocity PID asks for an acceleration limited only by the tilt limit ``MPC_TILTMAX_AIR``
  (degrees; ``ControlMath::limitTilt``): ``a <= g tan(MPC_TILTMAX_AIR)``, 9.8 m/s^2 at the
  default 45 deg. ``MPC_ACC_HOR`` / ``MPC_ACC_HOR_MAX`` bound the smoothed auto and position
  modes (``GotoControl``, the manual position mode), not offboard velocity setpoints. The PX4 SIH
  quadrotor flies about 4.5 m/s^2 at 5 m/s: its PID response, not a parameter, sets that.

The limit read is used by the guidance (``guidance.a_max_m_s2``: the law never plans or commands
beyond it; only ``predictive`` plans with it) unless the mission says otherwise: a ``vehicle:``
block wins outright, a lower ``guidance.a_max_m_s2`` is kept. The flight's log says which.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable

from companion.guidance.types import TAIL_COMPENSATED_LAMBDA_S4
from companion.io.setpoints import G_M_S2
from companion.mission.model import Mission
from companion.mission.turns import slowed_for_turns

#: The parameters read per autopilot (``AutopilotInfo.kind``).
LIMIT_PARAMS = {"ardupilot": ("WPNAV_ACCEL",), "px4": ("MPC_TILTMAX_AIR",)}
WPNAV_ACCEL_DEFAULT_CM_S2 = 250.0  # AC_WPNav: used when WPNAV_ACCEL <= 0
READ_TIMEOUT_S = 2.0


@dataclass(frozen=True)
class AutopilotLimit:
    """A horizontal acceleration limit and the parameter it comes from (for the log)."""

    a_max_m_s2: float
    source: str


def limit_from_params(values: dict[str, float]) -> AutopilotLimit | None:
    """The limit the parameter values imply (None: none of :data:`LIMIT_PARAMS` among them). The
    names tell the autopilot apart, so a replay finds the same limit in the log's PARAM_VALUEs.

    >>> limit_from_params({"WPNAV_ACCEL": 250.0})
    AutopilotLimit(a_max_m_s2=2.5, source='WPNAV_ACCEL 250 cm/s^2')
    >>> round(limit_from_params({"MPC_TILTMAX_AIR": 45.0}).a_max_m_s2, 4)
    9.8066
    """
    if "WPNAV_ACCEL" in values:
        cm_s2 = values["WPNAV_ACCEL"]
        if cm_s2 <= 0:
            return AutopilotLimit(WPNAV_ACCEL_DEFAULT_CM_S2 / 100.0,
                                  f"WPNAV_ACCEL {cm_s2:g} (<= 0: the firmware's {WPNAV_ACCEL_DEFAULT_CM_S2:g} cm/s^2)")
        return AutopilotLimit(cm_s2 / 100.0, f"WPNAV_ACCEL {cm_s2:g} cm/s^2")
    if "MPC_TILTMAX_AIR" in values:
        tilt_deg = values["MPC_TILTMAX_AIR"]
        if 0 < tilt_deg < 90:
            return AutopilotLimit(G_M_S2 * math.tan(math.radians(tilt_deg)),
                                  f"MPC_TILTMAX_AIR {tilt_deg:g} deg (g tan(tilt))")
    return None


def mission_with_limit(mission: Mission, limit: AutopilotLimit | None) -> tuple[Mission, str]:
    """The mission to fly on this autopilot, and the log line saying what it uses.

    Its guidance flies within ``limit`` unless the mission says otherwise (a ``vehicle:`` block, or
    a lower ``guidance.a_max_m_s2``). When a limit was read and there is no ``vehicle:`` block,
    nothing describes how the autopilot flies the commands, so ``adapt_model`` is turned on as
    well: ``predictive``'s model monitor learns the vehicle's lag and limit in flight
    (docs/guidance.md) instead of planning for an ideal inner loop; the other methods do not plan
    and ignore it. (Only then: the PARAM_VALUE answers in the tlog are what tells replay to do
    the same.) Whatever limit is used, the path is flown slower where its turns ask more of it
    than ``along_track.turn_accel_share`` allows (:func:`companion.mission.turns.slowed_for_turns`).
    """
    mission, line = _with_limit(mission, limit)
    mission, turns = slowed_for_turns(mission, flight_limit_m_s2(mission))
    return mission, line if turns is None else f"{line}; {turns}"


def flight_limit_m_s2(mission: Mission) -> float:
    """The lateral-acceleration limit a flight of ``mission`` uses (inf: none known): its
    ``vehicle:`` block's, else ``guidance.a_max_m_s2`` (the autopilot's once
    :func:`mission_with_limit` has read it)."""
    return mission.vehicle.a_max_m_s2 if mission.vehicle is not None else mission.guidance.a_max_m_s2


#: Autopilots whose flights send the acceleration target unless the mission says otherwise:
#: ArduCopter's, whose GUIDED chain the mock flies from the firmware's own formulas
#: (docs/real_firmware.md, "The command as acceleration feed-forward"; PX4's response to it is not
#: yet modelled).
ACCEL_FEEDFORWARD_AUTOPILOTS = ("ardupilot",)


def accel_feedforward_max(mission: Mission, autopilot: str | None, vehicle: str = "copter") -> float:
    """Up to what a velocity-output flight of ``mission`` on ``autopilot`` (``"px4"``,
    ``"ardupilot"``) sends its lateral command as the setpoint's acceleration target (m/s^2,
    :mod:`companion.io.setpoints`): 0 when it does not (a ``vehicle`` other than a copter: ArduPilot
    Rover ignores a setpoint that carries one, ``GCS_MAVLINK_Rover``'s "set ACC_IGNORE in mask";
    ``guidance.accel_feedforward: false``; or absent and the autopilot not in
    :data:`ACCEL_FEEDFORWARD_AUTOPILOTS`), else the flight's limit (:func:`flight_limit_m_s2`),
    or ``g`` when none is known.

    >>> from companion.mission.loader import parse_mission
    >>> def line(guidance):  # a 50 m line at 5 m/s with this guidance: block
    ...     return parse_mission("{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], "
    ...                          "[50, 0]]}, guidance: " + guidance + "}")
    >>> accel_feedforward_max(line("{method: corrector, a_max_m_s2: 2.5}"), "ardupilot")
    2.5
    >>> accel_feedforward_max(line("{method: corrector}"), "px4")
    0.0
    >>> accel_feedforward_max(line("{method: predictive, a_max_m_s2: 2.5}"), "ardupilot")
    2.5
    >>> round(accel_feedforward_max(line("{accel_feedforward: true}"), "px4"), 5)  # no limit known: g
    9.80665
    >>> accel_feedforward_max(line("{accel_feedforward: false}"), "ardupilot")
    0.0
    >>> accel_feedforward_max(line("{accel_feedforward: true}"), "ardupilot", "rover")
    0.0
    """
    if vehicle != "copter":
        return 0.0
    on = mission.accel_feedforward
    if on is None:
        on = autopilot in ACCEL_FEEDFORWARD_AUTOPILOTS
    return accel_feedforward_limit_m_s2(mission) if on else 0.0


def accel_feedforward_limit_m_s2(mission: Mission) -> float:
    """What the acceleration target is limited to when it is sent: the flight's limit
    (:func:`flight_limit_m_s2`), or ``g`` when none is known."""
    a_max = flight_limit_m_s2(mission)
    return float(a_max) if math.isfinite(a_max) else G_M_S2


#: The slow tail of each autopilot's copter velocity loop, as flown from velocity setpoints
#: (OFFBOARD, GUIDED): its share and time (s), identified from its SITL (docs/vehicle_model.md,
#: "The slow tail"). ArduCopter's loop has none.
VELOCITY_TAILS = {"px4": (0.857, 0.958)}
#: The autopilots whose flights compensate it unless the mission says otherwise (never with the
#: acceleration target, which the tail takes back too and the compensation does not run): PX4,
#: whose copter then flies the speed asked and the laws' first-order model (docs/real_firmware.md,
#: "PX4's slow tail compensated" and "The tail compensated by default on PX4").
TAIL_COMPENSATION_AUTOPILOTS: tuple[str, ...] = ("px4",)


def velocity_tail(mission: Mission, autopilot: str | None, vehicle: str = "copter",
                  accel_ff: bool = False) -> tuple[tuple[float, float], str]:
    """The slow tail a velocity-output flight of ``mission`` on ``autopilot`` compensates
    (:mod:`companion.guidance.tail_comp`): its share and time, ``(0, 0)`` for none, and where
    they come from (for the log).

    On when ``guidance.tail_compensation`` says so, or (absent) on an autopilot of
    :data:`TAIL_COMPENSATION_AUTOPILOTS` flying without the acceleration target (``accel_ff``);
    never for a ``vehicle`` other than a copter. The tail is the mission's ``vehicle:`` block's
    when it has one, else the autopilot's in :data:`VELOCITY_TAILS`.

    >>> from companion.mission.loader import parse_mission
    >>> def line(extra=""):  # a 50 m line at 5 m/s
    ...     return parse_mission("{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], "
    ...                          "[50, 0]]}" + extra + "}")
    >>> on = ", guidance: {tail_compensation: true}"
    >>> velocity_tail(line(on), "px4")
    ((0.857, 0.958), "px4's identified velocity loop")
    >>> velocity_tail(line(), "px4")[0]  # PX4's default
    (0.857, 0.958)
    >>> off = ", guidance: {tail_compensation: false}"
    >>> velocity_tail(line(off), "px4")[0], velocity_tail(line(), "px4", accel_ff=True)[0]
    ((0.0, 0.0), (0.0, 0.0))
    >>> velocity_tail(line(on), "ardupilot")[0], velocity_tail(line(), "ardupilot")[0]  # no tail known; off
    ((0.0, 0.0), (0.0, 0.0))
    >>> velocity_tail(line(on), "px4", "rover")[0]
    (0.0, 0.0)
    >>> velocity_tail(line(on + ", vehicle: {a_max_m_s2: 4, lag_s: 0.4, tail_share: 0.5, tail_tc_s: 2}"), "px4")
    ((0.5, 2.0), "the mission's vehicle block")
    """
    on = mission.tail_compensation
    if on is None:
        on = autopilot in TAIL_COMPENSATION_AUTOPILOTS and not accel_ff
    if vehicle != "copter" or not on:
        return (0.0, 0.0), ""
    if mission.vehicle is not None:
        if mission.vehicle.tail_share <= 0:
            return (0.0, 0.0), ""
        return (mission.vehicle.tail_share, mission.vehicle.tail_tc_s), "the mission's vehicle block"
    tail = VELOCITY_TAILS.get(autopilot or "")
    return (tail, f"{autopilot}'s identified velocity loop") if tail is not None else ((0.0, 0.0), "")


def mission_for_tail(mission: Mission, compensates_tail: bool) -> tuple[Mission, str]:
    """The mission a flight flies given whether it compensates the velocity loop's slow tail, and
    the log line saying what changed ("" for nothing).

    ``predictive`` at :data:`~companion.guidance.types.TAIL_COMPENSATED_LAMBDA_S4` when the
    flight compensates the tail and the mission states no ``guidance.lambda_s4``: on the real PX4,
    so compensated, the default lambda answered the position estimate's slow wander and rang on
    straights at about 0.3 Hz (docs/real_firmware.md, "The tail compensated by default on PX4").

    >>> from companion.mission.loader import parse_mission
    >>> def line(guidance):  # a 50 m line at 5 m/s with this guidance: block
    ...     return parse_mission("{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], "
    ...                          "[50, 0]]}, guidance: " + guidance + "}")
    >>> m, why = mission_for_tail(line("{method: predictive}"), True)
    >>> m.guidance.lambda_s4, why
    (0.3, 'predictive: lambda 0.3 s^4 (the tail compensated; the mission states none)')
    >>> [mission_for_tail(line(g), on)[0].guidance.lambda_s4 for g, on in (
    ...     ("{method: predictive}", False), ("{method: predictive, lambda_s4: 0.03}", True))]
    [0.03, 0.03]
    >>> mission_for_tail(line("{method: pure_pursuit}"), True)[1]
    ''
    """
    g = mission.guidance
    if not compensates_tail or mission.lambda_stated or g.method != "predictive":
        return mission, ""
    guidance = dataclasses.replace(g, lambda_s4=TAIL_COMPENSATED_LAMBDA_S4)
    return (dataclasses.replace(mission, guidance=guidance),
            f"predictive: lambda {TAIL_COMPENSATED_LAMBDA_S4:g} s^4 (the tail compensated; the mission states none)")


def _with_limit(mission: Mission, limit: AutopilotLimit | None) -> tuple[Mission, str]:
    """:func:`mission_with_limit` before the turns are slowed for."""
    g = mission.guidance
    if mission.vehicle is not None:
        read = f" (the autopilot's {limit.source} not used)" if limit is not None else ""
        return mission, (f"acceleration limit {mission.vehicle.a_max_m_s2:g} m/s^2 from the mission's "
                         f"vehicle: block{read}")
    if limit is None:
        own = "none" if math.isinf(g.a_max_m_s2) else f"{g.a_max_m_s2:g} m/s^2"
        return mission, f"acceleration limit: not read from the autopilot; the mission's ({own})"
    if g.a_max_m_s2 <= limit.a_max_m_s2:
        line = (f"acceleration limit {g.a_max_m_s2:g} m/s^2 from the mission's guidance.a_max_m_s2 "
                f"(the autopilot's {limit.source} = {limit.a_max_m_s2:.3g} m/s^2 is higher)")
    else:
        g = dataclasses.replace(g, a_max_m_s2=limit.a_max_m_s2)
        line = f"acceleration limit {limit.a_max_m_s2:.3g} m/s^2 from the autopilot's {limit.source}"
    if g.method == "predictive":
        line += "; no vehicle: block: the model monitor learns the vehicle"
    guidance = dataclasses.replace(g, adapt_model=True)
    return dataclasses.replace(mission, guidance=guidance), line


def apply_autopilot_limits(link, mission: Mission, event: Callable[[str], None],
                           idle: Callable[[], None] | None = None) -> Mission:
    """Read the copter autopilot's limit parameters over ``link`` (PARAM_REQUEST_READ; the
    answers land in the flight's tlog, where replay finds them), log which limit the flight uses,
    and return the mission to fly (its guidance within that limit). Other vehicles: unchanged."""
    info = link.info
    names = LIMIT_PARAMS.get(info.autopilot, ()) if info is not None and info.vehicle == "copter" else ()
    if not names:
        return mission
    values = link.read_params(names, READ_TIMEOUT_S, idle=idle)
    mission, line = mission_with_limit(mission, limit_from_params(values))
    event(line)
    return mission
