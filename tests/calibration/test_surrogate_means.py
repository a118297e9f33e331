"""Quadratic prior means: the full-Hessian start recovers a correlated bowl exactly."""

from __future__ import annotations

import numpy as np
import torch

from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate
from susp_bo.calibration.surrogate_means import FullQuadraticMean, initial_full_quadratic_mean


def _bowl(q: int = 5) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    m = rng.normal(size=(q, q))
    return m @ m.T * 50 + np.eye(q) * 5, rng.uniform(0.3, 0.7, q)


def test_full_quadratic_start_recovers_hessian_and_centre() -> None:
    a, c = _bowl()
    x = np.random.default_rng(1).uniform(size=(80, a.shape[0]))
    y = 10 - 0.5 * np.einsum("ni,ij,nj->n", x - c, a, x - c)
    z = torch.as_tensor((y - y.mean()) / y.std(ddof=1))
    mean = initial_full_quadratic_mean(torch.as_tensor(x), z)
    assert isinstance(mean, FullQuadraticMean)
    factor = mean.factor.detach().numpy()
    np.testing.assert_allclose(factor @ factor.T * y.std(ddof=1), a, atol=1e-4 * np.abs(a).max())
    np.testing.assert_allclose(mean.centre.detach().numpy(), c, atol=1e-5)


def test_full_quadratic_mean_predicts_a_correlated_bowl_the_default_cannot() -> None:
    a, c = _bowl()
    rng = np.random.default_rng(2)
    x = rng.uniform(size=(80, a.shape[0]))
    f = lambda u: 10 - 0.5 * np.einsum("ni,ij,nj->n", u - c, a, u - c)  # noqa: E731
    test = rng.uniform(size=(200, a.shape[0]))
    errors = {}
    for kind in ("auto", "full_quadratic"):
        s = fit_surrogate(x, f(x), SurrogateSettings(mean=kind), 0)
        predicted = s.log_likelihood_mean(torch.as_tensor(test)).numpy()
        errors[kind] = float(np.sqrt(np.mean((predicted - f(test)) ** 2)))
    assert errors["full_quadratic"] < 1e-2  # log L spans ~110 nats here
    assert errors["auto"] > 10 * errors["full_quadratic"]
