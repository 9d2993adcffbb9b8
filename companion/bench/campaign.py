"""Running many bench runs as one campaign: in-process, on a process pool, or on Dask.

A campaign is a list of tasks, a picklable function ``run(task) -> row`` (one dict per run) and
a stable id per task. :func:`run_campaign` hands the tasks to an executor, collects the rows as
they finish and returns them in task order, whichever executor ran them:

- :func:`serial_executor`: one after the other, in this process;
- :func:`pool_executor`: a ``multiprocessing`` pool of ``jobs`` processes (the bench's default);
- :func:`dask_executor`: a ``dask.distributed`` client, on a local cluster of ``workers``
  processes (one thread each) or on a running scheduler (``tcp://HOST:8786``). Needs the optional
  extra ``companion[campaign]``.

With a :class:`RowFile` (``--out FILE.jsonl``) every finished row is appended to the file as one
JSON line ``{"task_id": ..., **row}`` and flushed at once, and the rows already in the file are
not run again: a campaign killed at any point resumes from its file with no run lost or repeated.
A last line cut short by the kill is dropped (that run is simply run again); any other unreadable
line stops the campaign with its line number, so nothing recorded is ever overwritten. Rows of
other tasks in the file (an earlier campaign with other settings) are kept and not reported.
"""

from __future__ import annotations

import json
import math
import os
import sys
from typing import Callable, Iterable, Iterator, Sequence

from companion.errors import CompanionError

#: Row values written as null when not finite (JSON has no NaN) and read back as NaN.
NAN_KEYS = ("d_rms_m", "d_max_m", "a_rms_m_s2", "a_max_m_s2", "reach_s", "touch_s")
#: The one line shown when the extra is missing.
INSTALL_HINT = "install companion[campaign]"

Executor = Callable[[Callable[[object], dict], Sequence[object], Sequence[int], Sequence[str]],
                    Iterator[tuple[int, dict]]]


class CampaignError(CompanionError):
    """A campaign cannot start or go on (its file, its scheduler, a missing extra)."""


def finite_json(value):
    """NaN and infinities to None (JSON has neither), recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_json(v) for v in value]
    return value


class RowFile:
    """The JSON-lines file of a campaign: rows already there, and appending new ones.

    ``open()`` takes an exclusive lock (a second campaign on the same file is refused), reads the
    complete lines, cuts a partial last line off and returns ``{task_id: row}``.
    """

    def __init__(self, path: str):
        self.path = str(path)
        self._fh = None

    def open(self) -> dict[str, dict]:
        try:
            fh = open(self.path, "a+b")
        except OSError as err:
            raise CampaignError(f"{self.path}: cannot open the campaign file ({err.strerror})") from None
        try:
            import fcntl

            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # pragma: no cover - not on POSIX: no lock
            pass
        except OSError:
            fh.close()
            raise CampaignError(f"{self.path}: another campaign is writing this file") from None
        fh.seek(0)
        data = fh.read()
        keep = data.rfind(b"\n") + 1  # everything after the last newline is a cut-off write
        if keep < len(data):
            fh.truncate(keep)
        rows: dict[str, dict] = {}
        for number, line in enumerate(data[:keep].splitlines(), 1):
            if not line.strip():
                continue
            try:
                doc = json.loads(line)
            except ValueError:
                doc = None
            if not isinstance(doc, dict) or not isinstance(doc.get("task_id"), str):
                fh.close()
                raise CampaignError(f"{self.path}: line {number}: expected a JSON row with a task_id; "
                                    "not a campaign file (or damaged): use another --out")
            task_id = doc.pop("task_id")
            rows.setdefault(task_id, {k: (math.nan if k in NAN_KEYS and v is None else v) for k, v in doc.items()})
        fh.seek(0, os.SEEK_END)
        self._fh = fh
        return rows

    def write(self, task_id: str, row: dict) -> None:
        line = json.dumps(finite_json({"task_id": task_id, **row}), allow_nan=False) + "\n"
        self._fh.write(line.encode("utf-8"))
        self._fh.flush()

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


# ----------------------------------------------------------------------------- executors
def serial_executor(run, tasks, order, ids) -> Iterator[tuple[int, dict]]:
    for i in order:
        yield i, run(tasks[i])


def pool_executor(jobs: int) -> Executor:
    def execute(run, tasks, order, ids):
        if jobs <= 1 or len(order) < 2:
            yield from serial_executor(run, tasks, order, ids)
            return
        import multiprocessing as mp

        ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
        with ctx.Pool(jobs) as pool:
            yield from pool.imap_unordered(_Indexed(run), [(i, tasks[i]) for i in order])

    return execute


class _Indexed:
    """``(i, task) -> (i, run(task))``, picklable for the pool."""

    def __init__(self, run):
        self.run = run

    def __call__(self, item):
        i, task = item
        return i, self.run(task)


def dask_available() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def dask_executor(workers: int = 2, scheduler: str | None = None, processes: bool = True) -> Executor:
    """Runs every task as one Dask task: on ``scheduler`` if given, else on a local cluster of
    ``workers`` (processes, or threads with ``processes=False``), one thread per worker."""
    if not dask_available():
        raise CampaignError(f"--dask: dask.distributed is not installed; {INSTALL_HINT}")

    def execute(run, tasks, order, ids):
        import logging

        from distributed import Client, LocalCluster, as_completed

        if scheduler:
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError, ValueError) as err:
                raise CampaignError(f"--scheduler {scheduler}: cannot reach the scheduler ({err})") from None
            cluster = None
        else:
            # Logs silenced: a worker's heartbeat racing the cluster's shutdown logs a traceback.
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                                   dashboard_address=":0", scheduler_port=0, silence_logs=logging.CRITICAL)
            client = Client(cluster)
        try:
            futures = {client.submit(run, tasks[i], key=f"bench-run-{ids[i]}", pure=False): i for i in order}
            for future, row in as_completed(futures, with_results=True):
                yield futures[future], row
        finally:
            client.close()
            if cluster is not None:
                cluster.close()

    return execute


# ----------------------------------------------------------------------------- the campaign
def run_campaign(tasks: Sequence[object], run: Callable[[object], dict], ids: Sequence[str], *,
                 executor: Executor = serial_executor, out: RowFile | None = None,
                 order: Iterable[int] | None = None,
                 progress: Callable[[int, int], None] | None = None) -> tuple[list[dict], dict]:
    """Rows of every task, in task order, and counts ``{runs, from_file, ran}``.

    ``order`` is the order of submission (default: task order). With ``out`` the rows found in
    the file are taken from it, the others run and appended as they finish.
    """
    if len(set(ids)) != len(ids):
        raise CampaignError("campaign: two tasks have the same id (the same scenario, model, law and setting twice)")
    rows: list[dict | None] = [None] * len(tasks)
    done: dict[str, dict] = out.open() if out is not None else {}
    try:
        for i, task_id in enumerate(ids):
            if task_id in done:
                rows[i] = done[task_id]
        pending = [i for i in (range(len(tasks)) if order is None else order) if rows[i] is None]
        from_file = len(tasks) - len(pending)
        count = from_file
        if progress:
            progress(count, len(tasks))
        try:
            for i, row in executor(run, tasks, pending, ids) if pending else ():
                if out is not None:
                    out.write(ids[i], row)
                rows[i] = row
                count += 1
                if progress:
                    progress(count, len(tasks))
        except KeyboardInterrupt:
            where = f"; {out.path} holds them: rerun with the same --out to resume" if out is not None else ""
            print(f"companion: campaign interrupted after {count} of {len(tasks)} runs{where}", file=sys.stderr)
            raise
    finally:
        if out is not None:
            out.close()
    missing = [i for i, r in enumerate(rows) if r is None]
    if missing:  # pragma: no cover - every executor yields every pending task or raises
        raise CampaignError(f"campaign: {len(missing)} runs returned no row")
    return rows, {"runs": len(tasks), "from_file": from_file, "ran": len(tasks) - from_file}  # type: ignore[return-value]
