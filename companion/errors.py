"""Domain errors. The CLI maps each to a one-line message and an exit code (no traceback)."""

from __future__ import annotations


class CompanionError(Exception):
    """Base class: a failure the user can act on. ``str(err)`` is the one-line message."""

    exit_code = 2


class MissionError(CompanionError):
    """A mission file is unusable. Carries every problem found, one per line."""

    def __init__(self, problems: list[str] | str):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


class LinkError(CompanionError):
    """The MAVLink link failed (no heartbeat, timeout, refused connection, bad link string).

    ``counters`` holds the link's packet counts (received, rejected by reason, ...) when the link
    had opened before it failed (a failed pairing), else None.
    """

    counters: dict | None = None


class LogError(CompanionError):
    """A flight log (tlog) cannot be used."""


class FlightAborted(CompanionError):
    """A flight stopped early for a reason the user must see (pilot override, failsafe)."""

    exit_code = 1


class FlightUnhealthy(FlightAborted):
    """A flight-health failsafe stopped the flight (no progress, runaway): see docs/failsafes.md."""

    exit_code = 3
