"""kernel_advice: the additive kernel's leave-one-out gain, and the advice it changes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from susp_bo.calibration.kernel_advice import (
    additive_kernel_gain,
    needs_kernel_advice,
    with_kernel_gain,
)
from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.loop_step import fit_in_box
from susp_bo.calibration.reliability import Reliability
from susp_bo.calibration.reliability_sentence import ADDITIVE_GAIN_KEY, ADDITIVE_GAIN_NATS
from susp_bo.calibration.surrogate import SurrogateSettings
from tests.calibration.kernel_targets import DIM, UNIT_BOX, chain, three_way


def _gain(f, n: int, seed: int = 0) -> float:
    u = np.random.default_rng(seed).random((n, DIM))
    y = f(u)
    settings = CalibrationSettings(seed=seed)
    final = fit_in_box(u, y, UNIT_BOX, settings, 7)
    return additive_kernel_gain(u, y, UNIT_BOX, settings, 7, final)


def test_the_gain_tells_an_additive_log_l_from_one_with_three_way_terms() -> None:
    additive, not_additive = _gain(chain, 60), _gain(three_way, 60)
    assert additive >= ADDITIVE_GAIN_NATS, additive
    assert not_additive < ADDITIVE_GAIN_NATS, not_additive


def _not_converged(**evidence: object) -> Reliability:
    reason = {"code": "not_converged", "message": "the search had not converged"}
    return Reliability(
        "not_trusted", (reason,), evidence={"budget": 100, "minimum_budget": 40, **evidence}
    ).worded_for("python")


def test_only_a_default_kernel_run_untrusted_for_a_surrogate_reason_is_advised() -> None:
    default, auto = (
        CalibrationSettings(),
        CalibrationSettings(surrogate=SurrogateSettings(kernel="auto")),
    )
    mixing = Reliability(
        "not_trusted", ({"code": "poor_mixing", "message": "R-hat 1.2"},), evidence={}
    )
    assert needs_kernel_advice(_not_converged(), default)
    far = Reliability(  # the search did not reach the optimum: budget first
        "not_trusted",
        ({"code": "not_converged", "message": "m", "optimum_gap_nats": 140.0},),
    )
    misfit = {"code": "surrogate_misfit", "message": "check"}
    assert not needs_kernel_advice(far, default)
    assert needs_kernel_advice(Reliability("not_trusted", (misfit,)), default)
    below = {"code": "below_expected_fit", "message": "b"}
    assert not needs_kernel_advice(Reliability("not_trusted", (misfit, below)), default)
    assert not needs_kernel_advice(_not_converged(), auto)
    assert not needs_kernel_advice(mixing, default)
    assert not needs_kernel_advice(Reliability("trusted"), default)
    assert not needs_kernel_advice(None, default)


@pytest.mark.parametrize(
    ("gain", "kernel_advised"), [(0.37, True), (ADDITIVE_GAIN_NATS, True), (0.05, False)]
)
def test_the_advice_names_the_kernel_only_above_the_gain(gain: float, kernel_advised: bool) -> None:
    python = with_kernel_gain(_not_converged(), gain)
    command_line = python.worded_for("command_line")
    assert python.evidence[ADDITIVE_GAIN_KEY] == gain
    assert python.verdict == "not_trusted"  # advice only: the verdict is the same
    assert ('SurrogateSettings(kernel="auto"), refine_optimism=2.0' in python.sentence) == (
        kernel_advised
    )
    assert ('[search] kernel = "auto"' in command_line.sentence) == kernel_advised
    assert ("refine_optimism = 2 in the study's config" in command_line.sentence) == (
        kernel_advised
    )
    if kernel_advised:
        assert f"{gain:+.2f} nats a point" in python.sentence
        assert "max_evaluations=200" in python.sentence
        assert "--resume --budget 200" in command_line.sentence
    else:
        assert "max_evaluations=200" in python.sentence
        assert "kernel" not in python.sentence


def test_no_fit_where_the_sentence_would_not_use_the_gain() -> None:
    """The reviewer's cases: the fit ran and its gain was dropped where another reason's
    advice leads (a budget below the minimum, a bound, a noisy log L, a narrow posterior)."""
    default = CalibrationSettings()
    misfit = {"code": "surrogate_misfit", "message": "check"}
    led_by = [
        {"code": "budget_too_small", "message": "b"},
        {"code": "at_bound", "message": "a"},
        {"code": "not_converged", "message": "n", "posterior_width": 0.004},
    ]
    for first in led_by:
        assert not needs_kernel_advice(Reliability("not_trusted", (first, misfit)), default)
    noisy = {**misfit, "direction": "noisy"}
    assert not needs_kernel_advice(Reliability("not_trusted", (noisy,)), default)
    assert needs_kernel_advice(Reliability("not_trusted", (misfit, led_by[1])), default)


def test_a_gain_that_is_not_finite_is_not_stored() -> None:
    before = _not_converged()
    assert with_kernel_gain(before, float("nan")) == before


def test_a_failed_advice_fit_keeps_the_finished_result(monkeypatch: pytest.MonkeyPatch) -> None:
    """BoTorch's ModelFittingError is an Exception, not a RuntimeError: raised by the advice
    fit after every evaluation was spent, it must not lose the result."""
    from botorch.exceptions.errors import ModelFittingError

    import susp_bo.calibration.kernel_advice as kernel_advice

    def failing(*args: object, **kwargs: object) -> float:
        raise ModelFittingError("All attempts to fit the model have failed.")

    monkeypatch.setattr(kernel_advice, "additive_kernel_gain", failing)
    names = [f"w{i}" for i in range(DIM)]
    result = calibrate(_banana_target, UNIT_BOX, names, SMALL, progress=False)
    assert result.reliability is not None and result.reliability.verdict == "not_trusted"
    assert ADDITIVE_GAIN_KEY not in result.reliability.evidence
    assert result.n_evaluations == SMALL.max_evaluations


def test_a_narrow_posterior_keeps_its_trust_region_advice() -> None:
    narrow = replace(
        _not_converged(),
        reasons=({"code": "not_converged", "message": "m", "posterior_width": 0.004},),
    )
    advised = with_kernel_gain(narrow, 2.0)
    assert "trust_region=True" in advised.sentence
    assert "kernel" not in advised.sentence


def _banana_target(w: np.ndarray) -> np.ndarray:
    return chain(np.atleast_2d(w))


# the advice after a run that kept the Matérn: no switch during it (kernel_switch=False)
SMALL = CalibrationSettings(
    max_evaluations=24, batch_size=3, mcmc_chains=8, mcmc_warmup=100, mcmc_samples=100,
    candidate_count=64, check_points=0, allow_small_budget=True, kernel_switch=False,
)  # fmt: skip


def test_calibrate_computes_the_gain_only_where_it_advises() -> None:
    names = [f"w{i}" for i in range(DIM)]
    default = calibrate(_banana_target, UNIT_BOX, names, SMALL, progress=False)
    assert default.reliability is not None
    assert default.reliability.verdict == "not_trusted"
    assert any(r["code"] == "not_converged" for r in default.reliability.reasons)
    gain = default.reliability.evidence[ADDITIVE_GAIN_KEY]
    assert np.isfinite(gain)
    auto = calibrate(
        _banana_target,
        UNIT_BOX,
        names,
        replace(SMALL, surrogate=SurrogateSettings(kernel="auto")),
        progress=False,
    )
    assert auto.reliability is not None
    assert ADDITIVE_GAIN_KEY not in auto.reliability.evidence
