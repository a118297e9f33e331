"""A model that misses an effect: is the result refused, or trusted and wrong?

Session 26's outside probe. Data from the maintainer's base rig (the discrepancy
scenarios' rig, linearised fast path, 20 s runs, ν = 3, sensor noise 0.01 m/s²) with ONE
physical change in the generator only — a library effect the model lacks, or a
non-calibrated parameter (the wheel–rail equivalent conicity) that differs from the
model's — calibrated on q = 4 dampers (the worn truth of the scenarios) with the demo's
loop settings (local phase), paired or unpaired output error, as a study would (the log L
expected at the truth passed, so ``below_expected_fit`` can fire). Each run prints the
verdict *before* and *after* the lack-of-fit rule (:mod:`susp_bo.calibration.lack_of_fit`,
which :func:`~susp_bo.calibration.loop.calibrate` applies; "before" has every other rule,
since session 32 also ``runs_not_reproduced``), the truths inside their 95 % intervals,
the largest |z| = |truth − mean| / sd, the largest bias in % of the true value, and F
(weighted, as the rule uses it), F after the Gauss–Newton steps when they ran, the
equal-weight F of session 26 for comparison, and T (:mod:`susp_bo.calibration.track_match`,
unpaired B only).

A result is *trusted and wrong* when it is ``trusted`` with some |z| > 3. Usage::

    python benchmarks/misspecified_model.py --errors unpaired paired --seeds 0 1
    python benchmarks/misspecified_model.py --errors paired --model-error 0.03 --seeds 0 1

``--model-error τ`` fixes the paired model-error sd τ_c (log-amplitude; the study key
``[output_error] sigma`` with ``model = "paired"``) instead of profiling it. Exit status 1
when any result is trusted and wrong after the rule.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from susp_bo.calibration.budget import budget_requirement
from susp_bo.calibration.lack_of_fit import with_lack_of_fit
from susp_bo.calibration.likelihood import (
    OutputError,
    expected_log_likelihood_at_truth,
    log_likelihood,
)
from susp_bo.calibration.loop import calibrate
from susp_bo.calibration.paired_error import PairedOutputError, paired_log_likelihood
from susp_bo.calibration.study import calibration_settings
from susp_bo.commands.demo import demo_config
from susp_bo.discrepancy.problem import DiagnosisProblem, LinearSimulator
from susp_bo.discrepancy.scenarios import WORN_TRUTH, scenario_spec, synthesize_problem

CHANGES = {
    "none": None,
    "conicity_0.103": ("parameter", "contact_equivalent_conicity", 0.103),
    "conicity_0.105": ("parameter", "contact_equivalent_conicity", 0.105),
    "conicity_0.11": ("parameter", "contact_equivalent_conicity", 0.11),
    "conicity_0.15": ("parameter", "contact_equivalent_conicity", 0.15),
    "carbody_bending_9hz": (
        "effect",
        "carbody_bending",
        {"frequency_hz": 9.0, "damping_ratio": 0.02},
    ),
    "bump_stop_7mm": ("effect", "lateral_bump_stop", {"gap_m": 0.007}),
    "bump_stop_15mm": ("effect", "lateral_bump_stop", {"gap_m": 0.015}),
    "air_spring_reservoir": (
        "effect",
        "air_spring_reservoir",
        {"stiffness_ratio": 3.0, "corner_frequency_hz": 1.0},
    ),
}
"""The generator's change, by name: None, ("parameter", name, value) or ("effect", name,
values); the model is the base rig in every case."""
NAMES = tuple(WORN_TRUTH)
BUDGET = 120
NOISE_M_S2 = 0.01


class StudyEvaluator:
    """log L and spectra of the q = 4 dampers on the problem's tracks (what a study's
    evaluator gives, without the store)."""

    def __init__(self, problem: DiagnosisProblem, error: OutputError | PairedOutputError) -> None:
        self.problem, self.error, self.measured = problem, error, problem.measured
        self.simulator = LinearSimulator()

    def spectra(self, W: np.ndarray) -> np.ndarray:
        """(b x ν x C x F) spectra of the rows of W (physical units)."""
        return np.stack(
            [self.problem.simulate(self.simulator, self.problem.spec, NAMES, w) for w in W]
        )

    def log_likelihood_of(self, H: np.ndarray, exact: bool = False) -> np.ndarray:
        """(b,) log L of (b x ν x C x F) spectra."""
        if isinstance(self.error, PairedOutputError):
            return np.atleast_1d(paired_log_likelihood(self.measured, H, self.error, exact=exact))
        return np.array([log_likelihood(self.measured, h, self.error) for h in H])

    def __call__(self, W: np.ndarray) -> np.ndarray:
        return self.log_likelihood_of(self.spectra(np.atleast_2d(W)))


def run(change: str, error_model: str, seed: int, model_error: float | None) -> dict:
    """One calibration; returns the row printed."""
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    kind = CHANGES[change]
    truth = dict(WORN_TRUTH)
    effect = None
    if kind is not None and kind[0] == "parameter":
        truth[kind[1]] = kind[2]
    elif kind is not None:
        effect = (kind[1], kind[2])
    problem = synthesize_problem(
        spec, effect, truth=truth, nu=3, seed=seed, noise_m_s2=NOISE_M_S2, output_error="paired"
    )
    error: OutputError | PairedOutputError = problem.error
    if error_model == "paired":
        error = problem.paired
        if model_error is not None:
            error = dataclasses.replace(
                error, model_error_sigma=(model_error,) * problem.measured.shape[1]
            )
    index = [spec.calibration_names.index(n) for n in NAMES]
    bounds = np.asarray(spec.calibration_bounds)[:, index]
    config = demo_config(Path("unused"), smoke=False, seed=0)
    settings = calibration_settings(config)
    requirement = budget_requirement(len(NAMES), None, settings.batch_size, settings.check_points)
    settings = dataclasses.replace(
        settings,
        seed=1000 + seed,
        mcmc_seed=2000 + seed,
        max_evaluations=max(BUDGET, requirement.minimum),
        initial_design_size=min(config.budget.initial_design, 40),
        local_search=True,
    )
    evaluator = StudyEvaluator(problem, error)
    expected = expected_log_likelihood_at_truth(error, problem.measured, problem.frequencies_hz)
    before = calibrate(
        evaluator,
        bounds,
        list(NAMES),
        settings,
        progress=False,
        expected_at_truth=expected if all(map(math.isfinite, expected)) else None,
        lack_of_fit=False,  # the verdict before the rule, then with it
    )
    after = with_lack_of_fit(before, evaluator, problem.measured)
    truth_vector = np.array([WORN_TRUTH[n] for n in NAMES])
    lower, upper = np.asarray(before.summary.interval95).reshape(-1, 2).T
    inside = (lower <= truth_vector) & (truth_vector <= upper)
    mean, sd = np.asarray(before.summary.mean), np.asarray(before.summary.sd)
    z = np.abs(truth_vector - mean) / sd
    return {
        "change": change,
        "error": error_model if model_error is None else f"{error_model} τ={model_error:g}",
        "seed": seed,
        "before": before.reliability.verdict,
        "after": after.reliability.verdict,
        "reasons": ",".join(after.reliability.codes) or "-",
        "inside": f"{int(inside.sum())}/{len(NAMES)}",
        "max_z": float(np.max(z)),
        "max_bias_pct": float(np.max(np.abs(mean - truth_vector) / truth_vector) * 100),
        "F": after.reliability.evidence.get("lack_of_fit_ratio"),
        "F_steps": after.reliability.evidence.get("lack_of_fit_after_steps"),
        "F_plain": after.reliability.evidence.get("lack_of_fit_unweighted"),
        "T": after.reliability.evidence.get("track_match_ratio"),
    }


def main(argv: list[str] | None = None) -> int:
    """Run every (change, error model, seed); print the rows and the counts."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--changes", nargs="+", default=list(CHANGES), choices=list(CHANGES))
    parser.add_argument(
        "--errors", nargs="+", default=["unpaired", "paired"], choices=["unpaired", "paired"]
    )
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    parser.add_argument(
        "--model-error",
        type=float,
        default=None,
        help="fixed paired model-error sd τ_c (log-amplitude); default profiled",
    )
    args = parser.parse_args(argv)
    if args.model_error is not None and not (
        args.model_error > 0 and math.isfinite(args.model_error)
    ):
        parser.error(f"--model-error: {args.model_error} must be a finite number > 0")
    print(
        "change                error            seed before       after        inside "
        "max|z|  bias%      F F_steps F_plain      T  reasons",
        flush=True,
    )
    wrong_before = wrong_after = 0
    for change in args.changes:
        for error_model in args.errors:
            for seed in args.seeds:
                started = time.perf_counter()
                row = run(change, error_model, seed, args.model_error)
                bad = row["max_z"] > 3.0
                wrong_before += bad and row["before"] == "trusted"
                wrong_after += bad and row["after"] == "trusted"
                f, steps, plain, t = (
                    "   nan" if row[k] is None else f"{row[k]:6.2f}"
                    for k in ("F", "F_steps", "F_plain", "T")
                )
                print(
                    f"{row['change']:21s} {row['error']:16s} {seed:4d} {row['before']:12s} "
                    f"{row['after']:12s} {row['inside']:6s} {row['max_z']:6.1f} "
                    f"{row['max_bias_pct']:6.2f} {f}  {steps}  {plain}  {t}  "
                    f"{row['reasons']}  ({time.perf_counter() - started:.0f} s)",
                    flush=True,
                )
    print(
        f"trusted and wrong (|z| > 3): {wrong_before} before the lack-of-fit rule, "
        f"{wrong_after} after",
        flush=True,
    )
    return 1 if wrong_after else 0


if __name__ == "__main__":
    sys.exit(main())
