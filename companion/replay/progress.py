"""A progress bar over the bytes of a log (or the ticks of a replay), shown only when it helps.

The bar goes to stderr, only when stderr is a terminal, and only once reading has taken more
than a second (tqdm's ``delay``), so short logs and redirected output stay clean. tqdm is an
optional dependency (``pip install companion[progress]``); without it there is no bar.
"""

from __future__ import annotations

import sys

SHOW_AFTER_S = 1.0


class ByteProgress:
    """Context manager: ``update_to(done)`` as the work advances through ``total`` units."""

    def __init__(self, total: int, description: str, enabled: bool | None = None, unit: str = "B"):
        if enabled is None:
            enabled = sys.stderr.isatty()
        self._bar = None
        self._done = 0
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:  # optional dependency
                tqdm = None
            if tqdm is not None:
                self._bar = tqdm(total=total, desc=description, unit=unit, unit_scale=True,
                                 file=sys.stderr, delay=SHOW_AFTER_S, leave=False)

    def update_to(self, offset: int) -> None:
        if self._bar is not None and offset > self._done:
            self._bar.update(offset - self._done)
            self._done = offset

    def __enter__(self) -> "ByteProgress":
        return self

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.close()
