"""The failed_region rule alone: draws nearest failed evaluations, failed check points."""

from __future__ import annotations

import numpy as np

from susp_bo.calibration.failed_region import failed_region, failures_scattered
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
    assert "scattered" not in reason and "scattered" not in reason["message"]  # one region
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


def test_failures_that_strike_anywhere_are_told_apart_from_a_failed_region() -> None:
    """Outside probe, session 24: 20 % of the runs failed at random and the advice was to
    narrow the admissible interval, which cannot avoid them."""
    rng = np.random.default_rng(1)
    x = rng.uniform(0.0, 1.0, size=(200, 2))
    anywhere = rng.uniform(size=200) > 0.2  # 20 % fail wherever they are
    assert failures_scattered(x, anywhere)
    assert not failures_scattered(x, x[:, 0] < 0.8)  # a region: a > 0.8
    assert not failures_scattered(x, np.linalg.norm(x - 0.5, axis=1) < 0.45)  # a ring
    few = np.ones(200, bool)
    few[[3, 50, 120, 180]] = False  # 4 failures: too few to tell
    assert not failures_scattered(x, few)
    draws = rng.normal([0.5, 0.5], 0.2, size=(1000, 2))
    reason, _ = failed_region(draws, x, anywhere, None)
    assert reason is not None and reason["scattered"] is True
    assert "scattered among successful runs" in reason["message"]


def test_a_region_bounded_in_one_parameter_is_not_scattered_in_seven_dimensions() -> None:
    """Review, session 25: at q = 7 the evaluations are too sparse for neighbours to show a
    region (x0 > 0.75 failing was called scattered on 7 of 20 seeds); the one parameter
    that tells failed from successful runs does."""
    from scipy.stats import qmc

    for seed in range(5):
        rng = np.random.default_rng(seed)
        design = qmc.LatinHypercube(d=7, seed=seed).random(35)
        near = np.clip(rng.normal(0.5, 0.03, size=(60, 7)), 0, 1)
        x = np.vstack([design, near])
        assert not failures_scattered(x, x[:, 0] < 0.75)
        anywhere = rng.uniform(size=len(x)) > 0.2
        if int((~anywhere).sum()) >= 5:
            assert failures_scattered(x, anywhere)
