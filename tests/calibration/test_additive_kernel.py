"""Pairwise additive kernel: the Newton–Girard form is the sum over terms; on a
chained-banana log L it beats the Matérn kernel (and ``kernel="auto"`` picks it), while
on a three-way interaction ``auto`` keeps the Matérn. (The fast predictor against the GP:
``test_surrogate.py``.)"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from susp_bo.calibration.additive_kernel import PairwiseAdditiveKernel, pairwise_additive
from susp_bo.calibration.design import space_filling_design, to_unit
from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.surrogate_fit import Bowl, fit_surrogate
from susp_bo.calibration.test_functions import curved_chain_5d


def _brute_force(a: np.ndarray, b: np.ndarray, ls: np.ndarray, mix: float) -> np.ndarray:
    """(1 − ρ) mean of one-parameter terms + ρ mean of two-parameter products, by loops."""
    q = a.shape[1]
    out = np.zeros((a.shape[0], b.shape[0]))
    for i, ai in enumerate(a):
        for j, bj in enumerate(b):
            k = np.exp(-0.5 * ((ai - bj) / ls) ** 2)
            pairs = [k[m] * k[n] for m, n in itertools.combinations(range(q), 2)]
            out[i, j] = (1 - mix) * k.mean() + mix * np.mean(pairs)
    return out


def test_newton_girard_form_equals_the_sum_over_terms() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.random((6, 4)), rng.random((5, 4))
    ls = np.array([0.1, 0.3, 0.7, 2.0])
    got = pairwise_additive(torch.as_tensor(a), torch.as_tensor(b), torch.as_tensor(1 / ls), 0.3)
    np.testing.assert_allclose(got.numpy(), _brute_force(a, b, ls, 0.3), rtol=1e-12, atol=1e-14)


def test_kernel_is_a_correlation_and_broadcasts_over_batches() -> None:
    kernel = PairwiseAdditiveKernel(ard_num_dims=3).double()
    x = torch.rand(4, 7, 3, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    with torch.no_grad():
        k = kernel(x, x).to_dense()
        per_batch = torch.stack([kernel(xi, xi).to_dense() for xi in x])
        diag = kernel(x[0], x[0], diag=True)
    torch.testing.assert_close(k, per_batch)
    torch.testing.assert_close(diag, torch.ones(7, dtype=torch.float64))
    torch.testing.assert_close(k[0].diagonal(), torch.ones(7, dtype=torch.float64))
    assert float(torch.linalg.eigvalsh(k[0]).min()) > -1e-12
    assert 0.0 < float(kernel.mix.detach()) < 1.0


@pytest.fixture(scope="module")
def chain_data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """60 design points and 250 exact posterior draws of the chained banana (training),
    1 000 exact draws (testing), in the unit cube."""
    target = curved_chain_5d()
    x = np.vstack([space_filling_design(60, target.bounds, 1), target.sample(250, 1)])
    test = target.sample(1000, 7)
    b = target.bounds
    return to_unit(x, b), target(x), to_unit(test, b), target(test)


def _posterior_error(surrogate, u_test: np.ndarray, y_test: np.ndarray) -> float:
    """Half the 5–95 % range of (GP mean − log L) at exact posterior draws, nats."""
    with torch.no_grad():
        mean = surrogate.log_likelihood_mean(torch.as_tensor(u_test)).numpy()
    lo, hi = np.quantile(mean - y_test, [0.05, 0.95])
    return 0.5 * float(hi - lo)


@pytest.mark.slow
def test_additive_kernel_learns_the_chained_banana_and_auto_picks_it(chain_data) -> None:
    x, y, u_test, y_test = chain_data
    matern = fit_surrogate(x, y, SurrogateSettings(kernel="matern"), seed=0)
    additive = fit_surrogate(x, y, SurrogateSettings(kernel="additive_pairs"), seed=0)
    auto = fit_surrogate(x, y, SurrogateSettings(kernel="auto"), seed=0)
    err_matern = _posterior_error(matern, u_test, y_test)
    err_additive = _posterior_error(additive, u_test, y_test)
    assert err_additive < 0.5 * err_matern, (err_additive, err_matern)
    assert additive.loo_log_score() > matern.loo_log_score()
    assert (auto.kernel_kind, additive.kernel_kind, matern.kernel_kind) == (
        "additive_pairs",
        "additive_pairs",
        "matern",
    )


def test_auto_kernel_is_chosen_under_a_fixed_bowl_mean_too(chain_data) -> None:
    """With the local phase's Laplace bowl as the fixed mean, "auto" still picks by LOO."""
    x, y, u_test, y_test = chain_data
    bowl = Bowl(centre=x[np.argmax(y)], precision=np.eye(5) * 50.0)
    matern = fit_surrogate(x, y, SurrogateSettings(kernel="matern"), seed=0, bowl=bowl)
    auto = fit_surrogate(x, y, SurrogateSettings(kernel="auto"), seed=0, bowl=bowl)
    assert (matern.kernel_kind, auto.kernel_kind) == ("matern", "additive_pairs")
    assert auto.loo_log_score() > matern.loo_log_score()
    assert _posterior_error(auto, u_test, y_test) < _posterior_error(matern, u_test, y_test)


def test_auto_keeps_the_matern_kernel_on_a_three_way_interaction() -> None:
    """log L = −½ Σ (u − ½)²/0.04 − 40 (u₁ − ½)(u₂ − ½)(u₃ − ½)·8: no sum of pair terms."""
    rng = np.random.default_rng(3)
    x = rng.random((120, 3))
    c = x - 0.5
    y = -0.5 * (c**2).sum(1) / 0.04 - 320.0 * c[:, 0] * c[:, 1] * c[:, 2]
    matern = fit_surrogate(x, y, SurrogateSettings(kernel="matern"), seed=0)
    additive = fit_surrogate(x, y, SurrogateSettings(kernel="additive_pairs"), seed=0)
    auto = fit_surrogate(x, y, SurrogateSettings(kernel="auto"), seed=0)
    assert matern.loo_log_score() > additive.loo_log_score()
    assert auto.kernel_kind == "matern"


def test_kernel_setting_is_validated() -> None:
    with pytest.raises(ValueError, match="kernel: 'rbf'"):
        SurrogateSettings(kernel="rbf")  # type: ignore[arg-type]
