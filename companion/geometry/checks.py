"""Checks of the numbers in a parameter record, shared by the records of every maths layer.

>>> from dataclasses import dataclass
>>> @dataclass
... class Lag:
...     tau_s: float
>>> require_positive_finite(Lag(0.5), ("tau_s",))
>>> require_positive_finite(Lag(0.0), ("tau_s",))
Traceback (most recent call last):
...
ValueError: tau_s: expected a finite number > 0, got 0.0
"""

from __future__ import annotations

import math
from typing import Iterable


def require_positive_finite(record: object, names: Iterable[str]) -> None:
    """Raise ``ValueError`` naming the first field of ``names`` that is not a finite number > 0."""
    for name in names:
        value = getattr(record, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
