"""The verdict rules on constructed checks: naming, accept rule, reliability gate, sentences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from susp_bo.discrepancy.detection import FlaggedBand, predictive_check
from susp_bo.discrepancy.effects import EFFECTS
from susp_bo.discrepancy.verdict import (
    NO_RELIABILITY,
    VERDICTS,
    NamingRule,
    accept_augmented,
    calibration_reliability,
    check_naming,
    describe_band,
    not_trusted_sentence,
    parameters_at_bound,
    unexplained_sentence,
)

CHANNELS = ("carbody_mid_vertical", "carbody_mid_lateral")
EDGES = np.geomspace(0.5, 20.0, 21)


def _check(offset: np.ndarray, seed: int = 0):
    """A predictive check of data = model + offset (C x F, natural-log units) + N(0, 0.1²)."""
    rng = np.random.default_rng(seed)
    model = np.zeros((2, 20))
    measured = model + offset + rng.normal(0.0, 0.1, size=(3, 2, 20))
    predicted = np.stack([np.broadcast_to(model, (3, 2, 20))] * 4) + rng.normal(
        0.0, 1e-3, size=(4, 3, 2, 20)
    )
    return predictive_check(measured, predicted, np.array([0.1, 0.1]), CHANNELS, EDGES)


def _pattern(scale: float, elsewhere: float = 0.0) -> np.ndarray:
    offset = np.zeros((2, 20))
    offset[1, 8:12] = scale  # carbody mid lateral, a band of 4 bins
    offset[0, 2:6] = elsewhere
    return offset


def test_vocabulary_is_the_four_verdicts() -> None:
    assert VERDICTS == (
        "consistent",
        "named",
        "unexplained_disagreement",
        "calibration_not_trusted",
    )


def test_a_refit_that_removes_the_pattern_is_named() -> None:
    before, after = _check(_pattern(1.0)), _check(_pattern(0.0), seed=1)
    assert before.flagged[1, 8:12].all() and not after.bands
    result = check_naming(
        "effect", 50.0, ["effect_k"], ["a", "effect_k"], np.array([0.5, 0.4]),
        np.array([[0.0, 0.0], [1.0, 1.0]]), before.flagged, before, after, NamingRule(),
    )  # fmt: skip
    assert result.passes and result.reasons == ()
    assert result.explained_share > 0.95


def test_each_failed_condition_gives_its_reason() -> None:
    before = _check(_pattern(1.0))
    half = _check(_pattern(0.7, elsewhere=1.2), seed=1)  # explains half, new disagreement elsewhere
    result = check_naming(
        "effect", 2.0, ["effect_k"], ["a", "effect_k"], np.array([0.5, 0.999]),
        np.array([[0.0, 0.0], [1.0, 1.0]]), before.flagged, before, half, NamingRule(),
    )  # fmt: skip
    codes = {r["code"] for r in result.reasons}
    assert codes == {
        "weak_evidence",
        "effect_parameter_at_bound",
        "weak_signature",
        "disagreement_left",
        "new_disagreement",  # the vertical channel agreed before
    }
    assert result.at_bound == ("effect_k",) and not result.passes
    # the base parameter "a" at a bound would not count: only the effect's parameters
    assert parameters_at_bound(["a"], np.array([1.0]), np.array([[0.0], [1.0]]), 0.01) == ("a",)


def test_a_pattern_moved_elsewhere_is_disagreement_left_even_when_explained() -> None:
    before = _check(_pattern(1.0))
    moved = _check(_pattern(0.0, elsewhere=1.5), seed=1)
    result = check_naming(
        "effect", 80.0, ["effect_k"], ["effect_k"], np.array([0.5]),
        np.array([[0.0], [1.0]]), before.flagged, before, moved, NamingRule(),
    )  # fmt: skip
    assert result.explained_share > 0.9
    assert [r["code"] for r in result.reasons] == ["disagreement_left", "new_disagreement"]


def test_a_refit_that_creates_disagreement_in_a_clean_channel_is_not_named() -> None:
    # a sensor on a bracket was named carbody bending: the refit removed the flagged band
    # and put energy into another channel, where the data have none
    before = _check(_pattern(1.0))
    one_bin = np.zeros((2, 20))
    one_bin[0, 3] = 0.5  # one bin, half the strength: not "comparable disagreement left"
    created = _check(one_bin, seed=1)
    assert created.bands and all(b.channel == CHANNELS[0] for b in created.bands)
    result = check_naming(
        "effect", 80.0, ["effect_k"], ["effect_k"], np.array([0.5]),
        np.array([[0.0], [1.0]]), before.flagged, before, created, NamingRule(),
    )  # fmt: skip
    assert [r["code"] for r in result.reasons] == ["new_disagreement"], result.reasons
    assert "carbody mid-car vertical" in result.reasons[0]["message"]
    # the same band in a channel that was already flagged before is not new
    flagged = before.flagged.copy()
    flagged[0, 2:6] = True
    same = check_naming(
        "effect", 80.0, ["effect_k"], ["effect_k"], np.array([0.5]),
        np.array([[0.0], [1.0]]), flagged, before, created, NamingRule(),
    )  # fmt: skip
    assert "new_disagreement" not in {r["code"] for r in same.reasons}


def test_accept_rule_needs_both_density_and_flagged_share() -> None:
    base, better, worse = _check(_pattern(1.0)), _check(_pattern(0.0), 1), _check(_pattern(2.0), 1)
    assert accept_augmented(base, better) == (True, [])
    accepted, reasons = accept_augmented(base, worse)
    assert not accepted
    assert {r["code"] for r in reasons} == {
        "log_predictive_density_not_better",
        "flagged_share_not_lower",
    }
    accepted, reasons = accept_augmented(base, base)  # equal is not better
    assert not accepted and len(reasons) == 2


def test_reliability_gate_follows_the_shared_contract() -> None:
    missing = calibration_reliability({"joint_map": [1.0]})
    assert not missing.trusted and missing.verdict is None
    assert missing.reasons[0]["code"] == "no_reliability" and missing.sentence == NO_RELIABILITY
    trusted = calibration_reliability({"reliability": {"verdict": "trusted", "reasons": []}})
    assert trusted.trusted
    reason = {"code": "budget_too_small", "message": "40 evaluations for q = 7"}
    untrusted = calibration_reliability(
        {"reliability": {"verdict": "not_trusted", "reasons": [reason], "sentence": "no"}}
    )
    assert not untrusted.trusted and untrusted.reasons == (reason,)
    sentence = not_trusted_sentence(untrusted, "res", 40)
    assert "40 evaluations for q = 7" in sentence
    assert "--resume --budget 80" in sentence and "res/study.toml" in sentence
    # twice the evaluations done can still be below the minimum the calibration names
    small = {"code": "budget_too_small", "message": "12 evaluations", "minimum": 32}
    sentence = not_trusted_sentence(
        calibration_reliability({"reliability": {"verdict": "not_trusted", "reasons": [small]}}),
        "res",
        12,
    )
    assert "--resume --budget 32 " in sentence  # not 24, refused in turn
    # where simulations failed, more budget is not the remedy
    failed = {"code": "failed_region", "message": "2 of the 8 held-out check simulations failed"}
    sentence = not_trusted_sentence(
        calibration_reliability({"reliability": {"verdict": "not_trusted", "reasons": [failed]}}),
        "res",
        40,
    )
    assert "2 of the 8 held-out check simulations failed" in sentence
    assert "--resume" not in sentence and "narrow the admissible interval" in sentence


def test_bands_are_described_with_channel_band_sign_and_physics() -> None:
    band = FlaggedBand("carbody_mid_lateral", 1.2, 2.0, 1.5, "model_too_little", 5.0, 4.2, 3)
    text = describe_band(band)
    assert text.startswith("carbody mid-car lateral 1.2–2 Hz, measured above the model")
    assert "conicity" in text
    low = FlaggedBand("bogie_front_vertical", 25.0, 40.0, 30.0, "model_too_much", 4.0, -3.0, 4)
    assert "measured below the model" in describe_band(low)
    assert "out-of-roundness" in describe_band(low)
    sentence = unexplained_sentence([band, low, band, band])
    assert "4 band(s)" in sentence and "(and 1 more bands)" in sentence
    assert "no library effect explains" in sentence  # the whole library was tried
    assert unexplained_sentence([band], list(EFFECTS)) == unexplained_sentence([band])


def test_the_unexplained_sentence_names_the_effects_not_tried() -> None:
    # one candidate tried is not "no library effect explains": the others are named
    band = FlaggedBand("carbody_mid_lateral", 1.2, 2.0, 1.5, "model_too_little", 5.0, 4.2, 3)
    sentence = unexplained_sentence([band], ["carbody_bending"])
    assert "no library effect" not in sentence
    assert "none of the 1 effect(s) tried (carbody_bending) explains" in sentence
    others = [name for name in EFFECTS if name != "carbody_bending"]
    assert f"other effects ({', '.join(others)}) were not tried" in sentence


@pytest.mark.parametrize(
    "kwargs",
    [{"min_score": -1.0}, {"min_explained": 1.5}, {"max_remaining_share": 1.0},
     {"bound_tolerance": math.nan}],
)  # fmt: skip
def test_naming_rule_refuses_bad_thresholds(kwargs) -> None:
    with pytest.raises(ValueError, match="NamingRule"):
        NamingRule(**kwargs)


@pytest.mark.parametrize(
    ("verdict", "codes", "finished"),
    [
        ("trusted", [], True),
        ("not_trusted", ["below_expected_fit"], True),
        ("not_trusted", ["below_expected_fit", "at_bound"], True),  # compensating parameters
        ("not_trusted", ["runs_not_reproduced"], True),  # session 32: the unpaired B's misfit
        ("not_trusted", ["runs_not_reproduced", "at_bound"], True),
        ("not_trusted", ["poor_mixing", "runs_not_reproduced"], False),
        ("not_trusted", ["at_bound"], False),  # nothing says the model misses the data
        ("not_trusted", ["not_converged", "below_expected_fit"], False),  # unfinished search
        ("not_trusted", ["below_expected_fit", "surrogate_misfit"], False),
        ("not_trusted", ["below_expected_fit", "multimodal"], False),
        ("not_trusted", ["budget_too_small", "below_expected_fit"], False),
        (None, [], False),  # no verdict at all
    ],
)
def test_a_fit_is_finished_when_only_the_misfit_to_the_data_is_left(
    verdict: str | None, codes: list[str], finished: bool
) -> None:
    payload = {}
    if verdict is not None:
        payload["reliability"] = {
            "verdict": verdict,
            "reasons": [{"code": c, "message": c} for c in codes],
            "sentence": "s",
        }
    assert calibration_reliability(payload).fit_finished is finished
