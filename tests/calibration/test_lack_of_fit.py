"""Lack of fit from replicate runs: exact answers on Gaussian residuals, the rule's limit."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from susp_bo.calibration.lack_of_fit import (
    LIMIT,
    lack_of_fit_ratio,
    projected_lack_of_fit_ratio,
    pure_error_weights,
    systematic_misfit,
    with_lack_of_fit,
)
from susp_bo.calibration.likelihood import log_likelihood
from susp_bo.calibration.loop import calibrate
from susp_bo.discrepancy.problem import DiagnosisProblem, LinearSimulator
from susp_bo.discrepancy.scenarios import WORN_TRUTH, scenario_spec, synthesize_problem
from tests.calibration.conftest import Q1_SETTINGS


@pytest.mark.parametrize("runs", [2, 3, 6])
def test_independent_residuals_give_about_one(runs: int) -> None:
    """Residuals independent between runs (an exact model): mean F ≈ 1. Each bin weighed by
    its neighbours' scatter, F's sd over 400 seeds at P = 10 x 48 bins with a random scale
    per bin is 0.16 / 0.12 / 0.10 at ν = 2 / 3 / 6 (mean 1.006 / 0.999 / 0.991, extremes
    0.645–1.535; with the bin's own scatter in its weight the mean was 1.29 at ν = 2), so
    these 4 seeds stay within 0.6–1.6; equal weights stay within ±0.35 (sd below 0.1)."""
    for seed in range(4):
        rng = np.random.default_rng([seed, runs])
        y = rng.normal(size=(runs, 10, 48))
        h = 0.3 * rng.normal(size=(runs, 10, 48))
        scale = rng.uniform(0.01, 1.0, size=(1, 10, 48))  # heteroscedastic bins
        ratio = lack_of_fit_ratio(h + scale * y, h)
        assert 0.6 < ratio < 1.6, (seed, ratio)
        plain = lack_of_fit_ratio(h + scale * y, h, np.ones((10, 48)))
        assert 0.65 < plain < 1.35, (seed, plain)


def test_a_residual_every_run_shares_is_found_and_scales_as_expected() -> None:
    """A common offset d on top of unit noise: E[F] ≈ 1 + ν d² (the lack-of-fit mean square
    ν d² + 1 over the pure error 1); d = 0.5 with ν = 3 gives ≈ 1.75, d = 1.5 ≈ 7.75."""
    rng = np.random.default_rng(7)
    noise = rng.normal(size=(3, 10, 48))
    for d, expected in ((0.5, 1.75), (1.5, 7.75)):
        assert lack_of_fit_ratio(noise + d, np.zeros_like(noise)) == pytest.approx(
            expected, rel=0.15
        )


def test_a_shared_offset_in_a_quiet_band_is_found() -> None:
    """Session 26's review: a shared offset of 3 pure-error sd in the quietest quarter of
    the bins (a contiguous band, 100x less scatter than the rest) left the equal-weight F
    at about 1; each bin weighed by its band's own scatter, E[F] ≈ (¼ (1 + 3·9) + ¾) / 1 ≈
    7.75 (less near the band's edges, where the pooling window mixes in loud bins)."""
    rng = np.random.default_rng(11)
    runs, channels, bins = 3, 10, 96
    scale = np.ones((1, channels, bins))
    scale[..., : bins // 4] = 0.1
    residual = scale * rng.normal(size=(runs, channels, bins))
    residual[..., : bins // 4] += 3 * 0.1
    measured = residual  # against a simulation of zeros
    plain = lack_of_fit_ratio(measured, np.zeros_like(measured), np.ones((channels, bins)))
    weighted = lack_of_fit_ratio(measured, np.zeros_like(measured))
    assert plain < 1.5
    assert weighted > 1.5 * LIMIT  # 5.8 here
    # without the offset both are about 1
    quiet = scale * rng.normal(size=(runs, channels, bins))
    assert 0.7 < lack_of_fit_ratio(quiet, np.zeros_like(quiet)) < 1.3
    weights = pure_error_weights(quiet, np.zeros_like(quiet))
    assert weights.shape == (channels, bins)
    assert np.median(weights[:, : bins // 8]) > 50 * np.median(weights[:, bins // 2 :])


def test_a_bins_weight_knows_nothing_of_its_own_residuals() -> None:
    """Pooled with the bin itself, a weight favours bins whose scatter came out small by
    chance and F is biased up (mean 1.29 at ν = 2): the bin is left out of its own weight,
    so changing its residuals leaves its weight as it was and changes its neighbours'."""
    rng = np.random.default_rng(5)
    measured = rng.normal(size=(2, 3, 40))
    before = pure_error_weights(measured, np.zeros_like(measured))
    measured[0, 1, 20] += 5.0
    after = pure_error_weights(measured, np.zeros_like(measured))
    assert after[1, 20] == before[1, 20]
    changed = np.flatnonzero(after[1] != before[1])
    assert set(changed) == set(range(12, 29)) - {20}  # the 8 bins on either side
    assert np.array_equal(after[[0, 2]], before[[0, 2]])  # other channels untouched


def test_a_channel_that_does_not_scatter_keeps_the_rule_on() -> None:
    """Second review, session 27: one channel whose runs agree exactly (weights 1/0) made F
    of the whole result NaN. Its weights are now held at the floor, and F stays finite."""
    rng = np.random.default_rng(2)
    measured = rng.normal(size=(3, 4, 30))
    measured[:, 2, :] = 0.3  # every run the same in channel 2
    weights = pure_error_weights(measured, np.zeros_like(measured))
    assert np.all(np.isfinite(weights))
    ratio = lack_of_fit_ratio(measured, np.zeros_like(measured))
    assert math.isfinite(ratio) and ratio > LIMIT  # the shared 0.3 counts, at the floor


def test_one_run_no_scatter_or_failed_spectra_give_nan_and_bad_shapes_are_refused() -> None:
    y = np.ones((1, 2, 5))
    assert math.isnan(lack_of_fit_ratio(y, y))
    assert math.isnan(lack_of_fit_ratio(np.ones((3, 2, 5)), np.zeros((3, 2, 5))))
    h = np.zeros((3, 2, 5))
    h[1, 0, 0] = np.nan
    assert math.isnan(lack_of_fit_ratio(np.ones((3, 2, 5)), h))
    with pytest.raises(ValueError, match="measured, simulated: shapes"):
        lack_of_fit_ratio(np.ones((3, 2, 5)), np.ones((3, 2, 4)))


def test_the_rule_fires_above_the_limit_only() -> None:
    assert systematic_misfit(LIMIT, 3) is None
    assert systematic_misfit(math.nan, 3) is None
    reason = systematic_misfit(23.5, 3)
    assert reason is not None and reason["code"] == "below_expected_fit"
    assert reason["lack_of_fit_ratio"] == 23.5
    assert "F = 23.5" in reason["message"] and "3 runs" in reason["message"]


class _DamperEvaluator:
    """The yaw damper's log L under the unpaired B on a problem's own tracks, with the
    spectra a study's evaluator exposes (the linearised rig, no store)."""

    def __init__(self, problem: DiagnosisProblem) -> None:
        self.problem, self.measured = problem, problem.measured
        # the model: the other dampers at their true (worn) values, the rest the base rig's
        others = {k: v for k, v in WORN_TRUTH.items() if k != _DAMPER}
        self.spec = problem.spec.with_parameters(others)

    def spectra(self, W: np.ndarray) -> np.ndarray:
        simulator = LinearSimulator()
        return np.stack([self.problem.simulate(simulator, self.spec, [_DAMPER], w) for w in W])

    def __call__(self, W: np.ndarray) -> np.ndarray:
        return np.array(
            [log_likelihood(self.measured, h, self.problem.error) for h in self.spectra(W)]
        )


_DAMPER = "yaw_damper_damping"


class _FailingAfterTheBestPoint(_DamperEvaluator):
    """The same simulator, whose runs fail (NaN spectra) after the first call."""

    def __init__(self, problem: DiagnosisProblem) -> None:
        super().__init__(problem)
        self.calls = 0

    def spectra(self, W: np.ndarray) -> np.ndarray:
        self.calls += 1
        out = super().spectra(W)
        return out if self.calls == 1 else np.full_like(out, np.nan)


@pytest.mark.parametrize(("conicity", "fires"), [(None, False), (0.15, True)])
def test_a_calibration_of_data_from_another_vehicle_is_refused(
    conicity: float | None, fires: bool
) -> None:
    """Session 26's probe, reduced to the yaw damper (q = 1): data from a vehicle whose
    equivalent conicity is 0.15, the model's 0.10, under the unpaired B (whose scale hides
    the misfit from the log-L rule). The lack of fit is found (F ≈ 20 against ≈ 1 for data
    from the model itself) and the verdict says the model misses something; on the model's
    own data the verdict is left as it was."""
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    truth = dict(WORN_TRUTH) | (
        {} if conicity is None else {"contact_equivalent_conicity": conicity}
    )
    problem = synthesize_problem(spec, None, truth=truth, nu=3, seed=0, noise_m_s2=0.01)
    bounds = np.asarray(spec.calibration_bounds)[:, [spec.calibration_names.index(_DAMPER)]]
    settings = Q1_SETTINGS
    evaluator = _DamperEvaluator(problem)
    result = calibrate(evaluator, bounds, [_DAMPER], settings, progress=False, lack_of_fit=False)
    checked = with_lack_of_fit(result, evaluator, problem.measured)
    # calibrate applies the rule itself by default: the same verdict and evidence (to the
    # last bits: calibrate runs BLAS on one thread, this test's own call on the default)
    applied = calibrate(evaluator, bounds, [_DAMPER], settings, progress=False).reliability
    assert applied.codes == checked.reliability.codes
    assert applied.evidence.keys() == checked.reliability.evidence.keys()
    for key in ("lack_of_fit_ratio", "lack_of_fit_after_steps"):
        if key in applied.evidence:
            assert applied.evidence[key] == pytest.approx(checked.reliability.evidence[key], 1e-9)
    evidence = checked.reliability.evidence
    assert result.reliability.trusted  # before: trusted, whatever the vehicle
    lower, upper = result.summary.interval95[0]
    if fires:  # the probe's defect: the yaw damper 58 % low, trusted
        assert not lower <= WORN_TRUTH[_DAMPER] <= upper
        assert evidence["lack_of_fit_after_steps"] > 3 * LIMIT
        assert checked.reliability.codes == ("below_expected_fit",)
        assert "share a systematic part" in checked.reliability.reasons[0]["message"]
        assert checked.reliability.sentence.startswith("Not trusted: the 3 runs' residuals")
        # a simulation that fails during the Gauss–Newton steps cannot clear the alarm
        # (second review: it kept this result trusted)
        failing = _FailingAfterTheBestPoint(problem)
        again = with_lack_of_fit(result, failing, problem.measured)
        assert again.reliability.codes == ("below_expected_fit",)
        assert again.reliability.evidence["lack_of_fit_after_steps"] > LIMIT
        # a result another rule refused keeps its reasons; F is recorded
        refused = dataclasses.replace(
            result,
            reliability=dataclasses.replace(
                result.reliability,
                verdict="not_trusted",
                reasons=({"code": "poor_mixing", "message": "test"},),
            ),
        )
        kept = with_lack_of_fit(refused, evaluator, problem.measured).reliability
        assert kept.codes == ("poor_mixing",) and kept.evidence["lack_of_fit_ratio"] > LIMIT
        return
    assert lower <= WORN_TRUTH[_DAMPER] <= upper
    assert evidence["lack_of_fit_ratio"] < LIMIT / 2
    assert "lack_of_fit_after_steps" not in evidence
    assert (
        checked.reliability.trusted and checked.reliability.sentence == result.reliability.sentence
    )
    # where F cannot be computed the trusted sentence says the check was not made
    # (session 32): one measured run (and then no simulation), spectra that fail
    caveat = "the lack of fit between measured runs could not be checked"
    assert caveat not in checked.reliability.sentence
    failing = _FailingAfterTheBestPoint(problem)
    failing.calls = 1  # every call fails
    for unchecked in (
        with_lack_of_fit(result, failing, problem.measured[:1]),
        with_lack_of_fit(result, failing, problem.measured),
    ):
        assert unchecked.reliability.trusted
        assert unchecked.reliability.evidence["lack_of_fit_ratio"] is None
        assert caveat in unchecked.reliability.sentence
        assert unchecked.reliability.sentence.startswith(result.reliability.sentence[:-1])
    assert failing.calls == 2  # one simulation: the run with two or more runs
    # a best point 30 % off the truth leaves the damper's own signature (F ≈ 8): the
    # Gauss–Newton steps from it find the fit's optimum, and the verdict stays
    short = dataclasses.replace(result, X=np.array([[1.3 * WORN_TRUTH[_DAMPER]]]), y=np.zeros(1))
    stepped = with_lack_of_fit(short, evaluator, problem.measured)
    assert stepped.reliability.evidence["lack_of_fit_ratio"] > 2 * LIMIT
    assert stepped.reliability.evidence["lack_of_fit_after_steps"] < LIMIT / 2
    assert stepped.reliability.trusted


class _OneRun(_DamperEvaluator):
    """The same damper measured in one run only (the paired setting allows it): the
    unpaired B of the three runs, the first run's spectra and log L."""

    def __init__(self, problem: DiagnosisProblem) -> None:
        super().__init__(problem)
        self.measured = problem.measured[:1]

    def spectra(self, W: np.ndarray) -> np.ndarray:
        return super().spectra(W)[:, :1]


def test_a_calibration_on_one_run_says_its_lack_of_fit_was_not_checked() -> None:
    """Session 32: with one measured run the lack of fit cannot be computed, and a trusted
    result said nothing of it — a model error that B's scale hides went unlooked-for in
    silence. ``calibrate`` now records F as null and the trusted sentence says so."""
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    problem = synthesize_problem(spec, None, truth=dict(WORN_TRUTH), nu=3, seed=0, noise_m_s2=0.01)
    bounds = np.asarray(spec.calibration_bounds)[:, [spec.calibration_names.index(_DAMPER)]]
    settings = dataclasses.replace(Q1_SETTINGS, max_evaluations=24)
    result = calibrate(_OneRun(problem), bounds, [_DAMPER], settings, progress=False)
    reliability = result.reliability
    assert reliability is not None and reliability.evidence["lack_of_fit_ratio"] is None
    assert reliability.trusted, reliability.sentence
    assert "lack of fit between measured runs could not be checked" in reliability.sentence
    assert reliability.sentence.endswith("neither seen nor ruled out.")


def test_the_linear_step_removes_the_parameters_signature_only() -> None:
    """The yaw damper 10 % off its true value: on the model's own data the linear step from
    a 1 % difference takes F from ≈ 1.9 to ≈ 0.9; on data from a vehicle with conicity 0.15
    it leaves F ≈ 5 (the damper mimics part of the conicity's effect, not all of it)."""
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    truth = WORN_TRUTH[_DAMPER]
    for conicity, low, high in ((None, 0.0, 1.2), (0.15, LIMIT, math.inf)):
        changed = {} if conicity is None else {"contact_equivalent_conicity": conicity}
        problem = synthesize_problem(
            spec, None, truth=dict(WORN_TRUTH) | changed, nu=3, seed=1, noise_m_s2=0.01
        )
        h = _DamperEvaluator(problem).spectra(np.array([[1.1 * truth], [1.11 * truth]]))
        plain = lack_of_fit_ratio(problem.measured, h[0])
        stepped = projected_lack_of_fit_ratio(
            problem.measured, h[0], ((h[1] - h[0]) / (0.01 * truth))[None]
        )
        assert plain > 1.5, conicity
        assert low < stepped < high, (conicity, plain, stepped)
