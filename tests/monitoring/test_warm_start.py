"""Warm-start design: local points around the previous posterior, global points over C_w;
``calibrate(design=...)`` evaluates it first."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.test_functions import TARGETS
from susp_bo.monitoring.warm_start import warm_start_design

BOUNDS = np.array([[15.0e3, 0.5e6], [80.0e3, 8.0e6]])


def test_local_points_sit_around_the_previous_posterior_and_global_ones_span_c_w() -> None:
    rng = np.random.default_rng(0)
    previous = np.column_stack([rng.normal(30.0e3, 1.0e3, 4000), rng.normal(4.0e6, 0.5e6, 4000)])
    design = warm_start_design(previous, BOUNDS, size=8, seed=3, widen=2.0, global_points=2)
    assert design.shape == (8, 2)
    assert np.all(design >= BOUNDS[0]) and np.all(design <= BOUNDS[1])
    local = design[:6]
    lo, hi = np.quantile(previous, [0.025, 0.975], axis=0)
    median = np.median(previous, axis=0)
    half = np.maximum(2.0 * (hi - lo) / 2.0, 0.1 * (BOUNDS[1] - BOUNDS[0]) / 2.0)
    assert np.all(np.abs(local - median) <= half + 1e-9)
    np.testing.assert_array_equal(
        design, warm_start_design(previous, BOUNDS, size=8, seed=3, widen=2.0, global_points=2)
    )


def test_a_posterior_at_the_edge_is_clipped_to_c_w() -> None:
    previous = np.column_stack([np.full(100, 15.5e3), np.linspace(0.5e6, 0.6e6, 100)])
    design = warm_start_design(previous, BOUNDS, size=6, seed=1)
    assert np.all(design >= BOUNDS[0]) and np.all(design <= BOUNDS[1])


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="previous: shape"):
        warm_start_design(np.zeros((10, 3)), BOUNDS, size=6, seed=0)
    with pytest.raises(ValueError, match="size: 3"):
        warm_start_design(np.zeros((10, 2)) + 20e3, BOUNDS, size=3, seed=0)


def test_calibrate_evaluates_a_given_design_first() -> None:
    target = TARGETS["banana_2d"]()
    settings = CalibrationSettings(
        seed=0,
        max_evaluations=10,
        batch_size=2,
        mcmc_chains=8,
        mcmc_warmup=50,
        mcmc_samples=50,
        candidate_count=64,
        check_points=0,
        allow_small_budget=True,  # a 10-evaluation run below the minimum, on purpose: fast
    )
    rng = np.random.default_rng(1)
    design = target.bounds[0] + rng.random((6, 2)) * (target.bounds[1] - target.bounds[0])
    result = calibrate(target, target.bounds, target.names, settings, progress=False, design=design)
    np.testing.assert_array_equal(result.X[:6], design)
    assert result.n_evaluations == 10
    with pytest.raises(ValueError, match="design: points outside"):
        calibrate(target, target.bounds, target.names, settings, False, design=design * 100)
