"""Reading telemetry logs (tlogs): every MAVLink packet with its time and byte offset.

A tlog is a plain concatenation of records, each an 8-byte big-endian UNIX timestamp in
microseconds followed by one raw MAVLink packet (MAVLink 1, start byte ``0xFE``, or MAVLink 2,
start byte ``0xFD``, possibly signed). MAVProxy, QGroundControl and the companion's own recorder
all write this framing; the file carries both directions of the link and whatever else shared it
(a ground station, a camera, a second vehicle).

This reader frames the records itself instead of using ``mavutil``'s tlog reader, because a real
log can be cut mid-packet or carry garbage in the middle, and the right response is to say where
and carry on with what can be read. A record is accepted when

- its start byte is a MAVLink start byte and the packet fits in the file,
- its timestamp is plausible (within :data:`MAX_BACKWARD_S` before and :data:`MAX_FORWARD_S`
  after the previous accepted record), and
- its checksum (CRC-16/MCRF4XX with the message's CRC_EXTRA) is right; a message id the dialect
  does not know cannot be checked, so it is accepted only when a plausible record follows it.

When a record fails, the reader scans forward for the next position where a record is accepted,
and reports the skipped bytes as one :class:`LogWarning` with the byte offset. It never raises on
the content of the file; it raises :class:`companion.errors.LogError` only when the file cannot be
opened.

Decoding a packet into a pymavlink message object is the expensive part, so callers can ask for
only the message ids they use (``decode_ids``); the other records are checked and counted, and
come back with ``msg`` set to None.

Examples
--------
>>> reader = TlogReader("flight.tlog", decode_ids={MSG_ID["HEARTBEAT"]})  # doctest: +SKIP
>>> for rec in reader:                                                    # doctest: +SKIP
...     if rec.msg is not None:
...         print(rec.time_s, rec.src_system, mode_name_from_heartbeat(rec.msg))
>>> reader.warnings                                                       # doctest: +SKIP
"""

from __future__ import annotations

import math
import mmap
import operator
import os
import re
import struct
import sys
from array import array
from dataclasses import dataclass
from pathlib import Path
from collections import namedtuple
from typing import Callable, Iterable, Iterator, NamedTuple

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pymavlink.generator.mavcrc import x25crc

try:  # the C implementation pymavlink uses when it is installed
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover - fastcrc is optional
    _mcrf4xx = None

from companion.errors import LogError

# Framing constants of the tlog and of MAVLink 1 and 2.
TIMESTAMP_BYTES = 8
MAGIC_V1 = 0xFE
MAGIC_V2 = 0xFD
HEADER_BYTES_V1 = 6
HEADER_BYTES_V2 = 10
CRC_BYTES = 2
SIGNATURE_BYTES = 13
IFLAG_SIGNED = 0x01

# Timestamp plausibility, relative to the previous accepted record. Clocks can step back a
# little (NTP), and a log can span a long pause, but garbage read as a timestamp is usually
# centuries away.
MAX_BACKWARD_S = 3600.0
MAX_FORWARD_S = 7 * 86400.0
# Timestamps of the first record must fall in this UNIX-time range (1990 .. 2200).
FIRST_TIMESTAMP_RANGE_US = (631152000 * 10**6, 7258118400 * 10**6)

#: Message id by name, and name by id, for the dialect the reader decodes (ardupilotmega,
#: a superset of common).
MSG_ID: dict[str, int] = {cls.msgname: msg_id for msg_id, cls in mavlink.mavlink_map.items()}
MSG_NAME: dict[int, str] = {msg_id: cls.msgname for msg_id, cls in mavlink.mavlink_map.items()}

_TIMESTAMP = struct.Struct(">Q")
_MAX_BACKWARD_US = int(MAX_BACKWARD_S * 1e6)
_MAX_FORWARD_US = int(MAX_FORWARD_S * 1e6)
_MAVLINK_MAP = mavlink.mavlink_map
_new_tuple = tuple.__new__  # a named tuple from a tuple, without its Python-level __new__
_START_BYTES = re.compile(b"[\xfd\xfe]")


class LogRecord(NamedTuple):
    """One accepted record of a tlog.

    Attributes
    ----------
    time_s : UNIX time of the record (from the tlog framing), seconds.
    offset : byte offset of the record (its timestamp) in the file.
    msg_id : MAVLink message id.
    src_system, src_component : sender of the packet.
    msg : the decoded pymavlink message, or None when ``msg_id`` was not asked for.
    mavlink_version : 1 or 2.
    """

    time_s: float
    offset: int
    msg_id: int
    src_system: int
    src_component: int
    msg: object | None
    mavlink_version: int

    @property
    def msg_type(self) -> str:
        """Message name (``"UNKNOWN_<id>"`` for an id the dialect does not know)."""
        return MSG_NAME.get(self.msg_id, f"UNKNOWN_{self.msg_id}")


@dataclass(frozen=True)
class LogWarning:
    """A stretch of the file that could not be read as records.

    Attributes
    ----------
    offset : byte offset where the unreadable stretch starts.
    length : number of bytes skipped (to the next accepted record or the end of the file).
    reason : why the first record at ``offset`` was rejected.
    """

    offset: int
    length: int
    reason: str

    def __str__(self) -> str:
        return f"byte {self.offset}: skipped {self.length} bytes ({self.reason})"

    def as_dict(self) -> dict:
        return {"offset": self.offset, "length": self.length, "reason": self.reason}


def _crc16_extra(buf: bytes, extra: int) -> int:
    """:func:`_crc16` of ``buf`` followed by the byte ``extra`` (the message's CRC_EXTRA)."""
    if _mcrf4xx is not None:
        return _mcrf4xx(_EXTRA_BYTES[extra], _mcrf4xx(buf, 0xFFFF))
    return _crc16(buf + _EXTRA_BYTES[extra])


_EXTRA_BYTES = [bytes((b,)) for b in range(256)]


def _crc16(buf: bytes) -> int:
    """CRC-16/MCRF4XX (X.25) of ``buf``, as MAVLink computes it."""
    if _mcrf4xx is not None:
        return _mcrf4xx(buf, 0xFFFF)
    return x25crc(bytearray(buf)).crc


class _LightDecoder:
    """Decode one message type into a named tuple, straight from pymavlink's own layout tables.

    pymavlink's ``MAVLink.decode`` builds a full message object (several Python-level loops per
    packet); replay needs millions of packets and only reads fields, so this decoder unpacks the
    payload with the message's ``struct`` and maps the wire order to field names exactly as
    pymavlink does (arrays as lists, char arrays as text up to the first NUL). The tuple has the
    message's field names as attributes and ``get_type()``.
    """

    def __init__(self, cls):
        self.unpacker = cls.unpacker
        self.size = cls.unpacker.size
        self.plan = []
        for order in cls.orders:
            length = cls.lengths[order]
            tip = sum(cls.lengths[:order])
            self.plan.append((tip, length))
        base = namedtuple(f"{cls.msgname.title().replace('_', '')}Fields", cls.fieldnames)
        msgname = cls.msgname
        self.tuple_cls = type(base.__name__, (base,), {"__slots__": (), "get_type": lambda self: msgname})
        # Messages of scalar fields only (most of them) map wire order to field order with one
        # itemgetter; the others (arrays, text) go through the general loop.
        scalar = all(length == 1 and not cls.fieldtypes[i].startswith("char")
                     for i, length in enumerate(cls.lengths))
        tips = [tip for tip, _ in self.plan]
        self._scalar_getter = operator.itemgetter(*tips) if scalar and len(tips) > 1 else None
        self._new = tuple.__new__
        self._array_plan = _float_array_plan(cls) if sys.byteorder == "little" else None
        if self._array_plan is not None:
            self.head = struct.Struct(self._array_plan[0])

    def decode(self, payload: bytes):
        if len(payload) < self.size:
            payload = payload + bytes(self.size - len(payload))
        if self._array_plan is not None:
            return self._decode_with_arrays(payload)
        t = self.unpacker.unpack_from(payload)
        if self._scalar_getter is not None:
            return self._new(self.tuple_cls, self._scalar_getter(t))
        values = []
        for tip, length in self.plan:
            field = t[tip]
            if isinstance(field, bytes):  # char arrays: text up to the first NUL, as pymavlink
                values.append(field.split(b"\x00", 1)[0].decode("ascii", errors="replace"))
            elif length == 1:
                values.append(field)
            else:
                values.append(list(t[tip:tip + length]))
        return self.tuple_cls(*values)


    def _decode_with_arrays(self, payload: bytes):
        """Messages with long float arrays (DEBUG_FLOAT_ARRAY's 58 floats): those come as
        ``array('f')`` read straight from the bytes, the other fields as usual."""
        t = self.head.unpack_from(payload)
        values = []
        for tip, offset, count in self._array_plan[1]:
            if count:  # a long float array, by byte offset
                field = array("f")
                field.frombytes(payload[offset:offset + 4 * count])
                values.append(field)
                continue
            field = t[tip]
            if isinstance(field, bytes):
                values.append(field.split(b"\x00", 1)[0].decode("ascii", errors="replace"))
            elif offset:  # a short array
                values.append(list(t[tip:tip + offset]))
            else:
                values.append(field)
        return self.tuple_cls(*values)


#: Float arrays at least this long decode to ``array('f')`` (a list of Python floats costs more
#: to build than the arrays are long: DEBUG_FLOAT_ARRAY carries 58).
LONG_FLOAT_ARRAY = 8


def _float_array_plan(cls):
    """For a message with long float arrays: the struct format of its other fields (the arrays
    skipped as pad bytes) and, in field order, ``(tip, short_length, 0)`` of each field in that
    struct's tuple or ``(0, byte_offset, count)`` of each long float array. None otherwise."""
    tokens = re.findall(r"(\d*)([a-zA-Z?])", cls.unpacker.format.lstrip("<=!>@"))
    if len(tokens) != len(cls.orders) or not any(
            code == "f" and int(num or 1) >= LONG_FLOAT_ARRAY for num, code in tokens):
        return None
    head = "<"
    offset = 0
    tip = 0
    wire = []  # per wire position: (tip, short_length, 0) or (0, byte_offset, count)
    for num, code in tokens:
        count = int(num or 1)
        size = struct.calcsize("<" + num + code)
        if code == "f" and count >= LONG_FLOAT_ARRAY:
            head += f"{size}x"
            wire.append((0, offset, count))
        else:
            head += num + code
            values = 1 if code == "s" else count
            wire.append((tip, count if (count > 1 and code != "s") else 0, 0))
            tip += values
        offset += size
    return head, [wire[order] for order in cls.orders]


_LIGHT: dict[int, _LightDecoder] = {}


def _light_decoder(msg_id: int) -> _LightDecoder:
    dec = _LIGHT.get(msg_id)
    if dec is None:
        dec = _LIGHT[msg_id] = _LightDecoder(mavlink.mavlink_map[msg_id])
    return dec


def _map_file(path: Path):
    """The file's bytes, memory-mapped (a long log is not copied into memory); ``b""`` when empty."""
    with open(path, "rb") as f:
        if os.fstat(f.fileno()).st_size == 0:
            return b""
        return mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)


class _Reject(Exception):
    """Internal: the record at a position is not acceptable (message says why)."""


class TlogReader:
    """Iterate over the records of a tlog, skipping and reporting what cannot be read.

    Parameters
    ----------
    path : the tlog file.
    decode_ids : message ids to decode into pymavlink messages (None decodes every known id).
        Records of other ids are still checked (CRC) and yielded with ``msg=None``.
    on_warning : called with each :class:`LogWarning` as it is found (they are also collected in
        :attr:`warnings`).
    light : decode into light named tuples (field attributes and ``get_type()`` only) instead of
        pymavlink message objects: several times faster, for readers of many records (replay).

    Attributes
    ----------
    size_bytes : file size.
    warnings : every :class:`LogWarning`, in file order, after (or during) iteration.
    records : number of records accepted so far.
    bytes_skipped : total bytes that could not be read as records.
    position : byte offset the reader has reached (for progress reporting).
    """

    def __init__(
        self,
        path: str | Path,
        decode_ids: Iterable[int] | None = None,
        on_warning: Callable[[LogWarning], None] | None = None,
        light: bool = False,
    ):
        self.path = Path(path)
        self.light = bool(light)
        try:
            self._data = _map_file(self.path)
        except (OSError, ValueError) as err:
            reason = err.strerror if isinstance(err, OSError) and err.strerror else err
            raise LogError(f"{self.path}: cannot read the log ({reason})") from err
        self.size_bytes = len(self._data)
        self.decode_ids = None if decode_ids is None else frozenset(decode_ids)
        self.on_warning = on_warning
        self.warnings: list[LogWarning] = []
        self.records = 0
        self.bytes_skipped = 0
        self.position = 0
        self._mav = mavlink.MAVLink(None)

    # -- framing ---------------------------------------------------------------------------

    def _packet_length(self, pos: int) -> tuple[int, int, int, int, int]:
        """Length and header fields of the packet whose start byte is at ``pos``.

        Returns ``(packet_bytes, version, msg_id, src_system, src_component)``.
        """
        data = self._data
        magic = data[pos]
        if magic == MAGIC_V2:
            if pos + HEADER_BYTES_V2 > len(data):
                raise _Reject("file ends inside a MAVLink 2 header")
            payload = data[pos + 1]
            signed = data[pos + 2] & IFLAG_SIGNED
            msg_id = data[pos + 7] | (data[pos + 8] << 8) | (data[pos + 9] << 16)
            total = HEADER_BYTES_V2 + payload + CRC_BYTES + (SIGNATURE_BYTES if signed else 0)
            return total, 2, msg_id, data[pos + 5], data[pos + 6]
        if magic == MAGIC_V1:
            if pos + HEADER_BYTES_V1 > len(data):
                raise _Reject("file ends inside a MAVLink 1 header")
            payload = data[pos + 1]
            total = HEADER_BYTES_V1 + payload + CRC_BYTES
            return total, 1, data[pos + 5], data[pos + 3], data[pos + 4]
        raise _Reject(f"no MAVLink start byte (found 0x{magic:02x})")

    def _timestamp_ok(self, time_us: int, prev_us: int | None) -> bool:
        if prev_us is None:
            return FIRST_TIMESTAMP_RANGE_US[0] <= time_us <= FIRST_TIMESTAMP_RANGE_US[1]
        delta_s = (time_us - prev_us) * 1e-6
        return -MAX_BACKWARD_S <= delta_s <= MAX_FORWARD_S

    def _plausible_start(self, pos: int, prev_us: int | None) -> bool:
        """Cheap check that a record could start at ``pos`` (used after unknown ids)."""
        data = self._data
        if pos == len(data):
            return True
        if pos + TIMESTAMP_BYTES + 1 > len(data):
            return False
        (time_us,) = _TIMESTAMP.unpack_from(data, pos)
        return data[pos + TIMESTAMP_BYTES] in (MAGIC_V1, MAGIC_V2) and self._timestamp_ok(time_us, prev_us)

    def _try_record(self, pos: int, prev_us: int | None) -> tuple[LogRecord, int, int]:
        """Accept the record at ``pos`` or raise :class:`_Reject`.

        Returns ``(record, next_position, time_us)``.
        """
        data = self._data
        if pos + TIMESTAMP_BYTES + 1 > len(data):
            raise _Reject("file ends inside a record (truncated)")
        (time_us,) = _TIMESTAMP.unpack_from(data, pos)
        if not self._timestamp_ok(time_us, prev_us):
            raise _Reject("implausible timestamp")
        start = pos + TIMESTAMP_BYTES
        total, version, msg_id, src_system, src_component = self._packet_length(start)
        end = start + total
        if end > len(data):
            raise _Reject(f"file ends inside a packet (truncated, {end - len(data)} bytes missing)")
        cls = mavlink.mavlink_map.get(msg_id)
        decode = self.decode_ids is None or msg_id in self.decode_ids
        msg = None
        if cls is None:
            if not self._plausible_start(end, time_us):
                raise _Reject(f"unknown message id {msg_id} not followed by a record")
        elif decode and self.light:
            sig = SIGNATURE_BYTES if (version == 2 and data[start + 2] & IFLAG_SIGNED) else 0
            crc_end = end - sig
            crc = data[crc_end - 2] | (data[crc_end - 1] << 8)
            if _crc16(data[start + 1: crc_end - CRC_BYTES] + bytes((cls.crc_extra,))) != crc:
                raise _Reject(f"bad checksum in message id {msg_id}")
            header = HEADER_BYTES_V2 if version == 2 else HEADER_BYTES_V1
            try:
                msg = _light_decoder(msg_id).decode(data[start + header: crc_end - CRC_BYTES])
            except struct.error as err:
                raise _Reject(f"undecodable packet: {err}") from None
        elif decode:
            try:
                msg = self._mav.decode(bytearray(data[start:end]))
            except Exception as err:  # pymavlink raises MAVError and struct errors alike
                raise _Reject(f"undecodable packet: {err}") from None
            msg._timestamp = time_us * 1e-6
        else:
            sig = SIGNATURE_BYTES if (version == 2 and data[start + 2] & IFLAG_SIGNED) else 0
            crc_end = end - sig
            crc = data[crc_end - 2] | (data[crc_end - 1] << 8)
            if _crc16(data[start + 1: crc_end - CRC_BYTES] + bytes((cls.crc_extra,))) != crc:
                raise _Reject(f"bad checksum in message id {msg_id}")
        record = LogRecord(time_us * 1e-6, pos, msg_id, src_system, src_component, msg, version)
        return record, end, time_us

    def _resync(self, pos: int, prev_us: int | None):
        """Find the next acceptable record after ``pos``; None when there is none."""
        search = pos + TIMESTAMP_BYTES + 1
        while True:
            match = _START_BYTES.search(self._data, search)
            if match is None:
                return None
            candidate = match.start() - TIMESTAMP_BYTES
            try:
                return candidate, self._try_record(candidate, prev_us)
            except _Reject:
                search = match.start() + 1

    def _warn(self, offset: int, length: int, reason: str) -> None:
        warning = LogWarning(offset, length, reason)
        self.warnings.append(warning)
        self.bytes_skipped += length
        if self.on_warning is not None:
            self.on_warning(warning)

    # -- iteration -------------------------------------------------------------------------

    def __iter__(self) -> Iterator[LogRecord]:
        pos = 0
        prev_us: int | None = None
        data = self._data
        size = len(data)
        fast = self.light or self.decode_ids is not None
        while pos < size:
            self.position = pos
            found = self._fast_record(data, size, pos, prev_us) if fast and prev_us is not None else None
            if found is not None:
                record, nxt, time_us = found
            else:
                try:
                    record, nxt, time_us = self._try_record(pos, prev_us)
                except _Reject as why:
                    found = self._resync(pos, prev_us)
                    if found is None:
                        self._warn(pos, size - pos, str(why))
                        break
                    new_pos, (record, nxt, time_us) = found
                    self._warn(pos, new_pos - pos, str(why))
            self.records += 1
            prev_us = time_us
            pos = nxt
            yield record
        self.position = size

    def _fast_record(self, data, size: int, pos: int, prev_us: int):
        """The common case of :meth:`_try_record` in one function: a whole, known, checksummed
        record that needs no pymavlink decoding (light or not decoded). Returns the same tuple,
        or None whenever anything is unusual (the caller then runs :meth:`_try_record`, which
        accepts or rejects it with the reason)."""
        start = pos + TIMESTAMP_BYTES
        if start + HEADER_BYTES_V2 > size:
            return None
        (time_us,) = _TIMESTAMP.unpack_from(data, pos)
        if not -_MAX_BACKWARD_US < time_us - prev_us < _MAX_FORWARD_US:  # strictly: the float check decides the edges
            return None
        magic = data[start]
        if magic == MAGIC_V2:
            flags = data[start + 2]
            msg_id = data[start + 7] | (data[start + 8] << 8) | (data[start + 9] << 16)
            header = HEADER_BYTES_V2
            sig = SIGNATURE_BYTES if flags & IFLAG_SIGNED else 0
            src_system, src_component, version = data[start + 5], data[start + 6], 2
        elif magic == MAGIC_V1:
            msg_id = data[start + 5]
            header = HEADER_BYTES_V1
            sig = 0
            src_system, src_component, version = data[start + 3], data[start + 4], 1
        else:
            return None
        crc_end = start + header + data[start + 1] + CRC_BYTES
        end = crc_end + sig
        if end > size:
            return None
        cls = _MAVLINK_MAP.get(msg_id)
        if cls is None:
            return None
        decode = self.decode_ids is None or msg_id in self.decode_ids
        if decode and not self.light:
            return None
        body = data[start + 1: crc_end - CRC_BYTES]
        if _crc16_extra(body, cls.crc_extra) != data[crc_end - 2] | (data[crc_end - 1] << 8):
            return None
        msg = None
        if decode:
            dec = _LIGHT.get(msg_id) or _light_decoder(msg_id)
            try:
                msg = dec.decode(body[header - 1:])
            except struct.error:
                return None
        return _new_tuple(LogRecord, (time_us * 1e-6, pos, msg_id, src_system, src_component, msg, version)), end, time_us


def read_tlog(path: str | Path, decode_ids: Iterable[int] | None = None) -> tuple[list[LogRecord], list[LogWarning]]:
    """Read a whole tlog: ``(records, warnings)``. See :class:`TlogReader`."""
    reader = TlogReader(path, decode_ids=decode_ids)
    records = list(reader)
    return records, reader.warnings


# -- naming helpers (pymavlink's enums and mode tables stay behind this module) -------------

def enum_name(enum: str, value: int) -> str:
    """Name of a MAVLink enum value, e.g. ``enum_name("MAV_TYPE", 2) == "MAV_TYPE_QUADROTOR"``."""
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else f"{enum}_{value}"


MAV_AUTOPILOT_ARDUPILOTMEGA = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
MAV_AUTOPILOT_PX4 = mavlink.MAV_AUTOPILOT_PX4
MAV_AUTOPILOT_INVALID = mavlink.MAV_AUTOPILOT_INVALID
MAV_MODE_FLAG_SAFETY_ARMED = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


def mode_name(autopilot: int, mav_type: int, base_mode: int, custom_mode: int) -> str:
    """Flight-mode name from the fields of a HEARTBEAT.

    PX4 packs ``custom_mode = (main << 16) | (sub << 24)`` (e.g. OFFBOARD, MISSION, LOITER for
    AUTO/Hold); ArduPilot puts the vehicle's mode number in ``custom_mode`` and its meaning
    depends on the vehicle type (Copter 4 GUIDED, Plane/Rover 15 GUIDED). Anything else, or a
    number neither table knows, is returned as ``"custom_mode <n>"``.
    """
    if autopilot == MAV_AUTOPILOT_PX4:
        name = mavutil.interpret_px4_mode(base_mode, custom_mode)
        if name.startswith("Mode("):
            return f"custom_mode {custom_mode}"
        return name
    if autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA and base_mode & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        table = mavutil.mode_mapping_bynumber(mav_type) or {}
        if custom_mode in table:
            return table[custom_mode]
    return f"custom_mode {custom_mode}"


def mode_name_from_heartbeat(msg) -> str:
    """:func:`mode_name` of a decoded HEARTBEAT message."""
    return mode_name(msg.autopilot, msg.type, msg.base_mode, msg.custom_mode)


# -- writing packets (synthetic logs for tests and benchmarks) ------------------------------

class PacketEncoder:
    """Pack messages from one sender as raw MAVLink 2 packets (for synthetic tlogs).

    Each ``*_packet`` method returns the bytes a tlog record carries after its timestamp;
    :class:`companion.io.tlog.TlogWriter` adds the timestamp. The sequence number advances by one
    per packet, as on a real link.

    >>> enc = PacketEncoder(1, 1)
    >>> pkt = enc.local_position_ned_packet(1000, 1.0, 2.0, -3.0, 0.5, 0.0, 0.0)
    >>> pkt[0] == MAGIC_V2, pkt[5], pkt[6]
    (True, 1, 1)
    """

    def __init__(self, system: int, component: int):
        self._mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)

    def _pack(self, msg) -> bytes:
        packet = bytes(msg.pack(self._mav))
        self._mav.seq = (self._mav.seq + 1) % 256
        return packet

    def heartbeat_packet(self, mav_type: int, autopilot: int, base_mode: int = 0, custom_mode: int = 0) -> bytes:
        return self._pack(self._mav.heartbeat_encode(mav_type, autopilot, base_mode, custom_mode,
                                                     mavlink.MAV_STATE_ACTIVE))

    def local_position_ned_packet(self, time_boot_ms: int, x_m: float, y_m: float, z_m: float,
                                  vx_m_s: float, vy_m_s: float, vz_m_s: float) -> bytes:
        return self._pack(self._mav.local_position_ned_encode(int(time_boot_ms), x_m, y_m, z_m,
                                                              vx_m_s, vy_m_s, vz_m_s))

    def attitude_packet(self, time_boot_ms: int, roll_rad: float, pitch_rad: float, yaw_rad: float) -> bytes:
        return self._pack(self._mav.attitude_encode(int(time_boot_ms), roll_rad, pitch_rad, yaw_rad,
                                                    0.0, 0.0, 0.0))

    def global_position_int_packet(self, time_boot_ms: int, lat_deg: float, lon_deg: float, alt_msl_m: float,
                                   rel_alt_m: float, vn_m_s: float, ve_m_s: float, vd_m_s: float,
                                   heading_deg: float) -> bytes:
        return self._pack(self._mav.global_position_int_encode(
            int(time_boot_ms), int(round(lat_deg * 1e7)), int(round(lon_deg * 1e7)), int(round(alt_msl_m * 1e3)),
            int(round(rel_alt_m * 1e3)), int(round(vn_m_s * 100)), int(round(ve_m_s * 100)),
            int(round(vd_m_s * 100)), int(round(heading_deg * 100)) % 36000))

    def gps_raw_int_packet(self, time_usec: int, lat_deg: float, lon_deg: float, alt_msl_m: float,
                           ground_speed_m_s: float, course_deg: float, satellites: int = 10) -> bytes:
        return self._pack(self._mav.gps_raw_int_encode(
            int(time_usec), 3, int(round(lat_deg * 1e7)), int(round(lon_deg * 1e7)), int(round(alt_msl_m * 1e3)),
            121, 200, int(round(ground_speed_m_s * 100)), int(round(course_deg * 100)) % 36000, satellites))

    def vfr_hud_packet(self, airspeed_m_s: float, ground_speed_m_s: float, heading_deg: float,
                       throttle_pct: int, alt_m: float, climb_m_s: float) -> bytes:
        return self._pack(self._mav.vfr_hud_encode(airspeed_m_s, ground_speed_m_s, int(heading_deg) % 360,
                                                   int(throttle_pct), alt_m, climb_m_s))

    def sys_status_packet(self, voltage_mv: int, current_ca: int, battery_pct: int, load_permille: int = 200) -> bytes:
        sensors = 0x0020_FC3F  # gyro, accel, mag, baro, GPS, ... present, enabled and healthy
        return self._pack(self._mav.sys_status_encode(sensors, sensors, sensors, int(load_permille), int(voltage_mv),
                                                      int(current_ca), int(battery_pct), 0, 0, 0, 0, 0, 0))

    def velocity_setpoint_packet(self, target_system: int, target_component: int, type_mask: int,
                                 coordinate_frame: int, vx_m_s: float, vy_m_s: float, vz_m_s: float,
                                 yaw_rate_rad_s: float, time_boot_ms: int = 0, afx_m_s2: float = 0.0,
                                 afy_m_s2: float = 0.0) -> bytes:
        return self._pack(self._mav.set_position_target_local_ned_encode(
            int(time_boot_ms), target_system, target_component, coordinate_frame, type_mask,
            0.0, 0.0, 0.0, vx_m_s, vy_m_s, vz_m_s, afx_m_s2, afy_m_s2, 0.0, 0.0, yaw_rate_rad_s))

    def attitude_target_packet(self, target_system: int, target_component: int, type_mask: int,
                               q: tuple[float, float, float, float], thrust: float,
                               time_boot_ms: int = 0) -> bytes:
        return self._pack(self._mav.set_attitude_target_encode(
            int(time_boot_ms), target_system, target_component, type_mask, list(q), 0.0, 0.0, 0.0, thrust))

    def debug_float_array_packet(self, name: str, array_id: int, time_usec: int, data) -> bytes:
        values = [float(v) for v in data][:58]
        values += [math.nan] * (58 - len(values))
        return self._pack(self._mav.debug_float_array_encode(int(time_usec), name.encode()[:10],
                                                             int(array_id) % 65536, values))
