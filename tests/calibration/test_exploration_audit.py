"""An early stop's audit: maximin points far from the evaluations, and what counts as mass
the search had not seen; through the loop, a narrow second mode the search had missed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from susp_bo.calibration.exploration_audit import (
    audit_points,
    audit_size,
    posterior_reach,
    unseen_mass,
)
from susp_bo.calibration.loop import calibrate
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate_check import SurrogateCheck


def test_the_audit_spends_a_share_of_what_is_left_and_nothing_when_too_little() -> None:
    assert audit_size(178, 2) == 89
    assert audit_size(6, 2) == 3
    assert audit_size(5, 2) == 0  # 2 points cannot look at a 2-D box: no audit
    assert audit_size(178, 2, share=0.0) == 0
    # a whole-budget audit that found mass would leave nothing to search it with: a batch
    # is always kept (review, session 24)
    assert audit_size(20, 2, share=1.0, reserve=4) == 16
    assert audit_size(6, 2, share=1.0, reserve=4) == 0
    with pytest.raises(ValueError, match="audit_share"):
        CalibrationSettings(audit_share=1.5)


def test_audit_points_are_far_from_the_evaluations_and_from_each_other() -> None:
    rng = np.random.default_rng(0)
    evaluated = 0.25 * rng.random((30, 2))  # every evaluation in the lower-left corner
    points = audit_points(evaluated, 12, seed=3)
    assert points.shape == (12, 2) and np.all((points >= 0) & (points <= 1))
    to_evaluated = np.linalg.norm(points[:, None] - evaluated[None], axis=2).min(axis=1)
    assert to_evaluated.min() > 0.2  # none in or beside the evaluated corner
    between = np.linalg.norm(points[:, None] - points[None], axis=2)[np.triu_indices(12, 1)]
    assert between.min() > 0.15  # spread over the box, not bunched
    assert np.array_equal(points, audit_points(evaluated, 12, seed=3))  # seeded


def test_unseen_mass_needs_a_value_near_the_best_and_above_the_band() -> None:
    reach = posterior_reach(2)
    assert reach == pytest.approx(6.9078, abs=1e-3)  # ½ χ²₂(0.999)
    check = SurrogateCheck(
        points_unit=np.zeros((5, 2)),
        predicted=np.array([-40.0, -40.0, -1.0, -40.0, -40.0]),
        predicted_sd=np.full(5, 0.5),
        observed=np.array([2.0, -30.0, 0.5, -8.0, np.nan]),
        tolerance_nats=1.0,
    )
    found = unseen_mass(check, best_log_likelihood=0.0, q=2)
    # 2.0: above the best and 42 nats above its prediction -> unseen mass; -30: above its
    # prediction but far below the best (no posterior mass); 0.5: near the best but predicted
    # (the posterior already holds it); -8: beyond the reach; NaN: a failed run
    assert found.tolist() == [True, False, False, False, False]


def _needle(w: np.ndarray) -> np.ndarray:
    """Two modes of equal mass in [0, 1]²: a broad one (sd 0.08) and a 5x narrower one."""
    broad = -0.5 * np.sum(((w - [0.3, 0.3]) / 0.08) ** 2, axis=1) - 2 * np.log(0.08)
    narrow = -0.5 * np.sum(((w - [0.8, 0.75]) / 0.016) ** 2, axis=1) - 2 * np.log(0.016)
    return np.logaddexp(broad, narrow)


def test_a_narrow_second_mode_missed_by_an_early_stop_is_found_by_the_audit() -> None:
    """Outside probe, session 24: the loop stopped as converged after 22 of 200
    evaluations, never near the narrow mode, and said `trusted` with half the exact mass
    missing (MMTV 0.50). With the audit the search goes back and finds it; the result is
    never `trusted` with the narrow mode's share far from its exact 0.5."""
    settings = CalibrationSettings(
        seed=3, max_evaluations=200, mcmc_chains=256, mcmc_warmup=300, mcmc_samples=600
    )
    bounds = np.array([[0.0, 0.0], [1.0, 1.0]])
    result = calibrate(_needle, bounds, ["x", "y"], settings, progress=False)
    assert "explore" in [h.phase for h in result.history]
    near = np.linalg.norm(result.X - [0.8, 0.75], axis=1) < 0.05
    assert near.any() and np.nanmax(result.y[near]) > np.nanmax(result.y[~near])  # found
    draws = result.draws.reshape(-1, 2)
    share = float(np.mean(np.linalg.norm(draws - [0.8, 0.75], axis=1) < 0.1))
    assert result.reliability.trusted is False or 0.4 < share < 0.6
    assert 0.4 < share < 0.6 or "multimodal" in result.reliability.codes
    # without the audit (the code before): the early stop, `trusted`, the mode missed
    before = calibrate(
        _needle, bounds, ["x", "y"], replace(settings, audit_share=0.0), progress=False
    )
    assert before.n_evaluations < 60 and before.reliability.trusted
    assert (
        float(np.mean(np.linalg.norm(before.draws.reshape(-1, 2) - [0.8, 0.75], axis=1) < 0.1))
        == 0.0
    )


def test_a_trust_region_keeps_both_modes_of_the_needle() -> None:
    """Review, session 24, then measured in session 25: with ``trust_region=True`` the
    audit found the narrow mode, the box then followed the surrogate's draws onto it and
    cut the broad mode away — `trusted` with all the draws in the narrow mode (exact share
    0.5) on 5 of 5 seeds. The box now holds every evaluation within reach of the best log
    L, and an evaluation within reach outside the final box is `search_box_edge`."""
    settings = CalibrationSettings(
        seed=3,
        max_evaluations=200,
        mcmc_chains=256,
        mcmc_warmup=300,
        mcmc_samples=600,
        trust_region=True,
    )
    bounds = np.array([[0.0, 0.0], [1.0, 1.0]])
    result = calibrate(_needle, bounds, ["x", "y"], settings, progress=False)
    draws = result.draws.reshape(-1, 2)
    share = float(np.mean(np.linalg.norm(draws - [0.8, 0.75], axis=1) < 0.1))
    assert result.reliability.trusted is False or 0.4 < share < 0.6
    assert 0.4 < share < 0.6 or "multimodal" in result.reliability.codes
    assert result.search_box is not None
    assert np.all(result.search_box[0] <= 0.3) and np.all(result.search_box[1] >= 0.75)
