"""UDP links, datagram checking, MAVLink 2 signing and tlog recording for the mock autopilot.

A :class:`Link` is one UDP socket in the pymavlink link-string convention:

``udpout:HOST:PORT``
    The mock sends to HOST:PORT (as PX4 SITL sends to a companion listening on 14540) from an
    ephemeral port, and also answers any address a valid MAVLink frame arrives from.
``udpin:HOST:PORT`` (or ``udp:``)
    The mock listens on HOST:PORT (port 0 picks a free one) and sends to every address a valid
    frame has arrived from, as an autopilot's telemetry port serves ground stations.

Every datagram is split into frames and each frame checked before it is decoded: anything that is
not a well-formed MAVLink 1 or 2 frame with a good CRC of a known message id (and, with a signing
key, a good signature) is dropped and counted by reason in :class:`RxCounters`. Only a frame that
passed every check can add a peer, so garbage never redirects the link.
"""

from __future__ import annotations

import hashlib
import math
import socket
import struct
import time
from collections import Counter
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

MAGIC_V1 = 0xFE
MAGIC_V2 = 0xFD
HEADER_LEN_V1 = 6
HEADER_LEN_V2 = 10
SIGNATURE_LEN = 13
IFLAG_SIGNED = 0x01
# MAVLink signing timestamps count 10 us units since 2015-01-01 00:00:00 UTC.
SIGNING_EPOCH_UNIX_S = 1420070400.0

DROP_REASONS = ("garbage", "truncated", "bad_flags", "unknown_id", "bad_crc", "unsigned", "bad_signature",
                "decode_error", "bad_value", "handler_error")


@dataclass(frozen=True)
class LinkSpec:
    """A parsed link string."""

    kind: str  # "udpin" or "udpout"
    host: str
    port: int

    def __str__(self) -> str:
        return f"{self.kind}:{self.host}:{self.port}"


def parse_link(text: str) -> LinkSpec:
    """Parse ``udpin:HOST:PORT`` / ``udp:HOST:PORT`` / ``udpout:HOST:PORT``.

    Raises
    ------
    ValueError
        With a one-line message naming the link string and what was expected.
    """
    parts = text.split(":")
    if len(parts) != 3 or parts[0] not in ("udpin", "udp", "udpout"):
        raise ValueError(f"--link {text!r}: expected udpin:HOST:PORT or udpout:HOST:PORT")
    kind = "udpout" if parts[0] == "udpout" else "udpin"
    try:
        port = int(parts[2])
    except ValueError:
        raise ValueError(f"--link {text!r}: port {parts[2]!r} is not a number") from None
    if not 0 <= port <= 65535 or (kind == "udpout" and port == 0):
        raise ValueError(f"--link {text!r}: port out of range")
    if not parts[1]:
        raise ValueError(f"--link {text!r}: empty host")
    return LinkSpec(kind, parts[1], port)


def load_signing_key(path: str) -> bytes:
    """Read a MAVLink 2 signing key file.

    The file holds either 64 hexadecimal characters (the 32-byte key) or any other text, a
    passphrase whose SHA-256 digest is the key (the convention of MAVProxy's ``signing setup`` and
    QGroundControl). Surrounding white space is ignored.

    Raises
    ------
    ValueError
        If the file cannot be read or is empty.
    """
    try:
        with open(path, encoding="utf-8") as handle:
            text = handle.read().strip()
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"--signing-key-file {path}: cannot read it ({err})") from None
    if not text:
        raise ValueError(f"--signing-key-file {path}: empty; expected 64 hex characters or a passphrase")
    if len(text) == 64:
        try:
            return bytes.fromhex(text)
        except ValueError:
            pass
    return hashlib.sha256(text.encode("utf-8")).digest()


def signing_timestamp_now() -> int:
    """The current MAVLink signing timestamp (10 us units since 2015-01-01)."""
    return int((time.time() - SIGNING_EPOCH_UNIX_S) * 1e5)


class RxCounters:
    """Received datagrams and frames, and dropped ones by reason."""

    def __init__(self) -> None:
        self.datagrams = 0
        self.frames_ok = 0
        self.dropped: Counter[str] = Counter({reason: 0 for reason in DROP_REASONS})
        self.ignored_not_for_us = 0

    def drop(self, reason: str) -> None:
        self.dropped[reason] += 1

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())

    def summary_fields(self) -> str:
        """``key=value`` pairs for the exit summary."""
        parts = [f"rx_datagrams={self.datagrams}", f"rx_frames_ok={self.frames_ok}",
                 f"rx_dropped={self.dropped_total}"]
        parts += [f"{reason}={self.dropped[reason]}" for reason in DROP_REASONS]
        parts.append(f"not_for_us={self.ignored_not_for_us}")
        return " ".join(parts)


class Tlog:
    """Writes frames in tlog framing: 8-byte big-endian microseconds since the UNIX epoch, then the frame.

    Parameters
    ----------
    path : str
        File to create (truncated if it exists). Opening happens here, so an unwritable path is
        reported at start, not in flight.
    """

    def __init__(self, path: str) -> None:
        try:
            self._file = open(path, "wb")  # noqa: SIM115 - closed by close()
        except OSError as err:
            raise ValueError(f"--tlog {path}: cannot create it ({err.strerror})") from None
        self.path = path
        self.records = 0

    def write(self, frame: bytes, t_unix_s: float) -> None:
        self._file.write(struct.pack(">Q", int(t_unix_s * 1e6)) + bytes(frame))
        self.records += 1

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        if not self._file.closed:
            self._file.flush()
            self._file.close()


def split_frames(data: bytes):
    """Split a datagram into MAVLink frames.

    Yields ``(None, frame)`` for each candidate frame and ``(reason, chunk)`` for bytes that cannot
    be one: ``"garbage"`` for a stretch not starting with a MAVLink magic byte, ``"truncated"`` for
    a frame cut short by the end of the datagram.
    """
    i = 0
    n = len(data)
    while i < n:
        magic = data[i]
        if magic != MAGIC_V2 and magic != MAGIC_V1:
            j = i + 1
            while j < n and data[j] != MAGIC_V2 and data[j] != MAGIC_V1:
                j += 1
            yield "garbage", data[i:j]
            i = j
            continue
        header_len = HEADER_LEN_V2 if magic == MAGIC_V2 else HEADER_LEN_V1
        if n - i < 3:
            yield "truncated", data[i:]
            return
        total = header_len + data[i + 1] + 2
        if magic == MAGIC_V2 and data[i + 2] & IFLAG_SIGNED:
            total += SIGNATURE_LEN
        if n - i < total:
            yield "truncated", data[i:]
            return
        yield None, data[i:i + total]
        i += total


class Link:
    """One UDP link of the mock: socket, peers, its own MAVLink sequence and signing state.

    Parameters
    ----------
    spec : LinkSpec
        Parsed link string.
    index : int
        Link number; it is also the signing link id.
    sysid, compid : int
        Identity the mock sends with.
    signing_key : bytes or None
        32-byte MAVLink 2 signing key: outgoing frames are signed, unsigned or badly signed
        incoming frames are dropped.
    counters : RxCounters
        Shared drop counters.
    tlog : Tlog or None
        Where sent and accepted frames are recorded.
    clock_unix_s : callable
        Returns the timestamp to record in the tlog.
    """

    def __init__(self, spec: LinkSpec, index: int, sysid: int, compid: int, signing_key: bytes | None,
                 counters: RxCounters, tlog: Tlog | None, clock_unix_s) -> None:
        self.spec = spec
        self.index = index
        self.counters = counters
        self.tlog = tlog
        self._clock_unix_s = clock_unix_s
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        try:
            if spec.kind == "udpin":
                self.sock.bind((spec.host, spec.port))
                self.peers: dict[tuple, None] = {}
            else:
                self.sock.bind(("0.0.0.0", 0))
                self.peers = {(socket.gethostbyname(spec.host), spec.port): None}
        except OSError as err:
            self.sock.close()
            raise ValueError(f"--link {spec}: cannot open it ({err.strerror})") from None
        self.sock.setblocking(False)
        self.bound_port = self.sock.getsockname()[1]
        self.mav = mavlink.MAVLink(self, srcSystem=sysid, srcComponent=compid)
        self.signing_key = signing_key
        if signing_key is not None:
            self.mav.signing.secret_key = signing_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = index & 0xFF
            self.mav.signing.timestamp = signing_timestamp_now()
        self.tx_messages = 0
        self.tx_errors = 0
        # Telemetry streams of this link: message id -> interval (s of simulated time), next due time.
        self.stream_interval_s: dict[int, float] = {}
        self.stream_next_s: dict[int, float] = {}

    def describe(self) -> str:
        return f"{self.spec.kind}:{self.spec.host}:{self.bound_port}"

    # pymavlink calls write() with each packed frame.
    def write(self, buf: bytes) -> None:
        if not self.peers:
            return  # a udpin link with no ground station yet: nothing is sent, nothing recorded
        for peer in list(self.peers):
            try:
                self.sock.sendto(buf, peer)
            except OSError:
                # Nobody listening yet (ICMP port unreachable) or a full buffer: UDP drops it.
                self.tx_errors += 1
        self.tx_messages += 1
        if self.tlog is not None:
            self.tlog.write(buf, self._clock_unix_s())

    def send(self, msg) -> None:
        """Pack and send a message to every peer of this link (signed if a key is set)."""
        if self.signing_key is not None and self.tx_messages % 256 == 0:
            self.mav.signing.timestamp = max(self.mav.signing.timestamp, signing_timestamp_now())
        self.mav.send(msg)

    def receive(self, max_datagrams: int = 512) -> list:
        """Read waiting datagrams; return the messages that passed every check."""
        out = []
        for _ in range(max_datagrams):
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                continue  # e.g. ICMP errors reported on a UDP socket
            self.counters.datagrams += 1
            accepted = False
            for reason, chunk in split_frames(data):
                if reason is not None:
                    self.counters.drop(reason)
                    continue
                msg = self._check_and_decode(chunk)
                if msg is not None:
                    accepted = True
                    out.append(msg)
                    if self.tlog is not None:
                        self.tlog.write(chunk, self._clock_unix_s())
            if accepted and addr not in self.peers:
                self.peers[addr] = None
        return out

    def _check_and_decode(self, frame: bytes):
        counters = self.counters
        if frame[0] == MAGIC_V2:
            header_len = HEADER_LEN_V2
            incompat = frame[2]
            signed = bool(incompat & IFLAG_SIGNED)
            if incompat & ~IFLAG_SIGNED:
                counters.drop("bad_flags")
                return None
            msgid = frame[7] | (frame[8] << 8) | (frame[9] << 16)
        else:
            header_len = HEADER_LEN_V1
            signed = False
            msgid = frame[5]
        msgtype = mavlink.mavlink_map.get(msgid)
        if msgtype is None:
            counters.drop("unknown_id")
            return None
        payload_end = header_len + frame[1]
        crc = mavlink.x25crc(frame[1:payload_end])
        crc.accumulate(struct.pack("B", msgtype.crc_extra))
        if crc.crc != frame[payload_end] | (frame[payload_end + 1] << 8):
            counters.drop("bad_crc")
            return None
        if self.signing_key is not None and not signed:
            counters.drop("unsigned")
            return None
        try:
            msg = self.mav.decode(bytearray(frame))
        except mavlink.MAVError as err:
            counters.drop("bad_signature" if "signature" in str(err) else "decode_error")
            return None
        except Exception:  # noqa: BLE001 - a malformed payload must never stop the autopilot
            counters.drop("decode_error")
            return None
        counters.frames_ok += 1
        return msg

    def close(self) -> None:
        self.sock.close()


def finite_or_none(value: float) -> float | None:
    """The value if it is a finite number, else None (MAVLink lets senders put NaN in unused fields)."""
    return value if isinstance(value, (int, float)) and math.isfinite(value) else None
