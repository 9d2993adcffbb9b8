"""Measured figures of the reliability tests, appended to ``out/reliability/figures.jsonl``.

``docs/reliability.md`` quotes these; rerun ``.venv/bin/python -m pytest tests/reliability -q``
to reproduce them (each run appends one line per measuring test, with the test's name).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

OUT = Path(__file__).resolve().parents[2] / "out" / "reliability" / "figures.jsonl"


def _clean(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    return obj


def record(test: str, **values) -> None:
    """Append one line ``{"test": ..., "utc": ..., **values}``."""
    OUT.parent.mkdir(parents=True, exist_ok=True)
    line = {"test": test, "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), **values}
    with OUT.open("a", encoding="utf-8") as f:
        f.write(json.dumps(_clean(line)) + "\n")
