"""Warm-start design: local points around the previous posterior, global points over C_w;
``calibrate(design=...)`` evaluates it first; the plan only follows a trusted calibration."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.test_functions import TARGETS
from susp_bo.monitoring.warm_start import plan_warm_start, warm_start_design

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


def _finished(folder: Path, verdict: str, names: list[str], draws: np.ndarray) -> Path:
    """A results folder as run_study writes it (result.json and posterior_samples.npy)."""
    folder.mkdir(parents=True)
    (folder / "result.json").write_text(
        json.dumps({"parameters": names, "reliability": {"verdict": verdict, "reasons": []}})
    )
    np.save(folder / "posterior_samples.npy", draws)
    return folder


NAMES = ["secondary_vertical_damping", "yaw_damper_damping"]


def test_the_plan_starts_at_the_previous_median_and_only_from_a_trusted_calibration(
    tmp_path: Path,
) -> None:
    rng = np.random.default_rng(3)
    draws = np.column_stack([rng.normal(30e3, 300.0, 4000), rng.normal(3.0e6, 5e4, 4000)])
    bounds = np.array([[10e3, 1.0e6], [80e3, 9.0e6]])
    trusted = _finished(tmp_path / "a", "trusted", NAMES, draws)
    plan = plan_warm_start(trusted, "T/2026-01-01", NAMES, bounds, cold_design_size=26, seed=4)
    assert plan is not None and plan.source == "T/2026-01-01"
    assert plan.design.shape == (10, 2) and plan.global_points == 3  # 5 q, not the cold 26
    np.testing.assert_allclose(plan.design[0], np.median(draws, axis=0))
    local = plan.design[1:-3]
    half = np.maximum(3 * np.diff(np.quantile(draws, [0.025, 0.975], 0), axis=0)[0] / 2,
                      0.05 * (bounds[1] - bounds[0]))  # fmt: skip
    assert np.all(np.abs(local - np.median(draws, 0)) <= half + 1e-9)
    assert plan.to_dict()["from_campaign"] == "T/2026-01-01"
    # the design never exceeds the cold design's size
    small = plan_warm_start(trusted, "x", NAMES, bounds, cold_design_size=6, seed=4)
    assert small is not None and small.design.shape == (6, 2) and small.global_points == 3
    # with the local phase after the design: 3 q points, one of them over all of C_w
    local = plan_warm_start(trusted, "x", NAMES, bounds, 26, seed=4, local_phase=True)
    assert local is not None and local.design.shape == (6, 2) and local.global_points == 1
    np.testing.assert_allclose(local.design[0], np.median(draws, axis=0))
    inner = local.design[1:-1]
    assert np.all(np.abs(inner - np.median(draws, 0)) <= half + 1e-9)
    assert not np.all(np.abs(local.design[-1] - np.median(draws, 0)) <= half + 1e-9)
    # no warm start: not trusted, no verdict, other parameters, unfinished, too small a design
    assert plan_warm_start(_finished(tmp_path / "b", "not_trusted", NAMES, draws), "x", NAMES,
                           bounds, 26, 4) is None  # fmt: skip
    assert plan_warm_start(_finished(tmp_path / "c", "trusted", NAMES[::-1], draws), "x", NAMES,
                           bounds, 26, 4) is None  # fmt: skip
    assert plan_warm_start(tmp_path / "missing", "x", NAMES, bounds, 26, 4) is None
    assert plan_warm_start(trusted, "x", NAMES, bounds, cold_design_size=2, seed=4) is None
    unverdicted = _finished(tmp_path / "d", "trusted", NAMES, draws)
    (unverdicted / "result.json").write_text(json.dumps({"parameters": NAMES}))
    assert plan_warm_start(unverdicted, "x", NAMES, bounds, 26, 4) is None
