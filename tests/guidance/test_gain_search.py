"""The corrector's gain search finds the minimum of its own rollout cost, between grid points too.

The reference is a brute-force scan of the same cost over 801 ratios (a hundredth of a decade
apart): the search's choice must cost within a few percent of the scan's minimum. The coarse grid
alone (half a decade apart) misses it by up to tens of percent where the cost dips sharply
between two grid points, which is where two flights a few centimetres apart chose gains half a
decade apart (docs/guidance.md, "The gains refined between the grid points").
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from companion.guidance.optimiser import GainOptimiser, ratio_from_gains
from companion.guidance.types import GuidanceParams
from companion.mission import load_mission

MISSIONS = Path(__file__).resolve().parents[2] / "missions"


def _states(path, l1_m):
    """Vehicles along the racetrack's second half, a few decimetres either side, on its course."""
    for s in np.arange(150.0, 330.0, 6.0):
        x0, y0 = path.point(s)
        h = path.heading_rad(s)
        for off in (-0.3, 0.0, 0.2):
            x, y = x0 - off * math.sin(h), y0 + off * math.cos(h)
            s_look = path.lookahead(x, y, l1_m, s)
            if s_look is not None:
                yield x, y, h, float(s), s_look


def test_the_search_costs_within_5_percent_of_a_dense_scan_and_the_coarse_grid_does_not():
    path = load_mission(MISSIONS / "racetrack.yaml").path
    params = GuidanceParams()
    opt = GainOptimiser(path, params)
    dense = np.concatenate(([0.0], np.logspace(-1.0, 7.0, 801), [math.inf]))
    coarse = np.concatenate(([0.0], np.logspace(-1.0, 7.0, 17), [math.inf]))
    chosen_excess, coarse_excess = [], []
    for x, y, h, s, s_look in _states(path, params.l1_m):
        window = opt.window_s(s, 5.0)
        scan = opt._rollout_cost(dense, x, y, h, 5.0, s, s_look, window)
        if scan.max() - scan.min() < 1e-9:  # a straight reach: every ratio flies the same
            continue
        k1, k2, _ = opt.optimise(x, y, h, 5.0, s, s_look)
        chosen = opt._rollout_cost(np.array([ratio_from_gains(k1, k2)]), x, y, h, 5.0, s, s_look, window)
        chosen_excess.append(chosen[0] / scan.min() - 1.0)
        coarse_excess.append(opt._rollout_cost(coarse, x, y, h, 5.0, s, s_look, window).min() / scan.min() - 1.0)
    assert len(chosen_excess) > 20
    assert max(coarse_excess) > 0.2  # the premise: the grid alone misses dips between its points
    assert max(chosen_excess) < 0.05
