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

:func:`plan_warm_start` is what ``susp-bo monitor`` does for the next campaign of a
vehicle: it reads the previous campaign's results folder and, only when that
calibration was *trusted* (an untrusted posterior is no evidence of where the
parameters are) and calibrated the same parameters, returns a :class:`WarmStart`:
the previous posterior median first, then :func:`warm_start_design` (the cold
design's size at most). With the local phase on (``[search] local``) the study goes
from that design straight to the local phase (``run_study(local_after_design=True)``):
the global EGO batches are what a warm design makes redundant, and the design only
seeds the surrogate near the previous posterior: 3 q points, 1 of them over all of
C_w. Without the local phase the surrogate alone must find the new optimum: 5 q
points, 3 over C_w. Measured (q = 2, paired B, ``benchmarks/monitoring_warm_start.py``):
18 evaluations against 54 for the default cold start, 0.33 of its simulator runs;
with 4 or 5 points some seeds needed 28–29. The reliability verdict of the new campaign
is computed exactly as for a cold start, so a part that changed far more than
expected shows up as ``not_converged``, ``below_expected_fit`` or
``surrogate_misfit``, never as a
confident answer near the old value.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.calibration.design import check_bounds, space_filling_design
from susp_bo.monitoring.alarms import trust

RESULT_FILE = "result.json"
SAMPLES_FILE = "posterior_samples.npy"


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
        size: design points (>= global_points + 2); :func:`warm_design_shape` gives
            the sizes measured best in ``benchmarks/monitoring_warm_start.py``.
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


def warm_design_shape(q: int, cold_design_size: int, *, local_phase: bool) -> tuple[int, int]:
    """(points, of which over all of C_w) of a warm design for q parameters.

    With the local phase 3 q points, 1 over C_w; without it 5 q, 3 over C_w; never more
    than the cold design. The second number is negative when the design is too small to
    hold the median and a local box (then there is no warm start).
    """
    size = min((3 if local_phase else 5) * q, int(cold_design_size))
    return size, min(1 if local_phase else 3, size - 3)


@dataclass(frozen=True)
class WarmStart:
    """The initial design of a campaign started from the previous one.

    Attributes:
        source: campaign id (``<vehicle>/<date>``) whose posterior centres the design.
        design: (n0 x q) design in physical units: the previous median, the local points,
            then the global ones.
        global_points: how many of the last rows span all of C_w.
    """

    source: str
    design: np.ndarray
    global_points: int

    def to_dict(self) -> dict[str, Any]:
        """The ``warm_start`` block of ``result.json`` and ``monitor.json``."""
        return {
            "from_campaign": self.source,
            "design_points": int(self.design.shape[0]),
            "global_points": int(self.global_points),
            "rule": "previous posterior median + space-filling points in median ± 3 × its "
            "95 % half-width (at least 10 % of C_w) + points over all of C_w; prior unchanged; "
            "with [search] local the local phase follows the design (no global EGO batches)",
        }


def plan_warm_start(
    previous: Path,
    source: str,
    names: Sequence[str],
    bounds: np.ndarray,
    cold_design_size: int,
    seed: int,
    *,
    local_phase: bool = False,
) -> WarmStart | None:
    """The warm start from a previous campaign's results folder, or None (cold start).

    Args:
        previous: results folder of the previous campaign (``result.json`` and
            ``posterior_samples.npy``).
        source: its campaign id (recorded in the results).
        names: (q,) parameters of the new campaign; the previous one must have the same.
        bounds: (2 x q) admissible set C_w.
        cold_design_size: the cold start's design size (the warm design is not larger).
        seed: design seed.
        local_phase: the study runs the local phase right after the design
            (``[search] local``): the design only has to seed the surrogate near the
            previous posterior, so it is 3 q points with 1 over all of C_w; without it
            5 q points with 3 over C_w (the surrogate alone must find the new optimum).
            Sizes measured in ``benchmarks/monitoring_warm_start.py`` (q = 2).

    Returns:
        None when the previous calibration is missing, not trusted, of other parameters
        or gives too small a design; else the :class:`WarmStart`.
    """
    result_file, samples_file = previous / RESULT_FILE, previous / SAMPLES_FILE
    if not (result_file.is_file() and samples_file.is_file()):
        return None
    payload = json.loads(result_file.read_text())
    if not trust(payload)[0]:  # the monitoring's one reading of the reliability contract
        return None
    if list(payload.get("parameters", [])) != list(names):
        return None
    draws = np.load(samples_file)
    b = check_bounds(bounds)
    q = b.shape[1]
    size, global_points = warm_design_shape(q, cold_design_size, local_phase=local_phase)
    if global_points < 0 or draws.ndim != 2 or draws.shape[1] != q:
        return None
    centre = np.clip(np.median(draws, axis=0), b[0], b[1])
    rest = warm_start_design(draws, b, size - 1, seed, global_points=global_points)
    return WarmStart(source, np.vstack([centre[None], rest]), global_points)
