"""Detect → name → add → recalibrate → measure the gap: the discrepancy workflow.

1. **Base fit.** The calibrated base model (given, e.g. from a study, or fitted
   here with :func:`~susp_bo.discrepancy.fitting.fit_model`), polished to its
   maximum likelihood so that base and augmented models are compared on equal
   terms.
2. **Detection** (:mod:`.detection`): K posterior draws re-simulated on every
   measured track; standardised residuals; BH at q; flagged bands.
3. **Naming** (:mod:`.ranking`): every candidate effect refitted; the effect
   named is the best *score* (penalised log-likelihood gain) if it is > 0 and
   something was flagged; otherwise ``named_effect`` is None.
4. **Add and recalibrate.** The named effect's refit is the augmented model's
   maximum; its Laplace posterior gives the draws of the after-check (the same
   machinery as the base fit; the command line can recalibrate with the study
   loop instead, see :mod:`susp_bo.commands.diagnose`).
5. **Gap** (:func:`~susp_bo.discrepancy.detection.gap_metrics`): mean Z² over
   the bins flagged before, residual energy (dB) there, flagged fraction and
   posterior predictive log density — before and after.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from susp_bo.discrepancy.detection import Detection, gap_metrics, predictive_check
from susp_bo.discrepancy.fitting import Fit, fit_model
from susp_bo.discrepancy.problem import DiagnosisProblem, Simulator
from susp_bo.discrepancy.ranking import RankedEffect, rank_effects


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
    """

    q: float = 0.05
    n_draws: int = 6
    seed: int = 0
    candidates: tuple[str, ...] | None = None
    max_iterations: int = 12
    polish_base: bool = True

    def __post_init__(self) -> None:
        if not 0.0 < self.q < 1.0:
            raise ValueError(f"WorkflowSettings.q: got {self.q}; allowed range (0, 1)")
        if int(self.n_draws) != self.n_draws or self.n_draws < 2:
            raise ValueError(
                f"WorkflowSettings.n_draws: got {self.n_draws}; must be an integer >= 2"
            )
        if self.max_iterations < 1:
            raise ValueError(f"WorkflowSettings.max_iterations: got {self.max_iterations}; >= 1")


@dataclass(frozen=True)
class DiagnosisReport:
    """Everything the workflow found (``to_dict`` is ``discrepancy.json``)."""

    problem: DiagnosisProblem
    base: Fit
    before: Detection
    ranking: tuple[RankedEffect, ...]
    named_effect: str | None
    augmented: Fit | None
    after: Detection | None
    gap_before: dict[str, float]
    gap_after: dict[str, float]
    simulator: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def gap_ratio(self) -> float:
        """gap_after / gap_before of the headline value (1 when nothing was added)."""
        return self.gap_after["value"] / self.gap_before["value"]

    def parameter_table(self) -> list[dict[str, Any]]:
        """Base parameters before and after adding the effect, with the truth when known."""
        truth = self.problem.reference or {}
        after = self.augmented.parameters() if self.augmented is not None else {}
        rows = []
        for name, value in self.base.parameters().items():
            row: dict[str, Any] = {"name": name, "before": value, "after": after.get(name)}
            row["truth"] = truth.get(name)
            rows.append(row)
        if self.augmented is not None:
            for name, value in after.items():
                if name not in self.base.names:
                    rows.append({"name": name, "before": None, "after": value,
                                 "truth": truth.get(name)})  # fmt: skip
        return rows

    def to_dict(self) -> dict[str, Any]:
        """The ``discrepancy.json`` content (physical units)."""
        ranking = [r.to_dict() for r in self.ranking]
        scores = [r.score for r in self.ranking if math.isfinite(r.score)]
        margin = scores[0] - scores[1] if len(scores) >= 2 else None
        return {
            "flagged": [band.to_dict() for band in self.before.bands],
            "ranking": ranking,
            "named_effect": self.named_effect,
            "margin": margin,
            "gap_before": self.gap_before,
            "gap_after": self.gap_after,
            "gap_ratio": self.gap_ratio,
            "flagged_after": [] if self.after is None else [b.to_dict() for b in self.after.bands],
            "parameters": self.parameter_table(),
            "detection": {
                "q": self.before.q,
                "n_bins": int(self.before.z.size),
                "flagged_fraction": self.before.flagged_fraction,
                "channels": list(self.before.channels),
                "frequencies_hz": self.before.frequencies_hz.tolist(),
            },
            "base_log_likelihood": self.base.log_likelihood,
            "augmented_log_likelihood": None
            if self.augmented is None
            else self.augmented.log_likelihood,
            "simulator": self.simulator,
            **self.extra,
        }


def check(
    problem: DiagnosisProblem, simulator: Simulator, fit: Fit, settings: WorkflowSettings
) -> Detection:
    """The predictive check of a fitted model (K draws re-simulated on every track)."""
    draws = fit.draws(settings.n_draws, settings.seed)
    predicted = np.stack([problem.simulate(simulator, fit.spec, fit.names, w) for w in draws])
    return predictive_check(
        problem.measured,
        predicted,
        problem.sigma,
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


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """BLAS on one thread while the block runs (the small solves of the fast path are
    several times faster so, on a shared machine by far); restored afterwards."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl ships with the scientific stack
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


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
    with single_threaded_blas():
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
    name = simulator.name if fast is simulator else f"{simulator.name} (ranking: {fast.name})"
    if not before.bands:
        gap = gap_metrics(before, bins)
        return DiagnosisReport(problem, base, before, (), None, None, None, gap, gap, name)
    ranking_base = base if fast is simulator else fit_base(problem, fast, base.w)
    ranking = tuple(
        rank_effects(
            problem, fast, ranking_base, before, settings.candidates, settings.max_iterations
        )
    )
    best = ranking[0] if ranking else None
    if best is None or best.fit is None or not best.score > 0.0:
        gap = gap_metrics(before, bins)
        return DiagnosisReport(problem, base, before, ranking, None, None, None, gap, gap, name)
    augmented = best.fit if recalibrate is None else recalibrate(best)
    after = check(problem, simulator, augmented, settings)
    return DiagnosisReport(
        problem,
        base,
        before,
        ranking,
        best.effect,
        augmented,
        after,
        gap_metrics(before, bins),
        gap_metrics(after, bins),
        name,
    )
