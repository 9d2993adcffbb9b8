"""A tiny in-test autopilot: a pymavlink endpoint that sends heartbeats and positions on demand."""

from __future__ import annotations

import socket
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class _Out:
    def __init__(self, sock, dest):
        self.sock, self.dest = sock, dest

    def write(self, buf):
        self.sock.sendto(bytes(buf), self.dest)


class FakeAutopilot:
    """Sends to ``dest`` from its own UDP socket and reads what the companion sends back."""

    def __init__(self, dest, system_id=1, component_id=1, autopilot=12, mav_type=2, signing_key=None):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.dest = dest
        self.mav = mavlink2.MAVLink(_Out(self.sock, dest), srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.autopilot = autopilot
        self.mav_type = mav_type
        if signing_key is not None:
            self.mav.signing.secret_key = signing_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.timestamp = int((time.time() - 1420070400) * 100_000)
        self.received = []
        self.custom_mode = 0
        self.base_mode = 0

    @property
    def address(self):
        return self.sock.getsockname()

    def heartbeat(self):
        self.mav.heartbeat_send(self.mav_type, self.autopilot, self.base_mode, self.custom_mode, 4)

    def position(self, time_boot_ms, x=0.0, y=0.0, z=-10.0, vx=0.0, vy=0.0, vz=0.0):
        self.mav.local_position_ned_send(time_boot_ms, x, y, z, vx, vy, vz)

    def drain(self, duration_s=0.1, ack=True):
        """Read the companion's messages for ``duration_s``; ACK every COMMAND_LONG (accepted)."""
        end = time.monotonic() + duration_s
        out = []
        while time.monotonic() < end:
            try:
                data, _ = self.sock.recvfrom(65535)
            except socket.timeout:
                continue
            msgs = self.mav.parse_buffer(data) or []
            for m in msgs:
                out.append(m)
                if ack and m.get_type() == "COMMAND_LONG":
                    self.mav.command_ack_send(m.command, 0)
        self.received += out
        return out

    def close(self):
        self.sock.close()
