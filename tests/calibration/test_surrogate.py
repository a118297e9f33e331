"""Kriging surrogate: the fast predictor is the GP, warping and LOO are exact."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from susp_bo.calibration.design import space_filling_design, to_unit
from susp_bo.calibration.surrogate import OutputWarping, SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate
from susp_bo.calibration.test_functions import correlated_gaussian_7d

TARGET = correlated_gaussian_7d()


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    x = space_filling_design(60, TARGET.bounds, seed=0)
    return to_unit(x, TARGET.bounds), TARGET(x)


@pytest.mark.parametrize(
    ("transform", "mean", "kernel"),
    [
        ("none", "constant", "matern"),
        ("log_deficit", "quadratic", "matern"),
        ("none", "quadratic", "additive_pairs"),
    ],
)
def test_fast_predictor_equals_gpytorch_posterior(
    data, transform: str, mean: str, kernel: str
) -> None:
    x, y = data
    settings = SurrogateSettings(transform=transform, mean=mean, kernel=kernel)  # type: ignore[arg-type]
    s = fit_surrogate(x, y, settings, seed=0)
    assert s.kernel_kind == kernel
    u = torch.rand(40, 7, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    with torch.no_grad():
        post = s.model.posterior(u)
    mean_z, var_z = s.latent_mean_var(u)
    scale = float(post.mean.abs().max())
    torch.testing.assert_close(mean_z, post.mean[:, 0], atol=1e-7 * scale, rtol=1e-7)
    torch.testing.assert_close(var_z, post.variance[:, 0], atol=1e-6 * scale**2, rtol=1e-5)
    _, cov = s.latent_covariance(u[:5])
    torch.testing.assert_close(cov.diagonal(), var_z[:5], atol=1e-6 * scale**2, rtol=1e-5)


def test_near_noiseless_interpolation_of_log_likelihood(data) -> None:
    x, y = data
    s = fit_surrogate(x, y, SurrogateSettings(transform="log_deficit"), seed=0)
    got = s.log_likelihood_mean(torch.as_tensor(x))
    np.testing.assert_allclose(got.numpy(), y, atol=1e-2 * np.ptp(y) + 1e-3)


def test_warping_round_trip_and_moments() -> None:
    w = OutputWarping("log_deficit", y_max=-10.0, scale=3.0)
    y = np.array([-10.0, -11.0, -500.0])
    z = torch.as_tensor(w.forward(y))
    torch.testing.assert_close(w.plug_in(z), torch.as_tensor(y))
    # E[log L] under z ~ N(m, v) by Monte Carlo against the closed form
    m, v = torch.tensor([-0.3]), torch.tensor([0.04])
    draws = m + v.sqrt() * torch.randn(400_000, generator=torch.Generator().manual_seed(0))
    mc = w.plug_in(draws.double()).mean()
    assert float(w.mean_log_likelihood(m.double(), v.double())[0]) == pytest.approx(
        float(mc), rel=2e-3
    )


def test_expected_likelihood_is_lognormal_without_warping(data) -> None:
    x, y = data
    s = fit_surrogate(x, y, SurrogateSettings(transform="none"), seed=0)
    u = torch.rand(10, 7, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    m, v = s.latent_mean_var(u)
    torch.testing.assert_close(s.log_expected_likelihood(u), m + 0.5 * v)


def test_loo_score_matches_refitting_without_each_point(data) -> None:
    x, y = data
    s = fit_surrogate(x[:25], y[:25], SurrogateSettings(transform="log_deficit"), seed=0)
    # brute force with the same hyperparameters: condition on n-1 points through the kernel
    k_all = s._kernel(s.train_x, s.train_x) + torch.diag(
        s.model.likelihood.noise.detach().reshape(-1).expand(25)
    )
    t = s.model.train_targets.detach() - s._prior_mean(s.train_x)
    z = torch.as_tensor(s.warping.forward(y[:25]))
    log_py = []
    for i in range(25):
        keep = torch.arange(25) != i
        kk = k_all[keep][:, keep]
        ki = k_all[i, keep]
        mu = s._prior_mean(s.train_x[i : i + 1])[0] + ki @ torch.linalg.solve(kk, t[keep])
        var = k_all[i, i] - ki @ torch.linalg.solve(kk, ki)
        mu, var = mu * s._y_std + s._y_mean, var * s._y_std**2
        lp = -0.5 * (z[i] - mu) ** 2 / var - 0.5 * torch.log(2 * torch.pi * var)
        log_py.append(float(lp) + float(s.warping.log_abs_dz_dy(y[i : i + 1])[0]))
    best = np.argsort(y[:25])[::-1][:9]
    assert s.loo_log_score() == pytest.approx(float(np.mean(np.array(log_py)[best])), rel=1e-6)


def test_auto_picks_the_better_loo_score(data) -> None:
    x, y = data
    fits = {
        k: fit_surrogate(x, y, SurrogateSettings(transform=k), 0) for k in ("none", "log_deficit")
    }
    auto = fit_surrogate(x, y, SurrogateSettings(transform="auto"), 0)
    best = max(fits, key=lambda k: fits[k].loo_log_score())
    assert auto.warping.kind == best


def test_settings_validation() -> None:
    with pytest.raises(ValueError, match="transform"):
        SurrogateSettings(transform="log")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="deficit_scale"):
        SurrogateSettings(deficit_scale=0.0)
    with pytest.raises(ValueError, match="noise_variance"):
        SurrogateSettings(noise_variance=0.0)
    with pytest.raises(ValueError, match="mean: 'linear'"):
        SurrogateSettings(mean="linear")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="finite"):
        fit_surrogate(np.zeros((3, 2)), np.array([0.0, np.nan, 1.0]), SurrogateSettings(), 0)


def test_auto_mean_keeps_the_better_leave_one_out_fit() -> None:
    """On an exact quadratic bowl the negative-quadratic prior mean wins, and auto keeps it."""
    from susp_bo.calibration.surrogate_means import NegativeQuadraticMean

    rng = np.random.default_rng(3)
    x = rng.uniform(0.0, 1.0, (30, 2))
    y = -0.5 * np.sum(((x - 0.4) / 0.2) ** 2, axis=1)
    fits = {
        m: fit_surrogate(x, y, SurrogateSettings(mean=m), seed=0) for m in ("constant", "quadratic")
    }
    scores = {m: f.loo_log_score() for m, f in fits.items()}
    assert scores["quadratic"] > scores["constant"]
    auto = fit_surrogate(x, y, SurrogateSettings(mean="auto"), seed=0)
    assert isinstance(auto.model.mean_module, NegativeQuadraticMean)
    assert auto.loo_log_score() > scores["constant"]


@pytest.mark.parametrize(
    ("transform", "mean", "noise"),
    [("none", "quadratic", "fixed"), ("log_deficit", "full_quadratic", "learned")],
)
def test_closed_form_leave_one_out_is_the_gp_refitted_without_each_point(
    transform: str, mean: str, noise: str
) -> None:
    """``loo_log_likelihood_uncertainty`` against the exact GP posterior without point i
    (same hyperparameters, noise included: the predictive distribution of a new
    evaluation), mapped through the same warping (second review, session 28)."""
    rng = np.random.default_rng(0)
    x = rng.random((30, 2))
    y = -0.5 * ((x[:, 0] - 0.6) / 0.1) ** 2 - 0.5 * ((x[:, 1] - 0.4) / 0.15) ** 2
    y = y - 3.0 * np.sin(5.0 * x[:, 0]) + (rng.normal(0.0, 1.0, 30) if noise == "learned" else 0)
    s = fit_surrogate(x, y, SurrogateSettings(transform=transform, mean=mean, noise=noise), 0)
    mean_loo, sd_loo = s.loo_log_likelihood_uncertainty()
    model, t = s.model, s.model.train_targets.detach()
    with torch.no_grad():
        k = model.covar_module(s.train_x).to_dense()
        prior = model.mean_module(s.train_x)
        nugget = model.likelihood.noise.detach().reshape(-1).expand(30)
    means, variances = [], []
    for i in range(30):
        keep = np.arange(30) != i
        solve = torch.linalg.solve(
            k[keep][:, keep] + torch.diag(nugget[keep]),
            torch.stack([t[keep] - prior[keep], k[i, keep]], 1),
        )
        means.append(float(prior[i] + k[i, keep] @ solve[:, 0]))
        variances.append(float(k[i, i] - k[i, keep] @ solve[:, 1] + nugget[i]))
    z = torch.tensor(means, dtype=torch.float64) * s._y_std + s._y_mean
    var = torch.tensor(variances, dtype=torch.float64) * s._y_std**2
    np.testing.assert_allclose(mean_loo, s.warping.mean_log_likelihood(z, var).numpy(), atol=1e-4)
    np.testing.assert_allclose(sd_loo, (s.warping.slope(z) * var.sqrt()).numpy(), atol=1e-4)
