"""Refinement batches: the optimistic weight reaches posterior mass the surrogate misses."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from susp_bo.calibration.acquisition import select_uncertainty_batch
from susp_bo.calibration.loop import CalibrationSettings
from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate

VERTEX = np.array([0.5, 0.3])


def _banana(u: np.ndarray) -> np.ndarray:
    """2-D banana, log L 0 along x2 = 0.6 x1² (x = (u − vertex) / 0.1), both arms alike."""
    x = (u - VERTEX) / 0.1
    return -0.5 * x[:, 0] ** 2 - 0.5 * ((x[:, 1] - 0.6 * x[:, 0] ** 2) / 0.3) ** 2


def _arm(t: np.ndarray) -> np.ndarray:
    return np.column_stack([VERTEX[0] + 0.1 * t, VERTEX[1] + 0.06 * t**2])


def test_optimism_refines_the_unseen_arm_of_a_banana() -> None:
    """Evaluations on the left arm only: the surrogate puts the right arm 5–50 nats too low.

    There the truth is within 3 nats of the top, the surrogate says e.g. −11.4 ± 10.8 at
    t = 1.2 (measured). Plain refinement (κ = 0) stays near the vertex (t ≤ 0.7); with
    κ = 2 the batch goes out along the arm the search has not seen.
    """
    rng = np.random.default_rng(0)
    t_seen = rng.uniform(-2.5, 0.3, 40)
    seen = _arm(t_seen) + np.column_stack([np.zeros(40), 0.03 * rng.standard_normal(40)])
    x = np.vstack([rng.uniform(size=(12, 2)), seen]).clip(0.0, 1.0)
    surrogate = fit_surrogate(x, _banana(x), SurrogateSettings(), seed=0)
    right, left = _arm(np.linspace(0.3, 2.5, 12)), _arm(np.linspace(-2.5, -0.3, 12))
    with torch.no_grad():
        mean, sd = surrogate.log_likelihood_uncertainty(torch.as_tensor(right))
    assert np.all(_banana(right) > -3.5)
    assert mean[6] < _banana(right)[6] - 5.0 and sd[6] > 5.0  # unseen arm: low and unsure
    candidates = torch.as_tensor(np.vstack([left, right]))
    plain, _ = select_uncertainty_batch(surrogate, candidates, 4)
    bold, _ = select_uncertainty_batch(surrogate, candidates, 4, optimism=2.0)
    reach = lambda u: float(np.max((u.numpy()[:, 0] - VERTEX[0]) / 0.1))  # noqa: E731
    assert reach(plain) < 0.8
    assert reach(bold) > 1.0
    assert {tuple(r) for r in bold.numpy()} <= {tuple(r) for r in candidates.numpy()}


def test_optimism_must_be_finite_and_non_negative() -> None:
    with pytest.raises(ValueError, match="refine_optimism"):
        CalibrationSettings(refine_optimism=-1.0)
    with pytest.raises(ValueError, match="refine_optimism"):
        CalibrationSettings(refine_optimism=float("nan"))
    x = np.random.default_rng(1).uniform(size=(12, 2))
    surrogate = fit_surrogate(x, _banana(x), SurrogateSettings(), seed=0)
    with pytest.raises(ValueError, match="optimism"):
        select_uncertainty_batch(surrogate, torch.as_tensor(x), 2, optimism=-0.5)
