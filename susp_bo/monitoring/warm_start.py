"""Warm start across campaigns: the previous posterior of a vehicle as the centre of the design.

The tracks of two campaigns differ (new measurements), so the previous
campaign's simulations cannot be reused as evaluations of the new likelihood,
and its surrogate models a different log L. What carries over is *where the
parameters are*: a suspension changes slowly between campaigns, so the new
posterior lies near the old one. The warm-start design therefore puts most of a
small initial design (``size`` points) into a box around the previous posterior
(median ± ``widen`` × its 95 % half-width, at least ``min_width`` of C_w wide,
clipped to C_w) and keeps a few points spread over all of C_w, so that a part
that changed more than expected is still found by EGO. The prior stays uniform
on C_w: only the design moves, so the posterior is that of a cold start once the
surrogate is accurate; what is saved is the design spent on empty regions.
"""

from __future__ import annotations

import numpy as np

from susp_bo.calibration.design import check_bounds, space_filling_design


def warm_start_design(
    previous: np.ndarray,
    bounds: np.ndarray,
    size: int,
    seed: int,
    *,
    widen: float = 3.0,
    min_width: float = 0.1,
    global_points: int = 3,
) -> np.ndarray:
    """An initial design centred on a previous posterior.

    Args:
        previous: (n x q) posterior draws of the previous campaign (physical units).
        bounds: (2 x q) admissible set C_w.
        size: design points (>= global_points + 2); 10 for q = 2 measured best in
            ``benchmarks/monitoring_warm_start.py`` (6 was too few to fit the surrogate).
        seed: design seed.
        widen: half-width of the local box in units of the previous 95 % half-width.
        min_width: smallest local box width, as a fraction of each C_w range.
        global_points: points spread over all of C_w.

    Returns:
        (size x q) design inside C_w: ``size - global_points`` local points, then the
        global ones.
    """
    b = check_bounds(bounds)
    draws = np.asarray(previous, dtype=np.float64)
    if draws.ndim != 2 or draws.shape[1] != b.shape[1] or draws.shape[0] < 2:
        raise ValueError(f"previous: shape {draws.shape}; expected (n x {b.shape[1]}) draws")
    if size < global_points + 2:
        raise ValueError(f"size: {size}; expected >= global_points + 2 = {global_points + 2}")
    lo, median, hi = np.quantile(draws, [0.025, 0.5, 0.975], axis=0)
    half = np.maximum(widen * (hi - lo) / 2.0, min_width * (b[1] - b[0]) / 2.0)
    box = np.vstack([np.maximum(median - half, b[0]), np.minimum(median + half, b[1])])
    local = space_filling_design(size - global_points, box, seed)
    if global_points == 0:
        return local
    spread = space_filling_design(global_points, b, seed + 1)
    return np.vstack([local, spread])
