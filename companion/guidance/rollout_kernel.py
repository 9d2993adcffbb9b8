"""The predictive law's batched rollouts as compiled loops (numba), when numba is installed.

:meth:`companion.guidance.predictive.PredictiveGuidance.rollout` flies a few dozen candidate rows
through 25 steps of the pursuit and the vehicle model. In numpy each step is some ninety calls on
arrays of a few dozen numbers, and the interpreter's cost per call is most of a re-optimisation's
2-5 ms. :mod:`companion.guidance._rollout_numba` runs the same arithmetic as scalar loops
compiled by numba, so the results agree with the numpy rollouts to rounding (the transcendental
functions may differ in the last bit), which the tests check
(``tests/guidance/test_rollout_kernel.py``). The tick's own pursuit command is compiled too: in
numpy it is the same ninety calls for one vehicle, and in a flight loop that sleeps between
ticks each call starts cold (0.23 ms a tick measured at 50 Hz, 0.05 ms back to back).

Optional: ``pip install 'companion[fast]'``. :func:`load` imports numba on the first
``predictive`` law a process builds (never for the other laws: numba and its LLVM take about
100 MB of memory), compiles the loops or loads them from numba's cache beside the module (a few
seconds once per machine, a fraction of a second after that), before the flight's first tick.
Without numba it returns None and the law flies its numpy rollouts (as it does with
``PredictiveGuidance.compiled = False``).

Pure arithmetic on arrays, SI units, ENU: no I/O, no clocks.
"""

from __future__ import annotations

import importlib.util
from typing import Callable, NamedTuple

import numpy as np

#: True when numba is installed (checked without importing it).
AVAILABLE = importlib.util.find_spec("numba") is not None


class Kernel(NamedTuple):
    """The compiled loops: ``rollout`` (the rows of a re-optimisation), ``pursuit`` (one tick's
    pursuit command; :func:`companion.guidance.predictive.pursuit_command` for one vehicle) and
    ``project`` (one point's nearest sample and cross-track error)."""

    rollout: Callable[..., np.ndarray]
    pursuit: Callable[..., tuple[float, float, float, float, float]]
    project: Callable[..., tuple[int, float]]


_loaded: list[Kernel | None] = []  # empty until load() has run once


def load() -> Kernel | None:
    """The compiled loops (compiled, or read from the cache, and run once on a tiny problem on
    the first call), or None without numba (or with one that cannot be imported)."""
    if not _loaded:
        try:
            from companion.guidance._rollout_numba import _project, _pursuit, _rollout
        except ImportError:
            _loaded.append(None)
        else:
            s, z = np.arange(5.0), np.zeros(5)
            _rollout(s, z, np.ones(5), z, z, 1.0, 0.5, 0.5, 0.0, 0.0, np.array([3.0]), np.zeros((2, 1)), 5.0, 0.0,
                     0.0, 0.5, 0.2, 1.0, 0.3, 5.0, 2, 3, 5, False, np.zeros(2), 0.4, 0.1, 0.1,
                     np.zeros((3, 3)))
            _pursuit(s, z, np.ones(5), z, z, 1.0, 0.5, 0.5, 0.0, 5.0, 3.0, 1.0, 0.3, 2, 3, 5, False)
            _project(s, z, np.ones(5), z, z, 1.0, 0.5, 0.5, 2, 3, 5, False)
            _loaded.append(Kernel(_rollout, _pursuit, _project))
    return _loaded[0]
