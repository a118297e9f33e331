"""The pooled SBC rank test with within-experiment dependence, against exact answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special, stats

from susp_bo.calibration.rank_uniformity import _textbook_alarms, pooled_rank_ks

E, Q = 40, 7


def _equicorrelated(rho: float) -> np.ndarray:
    c = np.full((Q, Q), rho)
    np.fill_diagonal(c, 1.0)
    return np.broadcast_to(c, (E, Q, Q)).copy()


def test_independent_ranks_give_the_textbook_p_value_and_five_percent_false_alarms() -> None:
    u = np.random.default_rng(1).uniform(size=(E, Q))
    test = pooled_rank_ks(u, _equicorrelated(0.0), n_simulations=4000)
    assert test.p_independent == pytest.approx(stats.kstest(u.ravel(), "uniform").pvalue)
    # the simulated null of D is the textbook one: p agrees within Monte Carlo error
    assert abs(test.p_dependent - test.p_independent) < 4 * 0.5 / np.sqrt(4000)
    assert 0.04 < test.false_alarm_rate < 0.06  # binomial sd 0.0034 around 0.05


def test_correlated_calibrated_ranks_are_not_rejected_but_the_textbook_test_would_be() -> None:
    """Exactly calibrated ranks, strongly correlated within experiments (ρ = 0.8).

    Over 200 such SBC runs the textbook p falls below 0.05 far more than 5 % of the time,
    the dependence-aware p in about 5 % of them (a valid test).
    """
    corr = _equicorrelated(0.8)
    root = np.linalg.cholesky(corr[0])
    rng = np.random.default_rng(7)
    textbook, dependent = [], []
    for _ in range(200):
        u = special.ndtr(rng.standard_normal((E, Q)) @ root.T)
        test = pooled_rank_ks(u, corr, n_simulations=500, seed=3)
        textbook.append(test.p_independent < 0.05)
        dependent.append(test.p_dependent < 0.05)
    assert np.mean(textbook) > 0.3
    assert np.mean(dependent) < 0.1  # 5 % expected; binomial sd 0.015
    assert test.false_alarm_rate > 0.3


def test_overconfident_posteriors_are_rejected_with_the_dependence() -> None:
    """Errors 2x what the posterior says (overconfidence), ρ = 0.3: rejected (measured p
    0.0005, the smallest 2000 simulations can give; at 1.5x and ρ = 0.5 KS has little power
    with 40 experiments: p ≈ 0.08)."""
    corr = _equicorrelated(0.3)
    root = np.linalg.cholesky(corr[0])
    z = 2.0 * np.random.default_rng(11).standard_normal((E, Q)) @ root.T
    test = pooled_rank_ks(special.ndtr(z), corr, n_simulations=2000)
    assert test.p_dependent < 0.01


def test_bad_input_is_refused_by_name() -> None:
    u = np.full((E, Q), 0.5)
    with pytest.raises(ValueError, match="quantiles"):
        pooled_rank_ks(u + 1.0, _equicorrelated(0.0))
    with pytest.raises(ValueError, match="correlations"):
        pooled_rank_ks(u, _equicorrelated(0.0)[:, :3, :3])
    with pytest.raises(ValueError, match="correlations"):
        pooled_rank_ks(u, 2.0 * _equicorrelated(0.0))
    with pytest.raises(ValueError, match="semi-definite"):
        pooled_rank_ks(u, _equicorrelated(-0.9))
    with pytest.raises(ValueError, match="n_simulations"):
        pooled_rank_ks(u, _equicorrelated(0.0), n_simulations=10)


@pytest.mark.parametrize("n", [1, 14, 280, 1000])
@pytest.mark.parametrize("alpha", [0.01, 0.05, 0.5])
def test_the_false_alarm_count_is_the_count_of_textbook_p_values_below_alpha(
    n: int, alpha: float
) -> None:
    """The count from the critical value equals evaluating every p-value, also for
    statistics within rounding of the critical value."""
    critical = stats.kstwo.isf(alpha, n)
    rng = np.random.default_rng(n)
    d = np.concatenate(
        [
            rng.uniform(0.0, 1.0, 500),
            critical + rng.uniform(-1e-5, 1e-5, 500),
            critical + np.array([-1e-9, 0.0, 1e-9]),
        ]
    ).clip(0.0, 1.0)
    brute = int(np.count_nonzero(stats.kstwo.sf(d, n) < alpha))
    assert 0 < brute < d.size
    assert _textbook_alarms(d, n, alpha) == brute
