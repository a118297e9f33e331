"""The simulated tracks against the measured runs: exact answers of T, and the rule on a
calibration whose tracks are not the runs' own (the unpaired model's failing setting)."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

from susp_bo.calibration.likelihood import log_likelihood
from susp_bo.calibration.loop import calibrate
from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.calibration.track_match import (
    LIMIT,
    runs_not_reproduced,
    track_match_ratio,
    with_track_match,
)
from susp_bo.discrepancy.problem import DiagnosisProblem, LinearSimulator
from susp_bo.discrepancy.scenarios import WORN_TRUTH, scenario_spec, synthesize_problem
from tests.calibration.conftest import Q1_SETTINGS

_DAMPER = "yaw_damper_damping"


def test_t_is_each_runs_standardised_mean_square_against_its_nearest_simulated_run() -> None:
    sigma = np.array([0.1, 0.2])
    y = np.stack([np.zeros((2, 4)), np.ones((2, 4))])  # two measured runs
    own = y + sigma[None, :, None] * 0.5  # every residual half a sigma: T = 0.25
    assert track_match_ratio(y, own, sigma) == pytest.approx(0.25)
    far = y + sigma[None, :, None] * 3.0
    # two simulated runs, one near each measured run (in any order): the nearest counts
    near = np.stack([y[0] + sigma[:, None] * 0.1, y[1] - sigma[:, None] * 0.2])
    assert track_match_ratio(y, np.concatenate([far[:1], near[::-1]]), sigma) == pytest.approx(
        (0.01 + 0.04) / 2
    )
    assert track_match_ratio(y, far, sigma) == pytest.approx(9.0)
    broken = own.copy()
    broken[0, 1, 2] = np.nan
    for bad in (
        track_match_ratio(y, broken, sigma),
        track_match_ratio(y, own[:, :1], sigma),  # channels disagree
        track_match_ratio(y, own, sigma[:1]),
        track_match_ratio(y, own, np.array([0.1, 0.0])),
    ):
        assert math.isnan(bad)


def test_the_rule_fires_above_the_limit_only() -> None:
    assert runs_not_reproduced(LIMIT) is None and runs_not_reproduced(math.nan) is None
    reason = runs_not_reproduced(0.93)
    assert reason is not None and reason["code"] == "runs_not_reproduced"
    assert reason["track_match_ratio"] == 0.93 and "T = 0.93" in reason["message"]


class _Evaluator:
    """The yaw damper's log L under the unpaired B of ``data``'s runs, simulated on the
    tracks of ``simulate_on`` (the runs' own, or other realizations of the process)."""

    def __init__(self, data: DiagnosisProblem, simulate_on: DiagnosisProblem) -> None:
        self.measured, self.error, self.simulate_on = data.measured, data.error, simulate_on
        others = {k: v for k, v in WORN_TRUTH.items() if k != _DAMPER}
        self.spec = data.spec.with_parameters(others)

    def spectra(self, W: np.ndarray) -> np.ndarray:
        simulator = LinearSimulator()
        return np.stack([self.simulate_on.simulate(simulator, self.spec, [_DAMPER], w) for w in W])

    def __call__(self, W: np.ndarray) -> np.ndarray:
        return np.array([log_likelihood(self.measured, h, self.error) for h in self.spectra(W)])


def test_a_calibration_on_tracks_that_are_not_the_runs_own_is_not_trusted() -> None:
    """Session 32: SBC of the unpaired model on tracks known only by their statistics (the
    model simulating other realizations of the track process) gave results ``trusted``
    with the truth 3.5–8.1 posterior sd away. The same in one dimension: the yaw damper,
    simulated on another seed's tracks, is trusted by every other rule, and T ≈ 1 refuses
    it; on the runs' own tracks T is small and the verdict is left as it was."""
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    data = synthesize_problem(spec, None, truth=dict(WORN_TRUTH), nu=3, seed=0, noise_m_s2=0.01)
    elsewhere = synthesize_problem(
        spec, None, truth=dict(WORN_TRUTH), nu=3, seed=5, noise_m_s2=0.01
    )
    bounds = np.asarray(spec.calibration_bounds)[:, [spec.calibration_names.index(_DAMPER)]]
    settings = dataclasses.replace(Q1_SETTINGS, max_evaluations=24)
    unknown = _Evaluator(data, elsewhere)
    result = calibrate(unknown, bounds, [_DAMPER], settings, progress=False, lack_of_fit=False)
    reliability = result.reliability
    assert reliability is not None and reliability.codes == ("runs_not_reproduced",)
    assert reliability.evidence["track_match_ratio"] > 3 * LIMIT
    assert reliability.sentence.startswith("Not trusted: the simulation leaves residuals")
    assert "PairedOutputError" in reliability.sentence
    lower, upper = result.summary.interval95[0]  # and it was wrong: [3.19, 3.47] MN·s/m
    assert not lower <= WORN_TRUTH[_DAMPER] <= upper
    # (the rule refuses only results no other rule refused, so every other rule passed
    # it.) The runs' own tracks: T far below the limit, a trusted verdict stays
    before = dataclasses.replace(
        reliability, verdict="trusted", reasons=(), evidence=dict(reliability.evidence)
    )
    unrefused = dataclasses.replace(result, reliability=before)
    own = with_track_match(unrefused, _Evaluator(data, data), data.measured)
    assert own.reliability is not None and own.reliability.trusted
    assert own.reliability.evidence["track_match_ratio"] < LIMIT / 5
    # the paired B: not this rule's concern (its own expectation refuses other tracks)
    paired = copy.copy(unknown)
    rate = spec.simulation.sample_rate_hz
    paired.error = PairedOutputError(0.01, rate, (int(20 * rate),) * 3, spec.spectrum)
    assert with_track_match(result, paired, data.measured) is result
