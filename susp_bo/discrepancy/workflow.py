"""Detect → name → add → recalibrate → measure the gap: the discrepancy workflow.

1. **Base fit.** The calibrated base model (given, e.g. from a study, or fitted
   here with :func:`~susp_bo.discrepancy.fitting.fit_model`), polished to its
   maximum likelihood so that base and augmented models are compared on equal
   terms.
2. **Detection** (:mod:`.detection`): K posterior draws re-simulated on every
   measured track; standardised residuals; BH at q; flagged bands.
3. **Naming** (:mod:`.ranking`, :mod:`.verdict`): every candidate effect refitted
   and ranked by score (penalised log-likelihood gain); the best is named only if
   it passes the naming rule (:class:`~.verdict.NamingRule`: evidence, no effect
   parameter at a bound, explains the flagged pattern, leaves no comparable
   disagreement); otherwise the verdict is ``unexplained_disagreement``.
4. **Add and recalibrate.** The named effect's refit is the augmented model's
   maximum (or the command line recalibrates with the study loop, warm-started
   there, see :mod:`susp_bo.commands.diagnose`). The augmented model is accepted
   only if it beats the base model over *all* bins (log predictive density up,
   flagged share down, :func:`~.verdict.accept_augmented`); a recalibration that
   ends worse falls back to the ranking's refit when that passes, else the base
   model stays the answer.
5. **Gap** (:func:`~susp_bo.discrepancy.detection.gap_metrics`): mean Z² and
   residual energy (dB) over the bins flagged before and over all bins, flagged
   fraction and posterior predictive log density — before and after.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from susp_bo.discrepancy.detection import Detection, gap_metrics, predictive_check
from susp_bo.discrepancy.effects import EFFECTS, get_effect
from susp_bo.discrepancy.fitting import Fit, fit_model
from susp_bo.discrepancy.problem import DiagnosisProblem, Simulator
from susp_bo.discrepancy.ranking import RankedEffect, rank_effects
from susp_bo.discrepancy.report import DiagnosisReport
from susp_bo.discrepancy.verdict import NamingCheck, NamingRule, accept_augmented, check_naming
from susp_bo.numerics import one_blas_thread


@dataclass(frozen=True)
class WorkflowSettings:
    """Settings of :func:`run_workflow`.

    Args:
        q: BH false-discovery rate of the detection, in (0, 1).
        n_draws: posterior draws re-simulated per check (>= 2).
        seed: seed of the posterior draws.
        candidates: effect names to rank (None = the whole library).
        max_iterations: least-squares iterations per refit.
        polish_base: refit the given base model to its maximum first.
        rule: the naming rule's thresholds (:class:`~.verdict.NamingRule`).
    """

    q: float = 0.05
    n_draws: int = 6
    seed: int = 0
    candidates: tuple[str, ...] | None = None
    max_iterations: int = 12
    polish_base: bool = True
    rule: NamingRule = field(default_factory=NamingRule)

    def __post_init__(self) -> None:
        if not 0.0 < self.q < 1.0:
            raise ValueError(f"WorkflowSettings.q: got {self.q}; allowed range (0, 1)")
        for name, minimum in (("n_draws", 2), ("seed", 0)):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, numbers.Integral)
                or value < minimum
            ):
                raise ValueError(
                    f"WorkflowSettings.{name}: got {value!r}; must be an integer >= {minimum}"
                )
        if not isinstance(self.polish_base, bool):
            raise ValueError(
                f"WorkflowSettings.polish_base: got {self.polish_base!r}; expected True or False"
            )
        if not isinstance(self.rule, NamingRule):
            raise ValueError(
                f"WorkflowSettings.rule: got {type(self.rule).__name__}; expected a NamingRule"
            )
        if (
            isinstance(self.max_iterations, bool)
            or not isinstance(self.max_iterations, numbers.Integral)
            or self.max_iterations < 1
        ):  # SciPy's least squares never stops on a NaN or fractional limit
            raise ValueError(
                f"WorkflowSettings.max_iterations: got {self.max_iterations!r}; must be an "
                "integer >= 1"
            )
        if self.candidates is not None and (
            isinstance(self.candidates, str) or len(self.candidates) == 0
        ):
            raise ValueError(
                f"WorkflowSettings.candidates: got {self.candidates!r}; expected a non-empty "
                "sequence of effect names, or None for the whole library (with no effect "
                "tried, no disagreement could be called unexplained)"
            )
        if self.candidates is not None:
            unknown = [c for c in self.candidates if c not in EFFECTS]
            twice = sorted({c for c in self.candidates if list(self.candidates).count(c) > 1})
            if unknown or twice:  # checked here: on clean data the candidates are never read
                raise ValueError(
                    f"WorkflowSettings.candidates: {unknown or twice} "
                    f"{'unknown' if unknown else 'given more than once'}; allowed: distinct "
                    f"names of {', '.join(EFFECTS)}"
                )


def check(
    problem: DiagnosisProblem, simulator: Simulator, fit: Fit, settings: WorkflowSettings
) -> Detection:
    """The predictive check of a fitted model (K draws re-simulated on every track)."""
    draws = fit.draws(settings.n_draws, settings.seed)
    predicted = np.stack([problem.simulate(simulator, fit.spec, fit.names, w) for w in draws])
    return predictive_check(
        problem.measured,
        predicted,
        problem.detection_scale(predicted.mean(axis=0)),
        problem.spec.channels,
        problem.spec.spectrum.band_edges_hz(),
        settings.q,
    )


def fit_base(
    problem: DiagnosisProblem,
    simulator: Simulator,
    start: np.ndarray | None = None,
    max_iterations: int = 12,
) -> Fit:
    """Maximum-likelihood fit of the base model from ``start`` (default: the rig's values)."""
    if start is None:
        values = problem.spec.parameter_values()
        start = np.array([values[n] for n in problem.names])
    starts = [start]
    return fit_model(
        problem, simulator, problem.spec, problem.names, problem.bounds, starts, max_iterations
    )


Recalibrate = Callable[[RankedEffect], Fit]
"""``recalibrate(best) -> Fit``: calibrate the augmented rig of the best candidate."""


def run_workflow(
    problem: DiagnosisProblem,
    simulator: Simulator,
    base: Fit | None = None,
    settings: WorkflowSettings | None = None,
    fast: Simulator | None = None,
    recalibrate: Recalibrate | None = None,
) -> DiagnosisReport:
    """Detect, name, add, recalibrate and measure the gap (see the module docstring).

    Args:
        problem: measured data, tracks and the base rig.
        simulator: the model as calibrated, used for the checks before and after
            (the fast path :class:`~.problem.LinearSimulator`, or PyBullet).
        base: a fitted base model (e.g. from a study); fitted here when None.
        settings: workflow settings.
        fast: simulator of the ranking refits (default ``simulator``); with a
            different one the base is refitted on it so that base and candidates
            are compared on the same model.
        recalibrate: how the augmented rig is calibrated (default: the named
            candidate's refit, i.e. the same least-squares machinery as the base).
    """
    settings = settings or WorkflowSettings()
    with one_blas_thread():  # the small solves are faster so, and core-count independent
        return _run(problem, simulator, base, settings, fast or simulator, recalibrate)


def _run(
    problem: DiagnosisProblem,
    simulator: Simulator,
    base: Fit | None,
    settings: WorkflowSettings,
    fast: Simulator,
    recalibrate: Recalibrate | None,
) -> DiagnosisReport:
    if base is None:
        base = fit_base(problem, simulator, max_iterations=settings.max_iterations)
    elif settings.polish_base and fast is simulator:
        base = fit_base(problem, simulator, base.w, settings.max_iterations)
    before = check(problem, simulator, base, settings)
    bins = before.flagged
    gap = gap_metrics(before, bins)
    name = simulator.name if fast is simulator else f"{simulator.name} (ranking: {fast.name})"
    common = {"problem": problem, "base": base, "before": before, "gap_before": gap,
              "simulator": name}  # fmt: skip
    if not before.bands:  # a whole-channel level error alone: no library effect makes one
        verdict = "unexplained_disagreement" if before.offsets else "consistent"
        return DiagnosisReport(**common, ranking=(), named_effect=None, augmented=None,
                               after=None, gap_after=gap, verdict=verdict)  # fmt: skip
    ranking_base = base if fast is simulator else fit_base(problem, fast, base.w)
    ranking = tuple(
        rank_effects(
            problem, fast, ranking_base, before, settings.candidates, settings.max_iterations
        )
    )
    best = ranking[0] if ranking else None
    unexplained = {**common, "ranking": ranking, "named_effect": None, "augmented": None,
                   "after": None, "gap_after": gap,
                   "verdict": "unexplained_disagreement"}  # fmt: skip
    if best is None or best.fit is None:
        return DiagnosisReport(**unexplained)
    naming = name_check(
        problem, fast, ranking_base, before, best, settings, before if fast is simulator else None
    )
    if not naming.passes:
        return DiagnosisReport(**unexplained, naming_check=naming)
    augmented = best.fit if recalibrate is None else recalibrate(best)
    after = check(problem, simulator, augmented, settings)
    accepted, reasons = accept_augmented(before, after)
    extra: dict[str, Any] = {}
    if not accepted and recalibrate is not None:
        # the recalibration ended worse than the ranking's refit said: check the refit itself
        refit_after = check(problem, simulator, best.fit, settings)
        refit_ok, _ = accept_augmented(before, refit_after)
        extra["recalibration_rejected"] = [dict(r) for r in reasons]
        if refit_ok:
            augmented, after, accepted, reasons = best.fit, refit_after, True, []
            extra["augmented_source"] = "ranking refit (the recalibration was not better)"
    return DiagnosisReport(
        **common,
        ranking=ranking,
        named_effect=best.effect,
        augmented=augmented,
        after=after,
        gap_after=gap_metrics(after, bins),
        verdict="named",
        naming_check=naming,
        accepted=accepted,
        accept_reasons=tuple(reasons),
        extra=extra,
    )


def name_check(
    problem: DiagnosisProblem,
    fast: Simulator,
    ranking_base: Fit,
    before: Detection,
    best: RankedEffect,
    settings: WorkflowSettings,
    base_check: Detection | None = None,
) -> NamingCheck:
    """The naming rule on the best candidate: base refit and augmented refit checked on
    the ranking's simulator, compared on the bins flagged before (``base_check``: the
    base refit's check when already done)."""
    assert best.fit is not None
    if base_check is None:
        base_check = check(problem, fast, ranking_base, settings)
    augmented_check = check(problem, fast, best.fit, settings)
    return check_naming(
        best.effect,
        best.score,
        get_effect(best.effect).calibrated_names,
        best.fit.names,
        best.fit.w,
        best.fit.bounds,
        before.flagged,
        base_check,
        augmented_check,
        settings.rule,
    )
