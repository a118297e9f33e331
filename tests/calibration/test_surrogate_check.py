"""The held-out surrogate check: edge points, verdicts against known truths, loop wiring."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.sampling import sample_surrogate_posterior, surrogate_log_likelihood
from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.surrogate_check import SurrogateCheck, edge_points
from susp_bo.calibration.surrogate_fit import fit_surrogate
from susp_bo.calibration.test_functions import TARGETS


def test_edge_points_sit_at_the_interval_ends_of_the_principal_directions() -> None:
    gen = torch.Generator().manual_seed(0)
    sd = torch.tensor([0.10, 0.02], dtype=torch.float64)  # widest direction first: axis 0
    draws = 0.5 + sd * torch.randn((40_000, 2), generator=gen, dtype=torch.float64)
    logd = -0.5 * (((draws - 0.5) / sd) ** 2).sum(1)
    pts = edge_points(draws, logd, 4)
    assert pts.shape == (4, 2)
    assert len({tuple(p.tolist()) for p in pts}) == 4
    z = 1.959964
    np.testing.assert_allclose(
        np.sort(pts[:2, 0].numpy()), [0.5 - z * 0.10, 0.5 + z * 0.10], atol=0.008
    )
    np.testing.assert_allclose(
        np.sort(pts[2:, 1].numpy()), [0.5 - z * 0.02, 0.5 + z * 0.02], atol=0.002
    )
    # among the draws near each quantile the ridge point (highest density) is chosen
    assert torch.all(pts[:2, 1].sub(0.5).abs() < 0.005)
    assert edge_points(draws, logd, 3).shape == (3, 2)
    with pytest.raises(ValueError, match="n: 0"):
        edge_points(draws, logd, 0)


def _bowl(sd: float) -> callable:
    return lambda u: -0.5 * np.sum(((u - 0.5) / sd) ** 2, axis=1)


@pytest.mark.parametrize(
    ("true_sd", "verdict"),
    [(0.10, "ok"), (0.16, "overconfident"), (0.06, "underconfident")],
)
def test_verdict_against_a_known_truth(true_sd: float, verdict: str) -> None:
    """A surrogate of a bowl of sd 0.1, checked against a wider, equal or narrower truth."""
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, 1.0, (60, 2))
    surrogate = fit_surrogate(x, _bowl(0.10)(x), SurrogateSettings(), seed=0)
    draws, _ = sample_surrogate_posterior(
        surrogate, n_chains=32, warmup_steps=300, num_samples=200, seed=1
    )
    post = draws.reshape(-1, 2)
    u = edge_points(post, surrogate_log_likelihood(surrogate)(post), 4)
    mean, sd = surrogate.log_likelihood_uncertainty(u)
    check = SurrogateCheck(u.numpy(), mean.numpy(), sd.numpy(), _bowl(true_sd)(u.numpy()), 1.0)
    assert check.verdict == verdict, check.errors
    if verdict == "ok":
        assert check.max_abs_error < 0.3


def test_failed_runs_are_ignored_by_the_verdict() -> None:
    check = SurrogateCheck(
        np.zeros((3, 1)),
        np.zeros(3),
        np.ones(3),
        np.array([math.nan, 0.5, -0.2]),
        tolerance_nats=1.0,
    )
    assert check.verdict == "ok" and check.max_abs_error == pytest.approx(0.5)
    # one point above and one below the band: both directions, not the sign of the largest
    check = SurrogateCheck(np.zeros((2, 1)), np.zeros(2), np.zeros(2), np.array([2.0, -3.0]), 1.0)
    assert check.verdict == "mixed" and check.outside.tolist() == [True, True]
    # errors within 3 GP sd (1 nat) and jointly plausible (Σ z² 6.25 < χ²_2 99 % 9.21): ok
    check = SurrogateCheck(np.zeros((2, 1)), np.zeros(2), np.ones(2), np.array([1.5, -2.0]), 1.0)
    assert check.verdict == "ok" and check.band.tolist() == [3.0, 3.0]
    # within 3 sd each, but jointly too large (Σ z² 12.4): the larger one is outside
    check = SurrogateCheck(np.zeros((2, 1)), np.zeros(2), np.ones(2), np.array([2.0, -2.9]), 1.0)
    assert check.joint_p_value < 0.01 and check.verdict == "underconfident"
    all_failed = SurrogateCheck(np.zeros((1, 1)), np.zeros(1), np.ones(1), np.full(1, math.nan), 1)
    assert all_failed.verdict == "ok" and math.isnan(all_failed.max_abs_error)


def _settings(**kw: object) -> CalibrationSettings:
    base = dict(
        max_evaluations=30,
        batch_size=4,
        mcmc_chains=8,
        mcmc_warmup=100,
        mcmc_samples=100,
        candidate_count=128,
        check_points=4,
    )
    base.update(kw)
    return CalibrationSettings(**base)  # type: ignore[arg-type]


def test_calibrate_spends_the_last_evaluations_on_the_check() -> None:
    target = TARGETS["banana_2d"]()
    seen: list[int] = []

    def evaluate(w: np.ndarray) -> np.ndarray:
        seen.append(w.shape[0])
        return target.log_likelihood(w)

    result = calibrate(evaluate, target.bounds, target.names, _settings(), progress=False)
    assert result.n_evaluations == 30 and seen[-1] == 4
    assert result.history[-1].phase == "check"
    check = result.check
    assert check is not None and check.points_unit.shape == (4, 2)
    np.testing.assert_allclose(check.observed, result.y[-4:])
    lo, hi = target.bounds
    np.testing.assert_allclose(lo + check.points_unit * (hi - lo), result.X[-4:])
    d = result.to_dict()["surrogate_check"]
    assert d["verdict"] == check.verdict and len(d["points"]) == 4
    # the check points are in the final surrogate's data
    assert result.surrogate.train_x.shape[0] == 30


def test_no_check_when_switched_off() -> None:
    target = TARGETS["banana_2d"]()
    result = calibrate(
        target, target.bounds, target.names, _settings(check_points=0), progress=False
    )
    assert result.check is None and result.to_dict()["surrogate_check"] is None
    assert all(h.phase != "check" for h in result.history)


def test_edge_points_are_distinct_when_draws_repeat_and_rounds_go_inward() -> None:
    """MH repeats a draw on every rejection; more points than 2 q take inner quantiles."""
    gen = torch.Generator().manual_seed(1)
    draws = (0.5 + 0.1 * torch.randn((5_000, 2), generator=gen, dtype=torch.float64)).repeat(3, 1)
    logd = -0.5 * (((draws - 0.5) / 0.1) ** 2).sum(1)
    pts = edge_points(draws, logd, 8)
    assert len({tuple(p.tolist()) for p in pts}) == 8
    radius = (pts - 0.5).norm(dim=1) / 0.1
    assert torch.all(radius[:4] > 1.7) and torch.all(radius[4:] < 1.3)  # 2.5 % ends, then ±1 sd


def _failed_check(observed: np.ndarray) -> SurrogateCheck:
    """Three of four points 7–9.5 nats below a confident prediction: "underconfident" (beyond
    GROSS_NATS it would be "misplaced")."""
    return SurrogateCheck(
        points_unit=np.full((4, 1), 0.5),
        predicted=np.zeros(4),
        predicted_sd=np.full(4, 0.2),
        observed=observed,
        tolerance_nats=1.0,
    )


def test_a_failed_check_on_a_noisy_log_l_says_noisy_not_a_direction() -> None:
    """With 2 nats of noise and a surrogate assuming none, the reported posterior was half
    as wide as the exact one and the check said "underconfident ... narrower" (outside
    probe, session 24): the worst points are evaluated again, and a repeat that moves
    makes the verdict "noisy", whose advice is to learn the noise."""
    from susp_bo.calibration.loop_step import repeated_check
    from susp_bo.calibration.reliability import surrogate_misfit
    from susp_bo.calibration.reliability_sentence import sentence

    first = np.array([-8.0, -9.5, -0.3, -7.0])
    points = np.array([[0.1], [0.2], [0.3], [0.4]])
    rng = np.random.default_rng(0)
    noisy = repeated_check(_failed_check(first), lambda w: rng.normal(-10, 2, len(w)), points)
    assert noisy.verdict == "noisy" and noisy.noisy
    assert abs(noisy.repeat_difference_nats) > 0.1
    assert "log L is noisy: evaluated again, a point moved by" in noisy.line()
    reason = surrogate_misfit(noisy)
    assert reason is not None and reason["direction"] == "noisy"
    assert "may be wider or narrower" in reason["message"]
    advice = sentence((reason,), {"budget": 200}, "python")
    assert advice.endswith('CalibrationSettings(surrogate=SurrogateSettings(noise="learned")).')
    leading = {"code": "not_converged", "message": "m"}  # more budget cannot beat noise
    led = sentence((leading, reason), {"budget": 200}, "python")
    assert led.startswith("Not trusted: m (also: surrogate_misfit); let the surrogate learn")

    values = {0.1: -8.0, 0.2: -9.5, 0.3: -0.3, 0.4: -7.0}  # a repeatable log L
    steady = repeated_check(
        _failed_check(first), lambda w: np.array([values[float(v)] for v in w[:, 0]]), points
    )
    assert steady.verdict == "underconfident" and steady.repeat_difference_nats == 0.0
    assert "repeat_difference_nats" in steady.to_dict(np.array([[0.0], [1.0]]))
    passed = _failed_check(np.array([-0.1, 0.2, -0.3, 0.1]))
    assert repeated_check(passed, lambda w: 1 / 0, points) is passed  # nothing evaluated


def test_noise_the_surrogate_models_is_not_called_noisy_and_a_failed_repeat_is() -> None:
    """With noise="learned" a repeat moves by about √2 σ: not news, so the check keeps its
    direction; a repeat that fails where the first run succeeded is not repeatable."""
    modelled = SurrogateCheck(
        points_unit=np.full((4, 1), 0.5),
        predicted=np.zeros(4),
        predicted_sd=np.full(4, 0.2),
        observed=np.array([-8.0, -9.5, -0.3, -7.0]),
        tolerance_nats=1.0,
        noise_sd=1.0,
        repeat_difference_nats=1.5,
    )
    assert not modelled.noisy and modelled.verdict == "underconfident"
    beyond = SurrogateCheck(**{**modelled.__dict__, "repeat_difference_nats": 5.0})
    assert beyond.noisy and beyond.verdict == "noisy"
    failed = SurrogateCheck(**{**modelled.__dict__, "repeat_difference_nats": math.inf})
    assert failed.noisy and "failed (or gave ±inf) where it had succeeded" in failed.line()
    assert failed.to_dict(np.array([[0.0], [1.0]]))["repeat_difference_nats"] is None


def test_a_repeat_that_fails_makes_the_check_noisy() -> None:
    from susp_bo.calibration.loop_step import repeated_check

    check = _failed_check(np.array([-8.0, -9.5, -0.3, -7.0]))
    points = np.array([[0.1], [0.2], [0.3], [0.4]])
    repeated = repeated_check(check, lambda w: np.full(len(w), np.nan), points)
    assert repeated.verdict == "noisy" and math.isinf(repeated.repeat_difference_nats)
