"""The summary likelihood's goodness of fit, against exact answers on a linear-Gaussian toy.

A run's spectrum y = m0 + G w + e, e ~ N(0, Σ) with shared "track" factors across every
channel and band (the toy of ``test_track_statistics``): the test's T² must follow
Hotelling's distribution for data from the model wherever the parameters were fitted, must
not move when the data move as a parameter does, and must find an effect the parameters
cannot reproduce — which the summary log L itself cannot see.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from susp_bo.calibration.fit_rules import summary_misfit_reason
from susp_bo.calibration.summary_misfit import (
    BAND_GROUPS,
    P_LIMIT,
    SummaryMisfitTest,
    band_group_directions,
    group_labels,
    summary_misfit,
    summary_misfit_test,
    summary_residuals_z,
)
from susp_bo.calibration.track_statistics import (
    track_statistics_error,
    track_statistics_log_likelihood,
)
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


def _test(rng, m0, g, chol, count=M):
    pilot = toy_runs(rng, m0, g, chol, np.zeros(Q), count)
    test = summary_misfit_test(pilot, g.T.reshape(Q, C, F), NU, MU)
    assert test is not None
    return test


def test_band_groups_split_each_channel_into_contiguous_groups():
    g = band_group_directions(2, 7, 3).reshape(2, 7, 2, 3)
    assert g.sum(axis=(0, 1)).tolist() == [[2, 3, 2], [2, 3, 2]]  # sizes differ by <= 1
    assert np.all(g.sum(axis=(2, 3)) == 1)  # every band in exactly one group
    assert np.all(g[0, :, 1, :] == 0)  # a channel's groups hold its own bands only


def test_t2_follows_hotellings_distribution_for_data_from_the_model():
    """600 data sets, each with its own pilot, truth and fitted point anywhere (the test is
    blind to the parameters): the p-values are uniform. Taking C_B as known (χ²_k instead
    of Hotelling) or forgetting the simulated tracks' share of κ would not be."""
    m0, g, chol = toy()
    rng = np.random.default_rng(7)
    p_values, chi2_p, no_mu_p = [], [], []
    for _ in range(600):
        test = _test(rng, m0, g, chol)
        truth, fitted = rng.uniform(-1, 1, Q), rng.uniform(-3, 3, Q)
        measured = toy_runs(rng, m0, g, chol, truth, NU)
        simulated = toy_runs(rng, m0, g, chol, fitted, MU)
        t2, p = summary_misfit(measured, simulated, test)
        p_values.append(p)
        chi2_p.append(stats.chi2.sf(t2, test.dof))
        no_mu_p.append(stats.chi2.sf(t2 * test.scale * NU, test.dof))
    assert test.dof == C * BAND_GROUPS
    assert stats.kstest(p_values, "uniform").pvalue > 0.05  # seeded: 0.29
    assert 0.03 < np.mean(np.array(p_values) < 0.05) < 0.07
    assert np.mean(np.array(chi2_p) < 0.05) > 0.065  # the naive χ² over-rejects (seeded 0.073)
    assert stats.kstest(no_mu_p, "uniform").pvalue < 1e-6


def test_data_that_move_as_a_parameter_does_leave_t2_unchanged():
    """B is orthogonal to the Jacobian: what any change of w does to the spectra, the
    test does not see (that part belongs to the summary log L)."""
    m0, g, chol = toy()
    rng = np.random.default_rng(3)
    test = _test(rng, m0, g, chol)
    measured = toy_runs(rng, m0, g, chol, np.zeros(Q), NU)
    simulated = toy_runs(rng, m0, g, chol, np.zeros(Q), MU)
    shift = (g @ np.array([40.0, -25.0])).reshape(C, F)  # far beyond the posterior
    base = summary_misfit(measured, simulated, test)
    moved = summary_misfit(measured + shift, simulated, test)
    assert moved == pytest.approx(base, rel=1e-8)


def test_an_effect_the_parameters_cannot_reproduce_is_found_where_log_l_sees_nothing():
    """A rise of the last channel's highest bands (a mode the model lacks), 2 track sd
    per bin: at the summaries' exact fit log L is as high as at the truth for data from the
    model (it has no goodness-of-fit power: q summaries, q parameters), while p falls far
    below the limit; the same data without the effect pass."""
    m0, g, chol = toy()
    effect = effect_of_a_missing_mode(chol)
    rng = np.random.default_rng(11)
    error = track_statistics_error(
        toy_runs(rng, m0, g, chol, np.zeros(Q), M), g.T.reshape(Q, C, F), NU, MU
    )
    assert error.misfit is not None  # the error carries its test
    truth = np.array([0.3, -0.2])
    tracks = rng.standard_normal((MU, C * F)) @ chol.T  # the model's μ track realizations
    a = error.weights.reshape(-1, Q)
    for with_effect, fails in ((False, False), (True, True)):
        measured = toy_runs(rng, m0, g, chol, truth, NU, effect.ravel() if with_effect else None)
        # the exact fit of the q summaries: Aᵀ (ȳ − m0 − ē − G w) = 0
        residual = measured.mean(axis=0).ravel() - m0 - tracks.mean(axis=0)
        w = np.linalg.solve(a.T @ g, a.T @ residual)
        simulated = (m0 + g @ w + tracks).reshape(MU, C, F)
        log_l = track_statistics_log_likelihood(measured, simulated, error)
        maximum = -0.5 * (error.log_det + Q * math.log(2 * math.pi))
        assert log_l == pytest.approx(maximum, abs=1e-9)  # d = 0: log L cannot tell
        t2, p = summary_misfit(measured, simulated, error.misfit)
        assert (p < P_LIMIT) is fails, (t2, p)
        reason = summary_misfit_reason(t2, p, error.misfit.dof)
        assert (reason is not None) is fails
    assert reason["code"] == "below_expected_fit" and reason["summary_misfit_p"] == p
    assert f"p = {p:.1e}" in reason["message"]


def test_fewer_groups_when_the_pilot_is_small_and_none_when_too_small():
    m0, g, chol = toy()
    rng = np.random.default_rng(5)
    jac = g.T.reshape(Q, C, F)
    sizes = {}
    for count in (100, 19, 13, 6):
        test = summary_misfit_test(toy_runs(rng, m0, g, chol, np.zeros(Q), count), jac, NU, MU)
        sizes[count] = None if test is None else test.dof
    # k = C x groups must stay <= (M − 1) // 2: 3 groups (9), then 3 (9), 2 (6), none
    assert sizes == {100: 9, 19: 9, 13: 6, 6: None}


def test_bad_tests_and_shapes_are_refused_naming_the_field():
    m0, g, chol = toy()
    test = _test(np.random.default_rng(1), m0, g, chol)
    with pytest.raises(ValueError, match="covariance: not positive definite"):
        SummaryMisfitTest(test.directions, -test.covariance, M, NU, MU)
    with pytest.raises(ValueError, match="runs: 10; expected more than k"):
        SummaryMisfitTest(test.directions, test.covariance, 10, NU, MU)
    with pytest.raises(ValueError, match="n_measured"):
        SummaryMisfitTest(test.directions, test.covariance, M, 0, MU)
    with pytest.raises(ValueError, match="measured: shape"):
        summary_misfit(np.zeros((2, C, F)), np.zeros((MU, C, F)), test)
    nan = np.full((NU, C, F), np.nan)
    assert all(math.isnan(v) for v in summary_misfit(nan, np.zeros((MU, C, F)), test))
    assert summary_misfit_reason(math.nan, math.nan, test.dof) is None


def test_summaries_are_named_and_the_worst_is_where_the_effect_is():
    """Each summary has a name (by index, or by the rig's channels and band centres), and
    the largest standardised residual points at the effect's channel and band group."""
    m0, g, chol = toy()
    rng = np.random.default_rng(13)
    test = _test(rng, m0, g, chol)
    assert [test.label(j) for j in (0, 2, 8)] == [
        "channel 0, bands 0–3",
        "channel 0, bands 8–11",
        "channel 2, bands 8–11",
    ]
    frequencies = np.linspace(1.0, 12.0, F)
    labels = group_labels(test, ("front", "rear", "bogie"), frequencies)
    assert labels[0] == "front 1–4 Hz" and labels[-1] == "bogie 9–12 Hz"
    named = dataclasses.replace(test, labels=labels)
    assert named.label(8) == "bogie 9–12 Hz"
    with pytest.raises(ValueError, match="labels: 2 labels for k = 9"):
        dataclasses.replace(test, labels=("a", "b"))
    with pytest.raises(ValueError, match="channels: 2, frequencies_hz: 12; expected 3 and 12"):
        group_labels(test, ("front", "rear"), frequencies)
    effect = effect_of_a_missing_mode(chol).ravel()
    measured = toy_runs(rng, m0, g, chol, np.zeros(Q), NU, effect)
    simulated = toy_runs(rng, m0, g, chol, np.zeros(Q), MU)
    z = summary_residuals_z(measured, simulated, test)
    assert int(np.argmax(np.abs(z))) == 8 and z[8] > 5  # the last channel's high bands
