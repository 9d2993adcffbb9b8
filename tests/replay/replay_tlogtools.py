"""Helpers for the replay tests: write small tlogs with pymavlink, edit records in place.

These build the files the tests read, independently of the code under test: packets are packed
by pymavlink and framed here by hand (8-byte big-endian microsecond timestamp + packet).
"""

from __future__ import annotations

import struct
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pymavlink.generator.mavcrc import x25crc

T0_US = 1_795_000_000_000_000  # a UNIX time in 2026, microseconds


class TlogBuilder:
    """Collect (time, packet) records from several senders and write them as a tlog."""

    def __init__(self):
        self._senders: dict[tuple[int, int], mavlink.MAVLink] = {}
        self.records: list[tuple[int, bytes]] = []  # (time_us, packet)

    def sender(self, system: int, component: int, signing_key: bytes | None = None) -> mavlink.MAVLink:
        key = (system, component)
        if key not in self._senders:
            mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)
            if signing_key is not None:
                mav.signing.secret_key = signing_key
                mav.signing.link_id = 0
                mav.signing.timestamp = 1
                mav.signing.sign_outgoing = True
            self._senders[key] = mav
        return self._senders[key]

    def add(self, time_s: float, system: int, component: int, msg, mavlink1: bool = False,
            signing_key: bytes | None = None) -> int:
        """Append one message; returns its index in :attr:`records`."""
        mav = self.sender(system, component, signing_key)
        packet = msg.pack(mav, force_mavlink1=mavlink1)
        self.records.append((T0_US + int(round(time_s * 1e6)), bytes(packet)))
        return len(self.records) - 1

    def to_bytes(self) -> bytes:
        return b"".join(struct.pack(">Q", t) + p for t, p in self.records)

    def offsets(self) -> list[int]:
        """Byte offset of each record in :meth:`to_bytes`."""
        out, pos = [], 0
        for _, packet in self.records:
            out.append(pos)
            pos += 8 + len(packet)
        return out

    def write(self, path: Path) -> Path:
        path.write_bytes(self.to_bytes())
        return path


def heartbeat(mav_type: int, autopilot: int, custom_mode: int = 0, armed: bool = False):
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
    return mavlink.MAVLink_heartbeat_message(mav_type, autopilot, base, custom_mode,
                                             mavlink.MAV_STATE_ACTIVE, 3)


def local_position(time_boot_ms: int, x, y, z, vx, vy, vz):
    return mavlink.MAVLink_local_position_ned_message(time_boot_ms, x, y, z, vx, vy, vz)


def iter_frames(data: bytes):
    """(offset, time_us, packet) of each record of a clean tlog (no corruption handling)."""
    pos = 0
    while pos < len(data):
        (time_us,) = struct.unpack_from(">Q", data, pos)
        start = pos + 8
        if data[start] == 0xFD:
            signed = 13 if data[start + 2] & 1 else 0
            length = 10 + data[start + 1] + 2 + signed
        else:
            length = 6 + data[start + 1] + 2
        yield pos, time_us, data[start:start + length]
        pos = start + length


def refresh_crc(packet: bytearray) -> None:
    """Recompute the CRC of an unsigned MAVLink 2 packet edited in place."""
    msg_id = packet[7] | (packet[8] << 8) | (packet[9] << 16)
    crc_extra = mavlink.mavlink_map[msg_id].crc_extra
    body = bytearray(packet[1:-2])
    body.append(crc_extra)
    crc = x25crc(body).crc
    packet[-2] = crc & 0xFF
    packet[-1] = crc >> 8
