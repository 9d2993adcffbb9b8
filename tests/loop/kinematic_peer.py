"""A small threaded autopilot for loop tests: PX4 or ArduPilot modes, instant velocity following.

It streams HEARTBEAT (5 Hz), LOCAL_POSITION_NED (50 Hz) and ATTITUDE (20 Hz) to the companion's
udpin port, ACKs commands, obeys DO_SET_MODE / arming, and integrates the last velocity setpoint.
Knobs for faults: ``drop_positions_at_s`` (stop the position stream, keep the rest),
``mode_change_at_s`` (a "pilot" selects another mode), ``arm_refusals`` (refuse N arm requests
with a STATUSTEXT reason), ``arm_delay_s`` (ACK an arm command ACCEPTED at once, show the armed
flag in the HEARTBEAT only this much later, as PX4 does), ``positions_from_s`` (no position
before then; a STATUSTEXT and an EKF_STATUS_REPORT say why), ``unknown_ids_hz`` (frames with a
message id the dialect does not know, as a real PX4 sends). Its yaw is the direction of its
velocity while it moves (above 0.1 m/s) and integrates the setpoints' yaw rate while it hovers;
it starts at ``yaw`` (NED, default east: facing along the tests' line going east, so that the
companion has no turn to make before the path); ``yaw_turns=False`` ignores the yaw rate.
"""

from __future__ import annotations

import math
import socket
import threading
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class _Out:
    def __init__(self, sock, dest):
        self.sock, self.dest = sock, dest

    def write(self, buf):
        try:
            self.sock.sendto(bytes(buf), self.dest)
        except OSError:
            pass


PX4_OFFBOARD = 6 << 16
PX4_HOLD = (4 << 16) | (3 << 24)


class KinematicAutopilot(threading.Thread):
    def __init__(self, dest, autopilot="px4", x=0.0, y=0.0, alt=10.0, vn=0.0, ve=0.0, armed=True,
                 drop_positions_at_s=None, mode_change_at_s=None, arm_refusals=0, mode_return_at_s=None,
                 arm_delay_s=0.0, positions_from_s=0.0, unknown_ids_hz=0.0, yaw=math.pi / 2, yaw_turns=True,
                 rover=False):
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.002)
        self.mav = mavlink2.MAVLink(_Out(self.sock, dest), srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.px4 = autopilot == "px4"
        self.ap_code = 12 if self.px4 else 3
        self.mav_type = 10 if rover else 2  # MAV_TYPE_GROUND_ROVER, MAV_TYPE_QUADROTOR
        self.guided_mode = PX4_OFFBOARD if self.px4 else (15 if rover else 4)  # ArduPilot GUIDED
        self.hold_mode = PX4_HOLD if self.px4 else (4 if rover else 5)  # Rover HOLD, Copter LOITER
        self.custom_mode = self.hold_mode
        self.armed = armed
        self.pos = [x, y, -alt]
        self.vel = [vn, ve, 0.0]
        self.yaw = yaw
        self.yaw_rate = 0.0
        self.yaw_turns = yaw_turns  # False: the yaw rate setpoints are ignored (a stuck yaw)
        self.drop_positions_at_s = drop_positions_at_s
        self.mode_change_at_s = mode_change_at_s
        self.mode_return_at_s = mode_return_at_s  # the "pilot" selects OFFBOARD/GUIDED again
        self._returned = False
        self.arm_refusals = arm_refusals
        self.arm_delay_s = arm_delay_s
        self.armed_at_s = None
        self.positions_from_s = positions_from_s
        self.unknown_ids_hz = unknown_ids_hz
        self.stop_flag = threading.Event()
        self.setpoints = []  # (t_s, msg) received
        self.commands = []
        self.positions_sent = []  # time_boot_ms of every LOCAL_POSITION_NED sent
        self.t0 = time.monotonic()
        self.last_setpoint_s = -math.inf
        self.offboard_entered_s = None

    def now(self):
        return time.monotonic() - self.t0

    def run(self):
        next_pos = next_att = next_hb = 0.0
        last = self.now()
        while not self.stop_flag.is_set():
            t = self.now()
            dt, last = t - last, t
            self._receive(t)
            if self.custom_mode == self.guided_mode and self.armed and t - self.last_setpoint_s < 0.5:
                for i in range(3):
                    self.pos[i] += self.vel[i] * dt
            else:
                self.vel = [0.0, 0.0, 0.0]
                self.yaw_rate = 0.0
            if math.hypot(self.vel[0], self.vel[1]) > 0.1:
                self.yaw = math.atan2(self.vel[1], self.vel[0])
            elif self.yaw_turns:
                self.yaw += self.yaw_rate * dt
            if self.mode_change_at_s is not None and self.offboard_entered_s is not None and \
                    t - self.offboard_entered_s >= self.mode_change_at_s and self.custom_mode == self.guided_mode:
                if not self._returned:
                    self.custom_mode = self.hold_mode
            if self.mode_return_at_s is not None and self.offboard_entered_s is not None and \
                    not self._returned and t - self.offboard_entered_s >= self.mode_return_at_s:
                self.custom_mode = self.guided_mode
                self._returned = True
            tb = int(t * 1000)
            if self.armed_at_s is not None and t >= self.armed_at_s:
                self.armed, self.armed_at_s = True, None
            if t >= next_hb:
                base = 1 | (128 if self.armed else 0)
                self.mav.heartbeat_send(self.mav_type, self.ap_code, base, self.custom_mode, 4)
                if t < self.positions_from_s:
                    self.mav.statustext_send(4, b"PreArm: Need Position Estimate")
                    self.mav.ekf_status_report_send(1 | 2, 0, 0, 0, 0, 0)
                if self.unknown_ids_hz > 0:
                    unknown = bytes([0xFD, 1, 0, 0, self.mav.seq, 1, 1, 0x39, 0x30, 0x00, 0x00, 0x12, 0x34])
                    for _ in range(max(1, round(self.unknown_ids_hz * 0.2))):
                        self.mav.file.write(unknown)
                next_hb = t + 0.2
            if t >= next_pos and t >= self.positions_from_s:
                dropped = self.drop_positions_at_s is not None and self.offboard_entered_s is not None and \
                    t - self.offboard_entered_s >= self.drop_positions_at_s
                if not dropped:
                    self.mav.local_position_ned_send(tb, *self.pos, *self.vel)
                    self.positions_sent.append(tb)
                next_pos = t + 0.02
            if t >= next_att:
                yaw = math.atan2(math.sin(self.yaw), math.cos(self.yaw))
                self.mav.attitude_send(tb, 0.0, 0.0, yaw, 0.0, 0.0, 0.0)
                next_att = t + 0.05

    def _receive(self, t):
        try:
            data, _ = self.sock.recvfrom(65535)
        except (socket.timeout, BlockingIOError):
            return
        except OSError:
            return
        for m in self.mav.parse_buffer(data) or []:
            mt = m.get_type()
            if mt == "SET_POSITION_TARGET_LOCAL_NED":
                self.setpoints.append((t, m))
                self.last_setpoint_s = t
                self.vel = [m.vx, m.vy, m.vz]
                self.yaw_rate = m.yaw_rate
            elif mt == "COMMAND_LONG":
                self.commands.append((t, m))
                result = 0
                if m.command == 176:
                    mode = int(m.param2) << 16 | int(m.param3) << 24 if self.px4 else int(m.param2)
                    if mode == self.guided_mode and self.px4 and t - self.last_setpoint_s > 0.5:
                        result = 1
                    else:
                        self.custom_mode = mode
                        if mode == self.guided_mode:
                            self.offboard_entered_s = t
                elif m.command == 22:
                    self.pos[2] = -float(m.param7)
                elif m.command == 400:
                    if self.arm_refusals > 0:
                        self.arm_refusals -= 1
                        self.mav.statustext_send(4, b"PreArm: EKF not ready")
                        result = 1
                    elif m.param1 and self.arm_delay_s > 0:
                        self.armed_at_s = t + self.arm_delay_s
                    else:
                        self.armed = bool(m.param1)
                self.mav.command_ack_send(m.command, result)

    def stop(self):
        self.stop_flag.set()
        self.join(2.0)
        self.sock.close()
