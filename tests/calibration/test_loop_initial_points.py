"""calibrate(initial_points=...): a warm start evaluates given points with a smaller design."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.test_functions import TARGETS

SMALL = CalibrationSettings(
    seed=0, max_evaluations=14, initial_design_size=8, batch_size=3, mcmc_chains=8,
    mcmc_warmup=100, mcmc_samples=100, candidate_count=64, check_points=0,
)  # fmt: skip


def test_initial_points_are_evaluated_with_the_design_within_the_budget() -> None:
    target = TARGETS["banana_2d"]()
    start = target.bounds.mean(axis=0) + 0.1 * np.ptp(target.bounds, axis=0)
    outside = target.bounds[1] + 1.0  # clipped to the box
    result = calibrate(target, target.bounds, target.names, SMALL, progress=False,
                       initial_points=np.vstack([start, outside]))  # fmt: skip
    assert result.n_evaluations == 14
    np.testing.assert_array_equal(result.X[6], start)
    np.testing.assert_array_equal(result.X[7], target.bounds[1])
    assert result.y[6] == pytest.approx(float(target(start[None])[0]))
    plain = calibrate(target, target.bounds, target.names, SMALL, progress=False)
    assert not np.array_equal(plain.X[:8], result.X[:8])  # the design made room for them


def test_too_many_initial_points_are_refused() -> None:
    target = TARGETS["banana_2d"]()
    with pytest.raises(ValueError, match="initial_points"):
        calibrate(target, target.bounds, target.names, SMALL, progress=False,
                  initial_points=np.zeros((8, 2)))  # fmt: skip


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_initial_points_are_refused_before_any_evaluation(bad: float) -> None:
    """NaN reached evaluate (np.clip keeps it), inf was silently clipped to the bound."""
    target = TARGETS["banana_2d"]()
    calls: list[int] = []

    def evaluate(w: np.ndarray) -> np.ndarray:
        calls.append(w.shape[0])
        return target(w)

    with pytest.raises(ValueError, match=r"initial_points: row 1 is .*NaN and infinite"):
        calibrate(evaluate, target.bounds, target.names, SMALL, progress=False,
                  initial_points=np.array([[0.0, 0.0], [bad, 0.0]]))  # fmt: skip
    assert calls == []
