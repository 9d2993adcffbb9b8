"""Logged flights: summaries of any tlog, and re-running the guidance on the companion's own.

Public API (imported from the modules, which load numpy and the guidance only when used)::

    from companion.replay.summary import summarise_log, format_summary
    from companion.replay.replay import replay_log, Tolerance, ReplayResult
    from companion.replay.synthetic import write_synthetic_flight, replay_throughput

See ``docs/replay.md``.
"""
