"""Datagram fuzzer: a reproducible stream of bad, damaged and hostile MAVLink datagrams.

Kinds (each datagram is one of them, drawn with fixed weights from a seeded generator):

``random``       random bytes, 1-300 long (sometimes starting with a MAVLink magic byte);
``bad_crc``      a valid frame with one CRC byte changed;
``truncated``    a valid frame cut short;
``wrong_length`` a valid frame whose payload-length byte says something else;
``unknown_id``   a MAVLink 2 frame with a message id outside the dialect (correct CRC framing);
``bad_flags``    a MAVLink 2 frame with an unknown incompatibility flag;
``v1_valid``     a MAVLink 1 frame of a known message from a foreign system;
``hostile``      a valid, correctly framed message from the paired system whose fields are NaN,
                 infinite or out of range (target-specific: positions and attitudes for the
                 companion; setpoints and commands for the autopilot).

The fuzzer never sends a valid, plausible message from the paired system: that is
indistinguishable from the real thing without signing (see ``test_signing_end_to_end.py``).
"""

from __future__ import annotations

import math
import random
from collections import Counter

from mavframes import Encoder

INF = math.inf
NAN = math.nan

# COMMAND_LONG (command, params) with values no real sender would use: arm/disarm with NaN, inf
# or 0.5, a mode of NaN or 1e30, the position stream's interval NaN/inf, a message id of NaN.
# Not NAV_TAKEOFF or DO_CHANGE_SPEED (there NaN means "default" or "unchanged": the command is
# legitimate, e.g. PX4 switches to AUTO.TAKEOFF even in the air) and no negative interval (any
# negative interval disables a stream, as on PX4): valid commands are not fuzz.
HOSTILE_COMMANDS = [
    (400, (NAN,)), (400, (INF, 21196.0)), (400, (0.5,)),
    (176, (NAN, NAN, NAN)), (176, (1.0, INF, 0.0)), (176, (1.0, 1e30, 0.0)),
    (511, (32.0, NAN)), (511, (32.0, INF)), (511, (NAN, 20000.0)),
    (512, (NAN,)), (512, (INF,)),
]

KIND_WEIGHTS = {
    "random": 20, "bad_crc": 15, "truncated": 12, "wrong_length": 10, "unknown_id": 8, "bad_flags": 5,
    "v1_valid": 10, "hostile": 20,
}


class Fuzzer:
    """Generates datagrams for one target (``"companion"`` or ``"autopilot"``)."""

    def __init__(self, target: str, seed: int):
        if target not in ("companion", "autopilot"):
            raise ValueError(target)
        self.target = target
        self.rng = random.Random(seed)
        # The paired system as seen by the target: the autopilot (1, 1) for the companion, the
        # companion (1, 191) for the autopilot.
        self.own = Encoder(1, 1) if target == "companion" else Encoder(1, 191)
        self.foreign = Encoder(77, 1)
        self.v1 = Encoder(78, 1, v1=True)
        self.kinds = list(KIND_WEIGHTS)
        self.weights = [KIND_WEIGHTS[k] for k in self.kinds]
        self.counts: Counter = Counter()

    # -------------------------------------------------------------- valid frames to damage
    def _valid(self) -> bytes:
        r = self.rng
        enc = self.own if r.random() < 0.5 else self.foreign
        choice = r.randrange(4)
        if choice == 0:
            return enc.heartbeat()
        if choice == 1:
            return enc.local_position(r.randrange(1, 1 << 31), r.uniform(-50, 50), r.uniform(-50, 50))
        if choice == 2:
            return enc.attitude(r.randrange(1, 1 << 31), yaw=r.uniform(-3, 3))
        return enc.position_target(vx=r.uniform(-5, 5), vy=r.uniform(-5, 5))

    def _bad_number(self) -> float:
        return self.rng.choice([NAN, INF, -INF, 1e30, -1e30, 3.4e38])

    def _hostile(self) -> bytes:
        r = self.rng
        bad = self._bad_number
        if self.target == "companion":
            choice = r.randrange(3)
            if choice == 0:  # position with a bad field somewhere
                fields = [r.uniform(-20, 20) for _ in range(6)]
                fields[r.randrange(6)] = bad()
                return self.own.local_position(r.randrange(1, 1 << 31), *fields)
            if choice == 1:  # far beyond any local frame, finite
                return self.own.local_position(r.randrange(1, 1 << 31), x=r.choice([2e5, -5e6, 1e9]))
            return self.own.attitude(r.randrange(1, 1 << 31), roll=r.uniform(-1, 1),
                                     yaw=r.choice([NAN, INF, 50.0, -1e6]))
        choice = r.randrange(4)
        if choice == 3:  # a command with non-finite or out-of-range parameters
            command, params = r.choice(HOSTILE_COMMANDS)
            return self.own.command_long(command, params)
        if choice == 0:  # velocity setpoint with a non-finite used field
            v = [r.uniform(-5, 5) for _ in range(4)]
            v[r.randrange(4)] = r.choice([NAN, INF, -INF])
            return self.own.position_target(vx=v[0], vy=v[1], vz=v[2], yaw_rate=v[3])
        if choice == 1:  # an unsupported coordinate frame
            return self.own.position_target(vx=1.0, frame=r.choice([0, 3, 200, 255]))
        # an attitude target with a non-finite quaternion (copter: ignored; plane: bad_value)
        q = [NAN, 0.0, 0.0, 0.0]
        return self.own.pack(self.own.mod.MAVLink_set_attitude_target_message(
            0, 1, 1, 0, q, 0.0, 0.0, 0.0, 0.5))

    # -------------------------------------------------------------- one datagram
    def datagram(self) -> tuple[str, bytes]:
        r = self.rng
        kind = r.choices(self.kinds, self.weights)[0]
        self.counts[kind] += 1
        if kind == "random":
            n = r.randrange(1, 300)
            data = bytearray(r.getrandbits(8) for _ in range(n))
            if r.random() < 0.5:
                data[0] = r.choice([0xFD, 0xFE])
            return kind, bytes(data)
        if kind == "hostile":
            return kind, self._hostile()
        if kind == "v1_valid":
            return kind, self.v1.local_position(r.randrange(1, 1 << 31), r.uniform(-5, 5))
        frame = bytearray(self._valid())
        if kind == "bad_crc":
            end = len(frame) - 1 - r.randrange(2)
            frame[end] ^= r.randrange(1, 256)
        elif kind == "truncated":
            frame = frame[: r.randrange(1, len(frame))]
        elif kind == "wrong_length":
            frame[1] = (frame[1] + r.randrange(1, 255)) % 256
        elif kind == "unknown_id":
            msgid = r.choice([0x00FFFF, 0x123456, 0xFFFFFF, 60000, 0xABCDE])
            frame[7], frame[8], frame[9] = msgid & 0xFF, (msgid >> 8) & 0xFF, msgid >> 16
        elif kind == "bad_flags":
            frame[2] = r.choice([0x02, 0x04, 0x80, 0xFE])
        return kind, bytes(frame)
