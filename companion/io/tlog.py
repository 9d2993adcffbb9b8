"""tlog writer: both directions of a MAVLink session, standard framing, nothing lost on exit.

Each record is an 8-byte big-endian microsecond UNIX timestamp followed by one raw MAVLink packet,
the format ``pymavlink.mavutil.mavlink_connection("x.tlog")`` and ``mavlogdump.py`` read.

Robustness rules:

* the path is checked at start (:meth:`TlogWriter.open`): the directory is created, the file
  opened for writing and the free space checked, so an unwritable path or a full disk is reported
  before flight, not in it (``LogError``);
* every record is written straight to the OS with :meth:`flush` after each tick and on
  :meth:`close`, which the runner calls from ``finally`` (exit, Ctrl-C, SIGTERM, link timeout,
  exceptions): the file is complete up to the last message;
* a write error in flight (disk filled meanwhile) is remembered and reported in the summary; it
  never stops the loop that is commanding a vehicle.
"""

from __future__ import annotations

import datetime as _dt
import os
import shutil
import struct
import time
from pathlib import Path

from companion.errors import LogError

#: Refuse to start with less free space than this on the log's file system.
MIN_FREE_BYTES = 20 * 1024 * 1024


def default_tlog_path(directory: str | os.PathLike = "logs", now: _dt.datetime | None = None) -> Path:
    """``logs/flight-YYYYmmdd-HHMMSS.tlog`` (UTC)."""
    now = now or _dt.datetime.now(_dt.timezone.utc)
    return Path(directory) / f"flight-{now.strftime('%Y%m%d-%H%M%S')}.tlog"


#: The mission a flight used is written beside its tlog as ``<tlog>.mission.yaml``.
MISSION_SUFFIX = ".mission.yaml"


def mission_path_beside(tlog_path: str | os.PathLike) -> Path:
    """``<tlog>.mission.yaml``: where a flight's mission is written, and where replay looks first."""
    return Path(str(tlog_path) + MISSION_SUFFIX)


def write_mission_beside(tlog_path: str | os.PathLike, source_text: str) -> Path:
    """Write the mission's text beside the tlog (:func:`mission_path_beside`)."""
    out = mission_path_beside(tlog_path)
    out.write_text(source_text, encoding="utf-8")
    return out


class TlogWriter:
    """Append timestamped MAVLink packets to a tlog file."""

    def __init__(self, path: str | os.PathLike, min_free_bytes: int = MIN_FREE_BYTES):
        self.path = Path(path)
        self.min_free_bytes = int(min_free_bytes)
        self._file = None
        self.records = 0
        self.write_error: str | None = None

    def open(self) -> "TlogWriter":
        """Create the file; raise LogError if it cannot be written or the disk is (nearly) full."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "wb", buffering=64 * 1024)
        except OSError as err:
            raise LogError(f"{self.path}: cannot write the flight log ({err.strerror or err})") from err
        try:
            free = shutil.disk_usage(self.path.parent).free
        except OSError:
            free = None
        if free is not None and free < self.min_free_bytes:
            self._file.close()
            self._file = None
            raise LogError(
                f"{self.path}: only {free // 1024} KiB free on the log's disk, "
                f"expected at least {self.min_free_bytes // (1024 * 1024)} MiB"
            )
        return self

    def check_writable(self) -> "TlogWriter":
        """What :meth:`open` checks, creating nothing: the nearest existing directory of the path
        is writable (or the file itself, if it exists) and has ``min_free_bytes`` free.

        Lets a flight refuse an unusable log path before it connects, and open the log only once
        the autopilot has answered (a failed connection then leaves no empty file).
        """
        target = self.path.parent if str(self.path.parent) else Path(".")
        existing = target
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if self.path.exists():
            ok = self.path.is_file() and os.access(self.path, os.W_OK)
        else:
            ok = existing.is_dir() and os.access(existing, os.W_OK | os.X_OK)
        if not ok:
            why = "not a directory" if existing.exists() and not existing.is_dir() else "permission denied"
            raise LogError(f"{self.path}: cannot write the flight log ({why}: {existing})")
        try:
            free = shutil.disk_usage(existing).free
        except OSError:
            free = None
        if free is not None and free < self.min_free_bytes:
            raise LogError(
                f"{self.path}: only {free // 1024} KiB free on the log's disk, "
                f"expected at least {self.min_free_bytes // (1024 * 1024)} MiB"
            )
        return self

    @property
    def is_open(self) -> bool:
        return self._file is not None

    def write(self, packet: bytes, unix_time_s: float | None = None) -> None:
        """Record one raw MAVLink packet (bytes as on the wire)."""
        if self._file is None:
            return
        usec = int((time.time() if unix_time_s is None else unix_time_s) * 1.0e6)
        try:
            self._file.write(struct.pack(">Q", usec) + bytes(packet))
            self.records += 1
        except OSError as err:
            self._note_write_error(err)

    def flush(self) -> None:
        if self._file is None:
            return
        try:
            self._file.flush()
        except OSError as err:
            self._note_write_error(err)

    def _note_write_error(self, err: OSError) -> None:
        """Keep the first failure for the summary; recording goes on (nothing is raised mid-flight)."""
        if self.write_error is None:
            self.write_error = f"{self.path}: write failed ({err.strerror or err})"

    def close(self) -> None:
        if self._file is None:
            return
        self.flush()
        try:
            os.fsync(self._file.fileno())
        except OSError:
            pass
        try:
            self._file.close()
        except OSError:
            pass
        self._file = None

    def __enter__(self) -> "TlogWriter":
        return self.open() if self._file is None else self

    def __exit__(self, *exc) -> None:
        self.close()
