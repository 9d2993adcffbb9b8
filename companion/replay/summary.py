"""``companion log summary``: what is in a tlog, at a glance.

The summary answers the first questions about any flight log, whoever wrote it (the companion,
MAVProxy, QGroundControl): how long it is, who was talking (system/component ids with the
vehicle type and autopilot their HEARTBEAT declares), which messages each sent and how often,
which flight modes the autopilot went through and when, and where the traffic of a sender stopped
for longer than :data:`GAP_THRESHOLD_S`.

Conventions
-----------
- Times (``time_s``, ``start_s``) are seconds since the first record of the log;
  ``start_unix_s`` gives the absolute time of that first record.
- A message's ``rate_hz`` is ``(count - 1) / (last - first)`` over the span in which that sender
  sent that message (so a 50 Hz stream that ran for half the log still reads 50 Hz); when that
  span is shorter than :data:`MIN_RATE_SPAN_S` (a burst of parameters, a single command) it is
  ``count / duration`` of the whole log instead.
- Modes come from heartbeats of flight controllers (``autopilot`` other than
  MAV_AUTOPILOT_INVALID); an entry is recorded whenever the mode or the armed state changes.
- ``statustext``: every STATUSTEXT (the autopilot's messages and the companion's own events,
  which it records from its component), long texts reassembled from their MAVLink 2 chunks.
- A link gap is an interval longer than :data:`GAP_THRESHOLD_S` between two consecutive records
  from one sender. Senders whose median interval is itself longer than the threshold (a ground
  station sending only a 1 Hz heartbeat) are marked ``sparse`` and not searched for gaps.
"""

from __future__ import annotations

import datetime as _dt
from collections import defaultdict
from pathlib import Path
from typing import Callable

import numpy as np

from companion.errors import LogError
from companion.io.logread import (
    MAV_AUTOPILOT_INVALID,
    MAV_MODE_FLAG_SAFETY_ARMED,
    MSG_ID,
    LogWarning,
    TlogReader,
    enum_name,
    mode_name_from_heartbeat,
)
from companion.replay.progress import ByteProgress

GAP_THRESHOLD_S = 0.5
MIN_RATE_SPAN_S = 1.0
PROGRESS_EVERY_RECORDS = 4096


def summarise_log(
    path: str | Path,
    gap_threshold_s: float = GAP_THRESHOLD_S,
    on_warning: Callable[[LogWarning], None] | None = None,
    progress: bool | None = None,
) -> dict:
    """Summarise a tlog. Raises :class:`LogError` when no MAVLink record can be read.

    Parameters
    ----------
    path : the tlog.
    gap_threshold_s : shortest interval reported as a link gap.
    on_warning : called with each unreadable stretch of the file as it is found.
    progress : show a progress bar (None: only on a terminal, only after a second).

    Returns
    -------
    dict with ``file``, ``size_bytes``, ``records``, ``bytes_skipped``, ``warnings``,
    ``start_unix_s``, ``duration_s``, ``mavlink_versions``, ``systems``, ``messages``,
    ``modes``, ``statustext``, ``gap_threshold_s``, ``link_gaps`` (see the module docstring
    for their meaning).
    """
    heartbeat_id = MSG_ID["HEARTBEAT"]
    statustext_id = MSG_ID["STATUSTEXT"]
    reader = TlogReader(path, decode_ids={heartbeat_id, statustext_id}, on_warning=on_warning)
    texts: list[dict] = []
    open_chunks: dict[tuple[int, int, int], dict] = {}
    times_by_source: dict[tuple[int, int], list[float]] = defaultdict(list)
    span_by_message: dict[tuple[int, int, str], list] = {}
    identity: dict[tuple[int, int], tuple[int, int]] = {}
    versions = {1: 0, 2: 0}
    modes: list[dict] = []
    last_mode: dict[tuple[int, int], tuple[str, bool]] = {}
    first_time = None
    last_time = None

    with ByteProgress(reader.size_bytes, "summary", enabled=progress) as bar:
        for rec in reader:
            if reader.records % PROGRESS_EVERY_RECORDS == 0:
                bar.update_to(rec.offset)
            if first_time is None:
                first_time = rec.time_s
            last_time = rec.time_s
            source = (rec.src_system, rec.src_component)
            times_by_source[source].append(rec.time_s)
            versions[rec.mavlink_version] += 1
            key = (rec.src_system, rec.src_component, rec.msg_type)
            span = span_by_message.get(key)
            if span is None:
                span_by_message[key] = [1, rec.time_s, rec.time_s]
            else:
                span[0] += 1
                span[2] = rec.time_s
            if rec.msg_id == statustext_id and rec.msg is not None:
                _collect_statustext(rec, source, first_time, texts, open_chunks)
            if rec.msg_id == heartbeat_id and rec.msg is not None:
                identity[source] = (rec.msg.type, rec.msg.autopilot)
                _note_mode(rec, source, rec.time_s - first_time, last_mode, modes)

    if first_time is None:
        raise LogError(f"{path}: no MAVLink records could be read ({reader.size_bytes} bytes)")

    systems, link_gaps = _systems_and_gaps(times_by_source, identity, first_time, gap_threshold_s)
    messages = _message_rates(span_by_message, last_time - first_time)
    return {
        "file": str(path),
        "size_bytes": reader.size_bytes,
        "records": reader.records,
        "bytes_skipped": reader.bytes_skipped,
        "warnings": [w.as_dict() for w in reader.warnings],
        "start_unix_s": float(first_time),
        "duration_s": float(last_time - first_time),
        "mavlink_versions": {str(k): v for k, v in versions.items()},
        "systems": systems,
        "messages": messages,
        "modes": modes,
        "statustext": texts + list(open_chunks.values()),
        "gap_threshold_s": float(gap_threshold_s),
        "link_gaps": link_gaps,
    }


def _note_mode(rec, source: tuple[int, int], time_s: float, last_mode: dict, modes: list[dict]) -> None:
    """Append to ``modes`` when an autopilot's heartbeat shows a new mode or armed state."""
    hb = rec.msg
    if hb.autopilot == MAV_AUTOPILOT_INVALID:
        return
    state = (mode_name_from_heartbeat(hb), bool(hb.base_mode & MAV_MODE_FLAG_SAFETY_ARMED))
    if last_mode.get(source) != state:
        last_mode[source] = state
        modes.append({"time_s": time_s, "system": source[0], "component": source[1],
                      "mode": state[0], "armed": state[1]})


def _collect_statustext(rec, source, first_time, texts: list, open_chunks: dict) -> None:
    """One STATUSTEXT record: a whole text (``id`` 0), or a chunk of a long one (MAVLink 2
    ``id``/``chunk_seq``; a chunk shorter than 50 characters ends it)."""
    msg = rec.msg
    text = msg.text.decode("utf-8", "replace") if isinstance(msg.text, bytes) else str(msg.text)
    text = text.split("\x00", 1)[0]
    event_id = int(getattr(msg, "id", 0) or 0)
    entry = {"time_s": rec.time_s - first_time, "system": source[0], "component": source[1],
             "severity": enum_name("MAV_SEVERITY", msg.severity), "text": text}
    if event_id == 0:
        texts.append(entry)
        return
    key = (source[0], source[1], event_id)
    held = open_chunks.get(key)
    if held is None:
        open_chunks[key] = held = entry
    else:
        held["text"] += text
    if len(text.encode("utf-8")) < 50:
        texts.append(open_chunks.pop(key))


def format_summary(summary: dict, max_gaps_per_source: int = 5) -> str:
    """The human-readable text of a :func:`summarise_log` result."""
    start = _dt.datetime.fromtimestamp(summary["start_unix_s"], tz=_dt.timezone.utc)
    lines = [
        f"{summary['file']}: {summary['size_bytes']} bytes, {summary['records']} records"
        + (f", {summary['bytes_skipped']} bytes unreadable in {len(summary['warnings'])} places"
           if summary["warnings"] else ""),
        f"start {start.isoformat(timespec='seconds')}, duration {summary['duration_s']:.2f} s, "
        f"MAVLink 2: {summary['mavlink_versions']['2']} records, MAVLink 1: {summary['mavlink_versions']['1']}",
        "",
        "systems (system/component, heartbeat type and autopilot, records, seen from-to):",
    ]
    for s in summary["systems"]:
        ident = f"{s['type']} {s['autopilot']}" if s["type"] else "(no heartbeat)"
        lines.append(f"  {s['system']:>3}/{s['component']:<3} {ident:<55} {s['messages']:>7}  "
                     f"{s['first_s']:8.2f} - {s['last_s']:8.2f} s")
    lines += ["", "messages (system/component, type, count, rate over its own span):"]
    for m in summary["messages"]:
        lines.append(f"  {m['system']:>3}/{m['component']:<3} {m['type']:<32} {m['count']:>7}  {m['rate_hz']:7.2f} Hz")
    lines += ["", "modes (time since start, system/component, mode, armed):"]
    if not summary["modes"]:
        lines.append("  (no flight-controller heartbeat)")
    for m in summary["modes"]:
        lines.append(f"  {m['time_s']:8.2f} s  {m['system']:>3}/{m['component']:<3} {m['mode']:<16} "
                     f"{'armed' if m['armed'] else 'disarmed'}")
    lines += ["", "status texts (time since start, system/component, severity, text):"]
    if not summary.get("statustext"):
        lines.append("  (none)")
    for s in summary.get("statustext", []):
        severity = str(s["severity"]).removeprefix("MAV_SEVERITY_")
        lines.append(f"  {s['time_s']:8.2f} s  {s['system']:>3}/{s['component']:<3} {severity:<9} {s['text']}")
    threshold_s = summary.get("gap_threshold_s", GAP_THRESHOLD_S)
    lines += ["", f"link gaps longer than {threshold_s:g} s (per sender):"]
    by_source: dict[tuple[int, int], list[dict]] = defaultdict(list)
    for g in summary["link_gaps"]:
        by_source[(g["system"], g["component"])].append(g)
    if not by_source:
        lines.append("  none")
    for (system, component), gaps in sorted(by_source.items()):
        longest = max(g["duration_s"] for g in gaps)
        lines.append(f"  {system:>3}/{component:<3} {len(gaps)} gaps, longest {longest:.2f} s")
        for g in gaps[:max_gaps_per_source]:
            lines.append(f"          at {g['start_s']:8.2f} s for {g['duration_s']:.2f} s")
        if len(gaps) > max_gaps_per_source:
            lines.append(f"          ... {len(gaps) - max_gaps_per_source} more (--json lists all)")
    sparse = [f"{s['system']}/{s['component']}" for s in summary["systems"] if s["sparse"]]
    if sparse:
        lines.append(f"  not searched (sparse senders): {', '.join(sparse)}")
    return "\n".join(lines)


def _systems_and_gaps(times_by_source: dict[tuple[int, int], list[float]],
                      identity: dict[tuple[int, int], tuple[int, int]], first_time: float,
                      gap_threshold_s: float) -> tuple[list[dict], list[dict]]:
    """One entry per source (system, component), and the silences longer than the threshold of
    the sources that are not sparse."""
    systems = []
    link_gaps = []
    for source in sorted(times_by_source):
        times = np.asarray(times_by_source[source])
        intervals = np.diff(times)
        sparse = bool(intervals.size == 0 or np.median(intervals) > gap_threshold_s)
        mav_type, autopilot = identity.get(source, (None, None))
        systems.append({
            "system": source[0],
            "component": source[1],
            "type": None if mav_type is None else enum_name("MAV_TYPE", mav_type),
            "autopilot": None if autopilot is None else enum_name("MAV_AUTOPILOT", autopilot),
            "messages": int(times.size),
            "first_s": float(times[0] - first_time),
            "last_s": float(times[-1] - first_time),
            "sparse": sparse,
        })
        if not sparse:
            for i in np.flatnonzero(intervals > gap_threshold_s):
                link_gaps.append({"system": source[0], "component": source[1],
                                  "start_s": float(times[i] - first_time),
                                  "duration_s": float(intervals[i])})
    return systems, link_gaps


def _message_rates(span_by_message: dict[tuple[int, int, str], list], log_span: float) -> list[dict]:
    """Count and rate of each message type of each source (over its own span when long enough)."""
    messages = []
    for (system, component, name), (count, first, last) in sorted(span_by_message.items()):
        if last - first >= MIN_RATE_SPAN_S:
            rate = (count - 1) / (last - first)
        else:
            rate = count / log_span if log_span > 0 else 0.0
        messages.append({"system": system, "component": component, "type": name,
                         "count": count, "rate_hz": float(rate)})
    return messages
