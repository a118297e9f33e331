"""The verdict's fit rules after the others: the summary likelihood's goodness of fit through
:func:`calibrate`, its advice, its caveat when it cannot be computed, and that it applies to
that model only."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from susp_bo.calibration.fit_rules import with_fit_rules, with_summary_misfit
from susp_bo.calibration.loop import calibrate
from susp_bo.calibration.reliability_sentence import advice_code, sentence
from susp_bo.calibration.summary_misfit import BAND_GROUPS, P_LIMIT
from susp_bo.calibration.track_statistics import (
    track_statistics_error,
    track_statistics_log_likelihood,
)
from tests.calibration.conftest import Q1_SETTINGS
from tests.calibration.summary_toy import (
    MU,
    NU,
    C,
    F,
    M,
    Q,
    effect_of_a_missing_mode,
    toy,
    toy_runs,
)


class _ToyEvaluator:
    """The summary log L of the toy over w in one coordinate (the other at its truth),
    with the spectra and measured runs a study's evaluator exposes."""

    def __init__(self, effect: np.ndarray | None) -> None:
        m0, g, chol = toy()
        rng = np.random.default_rng(21)
        self.m0, self.g = m0, g
        self.error = track_statistics_error(
            toy_runs(rng, m0, g, chol, np.zeros(Q), M), g.T.reshape(Q, C, F), NU, MU
        )
        self.tracks = rng.standard_normal((MU, C * F)) @ chol.T
        self.measured = toy_runs(rng, m0, g, chol, np.array([0.4, 0.0]), NU, effect)

    def spectra(self, W: np.ndarray) -> np.ndarray:
        w = np.column_stack([np.asarray(W)[:, 0], np.zeros(len(W))])
        return (self.m0 + w @ self.g.T)[:, None, :].reshape(len(W), 1, C, F) + self.tracks.reshape(
            1, MU, C, F
        )

    def __call__(self, W: np.ndarray) -> np.ndarray:
        return np.asarray(
            track_statistics_log_likelihood(self.measured, self.spectra(W), self.error)
        )


@pytest.mark.parametrize("with_effect", [False, True])
def test_the_loop_applies_the_test_and_refuses_a_model_that_misses_an_effect(
    with_effect,
):
    """Through :func:`calibrate` (q = 1): with the effect the verdict is ``not_trusted``
    (``below_expected_fit``) and its advice is the summary model's own (diagnose cannot
    name an effect without measured tracks); without, the evidence holds a p above the
    limit and the rule leaves the verdict alone."""
    effect = effect_of_a_missing_mode(toy()[2])
    evaluator = _ToyEvaluator(effect.ravel() if with_effect else None)
    bounds = np.array([[-2.0], [2.0]])
    result = calibrate(evaluator, bounds, ["w0"], Q1_SETTINGS, progress=False)
    evidence = result.reliability.evidence
    assert evidence["summary_misfit_dof"] == C * BAND_GROUPS
    if with_effect:
        assert evidence["summary_misfit_p"] < P_LIMIT
        assert result.reliability.codes == ("below_expected_fit",)
        reasons = result.reliability.reasons
        assert advice_code(reasons, evidence, "command_line") == "summary_misfit"
        words = sentence(reasons, evidence, "command_line")
        assert "channel and band-group summaries" in words and "paired" in words
        # where: the effect's channel and band group (the toy's summaries by index)
        assert evidence["summary_misfit_worst"]["summary"] == "channel 2, bands 8–11"
        assert evidence["summary_misfit_worst"]["z"] > 3
        assert "most in channel 2, bands 8–11, z = +" in words
    else:
        assert evidence["summary_misfit_p"] > P_LIMIT
        assert "below_expected_fit" not in result.reliability.codes
    # lack_of_fit=False is the verdict of the other rules alone: no test either
    plain = calibrate(evaluator, bounds, ["w0"], Q1_SETTINGS, progress=False, lack_of_fit=False)
    assert "summary_misfit_p" not in plain.reliability.evidence


@pytest.fixture(scope="module")
def model_data_result():
    """A q = 1 calibration of data from the model, verdict of the other rules alone."""
    evaluator = _ToyEvaluator(None)
    bounds = np.array([[-2.0], [2.0]])
    result = calibrate(evaluator, bounds, ["w0"], Q1_SETTINGS, progress=False, lack_of_fit=False)
    assert result.reliability.trusted
    return evaluator, result


def test_a_test_that_could_not_be_made_is_said_in_the_trusted_sentence(model_data_result):
    """No test (a pilot too small for one band group per channel) or failed spectra at the
    best point: the evidence says null, the verdict stays, and its sentence says what was
    not checked."""
    evaluator, result = model_data_result
    untested = with_summary_misfit(result, evaluator, evaluator.measured, None)
    evidence = untested.reliability.evidence
    assert evidence["summary_misfit_p"] is None and evidence["summary_misfit_dof"] is None
    assert untested.reliability.trusted
    assert "summaries the fit does not use could not be tested" in untested.reliability.sentence

    class _Failing(_ToyEvaluator):
        def spectra(self, W: np.ndarray) -> np.ndarray:
            return np.full_like(super().spectra(W), np.nan)

    failing = _Failing(None)
    failed = with_summary_misfit(result, failing, failing.measured, failing.error.misfit)
    assert failed.reliability.evidence["summary_misfit_dof"] == C * BAND_GROUPS
    assert failed.reliability.evidence["summary_misfit_p"] is None
    assert "could not be tested" in failed.reliability.sentence
    tested = with_summary_misfit(result, evaluator, evaluator.measured, evaluator.error.misfit)
    assert "could not be tested" not in tested.reliability.sentence


def test_the_fit_rules_test_the_summaries_under_the_summary_likelihood_only(model_data_result):
    """The same evaluator and result: with the summary likelihood both rules leave their
    evidence; with another error model (here its plan, whose pilot has not run, and an
    object without a test) only the lack of fit does."""
    evaluator, result = model_data_result
    both = with_fit_rules(result, evaluator, evaluator.measured).reliability.evidence
    assert {"lack_of_fit_ratio", "summary_misfit_p"} <= both.keys()

    class _Other(_ToyEvaluator):
        def __init__(self) -> None:
            super().__init__(None)
            self.error = dataclasses.replace(self.error, misfit=None)
            object.__setattr__(self.error, "model", "paired")  # not the summary model

    other = _Other()
    evidence = with_fit_rules(result, other, other.measured).reliability.evidence
    assert "lack_of_fit_ratio" in evidence and "summary_misfit_p" not in evidence


def test_the_summary_models_refusals_advise_what_can_be_done_without_measured_tracks():
    """Under the summary likelihood (its fit rules ran: ``summary_misfit_dof`` in the
    evidence) ``susp-bo diagnose`` cannot examine the result: a model error (this test's or
    the lack of fit's) gets the advice to measure the tracks or add the effect; log L below
    what the model expects (a search short of the optimum, this model cannot fit worse)
    gets more budget. Other models keep diagnose's advice."""
    statistics = {"summary_misfit_dof": 30, "budget": 200}
    log_l = {"code": "below_expected_fit", "message": "m", "best_log_likelihood": -10.0}
    lack = {"code": "below_expected_fit", "message": "m", "lack_of_fit_ratio": 5.0}
    test = {"code": "below_expected_fit", "message": "m", "summary_misfit_p": 1e-6}
    assert advice_code([test], statistics, "command_line") == "summary_misfit"
    assert advice_code([lack], statistics, "command_line") == "summary_misfit"
    assert advice_code([log_l], statistics, "command_line") == "not_converged"
    assert "--resume --budget 400" in sentence([log_l], statistics, "command_line")
    for reason in (log_l, lack):
        assert advice_code([reason], {"budget": 200}, "command_line") == "below_expected_fit"
        assert "susp-bo diagnose" in sentence([reason], {"budget": 200}, "command_line")
