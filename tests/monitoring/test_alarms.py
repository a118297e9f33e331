"""P(outside) against exact answers, the trust contract and the alarm rule."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import norm

from susp_bo.monitoring.alarms import (
    NO_VERDICT,
    CampaignRecord,
    apply_alarms,
    attention_table,
    maintenance_table,
    p_outside,
    summarise_parameter,
    trust,
)

MU, SIGMA = 30.0e3, 1.5e3
BAND = (28.0e3, 56.0e3)
EXACT = norm.cdf(BAND[0], MU, SIGMA) + norm.sf(BAND[1], MU, SIGMA)


def test_p_outside_of_gaussian_quantile_draws_is_the_normal_cdf_within_one_over_n() -> None:
    n = 20_000
    draws = norm.ppf((np.arange(n) + 0.5) / n, MU, SIGMA)  # exact quantiles of N(MU, SIGMA²)
    assert abs(p_outside(draws, BAND) - EXACT) <= 1.0 / n
    assert abs(EXACT - 0.0912) < 1e-4  # Φ(-4/3): the case has a known answer


def test_p_outside_of_random_gaussian_draws_is_within_five_monte_carlo_errors() -> None:
    n = 200_000
    draws = np.random.default_rng(3).normal(MU, SIGMA, n)
    error = np.sqrt(EXACT * (1 - EXACT) / n)
    assert abs(p_outside(draws, BAND) - EXACT) < 5 * error


@pytest.mark.parametrize(
    ("draws", "acceptable", "message"),
    [
        ([30.0e3, np.nan, 60.0e3], BAND, "1 of 3 draws are not finite"),
        ([30.0e3, np.inf], BAND, "1 of 2 draws are not finite"),
        ([30.0e3], (56.0e3, 28.0e3), "expected bounds with lower < upper"),
        ([30.0e3], (np.nan, 56.0e3), "expected bounds with lower < upper"),
    ],
)
def test_p_outside_refuses_what_it_cannot_count(
    draws: list[float], acceptable: tuple[float, float], message: str
) -> None:
    # a NaN draw compares False on both sides: it was counted inside the domain
    with pytest.raises(ValueError, match=message):
        p_outside(np.array(draws), acceptable)


def test_p_outside_with_a_one_sided_domain() -> None:
    assert p_outside(np.array([1.0, 2.0, 3.0, 4.0]), (-np.inf, 2.5)) == 0.5


def test_summary_gives_median_equal_tailed_interval_and_the_side_of_the_mass() -> None:
    n = 40_000
    draws = norm.ppf((np.arange(n) + 0.5) / n, 20.0e3, 1.0e3)
    median, (lo, hi), p_out, side = summarise_parameter("d", draws, BAND)
    assert median == pytest.approx(20.0e3, rel=1e-6)
    assert lo == pytest.approx(20.0e3 - 1.959964e3, rel=1e-4)
    assert hi == pytest.approx(20.0e3 + 1.959964e3, rel=1e-4)
    assert p_out == pytest.approx(norm.cdf(28.0e3, 20.0e3, 1.0e3), abs=1 / n)
    assert side == "below"
    assert summarise_parameter("d", draws + 60.0e3, BAND)[3] == "above"
    assert summarise_parameter("d", draws, None)[2:] == (None, None)


def test_trust_follows_the_reliability_contract() -> None:
    assert trust({}) == (False, NO_VERDICT)
    assert trust({"reliability": {"verdict": "trusted", "reasons": [], "sentence": "ok"}}) == (
        True,
        "ok",
    )
    trusted, why = trust(
        {"reliability": {"verdict": "not_trusted", "reasons": [{"code": "not_converged"}]}}
    )
    assert not trusted and "not_converged" in why


def _record(day: int, p: float, trusted: bool, vehicle: str = "A") -> CampaignRecord:
    return CampaignRecord(
        f"{vehicle}/2026-01-{day:02d}",
        vehicle,
        f"2026-01-{day:02d}",
        trusted,
        "ok" if trusted else "not trusted (budget_too_small)",
        {"damper": (1.0, (0.5, 1.5), p, "below")},
    )


def test_untrusted_campaigns_neither_raise_nor_clear_an_alarm() -> None:
    records = [
        _record(1, 0.10, True),
        _record(2, 0.99, False),  # would raise: not trusted, ignored
        _record(3, 0.95, True),  # raises
        _record(4, 0.01, False),  # would clear: not trusted, ignored
        _record(5, 0.97, True),
        _record(6, 0.99, False),
    ]
    states = apply_alarms(records, {"damper": (0.0, 1.0)})
    alarms = [states[r.campaign_id]["damper"].alarm for r in records]
    used = [states[r.campaign_id]["damper"].used for r in records]
    assert alarms == [False, False, True, True, True, True]
    assert used == [True, False, True, False, True, False]
    (row,) = maintenance_table(records, states, {"damper": "secondary vertical damper"})
    assert row["since_campaign"] == "A/2026-01-03"
    assert row["last_trusted_campaign"] == "A/2026-01-05"
    assert row["probability"] == 0.97
    assert row["part"] == "secondary vertical damper"
    assert row["untrusted_since"] == ["A/2026-01-06"]


def test_the_threshold_is_strict_and_alarms_clear_and_vehicles_are_independent() -> None:
    records = [
        _record(1, 0.9, True),  # exactly the threshold: no alarm
        _record(2, 0.91, True),
        _record(3, 0.2, True),  # trusted and inside: clears
        _record(1, 0.95, True, vehicle="B"),
    ]
    states = apply_alarms(records, {"damper": (0.0, 1.0)})
    assert [states[r.campaign_id]["damper"].alarm for r in records] == [False, True, False, True]
    table = maintenance_table(records, states)
    assert [(r["vehicle"], r["since_campaign"]) for r in table] == [("B", "B/2026-01-01")]
    with pytest.raises(ValueError, match="threshold"):
        apply_alarms(records, {"damper": (0.0, 1.0)}, threshold=1.0)


def test_a_posterior_wider_than_the_domain_has_no_side() -> None:
    # median at nominal, P(outside) 0.93 split evenly: "below" was reported
    n = 40_000
    draws = norm.ppf((np.arange(n) + 0.5) / n, 40.0e3, 1.0e3)
    _, _, p_out, side = summarise_parameter("d", draws, (39.9e3, 40.1e3))
    assert p_out == pytest.approx(0.92, abs=0.01) and side == "both"
    lean = summarise_parameter("d", draws - 1000.0, (39.9e3, 40.1e3))  # 0.82 below, 0.14 above
    assert lean[3] == "below"


def _sided(day: int, p: float, side: str) -> CampaignRecord:
    return CampaignRecord(
        f"A/2026-01-{day:02d}", "A", f"2026-01-{day:02d}", True, "ok",
        {"damper": (1.0, (0.5, 1.5), p, side)},
    )  # fmt: skip


def test_an_alarm_that_changes_side_starts_again() -> None:
    records = [_sided(1, 0.95, "above"), _sided(2, 0.96, "below"), _sided(3, 0.97, "below")]
    states = apply_alarms(records, {"damper": (0.0, 1.0)})
    (row,) = maintenance_table(records, states)
    assert row["direction"] == "below" and row["since_campaign"] == "A/2026-01-02"


def test_attention_lists_vehicles_whose_state_the_table_cannot_give() -> None:
    records = [
        _record(1, 0.10, True),
        _record(2, 1.00, False),  # the latest campaign of A: not trusted
        _record(1, 0.05, True, vehicle="B"),
        _record(1, 0.99, False, vehicle="C"),  # never trusted
    ]
    states = apply_alarms(records, {"damper": (0.0, 1.0)})
    assert maintenance_table(records, states) == []  # "no alarm": but A and C are unknown
    rows = {row["vehicle"]: row for row in attention_table(records, states)}
    assert set(rows) == {"A", "C"}
    assert rows["A"]["last_campaign"] == "A/2026-01-02" and not rows["A"]["last_trusted"]
    assert rows["A"]["last_trusted_campaign"] == "A/2026-01-01"
    assert rows["C"]["last_trusted_campaign"] is None and "budget_too_small" in rows["C"]["why"]
    unbounded = [_record(1, 0.5, True)]
    unbounded = [
        dataclasses.replace(unbounded[0], summaries={"damper": (1.0, (0.5, 1.5), None, None)})
    ]
    (row,) = attention_table(unbounded, apply_alarms(unbounded, {"damper": None}))
    assert row["last_trusted"] and row["no_domain"] == ["damper"]
