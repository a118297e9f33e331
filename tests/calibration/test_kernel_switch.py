"""kernel_switch: the run takes the additive kernel's advice during its search."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from susp_bo.calibration import kernel_switch
from susp_bo.calibration.kernel_switch import (
    CHECK_EVERY,
    LATER_GAIN_NATS,
    SWITCH_OPTIMISM,
    KernelSwitcher,
)
from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.loop_step import fit_in_box
from susp_bo.calibration.reliability_sentence import ADDITIVE_GAIN_KEY, ADDITIVE_GAIN_NATS
from susp_bo.calibration.result import KernelSwitch
from susp_bo.calibration.surrogate import SurrogateSettings
from tests.calibration.kernel_targets import DIM, UNIT_BOX, chain, three_way


def _considered(f, settings: CalibrationSettings, n: int = 60) -> tuple[KernelSwitcher, object]:
    u = np.random.default_rng(0).random((n, DIM))
    y = f(u)
    switcher = KernelSwitcher(settings, DIM, 200, local_phase=False)
    matern = fit_in_box(u, y, UNIT_BOX, settings, 7)
    return switcher, switcher.consider(u, y, UNIT_BOX, settings, 7, matern)


def test_an_additive_log_l_switches_the_rest_of_the_run_to_both_kernels() -> None:
    settings = CalibrationSettings(refine_optimism=0.5)
    switcher, after = _considered(chain, settings)
    assert switcher.switched_at == 60
    assert after.surrogate.kernel == "auto"
    assert after.refine_optimism == SWITCH_OPTIMISM  # at least 2
    assert after.seed == settings.seed and after.max_evaluations == settings.max_evaluations
    (n, gain), = switcher.record().checks  # fmt: skip
    assert n == 60 and gain >= ADDITIVE_GAIN_NATS
    # switched once: no more comparisons
    assert not switcher.due(200, "refine", boxed=False)
    _, higher = _considered(chain, replace(settings, refine_optimism=3.0))
    assert higher.surrogate.kernel == "auto" and higher.refine_optimism == 3.0  # kept


def test_a_log_l_with_a_three_way_term_keeps_the_matern() -> None:
    settings = CalibrationSettings()
    switcher, after = _considered(three_way, settings)
    assert after is settings
    assert switcher.switched_at is None
    (_, gain), = switcher.record().checks  # fmt: skip
    assert gain < ADDITIVE_GAIN_NATS


def test_a_failed_additive_fit_switches_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    from botorch.exceptions.errors import ModelFittingError

    def failing(*args: object, **kwargs: object) -> float:
        raise ModelFittingError("All attempts to fit the model have failed.")

    monkeypatch.setattr(kernel_switch, "additive_kernel_gain", failing)
    settings = CalibrationSettings()
    switcher, after = _considered(chain, settings)
    assert after is settings and switcher.switched_at is None
    record = switcher.record()
    assert math.isnan(record.checks[0][1])
    assert record.to_dict()["checks"][0]["additive_kernel_loo_gain"] is None  # JSON null


def test_a_later_comparison_needs_a_larger_gain(monkeypatch: pytest.MonkeyPatch) -> None:
    """Refinement packs points where the posterior has mass; there the additive kernel
    gains a little on any log L (a Student-t: +0.16 late in a run), so a comparison after
    the first needs LATER_GAIN_NATS."""
    between = 0.5 * (ADDITIVE_GAIN_NATS + LATER_GAIN_NATS)
    monkeypatch.setattr(kernel_switch, "additive_kernel_gain", lambda *a, **k: between)
    settings = CalibrationSettings()
    switcher, after = _considered(three_way, settings)  # the first comparison: switches
    assert switcher.switched_at == 60 and after.surrogate.kernel == "auto"
    later = KernelSwitcher(settings, DIM, 200, local_phase=False)
    later.checks.append((40, -0.5))
    u = np.random.default_rng(0).random((60, DIM))
    matern = fit_in_box(u, three_way(u), UNIT_BOX, settings, 7)
    assert later.consider(u, three_way(u), UNIT_BOX, settings, 7, matern) is settings
    assert later.switched_at is None and later.checks[-1] == (60, between)
    monkeypatch.setattr(kernel_switch, "additive_kernel_gain", lambda *a, **k: LATER_GAIN_NATS)
    assert later.consider(u, three_way(u), UNIT_BOX, settings, 7, matern) is not settings
    assert later.switched_at == 60


@pytest.mark.parametrize(
    ("settings", "q", "local_phase"),
    [
        (CalibrationSettings(kernel_switch=False), 5, False),
        (CalibrationSettings(surrogate=SurrogateSettings(kernel="additive_pairs")), 5, False),
        (CalibrationSettings(surrogate=SurrogateSettings(kernel="auto")), 5, False),
        (CalibrationSettings(surrogate=SurrogateSettings(noise="learned")), 5, False),
        (CalibrationSettings(), 2, False),
        (CalibrationSettings(trust_region=True), 5, False),
        (CalibrationSettings(), 5, True),
    ],
    ids=["off", "additive", "auto", "noise_learned", "q2", "trust_region", "local_phase"],
)
def test_no_comparison_where_the_switch_does_not_apply(
    settings: CalibrationSettings, q: int, local_phase: bool
) -> None:
    assert not KernelSwitcher(settings, q, 350, local_phase).due(150, "refine", boxed=False)


def test_comparisons_come_when_refinement_starts_then_every_tenth_of_the_budget() -> None:
    switcher = KernelSwitcher(CalibrationSettings(), 5, 350, local_phase=False)
    every = math.ceil(CHECK_EVERY * 350)
    assert not switcher.due(150, "ego", boxed=False)
    assert not switcher.due(150, "refine", boxed=True)  # a search box: the GP is local
    assert switcher.due(150, "refine", boxed=False)
    switcher.checks.append((150, 0.05))
    assert not switcher.due(150 + every - 1, "refine", boxed=False)
    assert switcher.due(150 + every, "refine", boxed=False)


SMALL = CalibrationSettings(
    max_evaluations=36, batch_size=3, mcmc_chains=8, mcmc_warmup=100, mcmc_samples=100,
    candidate_count=64, check_points=0, allow_small_budget=True,
)  # fmt: skip


def _banana(w: np.ndarray) -> np.ndarray:
    return chain(np.atleast_2d(w))


def _radial(w: np.ndarray) -> np.ndarray:
    return three_way(np.atleast_2d(w))


def test_calibrate_switches_on_a_banana_chain_and_records_it() -> None:
    names = [f"w{i}" for i in range(DIM)]
    result = calibrate(_banana, UNIT_BOX, names, SMALL, progress=False)
    record = result.kernel_switch
    assert isinstance(record, KernelSwitch)
    assert record.switched_at is not None
    assert record.switched_at == record.checks[-1][0]
    needed = ADDITIVE_GAIN_NATS if len(record.checks) == 1 else LATER_GAIN_NATS
    assert record.checks[-1][1] >= needed
    assert result.n_evaluations == SMALL.max_evaluations
    as_json = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert as_json["kernel_switch"]["switched_at"] == record.switched_at
    # the advice after the run is for runs that kept the Matérn: this one took it
    assert result.reliability is not None
    assert ADDITIVE_GAIN_KEY not in result.reliability.evidence


def test_a_comparison_that_does_not_switch_leaves_the_run_bit_identical() -> None:
    """The extra fit runs under the loop's own seeds and forked RNG: a run whose
    comparisons all kept the Matérn equals the run without them, to the bit."""
    names = [f"w{i}" for i in range(DIM)]
    on = calibrate(_radial, UNIT_BOX, names, SMALL, progress=False)
    assert on.kernel_switch is not None and on.kernel_switch.switched_at is None
    off = calibrate(_radial, UNIT_BOX, names, replace(SMALL, kernel_switch=False), progress=False)
    assert off.kernel_switch is None and "kernel_switch" not in off.to_dict()
    np.testing.assert_array_equal(on.X, off.X)
    np.testing.assert_array_equal(on.draws, off.draws)
