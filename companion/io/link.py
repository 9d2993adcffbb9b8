"""The MAVLink link: the one adapter between the companion and pymavlink.

``MavLink(connect, ...)`` opens a connection string, sends the companion's own HEARTBEAT
(MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID, component 191 by default), pairs with one
autopilot and from then on accepts state only from it.

Connection strings (as pymavlink spells them):

* ``udpin:0.0.0.0:14540`` listen (PX4 SITL's offboard port). The peer is **pinned** to the
  address the paired autopilot's heartbeat came from; datagrams from any other address are
  dropped and counted (pymavlink's own UDP server would start sending to whoever wrote last).
  After the pinned peer has been silent for ``repin_after_s`` a heartbeat of the *same* system
  and component from a new address re-pins it (an autopilot restart gets a new source port).
* ``udp:0.0.0.0:14540`` the same as ``udpin:`` (pymavlink's ``mavlink_connection`` and
  MAVProxy's ``--master`` listen on a plain ``udp:`` address).
* ``udpout:127.0.0.1:14550`` send to a fixed address, receive replies on the same socket (only
  datagrams from that address are accepted).
* ``tcp:127.0.0.1:5760`` (ArduPilot SITL; a refused connection is retried quietly twice, half a
  second apart, then reported in one line), ``/dev/ttyACM0,921600`` (serial; 57600 baud if
  none is given).

Pairing before recording: :func:`connect_autopilot` opens the link and waits for the
autopilot's heartbeat with the packets kept in memory, so that a failed connection leaves no
file behind; :meth:`MavLink.attach_tlog` then moves them into the flight's tlog.

Packets are parsed with pymavlink's MAVLink 2 parser (MAVLink 1 is read too). A UDP datagram is
parsed on its own (no bytes carried over to the next datagram). Rejections are counted by reason
in :attr:`MavLink.rejected`: ``bad_crc``, ``bad_data`` (bad prefix, wrong length, truncated),
``wrong_system`` (not the paired system/component),
``wrong_address`` (UDP datagram not from the pinned peer), ``unsigned`` and ``bad_signature``
(signing on), ``nan`` and ``out_of_range`` (state fields), ``old_sample`` (a LOCAL_POSITION_NED
not newer than the one held: reordered, duplicated or replayed; an earlier time is taken only as
an autopilot reboot, after a silence and with evidence, see :meth:`MavLink._position_restart`).
A message whose id the dialect does not know (a real PX4 sends about 25 a second: newer or
development messages) is not an error: it is counted in :attr:`MavLink.ignored` and dropped.

Signing (MAVLink 2): ``signing_key`` is 32 bytes (:func:`load_signing_key` reads a file with 64
hex characters, or any other text as a passphrase hashed with SHA-256). When set, every outgoing
packet is signed and unsigned or wrongly signed incoming packets are rejected.
"""

from __future__ import annotations

import hashlib
import math
import os
import select
import signal
import socket
import struct
import threading
import time
from dataclasses import dataclass, field
from types import FrameType
from typing import Callable

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from companion.errors import LinkError
from companion.io.setpoints import (
    IGNORE_AX,
    IGNORE_AY,
    IGNORE_AZ,
    IGNORE_VX,
    IGNORE_VY,
    IGNORE_VZ,
    IGNORE_YAW,
    IGNORE_YAW_RATE,
    MAV_FRAME_LOCAL_NED,
    AttitudeSetpoint,
    VelocitySetpoint,
)
from companion.io.state import GlobalOrigin, PositionSample, global_origin_from_wire, position_problem, yaw_problem
from companion.io.tlog import TlogWriter

# The dialect's names (pymavlink's ardupilotmega, a superset of common), re-exported for the
# rest of the companion, which never imports pymavlink.
MAV_COMP_ID_ONBOARD_COMPUTER = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER
MAV_TYPE_ONBOARD_CONTROLLER = mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
MAV_AUTOPILOT_INVALID = mavlink2.MAV_AUTOPILOT_INVALID
MAV_AUTOPILOT_ARDUPILOTMEGA = mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
MAV_AUTOPILOT_PX4 = mavlink2.MAV_AUTOPILOT_PX4
MSG_ID_LOCAL_POSITION_NED = mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED
MSG_ID_ATTITUDE = mavlink2.MAVLINK_MSG_ID_ATTITUDE
MSG_ID_GPS_GLOBAL_ORIGIN = mavlink2.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN
#: What explains a wait for the position (GPS fix, EKF flags, landed state): the flight asks for
#: them at 1 Hz; each fills a field of :class:`LinkState` when the autopilot sends it.
READINESS_MSG_IDS = (mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT, mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
                     mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)
MAV_PARAM_TYPE_REAL32 = mavlink2.MAV_PARAM_TYPE_REAL32

MAV_CMD_NAV_LAND = mavlink2.MAV_CMD_NAV_LAND
MAV_CMD_NAV_TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF
MAV_CMD_DO_SET_MODE = mavlink2.MAV_CMD_DO_SET_MODE
MAV_CMD_DO_CHANGE_SPEED = mavlink2.MAV_CMD_DO_CHANGE_SPEED
MAV_CMD_COMPONENT_ARM_DISARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
MAV_CMD_SET_MESSAGE_INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
MAV_CMD_REQUEST_MESSAGE = mavlink2.MAV_CMD_REQUEST_MESSAGE
MAV_CMD_GUIDED_CHANGE_SPEED = mavlink2.MAV_CMD_GUIDED_CHANGE_SPEED
MAV_CMD_GUIDED_CHANGE_ALTITUDE = mavlink2.MAV_CMD_GUIDED_CHANGE_ALTITUDE
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
MAV_MODE_FLAG_SAFETY_ARMED = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
MAV_RESULT_IN_PROGRESS = mavlink2.MAV_RESULT_IN_PROGRESS
MAV_LANDED_STATE_ON_GROUND = mavlink2.MAV_LANDED_STATE_ON_GROUND
MAV_LANDED_STATE_IN_AIR = mavlink2.MAV_LANDED_STATE_IN_AIR
MAV_LANDED_STATE_UNDEFINED = mavlink2.MAV_LANDED_STATE_UNDEFINED

#: MAV_RESULT in words (``ACCEPTED``, ``DENIED``, ...), from the dialect's enum.
MAV_RESULT_NAMES = {value: entry.name.removeprefix("MAV_RESULT_")
                    for value, entry in mavlink2.enums["MAV_RESULT"].items() if entry.name != "MAV_RESULT_ENUM_END"}
MAV_RESULT_NAMES.setdefault(6, "CANCELLED")  # MAV_RESULT_CANCELLED: newer than this dialect
MAV_SEVERITY_CRITICAL = mavlink2.MAV_SEVERITY_CRITICAL
MAV_SEVERITY_WARNING = mavlink2.MAV_SEVERITY_WARNING
MAV_SEVERITY_NOTICE = mavlink2.MAV_SEVERITY_NOTICE
MAV_SEVERITY_INFO = mavlink2.MAV_SEVERITY_INFO
STATUSTEXT_CHARS = 50  # the text field of STATUSTEXT

#: A time_boot_ms this far behind the newest one means the autopilot restarted.
RESTART_JUMP_S = 2.0

REJECT_REASONS = ("bad_crc", "bad_data", "wrong_system", "wrong_address", "unsigned",
                  "bad_signature", "nan", "out_of_range", "old_sample")

_T = mavlink2
COPTER_TYPES = {_T.MAV_TYPE_QUADROTOR, _T.MAV_TYPE_COAXIAL, _T.MAV_TYPE_HELICOPTER, _T.MAV_TYPE_HEXAROTOR,
                _T.MAV_TYPE_OCTOROTOR, _T.MAV_TYPE_TRICOPTER, _T.MAV_TYPE_DODECAROTOR}
PLANE_TYPES = {_T.MAV_TYPE_FIXED_WING, _T.MAV_TYPE_FLAPPING_WING, _T.MAV_TYPE_VTOL_DUOROTOR,  # and VTOLs
               _T.MAV_TYPE_VTOL_QUADROTOR, _T.MAV_TYPE_VTOL_TILTROTOR, _T.MAV_TYPE_VTOL_RESERVED2,
               _T.MAV_TYPE_VTOL_RESERVED3, _T.MAV_TYPE_VTOL_RESERVED4, _T.MAV_TYPE_VTOL_RESERVED5}
ROVER_TYPES = {_T.MAV_TYPE_GROUND_ROVER, _T.MAV_TYPE_SURFACE_BOAT}

# PX4 custom_mode = (main << 16) | (sub << 24).
PX4_MODES = {
    "offboard": (6, 0),
    "position": (3, 0),
    "hold": (4, 3),
    "loiter": (4, 3),
    "rtl": (4, 5),
    "land": (4, 6),
}
# ArduPilot custom_mode by vehicle.
ARDUPILOT_MODES = {
    "copter": {"guided": 4, "loiter": 5, "rtl": 6, "land": 9, "brake": 17, "hold": 4},
    "plane": {"guided": 15, "loiter": 12, "rtl": 11, "hold": 12},
    "rover": {"guided": 15, "hold": 4, "loiter": 5, "rtl": 11, "land": 4},
}


def load_signing_key(path: str | os.PathLike) -> bytes:
    """Read a 32-byte MAVLink 2 signing key: 64 hex characters, or a passphrase (SHA-256 of it).

    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "k"; _ = p.write_text("00" * 32 + "\\n")
    >>> load_signing_key(p) == bytes(32)
    True
    """
    try:
        text = open(path, encoding="utf-8").read().strip()
    except OSError as err:
        raise LinkError(f"{path}: cannot read the signing key ({err.strerror or err})") from err
    except UnicodeDecodeError as err:
        raise LinkError(f"{path}: signing key must be text (64 hex characters or a passphrase)") from err
    if not text:
        raise LinkError(f"{path}: signing key file is empty (expected 64 hex characters or a passphrase)")
    if len(text) == 64:
        try:
            return bytes.fromhex(text)
        except ValueError:
            pass
    return hashlib.sha256(text.encode("utf-8")).digest()


def signing_timestamp_now() -> int:
    """MAVLink signing timestamp: units of 10 us since 2015-01-01 00:00 UTC."""
    return int(max(time.time() - 1420070400, 0) * 100_000)


# --------------------------------------------------------------------------------------------
# Transports: raw bytes in and out. UDP keeps datagram boundaries and source addresses.
# --------------------------------------------------------------------------------------------


class _UdpTransport:
    datagrams = True

    def __init__(self, host: str, port: int, listen: bool):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.listen = listen
        self.description = ""
        self.peer: tuple[str, int] | None = None
        try:
            if listen:
                self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                self.sock.bind((host, port))
            else:
                self.peer = (socket.gethostbyname(host), port)
        except OSError as err:
            self.sock.close()
            raise LinkError(f"udp {host}:{port}: {err.strerror or err}") from None
        self.sock.setblocking(False)

    def fileno(self) -> int:
        return self.sock.fileno()

    def recv(self) -> list[tuple[bytes, object]]:
        out = []
        for _ in range(256):
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionRefusedError:
                continue  # ICMP port unreachable from an earlier send: the peer is not up yet
            out.append((data, addr))
        return out

    def send(self, buf: bytes) -> bool:
        if self.peer is None:
            return False  # udpin before pairing: nobody to send to yet
        try:
            self.sock.sendto(buf, self.peer)
        except OSError:
            pass  # a lost datagram is a lost datagram; the link timeout reports a dead link
        return True

    def close(self) -> None:
        self.sock.close()


class _StreamTransport:
    """Serial through pymavlink's raw serial port (byte stream, no source address)."""

    datagrams = False

    def __init__(self, conn, description: str = ""):
        self.conn = conn
        self.peer = None
        self.description = description

    def fileno(self) -> int:
        return self.conn.fd

    def recv(self) -> list[tuple[bytes, object]]:
        try:
            data = self.conn.recv(4096)
        except OSError as err:
            raise LinkError(f"{self.conn.address}: connection lost ({err.strerror or err})") from err
        if not data:
            return []
        if isinstance(data, str):
            data = data.encode("latin-1")
        return [(bytes(data), None)]

    def send(self, buf: bytes) -> bool:
        try:
            self.conn.write(buf)
        except OSError:
            pass
        return True

    def close(self) -> None:
        try:
            self.conn.close()
        except Exception:  # noqa: BLE001 - closing a dead port must not raise
            pass


class _TcpTransport:
    """A TCP client (ArduPilot SITL's ``tcp:127.0.0.1:5760``): byte stream, no source address.

    pymavlink's ``mavtcp`` retries a refused connection by printing ``[Errno 111] Connection
    refused sleeping`` on stdout and raises the bare socket error; this opens the socket itself,
    retries quietly (an autopilot that is just starting listens within a second) and fails with
    one line.
    """

    datagrams = False

    def __init__(self, host: str, port: int, *, attempts: int = 3, retry_s: float = 0.5,
                 connect_timeout_s: float = 5.0):
        where = f"tcp:{host}:{port}"
        self.description = f"connected to {host}:{port}"
        self.peer = None
        self.sock = None
        for attempt in range(attempts):
            try:
                self.sock = socket.create_connection((host, port), timeout=connect_timeout_s)
                break
            except ConnectionRefusedError:
                if attempt + 1 < attempts:
                    time.sleep(retry_s)
            except socket.gaierror as err:
                raise LinkError(f"{where}: unknown host {host!r} ({err.strerror or err})") from None
            except socket.timeout:
                raise LinkError(f"{where}: no answer within {connect_timeout_s:g} s "
                                "(host unreachable, or a firewall drops the connection)") from None
            except OSError as err:
                raise LinkError(f"{where}: cannot connect ({err.strerror or err})") from None
        if self.sock is None:
            raise LinkError(f"{where}: connection refused: nothing listens on {host}:{port} "
                            f"(is the autopilot or SITL running? tried {attempts} times)")
        self.sock.setblocking(False)
        try:
            self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError:
            pass
        self.where = where

    def fileno(self) -> int:
        return self.sock.fileno()

    def recv(self) -> list[tuple[bytes, object]]:
        try:
            data = self.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError as err:
            raise LinkError(f"{self.where}: connection lost ({err.strerror or err})") from None
        if not data:
            raise LinkError(f"{self.where}: connection closed by the autopilot")
        return [(data, None)]

    def send(self, buf: bytes) -> bool:
        try:
            self.sock.sendall(buf)
        except OSError:
            pass  # a full socket buffer or a dead peer: the link timeout reports a dead link
        return True

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


def _port_number(connect: str, text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not (0 < port < 65536):
        raise LinkError(f"{connect}: port {text!r} is not a number 1..65535 (expected KIND:HOST:PORT, "
                        "e.g. udpin:0.0.0.0:14540)")
    return port


#: Connection string kinds: ``udp:`` listens, as pymavlink's ``mavlink_connection`` and MAVProxy's
#: ``--master`` take it (``input=True``); ``udpout:`` sends to a fixed address.
UDP_KINDS = {"udpin": True, "udp": True, "udpout": False}


def open_transport(connect: str):
    """Open a connection string (udpin:, udp:, udpout:, tcp:, serial DEVICE[,BAUD])."""
    kind, sep, rest = connect.partition(":")
    if sep and kind in UDP_KINDS:
        host, _, port = rest.rpartition(":")
        port_n = _port_number(connect, port)
        if not host:
            raise LinkError(f"{connect}: expected {kind}:HOST:PORT, e.g. {kind}:0.0.0.0:14540")
        transport = _UdpTransport(host, port_n, listen=UDP_KINDS[kind])
        transport.description = (f"listening on {host}:{port_n}" if UDP_KINDS[kind]
                                 else f"sending to {host}:{port_n}")
        return transport
    if sep and kind == "tcp":
        host, _, port = rest.rpartition(":")
        port_n = _port_number(connect, port)
        if not host:
            raise LinkError(f"{connect}: expected tcp:HOST:PORT, e.g. tcp:127.0.0.1:5760")
        return _TcpTransport(host, port_n)
    if connect.startswith("/dev/") or connect.upper().startswith("COM"):
        device, comma, baud_text = connect.partition(",")
        baud = 57600
        if comma:
            if not baud_text.strip().isdigit() or int(baud_text) <= 0:
                raise LinkError(f"{connect}: baud rate {baud_text!r} is not a positive whole number "
                                "(expected DEVICE,BAUD, e.g. /dev/ttyACM0,921600)")
            baud = int(baud_text)
        try:
            conn = mavutil.mavserial(device, baud=baud, autoreconnect=False)
        except Exception as err:  # noqa: BLE001 - pyserial raises its own SerialException
            raise LinkError(f"{connect}: cannot open the serial port ({err})") from None
        return _StreamTransport(conn, f"serial {device} at {baud} baud")
    raise LinkError(
        f"{connect}: unknown connection string (expected udpin:HOST:PORT, udp:HOST:PORT, "
        "udpout:HOST:PORT, tcp:HOST:PORT or /dev/DEVICE,BAUD)"
    )


# --------------------------------------------------------------------------------------------


@dataclass
class AutopilotInfo:
    system_id: int
    component_id: int
    autopilot: str  # "px4" or "ardupilot"
    vehicle: str  # "copter", "plane" or "rover"
    mav_type: int


@dataclass
class LinkState:
    """What the link knows of the paired autopilot (updated by :meth:`MavLink.poll`)."""

    position: PositionSample | None = None
    yaw_ned_rad: float | None = None
    custom_mode: int | None = None
    base_mode: int = 0
    armed: bool = False
    last_heartbeat_s: float = math.nan  # monotonic
    last_message_s: float = math.nan  # monotonic, any accepted message
    autopilot_time_s: float = math.nan  # newest time_boot_ms of an accepted message, seconds
    statustext: list = field(default_factory=list)  # (severity, text), newest last (the last 50)
    statustext_count: int = 0  # every STATUSTEXT accepted since the link opened
    acks: dict = field(default_factory=dict)  # command -> (result, monotonic time)
    heartbeats: int = 0
    positions: int = 0
    global_origin: "GlobalOrigin | None" = None  # newest GPS_GLOBAL_ORIGIN (the EKF's local origin)
    landed_state: int = MAV_LANDED_STATE_UNDEFINED  # EXTENDED_SYS_STATE, if the autopilot sends it
    ekf_flags: int | None = None  # EKF_STATUS_REPORT flags (ArduPilot), if sent
    gps_fix_type: int | None = None  # GPS_RAW_INT fix_type, if sent
    gps_satellites: int | None = None
    params: dict = field(default_factory=dict)  # name -> (value, MAV_PARAM_TYPE) of each PARAM_VALUE


#: Messages that explain why the autopilot is not ready: LinkState field <- message field.
_STATUS_FIELDS = {
    "EXTENDED_SYS_STATE": (("landed_state", "landed_state"),),
    "EKF_STATUS_REPORT": (("ekf_flags", "flags"),),
    "GPS_RAW_INT": (("gps_fix_type", "fix_type"), ("gps_satellites", "satellites_visible")),
}

#: EKF_STATUS_REPORT flags a position estimate needs (ArduPilot's EKF_STATUS_FLAGS).
EKF_POSITION_FLAGS = (("attitude", mavlink2.EKF_ATTITUDE), ("horizontal velocity", mavlink2.EKF_VELOCITY_HORIZ),
                      ("relative position", mavlink2.EKF_POS_HORIZ_REL),
                      ("absolute position", mavlink2.EKF_POS_HORIZ_ABS))


def readiness_text(state: LinkState) -> str:
    """What the autopilot's own messages say of its position estimate, in one short phrase:
    GPS fix and satellites (GPS_RAW_INT), the EKF flags still missing (EKF_STATUS_REPORT), the
    newest STATUSTEXT. Empty when it sent none of them.

    >>> st = LinkState(gps_fix_type=1, gps_satellites=0, ekf_flags=1 | 2)
    >>> st.statustext.append((6, "EKF3 IMU0 initialised"))
    >>> readiness_text(st)
    'GPS NO_FIX (0 sats); EKF lacks relative position, absolute position; autopilot: EKF3 IMU0 initialised'
    """
    parts = []
    if state.gps_fix_type is not None:
        entry = mavlink2.enums["GPS_FIX_TYPE"].get(state.gps_fix_type)
        fix = entry.name.removeprefix("GPS_FIX_TYPE_") if entry is not None else str(state.gps_fix_type)
        parts.append(f"GPS {fix} ({state.gps_satellites or 0} sats)")
    if state.ekf_flags is not None:
        missing = [name for name, flag in EKF_POSITION_FLAGS if not state.ekf_flags & flag]
        parts.append(f"EKF lacks {', '.join(missing)}" if missing else "EKF position ok")
    if state.statustext:
        parts.append(f"autopilot: {state.statustext[-1][1]}")
    return "; ".join(parts)


class MemoryRecorder:
    """Stands in for a :class:`TlogWriter` until the flight's tlog is created (nothing on disk).

    Keeps up to ``max_records`` packets with their UNIX times; older ones are dropped (counted).
    """

    def __init__(self, max_records: int = 100_000):
        self.records: list[tuple[float, bytes]] = []
        self.max_records = int(max_records)
        self.dropped = 0

    def write(self, packet: bytes, unix_time_s: float | None = None) -> None:
        if len(self.records) >= self.max_records:
            self.records.pop(0)
            self.dropped += 1
        self.records.append((time.time() if unix_time_s is None else unix_time_s, bytes(packet)))

    def flush(self) -> None:
        pass


def connect_autopilot(connect: str, *, heartbeat_timeout_s: float,
                      progress: Callable[[str], None] | None = None, **link_kw) -> "MavLink":
    """Open ``connect`` and pair with an autopilot, creating no file.

    The flight's order (so that a failed connection leaves no empty tlog and no mission copy):
    check the tlog path (:meth:`TlogWriter.check_writable`), ``link = connect_autopilot(...)``,
    open the tlog, write the mission beside it, ``link.attach_tlog(tlog)``. Until then the
    packets of both directions are kept in memory (:class:`MemoryRecorder`), so the tlog still
    starts with the first heartbeat. ``progress`` gets the waiting status line (see
    :meth:`MavLink.wait_heartbeat`); ``link_kw`` are :class:`MavLink`'s keywords. On failure the
    link is closed and the LinkError raised, with the link's counters in its ``counters``.
    """
    link_kw.pop("tlog", None)
    link = MavLink(connect, tlog=MemoryRecorder(), **link_kw)
    try:
        link.wait_heartbeat(heartbeat_timeout_s, progress=progress)
        link.send_heartbeat()
    except LinkError as err:
        link.close()
        err.counters = link.counters()  # what came in meanwhile (a wrong signing key: bad_signature)
        raise
    except BaseException:
        link.close()
        raise
    return link


# Ctrl-C (KeyboardInterrupt) and SIGTERM (the runner's _Terminate) raise in the main thread between
# any two bytecodes, whichever thread the signal reached (a library's native thread as well). While a
# packet is sent and recorded the sending thread blocks them, and the runner's handlers
# (:func:`hold_interrupts_during_sends`) wait, so that the two cannot be split: a setpoint the
# autopilot flew is always in the tlog.
INTERRUPT_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})
CAN_HOLD_SIGNALS = hasattr(signal, "pthread_sigmask")  # POSIX


class _SendHold:
    """While the main thread is inside (sending and recording a packet), the wrapped handlers
    wait; the first signal that came meanwhile is handled on leaving. Handlers run in the main
    thread only, so another thread's sends do not hold them."""

    def __init__(self) -> None:
        self.depth = 0
        self.pending: tuple[Callable, int, FrameType | None] | None = None  # the first signal held

    def wrap(self, handler: Callable[[int, FrameType | None], object]) -> Callable[[int, FrameType | None], None]:
        def wait_for_the_send(signum: int, frame: FrameType | None) -> None:
            if self.depth:
                self.pending = self.pending or (handler, signum, frame)
            else:
                handler(signum, frame)

        return wait_for_the_send

    def __enter__(self) -> None:
        if threading.current_thread() is threading.main_thread():
            self.depth += 1

    def __exit__(self, *exc: object) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        self.depth -= 1
        if not self.depth and self.pending is not None:
            (handler, signum, frame), self.pending = self.pending, None
            handler(signum, frame)


_SENDS = _SendHold()


def hold_interrupts_during_sends(on_sigterm: Callable[[int, FrameType | None], object]) -> dict:
    """Install ``on_sigterm`` for SIGTERM and keep SIGINT's handler, both waiting for any send in
    progress; returns the previous handlers (for :func:`restore_handlers`). Main thread only
    (``ValueError`` elsewhere, as :func:`signal.signal`)."""
    old = {signal.SIGTERM: signal.signal(signal.SIGTERM, _SENDS.wrap(on_sigterm))}
    on_sigint = signal.getsignal(signal.SIGINT)
    if callable(on_sigint):  # not when started with Ctrl-C ignored (SIG_IGN)
        old[signal.SIGINT] = signal.signal(signal.SIGINT, _SENDS.wrap(on_sigint))
    return old


def restore_handlers(old: dict) -> None:
    for signum, handler in old.items():
        signal.signal(signum, handler)


class _TlogTap:
    """The ``file`` given to pymavlink's MAVLink object: every packet sent is also recorded."""

    def __init__(self, link: "MavLink"):
        self.link = link

    def write(self, buf) -> None:
        # A signal another thread took: the runner's handlers wait until the hold is left. A signal
        # sent to this thread, whatever its handler: blocked until the mask is lifted. Either way
        # the interrupt is raised after the record.
        with _SENDS:
            try:
                if CAN_HOLD_SIGNALS:
                    signal.pthread_sigmask(signal.SIG_BLOCK, INTERRUPT_SIGNALS)
                if not self.link._transport.send(bytes(buf)):
                    return
                if self.link.tlog is not None:
                    self.link.tlog.write(bytes(buf))
                self.link.sent += 1
            finally:
                if CAN_HOLD_SIGNALS:
                    signal.pthread_sigmask(signal.SIG_UNBLOCK, INTERRUPT_SIGNALS)


# Over 300 lines on purpose: the one pymavlink adapter (as mavutil's connection is one object):
# parsing, pairing, validation, commands and setpoints share the connection, the parser and the
# signing state. The transports and the vehicle state types already live outside it.
class MavLink:
    """A MAVLink connection to one autopilot, with pairing, filtering, signing and a tlog.

    Parameters
    ----------
    connect : connection string (see module docstring).
    source_system, source_component : the companion's own ids (component 191 by default).
    signing_key : 32-byte MAVLink 2 key, or None.
    tlog : an opened :class:`TlogWriter`, a :class:`MemoryRecorder` (see :meth:`attach_tlog`),
        or None.
    target_system : pair only with this system id (None = the first autopilot heard).
    autopilot : ``"auto"``, ``"px4"`` or ``"ardupilot"`` (required flavour, checked on pairing).
    repin_after_s : silence of the pinned UDP peer after which a heartbeat of the same
        system/component from a new address is accepted (autopilot restart).
    clock : monotonic clock (injectable for tests).
    """

    def __init__(
        self,
        connect: str,
        *,
        source_system: int = 1,
        source_component: int = MAV_COMP_ID_ONBOARD_COMPUTER,
        signing_key: bytes | None = None,
        tlog: TlogWriter | None = None,
        target_system: int | None = None,
        autopilot: str = "auto",
        repin_after_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ):
        if autopilot not in ("auto", "px4", "ardupilot"):
            raise LinkError(f"--autopilot: expected auto, px4 or ardupilot, got {autopilot!r}")
        for name, value in (("source_system", source_system), ("source_component", source_component)):
            if not (1 <= int(value) <= 255):
                raise LinkError(f"{name}: expected 1..255, got {value}")
        self.connect = connect
        self.tlog = tlog
        self.clock = clock
        self.target_system = target_system
        self.autopilot_wanted = autopilot
        self.repin_after_s = float(repin_after_s)
        self._transport = open_transport(connect)
        self._mav = mavlink2.MAVLink(_TlogTap(self), srcSystem=int(source_system),
                                     srcComponent=int(source_component))
        self._mav.robust_parsing = True
        # A second encoder for records written to the tlog only (its own sequence numbers, so the
        # autopilot never sees a gap in the companion's stream).
        self._recorder = mavlink2.MAVLink(None, srcSystem=int(source_system),
                                          srcComponent=int(source_component))
        self.signing = signing_key is not None
        if signing_key is not None:
            if len(signing_key) != 32:
                raise LinkError(f"signing key: expected 32 bytes, got {len(signing_key)}")
            self._mav.signing.secret_key = bytes(signing_key)
            self._mav.signing.sign_outgoing = True
            self._mav.signing.allow_unsigned_callback = None
            self._mav.signing.link_id = 0
            self._mav.signing.timestamp = signing_timestamp_now()
            # pymavlink records a stream's timestamp before checking the signature, so one forged
            # packet with a future timestamp would lock out the real autopilot; check it first.
            self._mav.check_signature = self._check_signature
        self.info: AutopilotInfo | None = None
        self.state = LinkState()
        self.rejected = {reason: 0 for reason in REJECT_REASONS}
        self.ignored = 0  # messages whose id the dialect does not know (not an error)
        self.received = 0
        self.sent = 0
        self.stranger_addresses: set = set()
        self.restarts = 0
        self._restarts_at_position = 0  # self.restarts when the position held was accepted
        self._peer_last_s = math.nan
        self._last_own_heartbeat_s = -math.inf
        self._event_id = 0  # the id of the last chunked STATUSTEXT event recorded
        self.on_message: Callable | None = None  # optional hook(msg) for accepted messages

    # ---------------------------------------------------------------- receiving

    def fileno(self) -> int:
        return self._transport.fileno()

    def poll(self, timeout_s: float = 0.0) -> int:
        """Wait up to ``timeout_s`` for data, then handle everything available. Returns #accepted."""
        try:
            ready, _, _ = select.select([self._transport.fileno()], [], [], max(0.0, timeout_s))
        except (OSError, ValueError):
            return 0
        if not ready:
            return 0
        accepted = 0
        for data, addr in self._transport.recv():
            accepted += self._handle_bytes(data, addr)
        return accepted

    def _reset_parser(self) -> None:
        self._mav.buf = bytearray()
        self._mav.buf_index = 0
        self._mav.expected_length = mavlink2.HEADER_LEN_V1 + 2

    def _handle_bytes(self, data: bytes, addr) -> int:
        if self._transport.datagrams:
            self._reset_parser()
        try:
            msgs = self._mav.parse_buffer(data) or []
        except Exception:  # noqa: BLE001 - the parser must never take the loop down
            self.rejected["bad_data"] += 1
            self._reset_parser()
            return 0
        if self._transport.datagrams and self._mav.buf_len() > 0:
            self.rejected["bad_data"] += 1  # truncated frame at the end of a datagram
            self._reset_parser()
        accepted = 0
        for msg in msgs:
            try:
                accepted += self._handle_message(msg, addr)
            except LinkError:
                raise
            except Exception:  # noqa: BLE001 - a malformed field value must not stop the loop
                self.rejected["bad_data"] += 1
        return accepted

    def _classify_bad(self, msg) -> str:
        reason = str(getattr(msg, "reason", ""))
        if "CRC" in reason:
            return "bad_crc"
        if "signature" in reason:
            buf = bytes(msg.get_msgbuf())
            signed = len(buf) > 2 and buf[0] == 0xFD and (buf[2] & 0x01)
            return "bad_signature" if signed else "unsigned"
        return "bad_data"

    def _handle_message(self, msg, addr) -> int:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.rejected[self._classify_bad(msg)] += 1
            return 0
        if mtype.startswith("UNKNOWN"):
            self.ignored += 1
            return 0
        now = self.clock()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.info is None:
            if mtype == "HEARTBEAT" and self._is_autopilot_heartbeat(msg):
                if self.target_system is None or src[0] == self.target_system:
                    self._pair(msg, addr)
                else:
                    self.rejected["wrong_system"] += 1
                    return 0
            else:
                return 0
        paired = (self.info.system_id, self.info.component_id)
        if src != paired:
            self.rejected["wrong_system"] += 1
            return 0
        if self._transport.datagrams and addr != self._transport.peer:
            silent = not (now - self._peer_last_s < self.repin_after_s)
            if mtype == "HEARTBEAT" and silent and self._transport.listen and self._is_autopilot_heartbeat(msg):
                self._transport.peer = addr  # the same autopilot came back on a new address
            else:
                self.rejected["wrong_address"] += 1
                self.stranger_addresses.add(addr)
                return 0
        if not self._accept_fields(msg, mtype, now):
            return 0
        self._peer_last_s = now
        self.received += 1
        self.state.last_message_s = now
        if self.tlog is not None:
            self.tlog.write(bytes(msg.get_msgbuf()))
        if self.on_message is not None:
            self.on_message(msg)
        return 1

    @staticmethod
    def _is_autopilot_heartbeat(msg) -> bool:
        return msg.autopilot in (MAV_AUTOPILOT_PX4, MAV_AUTOPILOT_ARDUPILOTMEGA) and msg.type not in (
            mavlink2.MAV_TYPE_GCS, MAV_TYPE_ONBOARD_CONTROLLER, mavlink2.MAV_TYPE_GIMBAL)

    def _pair(self, msg, addr) -> None:
        flavour = "px4" if msg.autopilot == MAV_AUTOPILOT_PX4 else "ardupilot"
        if self.autopilot_wanted != "auto" and flavour != self.autopilot_wanted:
            raise LinkError(
                f"{self.connect}: autopilot is {flavour} (system {msg.get_srcSystem()}), "
                f"expected {self.autopilot_wanted} (--autopilot)"
            )
        if msg.type in COPTER_TYPES:
            vehicle = "copter"
        elif msg.type in PLANE_TYPES:
            vehicle = "plane"
        elif msg.type in ROVER_TYPES:
            vehicle = "rover"
        else:
            vehicle = "copter"
        self.info = AutopilotInfo(msg.get_srcSystem(), msg.get_srcComponent(), flavour, vehicle, msg.type)
        if self._transport.datagrams and self._transport.listen:
            self._transport.peer = addr

    def _accept_fields(self, msg, mtype: str, now: float) -> bool:
        st = self.state
        if mtype == "LOCAL_POSITION_NED":
            problem = position_problem(msg.time_boot_ms, msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz)
            if problem:
                self.rejected[problem] += 1
                return False
            prev = st.position
            if prev is not None and msg.time_boot_ms <= prev.time_boot_ms and not self._position_restart(
                    prev, msg.time_boot_ms, now):
                # Not newer than the sample held (a reordered, duplicated or replayed datagram):
                # using it would steer on old data that looks fresh.
                self.rejected["old_sample"] += 1
                return False
            self._restarts_at_position = self.restarts
            st.position = PositionSample(msg.time_boot_ms, msg.x, msg.y, msg.z, msg.vx, msg.vy,
                                         msg.vz, received_s=now)
            st.positions += 1
            self._advance_time(msg.time_boot_ms)
        elif mtype == "ATTITUDE":
            problem = yaw_problem(msg.roll, msg.pitch, msg.yaw)
            if problem:
                self.rejected[problem] += 1
                return False
            st.yaw_ned_rad = float(msg.yaw)
            self._advance_time(msg.time_boot_ms)
        elif mtype == "HEARTBEAT":
            st.custom_mode = int(msg.custom_mode)
            st.base_mode = int(msg.base_mode)
            st.armed = bool(msg.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
            st.last_heartbeat_s = now
            st.heartbeats += 1
        elif mtype == "STATUSTEXT":
            text = msg.text.decode("utf-8", "replace") if isinstance(msg.text, bytes) else str(msg.text)
            st.statustext.append((int(msg.severity), text.rstrip("\x00")))
            del st.statustext[:-50]
            st.statustext_count += 1
        elif mtype == "COMMAND_ACK":
            st.acks[int(msg.command)] = (int(msg.result), now)
        elif mtype in _STATUS_FIELDS:
            for attr, wire in _STATUS_FIELDS[mtype]:
                setattr(st, attr, int(getattr(msg, wire)))
        elif mtype == "PARAM_VALUE":
            name = msg.param_id.decode("ascii", "replace") if isinstance(msg.param_id, bytes) else str(msg.param_id)
            st.params[name.rstrip("\x00")] = (float(msg.param_value), int(msg.param_type))
        elif mtype == "GPS_GLOBAL_ORIGIN":
            origin = global_origin_from_wire(msg.latitude, msg.longitude, msg.altitude, now)
            if origin is None:
                self.rejected["out_of_range"] += 1
                return False
            st.global_origin = origin
        elif hasattr(msg, "time_boot_ms"):
            tb = msg.time_boot_ms
            if isinstance(tb, int) and tb >= 0:
                self._advance_time(tb)
        return True

    def _position_restart(self, prev: PositionSample, time_boot_ms: int, now: float) -> bool:
        """Whether a position older than the one held may start a new series (autopilot reboot).

        Silence alone is not enough: a stall of either process (a loaded machine) looks like
        silence to the receiver, and a replayed old datagram read first after it would pass.
        A reboot must also be evidenced: after at least ``repin_after_s`` without positions,
        either another message already showed the autopilot's clock restarting
        (:meth:`_advance_time`), or the new clock is younger than the silence itself (the
        autopilot booted during the gap; a replay from before the gap is older than that).
        """
        silence_s = now - prev.received_s
        if not silence_s >= self.repin_after_s:
            return False
        if self.restarts > self._restarts_at_position:
            return True
        return time_boot_ms / 1000.0 <= silence_s

    def _advance_time(self, time_boot_ms: int) -> None:
        t = time_boot_ms / 1000.0
        if not (t <= self.state.autopilot_time_s):  # also when still NaN
            self.state.autopilot_time_s = t
        elif t < self.state.autopilot_time_s - RESTART_JUMP_S:
            self.state.autopilot_time_s = t  # the autopilot rebooted: its clock starts again
            self.restarts += 1

    def _check_signature(self, msgbuf, src_system: int, src_component: int) -> bool:
        """MAVLink 2 signature check: signature first, then a strictly increasing timestamp."""
        signing = self._mav.signing
        h = hashlib.sha256()
        h.update(signing.secret_key)
        h.update(bytes(msgbuf[:-6]))
        if h.digest()[:6] != bytes(msgbuf[-6:]):
            return False
        tlow, thigh = struct.unpack("<IH", bytes(msgbuf[-12:-6]))
        timestamp = tlow + (thigh << 32)
        key = (msgbuf[-13], src_system, src_component)
        last = signing.stream_timestamps.get(key)
        if last is not None and timestamp <= last:
            return False  # replayed or reordered
        if last is None and timestamp + 6_000_000 < signing.timestamp:
            return False  # a new stream more than a minute in the past
        signing.stream_timestamps[key] = timestamp
        signing.timestamp = max(signing.timestamp, timestamp)
        return True

    # ---------------------------------------------------------------- pairing, heartbeat

    def send_heartbeat(self) -> None:
        self._mav.heartbeat_send(MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID, 0, 0, 4)  # ACTIVE
        self._last_own_heartbeat_s = self.clock()

    def heartbeat_if_due(self, period_s: float = 1.0) -> None:
        if self.clock() - self._last_own_heartbeat_s >= period_s:
            self.send_heartbeat()

    def wait_heartbeat(self, timeout_s: float, progress: Callable[[str], None] | None = None,
                       progress_every_s: float = 1.0) -> AutopilotInfo:
        """Send our heartbeat and wait for an autopilot's; raise LinkError after ``timeout_s``.

        ``progress(text)``, if given, is called at the start and then every ``progress_every_s``
        with one status line: what is awaited, on which link, and the seconds elapsed, e.g.
        ``waiting for a HEARTBEAT from an autopilot on udp:0.0.0.0:14540 (listening on
        0.0.0.0:14540): 3 s of 15 s``.
        """
        t0 = self.clock()
        deadline = t0 + timeout_s
        who = f"system {self.target_system}" if self.target_system else "an autopilot"
        how = getattr(self._transport, "description", "")
        next_progress = t0
        while self.info is None:
            self.heartbeat_if_due()
            now = self.clock()
            remaining = deadline - now
            if remaining <= 0:
                raise LinkError(
                    f"{self.connect}: no HEARTBEAT from {who} within {timeout_s:g} s "
                    "(is the autopilot running and the connection string right?)"
                )
            if progress is not None and now >= next_progress:
                progress(f"waiting for a HEARTBEAT from {who} on {self.connect}"
                         f"{f' ({how})' if how else ''}: {now - t0:.0f} s of {timeout_s:g} s")
                next_progress += progress_every_s
            self.poll(min(0.1, remaining))
        return self.info

    def attach_tlog(self, tlog: TlogWriter) -> None:
        """Record into ``tlog`` from now on, starting with what was kept in memory before it.

        A link opened by :func:`connect_autopilot` keeps every packet sent and received (with its
        time) until the flight's tlog exists; they are written first, in order, with their times.
        """
        early = self.tlog
        self.tlog = tlog
        if isinstance(early, MemoryRecorder):
            for unix_time_s, packet in early.records:
                tlog.write(packet, unix_time_s=unix_time_s)

    def link_age_s(self) -> float:
        """Seconds since the paired autopilot's last heartbeat."""
        return self.clock() - self.state.last_heartbeat_s

    # ---------------------------------------------------------------- commands

    def _target(self) -> tuple[int, int]:
        if self.info is None:
            raise LinkError(f"{self.connect}: not paired with an autopilot yet")
        return self.info.system_id, self.info.component_id

    def command_long(self, command: int, params=(0, 0, 0, 0, 0, 0, 0), *, wait_ack_s: float = 1.0,
                     retries: int = 3, idle: Callable[[], None] | None = None) -> int | None:
        """Send COMMAND_LONG and wait for its COMMAND_ACK; returns the MAV_RESULT or None."""
        ts, tc = self._target()
        p = list(params) + [0.0] * (7 - len(params))
        for attempt in range(max(1, retries)):
            self.state.acks.pop(int(command), None)
            self._mav.command_long_send(ts, tc, int(command), attempt, *[float(x) for x in p])
            deadline = self.clock() + wait_ack_s
            while self.clock() < deadline:
                self.poll(0.02)
                if idle is not None:
                    idle()
                ack = self.state.acks.get(int(command))
                if ack is not None and ack[0] != MAV_RESULT_IN_PROGRESS:  # keep waiting
                    return ack[0]
        return None

    def request_message_interval(self, msg_id: int, rate_hz: float, **kw) -> int | None:
        """MAV_CMD_SET_MESSAGE_INTERVAL for ``msg_id`` at ``rate_hz``; returns the MAV_RESULT."""
        return self.command_long(MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, 1.0e6 / rate_hz), **kw)

    def request_global_origin(self, timeout_s: float, *, resend_s: float = 1.0,
                              idle: Callable[[], None] | None = None) -> GlobalOrigin | None:
        """Ask for GPS_GLOBAL_ORIGIN (MAV_CMD_REQUEST_MESSAGE 49) until one arrives or ``timeout_s``.

        PX4 sends GPS_GLOBAL_ORIGIN once when its estimator sets the origin and on request; ArduPilot
        sends it when the EKF origin is set and on request, but answers a request with nothing (its
        ACK still ACCEPTED) while the EKF has no origin. So the request is repeated every
        ``resend_s`` and only the message itself counts, never the ACK. An origin already held
        (sent unsolicited since pairing) is returned at once. Returns None after ``timeout_s``.
        """
        if self.state.global_origin is not None:
            return self.state.global_origin
        ts, tc = self._target()
        deadline = self.clock() + timeout_s
        next_send = self.clock()
        attempt = 0
        while self.state.global_origin is None:
            now = self.clock()
            if now >= deadline:
                return None
            if now >= next_send:
                self._mav.command_long_send(ts, tc, MAV_CMD_REQUEST_MESSAGE, attempt,
                                            float(MSG_ID_GPS_GLOBAL_ORIGIN), 0, 0, 0, 0, 0, 0)
                attempt = min(attempt + 1, 255)
                next_send = now + resend_s
            self.poll(min(0.02, max(0.0, deadline - now)))
            if idle is not None:
                idle()
        return self.state.global_origin

    def read_params(self, names: tuple[str, ...], timeout_s: float, *, resend_s: float = 0.5,
                    idle: Callable[[], None] | None = None) -> dict[str, float]:
        """Ask for each named parameter (PARAM_REQUEST_READ by name) until all have answered or
        ``timeout_s``; returns the finite REAL32 values received (an absent name is not in it).

        A request is repeated every ``resend_s`` for the names still missing (a datagram may be
        lost). Only float parameters are read: an integer one would need the autopilot's encoding.
        """
        ts, tc = self._target()
        deadline = self.clock() + timeout_s
        next_send = self.clock()
        for name in names:
            self.state.params.pop(name, None)
        while True:
            missing = [n for n in names if n not in self.state.params]
            now = self.clock()
            if not missing or now >= deadline:
                break
            if now >= next_send:
                for name in missing:
                    self._mav.param_request_read_send(ts, tc, name.encode("ascii"), -1)
                next_send = now + resend_s
            self.poll(min(0.02, max(0.0, deadline - now)))
            if idle is not None:
                idle()
        return {n: v for n, (v, t) in self.state.params.items()
                if n in names and t == MAV_PARAM_TYPE_REAL32 and math.isfinite(v)}

    def mode_number(self, name: str) -> tuple[int, int, int]:
        """(base_mode flags, custom main mode, sub mode) of a mode name for this autopilot."""
        info = self.info
        if info is None:
            raise LinkError("not paired")
        if info.autopilot == "px4":
            if name == "guided":
                name = "offboard"
            main, sub = PX4_MODES[name]
            return MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub
        table = ARDUPILOT_MODES[info.vehicle]
        if name == "offboard":
            name = "guided"
        if name not in table:
            raise LinkError(f"mode {name!r} is not available on an ArduPilot {info.vehicle}")
        return MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, table[name], 0

    def custom_mode_value(self, name: str) -> int:
        """The HEARTBEAT custom_mode the autopilot reports in mode ``name``."""
        _, main, sub = self.mode_number(name)
        if self.info.autopilot == "px4":
            return (main << 16) | (sub << 24)
        return main

    def in_mode(self, name: str) -> bool:
        cm = self.state.custom_mode
        if cm is None:
            return False
        if self.info.autopilot == "px4":
            _, main, sub = self.mode_number(name)
            if sub == 0:
                return ((cm >> 16) & 0xFF) == main
            return cm == ((main << 16) | (sub << 24))
        return cm == self.custom_mode_value(name)

    def mode_text(self) -> str:
        """The autopilot's current mode in its own words (``OFFBOARD``, ``GUIDED``; ``""``: unknown)."""
        from companion.io.logread import mode_name

        if self.info is None or self.state.custom_mode is None:
            return ""
        code = MAV_AUTOPILOT_PX4 if self.info.autopilot == "px4" else MAV_AUTOPILOT_ARDUPILOTMEGA
        return mode_name(code, self.info.mav_type, self.state.base_mode, self.state.custom_mode)

    def set_custom_mode(self, custom_mode: int, **kw) -> int | None:
        """DO_SET_MODE back to a mode as the HEARTBEAT reported it (restoring the mode found)."""
        if self.info is not None and self.info.autopilot == "px4":
            main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
        else:
            main, sub = custom_mode, 0
        return self.command_long(MAV_CMD_DO_SET_MODE, (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub), **kw)

    def in_mode_value(self, custom_mode: int) -> bool:
        """Whether the HEARTBEAT reports exactly this ``custom_mode``."""
        return self.state.custom_mode == custom_mode

    def set_mode(self, name: str, **kw) -> int | None:
        base, main, sub = self.mode_number(name)
        return self.command_long(MAV_CMD_DO_SET_MODE, (base, main, sub), **kw)

    def arm(self, **kw) -> int | None:
        return self.command_long(MAV_CMD_COMPONENT_ARM_DISARM, (1,), **kw)

    def takeoff(self, altitude_m: float, **kw) -> int | None:
        return self.command_long(MAV_CMD_NAV_TAKEOFF, (0, 0, 0, math.nan, math.nan, math.nan, altitude_m), **kw)

    def change_speed(self, speed_m_s: float, **kw) -> int | None:
        """Ground speed for a fixed-wing flight: DO_CHANGE_SPEED (PX4), GUIDED_CHANGE_SPEED (ArduPilot)."""
        if self.info is not None and self.info.autopilot == "ardupilot":
            return self.command_long(MAV_CMD_GUIDED_CHANGE_SPEED, (1, speed_m_s, 0), **kw)
        return self.command_long(MAV_CMD_DO_CHANGE_SPEED, (1, speed_m_s, -1), **kw)

    def change_altitude(self, altitude_m: float, rate_m_s: float = 0.0, **kw) -> int | None:
        """ArduPlane's GUIDED_CHANGE_ALTITUDE: the height (m above home) to hold in GUIDED, reached
        at ``rate_m_s`` (0: the autopilot's own)."""
        return self.command_long(MAV_CMD_GUIDED_CHANGE_ALTITUDE, (0, 0, rate_m_s, 0, 0, 0, altitude_m), **kw)

    # ---------------------------------------------------------------- setpoints and records

    def time_boot_ms(self) -> int:
        t = self.state.autopilot_time_s
        return int(t * 1000) & 0xFFFFFFFF if math.isfinite(t) else 0

    def send_setpoint(self, sp: VelocitySetpoint | AttitudeSetpoint) -> None:
        ts, tc = self._target()
        if isinstance(sp, VelocitySetpoint):
            self._mav.set_position_target_local_ned_send(
                self.time_boot_ms(), ts, tc, sp.coordinate_frame, sp.type_mask,
                0.0, 0.0, 0.0, sp.vx_ned_m_s, sp.vy_ned_m_s, sp.vz_ned_m_s,
                sp.afx_ned_m_s2, sp.afy_ned_m_s2, 0.0, 0.0, sp.yaw_rate_ned_rad_s)
        else:
            self._mav.set_attitude_target_send(
                self.time_boot_ms(), ts, tc, sp.type_mask, list(sp.q), 0.0, 0.0, 0.0, sp.thrust)

    def send_position_hold(self, x_ned_m: float, y_ned_m: float, z_ned_m: float) -> None:
        """Position-only target (ArduCopter GUIDED hover at a point: all three position bits used)."""
        ts, tc = self._target()
        mask = (IGNORE_VX | IGNORE_VY | IGNORE_VZ | IGNORE_AX | IGNORE_AY | IGNORE_AZ | IGNORE_YAW
                | IGNORE_YAW_RATE)
        self._mav.set_position_target_local_ned_send(
            self.time_boot_ms(), ts, tc, MAV_FRAME_LOCAL_NED, mask, x_ned_m, y_ned_m, z_ned_m,
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def record_debug(self, name: str, array_id: int, time_usec: int, data) -> None:
        """Write one DEBUG_FLOAT_ARRAY to the tlog only (never sent to the vehicle)."""
        if self.tlog is None:
            return
        values = [float(x) for x in data][:58]
        values += [math.nan] * (58 - len(values))
        msg = self._recorder.debug_float_array_encode(int(time_usec), name.encode()[:10],
                                                      int(array_id) % 65536, values)
        self.tlog.write(bytes(msg.pack(self._recorder)))
        self._recorder.seq = (self._recorder.seq + 1) % 256

    def record_event(self, text: str, severity: int = MAV_SEVERITY_INFO) -> None:
        """Write one of the companion's own events to the tlog as STATUSTEXT (never sent).

        From the companion's system and component, so ``companion log summary`` can list the
        companion's decisions (holds, overrides, arming refusals, failsafes) beside the
        autopilot's. A text longer than a STATUSTEXT's 50 characters is split into chunks with
        one nonzero ``id`` and ``chunk_seq`` 0, 1, ... (MAVLink 2); a chunk shorter than 50
        characters (an empty one if need be) ends it.
        """
        if self.tlog is None:
            return
        data = text.encode("utf-8")
        chunks = [data[i:i + STATUSTEXT_CHARS] for i in range(0, len(data), STATUSTEXT_CHARS)] or [b""]
        event_id = 0
        if len(chunks) > 1:
            if len(chunks[-1]) == STATUSTEXT_CHARS:
                chunks.append(b"")
            self._event_id = self._event_id % 65535 + 1
            event_id = self._event_id
        for seq, chunk in enumerate(chunks[:256]):
            msg = self._recorder.statustext_encode(int(severity), chunk, event_id, seq)
            self.tlog.write(bytes(msg.pack(self._recorder)))
            self._recorder.seq = (self._recorder.seq + 1) % 256

    def counters(self) -> dict:
        return {"received": self.received, "sent": self.sent, "autopilot_restarts": self.restarts,
                "rejected": dict(self.rejected), "rejected_total": sum(self.rejected.values()),
                "ignored_unknown_id": self.ignored}

    def close(self) -> None:
        if self.tlog is not None:
            self.tlog.flush()
        self._transport.close()
