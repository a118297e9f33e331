"""The local phase: trust-region Gauss–Newton on the spectra, against exact answers.

The evaluators here have known spectra maps h(w) and a Gaussian output error, so the
mode and the Laplace covariance are known in closed form (linear h) or by a direct
optimisation of the exact log L (nonlinear h).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import minimize

from susp_bo.calibration.local_search import (
    LocalSearchSettings,
    SpectraEvaluator,
    local_search,
)
from susp_bo.calibration.loop import calibrate
from susp_bo.calibration.settings import CalibrationSettings


class GaussianSpectra:
    """y = h(w_true) + e, e ~ N(0, σ² I), h(w) = A (w − c) (+ ``bend`` (w − c)² per row).

    Spectra are shaped (1 run x 1 channel x F bands); log L is the exact Gaussian one.
    """

    def __init__(self, q: int, n_bands: int, sigma: float, bend: float, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.bounds = np.stack([np.zeros(q), np.full(q, 10.0)])
        self.a = rng.normal(size=(n_bands, q))
        self.c = np.full(q, 5.0)
        self.bend = bend
        self.sigma = sigma
        self.truth = self.c + rng.uniform(-2.0, 2.0, size=q)
        self.y = self.h(self.truth[None])[0] + sigma * rng.normal(size=(1, 1, n_bands))
        self.calls = 0

    def h(self, W: np.ndarray) -> np.ndarray:
        d = np.atleast_2d(W) - self.c
        out = d @ self.a.T + self.bend * (d**2) @ np.abs(self.a.T)
        return out[:, None, None, :]

    def spectra(self, W: np.ndarray) -> np.ndarray:
        self.calls += len(np.atleast_2d(W))
        return self.h(W)

    def log_likelihood_of(self, H: np.ndarray, exact: bool = False) -> np.ndarray:
        r = (self.y[None] - np.asarray(H)).reshape(len(H), -1) / self.sigma
        return -0.5 * np.sum(r * r, axis=1)

    def __call__(self, W: np.ndarray) -> np.ndarray:
        return self.log_likelihood_of(self.spectra(W))


def test_linear_spectra_give_the_exact_mode_and_covariance() -> None:
    problem = GaussianSpectra(q=4, n_bands=30, sigma=0.01, bend=0.0, seed=1)
    assert isinstance(problem, SpectraEvaluator)
    seen: list[np.ndarray] = []
    result = local_search(
        problem,
        problem.bounds,
        start=np.array([1.0, 9.0, 2.0, 8.0]),
        max_evaluations=60,
        on_evaluations=lambda w, y, gain: seen.append(w),
    )
    span = problem.bounds[1] - problem.bounds[0]
    # exact: least squares in unit coordinates, covariance σ² (Jᵀ J)⁻¹ with J = A diag(span)
    jac = problem.a * span
    mode = np.linalg.lstsq(problem.a, problem.y.ravel(), rcond=None)[0] + problem.c
    cov = problem.sigma**2 * np.linalg.inv(jac.T @ jac)
    assert result.stop_reason == "converged"
    np.testing.assert_allclose(problem.bounds[0] + result.mode * span, mode, atol=1e-6)
    np.testing.assert_allclose(result.covariance, cov, rtol=1e-3)
    assert result.n_evaluations == sum(len(w) for w in seen) <= 60
    assert result.log_likelihood == pytest.approx(float(problem(mode[None])[0]), abs=1e-6)


def test_nonlinear_spectra_reach_the_maximum_of_the_exact_log_likelihood() -> None:
    problem = GaussianSpectra(q=3, n_bands=25, sigma=0.02, bend=0.3, seed=2)
    start = np.array([9.0, 1.0, 9.0])
    result = local_search(problem, problem.bounds, start, max_evaluations=120)
    span = problem.bounds[1] - problem.bounds[0]
    found = problem.bounds[0] + result.mode * span

    def negative(w: np.ndarray) -> float:
        return -float(problem(w[None])[0])

    exact = minimize(
        negative,
        problem.truth,
        method="Nelder-Mead",
        options={"xatol": 1e-10, "fatol": 1e-10, "maxiter": 20000},
    )
    assert result.log_likelihood >= -exact.fun - 0.05
    np.testing.assert_allclose(found, exact.x, atol=5e-3)


def test_the_evaluation_cap_is_respected() -> None:
    problem = GaussianSpectra(q=5, n_bands=20, sigma=0.01, bend=0.2, seed=3)
    problem.calls = 0
    result = local_search(problem, problem.bounds, np.full(5, 1.0), max_evaluations=13)
    assert result.n_evaluations <= 13
    assert result.stop_reason == "budget"
    assert problem.calls <= 13 + 1  # + the start point, looked up again


def test_settings_refuse_bad_values() -> None:
    with pytest.raises(ValueError, match="initial_radius"):
        LocalSearchSettings(initial_radius=0.0)
    with pytest.raises(ValueError, match="local_search_fraction"):
        CalibrationSettings(local_search_fraction=1.0)


def _loop_settings(**overrides: object) -> CalibrationSettings:
    values = dict(
        seed=3,
        max_evaluations=90,
        initial_design_size=20,
        batch_size=4,
        check_points=6,
        mcmc_chains=64,
        mcmc_warmup=300,
        mcmc_samples=600,
        local_search=True,
    )
    values.update(overrides)
    return CalibrationSettings(**values)  # type: ignore[arg-type]


def test_the_loop_finds_a_sharp_posterior_with_the_local_phase() -> None:
    """Posterior sd ≈ 1e-3 of C_w: the local phase reaches the mode, the box holds it."""
    problem = GaussianSpectra(q=3, n_bands=40, sigma=0.002, bend=0.05, seed=4)
    names = ["a", "b", "c"]
    result = calibrate(problem, problem.bounds, names, _loop_settings(), progress=False)
    assert result.local_search is not None
    assert any(h.phase == "local" for h in result.history)
    # reports numbered as evaluated: the step handing over to the local phase left a gap
    assert [h.iteration for h in result.history] == list(range(1, len(result.history) + 1))
    assert "nan" not in " ".join(h.line() for h in result.history)
    span = problem.bounds[1] - problem.bounds[0]
    mode = problem.bounds[0] + result.local_search.mode * span
    sd = result.local_search.sd * span
    assert np.all(sd < 2e-3 * span)  # a sharp posterior indeed
    assert float(np.nanmax(result.y)) >= float(problem(mode[None])[0]) - 1e-9
    box = result.search_box
    assert box is not None and np.all(box[0] <= mode) and np.all(mode <= box[1])
    # kriging/MCMC posterior against the Laplace one (exact to O(bend) here)
    mean = result.draws.reshape(-1, 3).mean(axis=0)
    post_sd = result.draws.reshape(-1, 3).std(axis=0)
    assert np.all(np.abs(mean - mode) < 0.5 * sd)
    np.testing.assert_allclose(post_sd, sd, rtol=0.35)


def test_without_spectra_the_loop_warns_and_skips_the_local_phase(
    caplog: pytest.LogCaptureFixture,
) -> None:
    problem = GaussianSpectra(q=2, n_bands=10, sigma=0.5, bend=0.0, seed=5)

    def scalar_only(W: np.ndarray) -> np.ndarray:
        return problem(W)

    with caplog.at_level(logging.WARNING):
        result = calibrate(
            scalar_only,
            problem.bounds,
            ["a", "b"],
            _loop_settings(max_evaluations=40, initial_design_size=12, check_points=2),
            progress=False,
        )
    assert result.local_search is None
    assert "exposes no spectra" in caplog.text


class WavySpectra:
    """1-D: h_b(w) = sin(f_b w), several local maxima of log L; truth 3.0, noise 0.05."""

    def __init__(self) -> None:
        self.f = np.linspace(0.5, 2.0, 20)
        self.sigma = 0.05
        rng = np.random.default_rng(6)
        self.y = self.h(np.array([[3.0]]))[0] + self.sigma * rng.normal(size=(1, 1, 20))

    def h(self, W: np.ndarray) -> np.ndarray:
        return np.sin(np.atleast_2d(W)[:, :1] * self.f[None, :])[:, None, None, :]

    def spectra(self, W: np.ndarray) -> np.ndarray:
        return self.h(W)

    def log_likelihood_of(self, H: np.ndarray, exact: bool = False) -> np.ndarray:
        r = (self.y[None] - np.asarray(H)).reshape(len(H), -1) / self.sigma
        return -0.5 * np.sum(r * r, axis=1)

    def __call__(self, W: np.ndarray) -> np.ndarray:
        return self.log_likelihood_of(self.spectra(W))


def test_a_local_maximum_is_not_trusted_when_the_expected_log_l_says_so() -> None:
    """The design only sees [7, 10]: the local phase climbs a wrong hill, the interval
    misses the truth, and the verdict says ``below_expected_fit`` (best log L far below
    the log L expected at the truth, −n/2 ± √(n/2) for this Gaussian B; its message names
    the local optimum as one of the two causes). Without the early stop's audit: with it
    the search looks at the rest of C_w and climbs the right hill (below). The budget is 44
    since session 31: the wrong hill's posterior reaches past the local phase's box, which
    the refinement now grows once (its draws' tail at the face), and at 40 that batch left
    nothing for the audit (``not_trusted``, ``below_expected_fit``, never trusted)."""
    problem = WavySpectra()
    bounds = np.array([[0.0], [10.0]])
    n = problem.f.size
    settings = _loop_settings(
        max_evaluations=44,
        initial_design_size=6,
        max_ego_fraction=0.0,
        check_points=4,
        allow_small_budget=True,
    )
    arguments = dict(
        progress=False,
        design=np.linspace(7.0, 10.0, 6)[:, None],
        expected_at_truth=(-0.5 * n, (n / 2) ** 0.5),
    )
    audited = calibrate(problem, bounds, ["w"], settings, **arguments)  # type: ignore[arg-type]
    assert "explore" in [h.phase for h in audited.history]
    lo, hi = audited.summary.interval95[0]
    assert lo <= 3.0 <= hi  # the audit found the hill the design never saw
    # the local phase's record describes the first hill: result.json says it was superseded
    assert audited.local_search is not None and audited.local_search_superseded
    assert audited.local_search_dict()["superseded_by_audit"] is True
    result = calibrate(
        problem,
        bounds,
        ["w"],
        replace(settings, audit_share=0.0),
        **arguments,  # type: ignore[arg-type]
    )
    assert result.local_search is not None and not result.local_search_superseded
    assert "superseded_by_audit" not in result.local_search_dict()
    lo, hi = result.summary.interval95[0]
    assert not lo <= 3.0 <= hi  # a confident wrong answer...
    rel = result.reliability
    assert rel is not None and rel.verdict == "not_trusted"  # ...that says it is not trusted
    assert "below_expected_fit" in rel.codes
    assert "local optimum" in rel.sentence
