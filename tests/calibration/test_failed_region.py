"""The failed_region rule alone: draws nearest failed evaluations, failed check points."""

from __future__ import annotations

import numpy as np

from susp_bo.calibration.failed_region import failed_region
from susp_bo.calibration.surrogate_check import SurrogateCheck


def test_failed_region_fires_on_failed_check_points_or_draws_nearest_to_failures() -> None:
    grid = np.linspace(0.05, 0.95, 7)
    x = np.array([(a, b) for a in grid for b in grid])  # 49 evaluated points
    ok = x[:, 0] <= 0.6  # every point with a > 0.6 failed
    left = np.random.default_rng(0).uniform([0.0, 0.0], [0.5, 1.0], size=(1000, 2))
    reason, evidence = failed_region(left, x, ok, None)
    assert reason is None  # the posterior lies where simulations ran
    assert evidence == {
        "failed_evaluations": int((~ok).sum()),
        "failed_check_points": 0,
        "draws_near_failed": 0.0,
    }
    spread = np.random.default_rng(0).uniform(0.0, 1.0, size=(1000, 2))
    reason, evidence = failed_region(spread, x, ok, None)
    assert reason is not None and reason["code"] == "failed_region"
    assert 0.3 < evidence["draws_near_failed"] < 0.45  # a > ~0.65 of the unit square
    assert "nearer to a failed evaluation" in reason["message"]
    # no failure at all: nothing to say, and no share measured
    assert failed_region(spread, x, np.ones(len(x), bool), None) == (
        None,
        {"failed_evaluations": 0, "failed_check_points": 0, "draws_near_failed": None},
    )
    # one failed check simulation at the posterior's edge is enough
    check = SurrogateCheck(
        np.full((4, 2), 0.3), np.zeros(4), np.ones(4), np.array([0.1, np.nan, -0.2, 0.0]), 1.0
    )
    reason, evidence = failed_region(left, x, np.ones(len(x), bool), check)
    assert reason is not None and "1 of the 4 held-out check simulations" in reason["message"]
    assert evidence["failed_check_points"] == 1
