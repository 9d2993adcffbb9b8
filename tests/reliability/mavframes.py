"""Build MAVLink frames byte by byte for the attacks: valid, signed, wrongly signed, MAVLink 1.

A frame is built by pymavlink (so a "valid" frame is valid by the reference implementation's
rules) and then optionally damaged by the fuzzer.
"""

from __future__ import annotations

import time

from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

SIGNING_EPOCH_UNIX_S = 1420070400


class Encoder:
    """Packs messages as one sender (system, component), MAVLink 2 (optionally signed) or 1."""

    def __init__(self, system: int = 1, component: int = 1, *, v1: bool = False,
                 signing_key: bytes | None = None, link_id: int = 0):
        mod = mavlink1 if v1 else mavlink2
        self.mod = mod
        self.mav = mod.MAVLink(None, srcSystem=system, srcComponent=component)
        if signing_key is not None:
            self.mav.signing.secret_key = bytes(signing_key)
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = link_id
            self.mav.signing.timestamp = int((time.time() - SIGNING_EPOCH_UNIX_S) * 100_000)

    def pack(self, msg) -> bytes:
        buf = bytes(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256
        return buf

    # Messages the attacks use ------------------------------------------------------------
    def heartbeat(self, autopilot: int = 12, mav_type: int = 2, custom_mode: int = 0, base_mode: int = 0x81):
        return self.pack(self.mod.MAVLink_heartbeat_message(mav_type, autopilot, base_mode, custom_mode, 4, 3))

    def local_position(self, time_boot_ms: int, x=0.0, y=0.0, z=-10.0, vx=0.0, vy=0.0, vz=0.0):
        return self.pack(self.mod.MAVLink_local_position_ned_message(time_boot_ms, x, y, z, vx, vy, vz))

    def attitude(self, time_boot_ms: int, roll=0.0, pitch=0.0, yaw=0.0):
        return self.pack(self.mod.MAVLink_attitude_message(time_boot_ms, roll, pitch, yaw, 0.0, 0.0, 0.0))

    def position_target(self, target_system=1, target_component=1, vx=0.0, vy=0.0, vz=0.0,
                        yaw_rate=0.0, type_mask=1479, frame=1, time_boot_ms=0):
        return self.pack(self.mod.MAVLink_set_position_target_local_ned_message(
            time_boot_ms, target_system, target_component, frame, type_mask,
            0.0, 0.0, 0.0, vx, vy, vz, 0.0, 0.0, 0.0, 0.0, yaw_rate))

    def command_long(self, command: int, params=(0, 0, 0, 0, 0, 0, 0), target_system=1, target_component=1):
        p = list(params) + [0.0] * (7 - len(params))
        return self.pack(self.mod.MAVLink_command_long_message(target_system, target_component, command, 0, *p))


def msgid_of(frame: bytes) -> int:
    return frame[7] | (frame[8] << 8) | (frame[9] << 16) if frame[0] == 0xFD else frame[5]
