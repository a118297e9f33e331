"""The lack-of-fit ratio at the fit's optimum, on data from the model itself or with one change.

Linearised fast path, the q = 4 dampers of ``benchmarks/misspecified_model.py`` (the same
scenario rig, 20 s runs): from the true dampers, four weighted Gauss–Newton steps (finite
differences of 1 %, the bin weights of :func:`~susp_bo.calibration.lack_of_fit.pure_error_weights`
at the truth) find the optimum of the weighted fit, and four unweighted steps that of the
equal-weight fit; F is printed at each (weighted / equal weights), with the largest bias of
the fitted dampers. No surrogate, no sampler: this measures the statistic, not a search.
Cases are ``change:seed:runs:noise`` (change as in misspecified_model.py, plus
"conicity_0.103" and "conicity_0.105"). Usage::

    python benchmarks/lack_of_fit_null.py none:0:3:0.01 none:0:2:0.01 none:0:20:0.5 \\
        conicity_0.105:0:3:0.01

Measured as a rate (session 28, seeds 100–199 at ν = 2 and ν = 3, noise 0.01, 804 s):
weighted F above 3 in 0 of 100 cases at either ν; ν = 2 mean 1.32, 99th percentile 2.80,
largest 2.84; ν = 3 mean 1.13, largest 1.90.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from misspecified_model import CHANGES, NAMES, StudyEvaluator

from susp_bo.calibration.lack_of_fit import (
    gauss_newton_step,
    lack_of_fit_ratio,
    pure_error_weights,
)
from susp_bo.discrepancy.scenarios import WORN_TRUTH, scenario_spec, synthesize_problem

STEPS = 4


def fitted(
    evaluator: StudyEvaluator, measured: np.ndarray, start: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """The dampers after :data:`STEPS` Gauss–Newton steps of the ``weights``-weighted fit
    (the rule's own step, :func:`~susp_bo.calibration.lack_of_fit.gauss_newton_step`)."""
    w = start.copy()
    for _ in range(STEPS):
        h = evaluator.spectra(w[None])[0]
        d = 0.01 * w
        jac = (evaluator.spectra(w[None] + np.diag(d)) - h[None]) / d[:, None, None, None]
        w = w + gauss_newton_step(measured, h, jac.reshape(len(w), -1), weights)
    return w


def parse_cases(
    parser: argparse.ArgumentParser, cases: list[str]
) -> list[tuple[str, int, int, float]]:
    """``change:seed:runs:noise`` strings as tuples; a bad one is refused through ``parser``
    (exit 2, naming it and the changes of ``CHANGES`` allowed)."""
    parsed = []
    for case in cases:
        parts = case.split(":")
        if len(parts) != 4 or parts[0] not in CHANGES:
            parser.error(
                f"cases: {case!r}; expected change:seed:runs:noise, change one of {sorted(CHANGES)}"
            )
        parsed.append((parts[0], int(parts[1]), int(parts[2]), float(parts[3])))
    return parsed


def case_problem(
    spec: Any, kind: tuple | None, seed: int, runs: int, noise: float
) -> tuple[Any, StudyEvaluator]:
    """The data of one case (the worn truth with the change ``kind``, as ``CHANGES`` gives
    it: None, ("parameter", name, value) or ("effect", name, values)) and its paired
    evaluator: ``runs`` runs of seed ``seed`` with ``noise`` m/s² of sensor noise."""
    truth, effect = dict(WORN_TRUTH), None
    if kind is not None and kind[0] == "parameter":
        truth[kind[1]] = kind[2]
    elif kind is not None:
        effect = (kind[1], kind[2])
    problem = synthesize_problem(
        spec, effect, truth=truth, nu=runs, seed=seed, noise_m_s2=noise, output_error="paired"
    )
    return problem, StudyEvaluator(problem, problem.paired)


def main(argv: list[str] | None = None) -> int:
    """Print one line per case."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", help="change:seed:runs:noise_m_s2")
    args = parser.parse_args(argv)
    parsed = parse_cases(parser, args.cases)
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    truth_w = np.array([WORN_TRUTH[n] for n in NAMES], dtype=np.float64)
    for change, seed, runs, noise in parsed:
        problem, evaluator = case_problem(spec, CHANGES[change], seed, runs, noise)
        y = problem.measured
        weights = pure_error_weights(y, evaluator.spectra(truth_w[None])[0])
        weighted = fitted(evaluator, y, truth_w, weights)
        plain = fitted(evaluator, y, truth_w, np.ones(y.shape[1:]))
        f_weighted = lack_of_fit_ratio(y, evaluator.spectra(weighted[None])[0], weights)
        f_plain = lack_of_fit_ratio(y, evaluator.spectra(plain[None])[0], np.ones(y.shape[1:]))
        bias_weighted = np.max(np.abs(weighted / truth_w - 1)) * 100
        bias_plain = np.max(np.abs(plain / truth_w - 1)) * 100
        print(
            f"{change}:{seed}:{runs}:{noise:g}  F {f_weighted:.2f} (bias {bias_weighted:.2f} %)"
            f"  equal weights {f_plain:.2f} (bias {bias_plain:.2f} %)",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
