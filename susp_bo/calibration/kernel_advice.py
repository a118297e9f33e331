"""Would the pairwise additive kernel have fitted this log L better? Advice, not a verdict.

On a curved posterior — a banana chained over 5 dimensions, whose log L is a sum of terms
in one or two parameters each — the default Matérn surrogate stays several nats too low
in the banana's arms, the refinement never looks there, and the run ends ``not_trusted``
(``not_converged``) with MMTV 0.13–0.16 against the exact posterior, where
``SurrogateSettings(kernel="auto")`` with ``refine_optimism=2`` reaches 0.02–0.03 at the
same budget (README, "What it achieves"; ``benchmarks/posterior_accuracy_results.md``).
The default does not fit the additive kernel at every refit (about 4× the cost of each),
so without this module a user on such a target is told "more budget", which refines the
same wrong surrogate.

When a run with the default kernel ends ``not_trusted`` for a surrogate reason
(:data:`.reliability_sentence.KERNEL_ADVISED_REASONS`), :func:`additive_kernel_gain` fits
the additive kernel once on the final surrogate's own training points, seed and settings
(what ``kernel="auto"`` would have compared at that refit) and returns the difference of
the two leave-one-out scores (:meth:`.surrogate.Surrogate.loo_log_score`: mean log
predictive density of the best third of the evaluations, nats a point). The verdict is
not changed; the gain goes into the evidence (``additive_kernel_loo_gain``) and, at or
above :data:`.reliability_sentence.ADDITIVE_GAIN_NATS`, the sentence's advice names the
kernel settings instead of "more budget" (:mod:`.reliability_sentence`). A trusted run,
or one with another kernel, pays nothing; the fit costs about one final fit with the
additive kernel (124–394 s against the Matérn's 41–106 s on the curved chain's 350
points, two shared cores).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from susp_bo.calibration.loop_step import FINAL_ITERATION, Laplace, fit_in_box, torch_state
from susp_bo.calibration.reliability import Reliability
from susp_bo.calibration.reliability_sentence import (
    ADDITIVE_GAIN_KEY,
    KERNEL_ADVISED_REASONS,
    advice_code,
)
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate import Surrogate

logger = logging.getLogger(__name__)


def needs_kernel_advice(reliability: Reliability | None, settings: CalibrationSettings) -> bool:
    """Whether the run used the default Matérn, its sentence would give the advice of a
    surrogate reason (:func:`.reliability_sentence.advice_code`: not when a noisy log L, a
    narrow posterior, a budget below the minimum or a bound leads), and its search reached
    the optimum.

    A search that did not (``not_converged`` with an optimum gap, or ``below_expected_fit``:
    the best point lies far below the fit the output error expects) needs budget first; a
    leave-one-out score of a surrogate that is wrong everywhere says nothing about the
    kernel (measured: the demo's problem at a budget of 60, 140–400 nats from the optimum,
    gave gains 0.08–0.39).
    """
    if reliability is None or reliability.trusted or settings.surrogate.kernel != "matern":
        return False
    reasons = reliability.reasons
    far = any(r["code"] == "below_expected_fit" for r in reasons) or any(
        "optimum_gap_nats" in r for r in reasons if r["code"] == "not_converged"
    )
    evidence = {k: v for k, v in reliability.evidence.items() if k != ADDITIVE_GAIN_KEY}
    return not far and advice_code(reasons, evidence, "python") in KERNEL_ADVISED_REASONS


def additive_kernel_gain(
    x: np.ndarray,
    y: np.ndarray,
    box: np.ndarray,
    settings: CalibrationSettings,
    iteration: int,
    final: Surrogate,
    boxed: bool = False,
    laplace: Laplace | None = None,
) -> float:
    """LOO score of the additive kernel minus ``final``'s, on ``final``'s training data.

    Used after a run (the advice: ``final`` is the run's final surrogate) and during one
    (:mod:`.kernel_switch`: ``final`` is the step's Matérn fit, ``iteration`` the step's).

    Args:
        x: (n x q) every evaluated point (physical units), as the final fit got them.
        y: (n,) their log L (NaN for failures; imputed as the final fit imputes them).
        box: (2 x q) the final fit's box; ``iteration``, ``boxed``, ``laplace``: the final
            fit's (:func:`.loop_step.fit_in_box`), so that the two fits differ only by kernel.
        settings: the run's settings (kernel "matern").
        final: the run's final surrogate.

    Returns:
        Nats a point; > 0 when the additive kernel predicts held-out evaluations better.
    """
    additive = dataclasses.replace(
        settings, surrogate=dataclasses.replace(settings.surrogate, kernel="additive_pairs")
    )
    fit = fit_in_box(x, y, box, additive, iteration, boxed, laplace)
    return float(fit.loo_log_score() - final.loo_log_score())


def with_kernel_gain(reliability: Reliability, gain: float) -> Reliability:
    """``reliability`` with the gain in its evidence and its sentence worded again
    (Python terms, as :func:`.reliability.assess` words it; a study rewords it)."""
    if not math.isfinite(gain):  # JSON would store null: nothing to advise on
        return reliability
    evidence = dict(reliability.evidence) | {ADDITIVE_GAIN_KEY: gain}
    return dataclasses.replace(reliability, evidence=evidence).worded_for("python")


def with_kernel_advice(
    reliability: Reliability | None,
    x: np.ndarray,
    y: np.ndarray,
    box: np.ndarray,
    settings: CalibrationSettings,
    final: Surrogate,
    boxed: bool = False,
) -> Reliability | None:
    """The finished run's verdict with the gain in its evidence where it advises
    (:func:`needs_kernel_advice`), else ``reliability`` itself; arguments as
    :func:`additive_kernel_gain` (the final fit's; only unboxed, so no Laplace bowl). A fit
    that fails is logged and the verdict kept: advice must not lose a finished result.

    Not in a search box (``boxed``: a trust region or the local phase's box): there the
    GP models what is left of log L around the Laplace bowl on the few points in the box,
    and the gain says nothing about the posterior's shape (session 37, on the demo's
    problem: +0.01 to +1.18 in the box of results the Matérn got ``trusted`` and right;
    :mod:`.kernel_switch`). Such a run is advised more budget, as before session 30.
    """
    if reliability is None or boxed or not needs_kernel_advice(reliability, settings):
        return reliability
    try:
        with torch_state(settings.num_threads):
            gain = additive_kernel_gain(x, y, box, settings, FINAL_ITERATION, final)
    except Exception as error:  # BoTorch's ModelFittingError is an Exception
        logger.warning("the additive kernel could not be fitted for advice: %s", error)
        return reliability
    logger.info("additive kernel's leave-one-out gain over the Matérn: %.3f nats", gain)
    return with_kernel_gain(reliability, gain)
