"""The four steps of the paper (section 3.1) as one driver: :func:`calibrate`.

1. space-filling design of C_w (:mod:`.design`);
2. kriging of log L, refitted after every batch (:mod:`.surrogate`);
3. refinement in batches of ``batch_size`` points (simulator calls run in parallel):
   a. EGO with qLogEI until the stopping rule — batch EI below ``ei_tolerance`` x
      the spread (sd) of the observed latent log L — or until EGO has used
      ``max_ego_fraction`` of the evaluations left after the design;
   a''. with ``settings.basin_search`` (default): when EGO ends, local qLogEI climbs from
      evaluated points that head basins of the surrogate other than the best point's
      (:mod:`.basin_search`: modes EGO saw only at their fringe), up to
      ``basin.budget_fraction`` of the evaluations left; nothing when there is none;
   a'. with ``settings.local_search`` and an evaluator that exposes its spectra
      (:class:`.local_search.SpectraEvaluator`, as the study's does): when EGO ends,
      trust-region Gauss–Newton on the spectra from the best point (up to
      ``local_search_fraction`` of the evaluations left); its runs join the data and
      its Laplace approximation sets the search box (mode ± ``trust_region_half_width_sd``
      sd, :mod:`.trust_region`) and the GP's fixed prior mean (``laplace_mean``);
   b. posterior refinement (:func:`.acquisition.select_uncertainty_batch`) until the
      posterior mean of sd[log L̃] falls below ``refine_tolerance`` nats;
   all within the budget ``max_evaluations``;
4. MH sampling of the surrogate posterior and summaries (:mod:`.mcmc`, :mod:`.posterior`).

Before the first evaluation the budget is checked against what q needs
(:func:`.reliability.budget_requirement`); a smaller one raises
:class:`BudgetTooSmallError` unless ``settings.allow_small_budget``. After the MCMC
the result gets its reliability verdict (:func:`.reliability.assess`).

Failed evaluations (``evaluate`` returns NaN or −inf) are kept as NaN in the result;
for the surrogate they are imputed with the lowest finite log L observed so far
(recomputed at every refit), which steers the search away from them without
inventing structure below the data. If the whole initial design fails,
``RuntimeError`` is raised.

Determinism: every random choice (design scrambling, acquisition restarts, QMC
samplers, hyperparameter restarts, MCMC) is seeded from ``settings.seed`` and the
iteration number, and runs under ``torch.random.fork_rng`` (no global state is
changed). Given the same seed and the same ``evaluate`` results (e.g. replayed from
a cache), a rerun reproduces the result exactly.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from susp_bo.calibration.acquisition import (
    posterior_candidates,
    propose_ei_batch,
    refinement_candidates,
    select_uncertainty_batch,
)
from susp_bo.calibration.basin_search import ClimbReport, basin_phase
from susp_bo.calibration.design import (
    check_bounds,
    default_design_size,
    from_unit,
    space_filling_design,
    to_unit,
)
from susp_bo.calibration.iteration_record import PhaseRecorder, record_iteration
from susp_bo.calibration.local_search import LocalSearchResult, SpectraEvaluator, local_search
from susp_bo.calibration.posterior import summarize
from susp_bo.calibration.reliability import (
    assess,
    budget_message,
    budget_requirement,
)
from susp_bo.calibration.result import CalibrationResult, IterationReport, Phase
from susp_bo.calibration.sampling import (
    sample_surrogate_posterior,
    surrogate_log_likelihood,
)
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate import Bowl, Surrogate, fit_surrogate
from susp_bo.calibration.surrogate_check import (
    SurrogateCheck,
    edge_points,
    observation_noise_sd,
)
from susp_bo.calibration.trust_region import box_edge, next_box, to_global_unit, training_mask
from susp_bo.progress import progress_bar

logger = logging.getLogger(__name__)

Evaluate = Callable[[np.ndarray], np.ndarray]
_FINAL = 1_000_000  # iteration index used to seed the final fit and MCMC
_CHECK = 2_000_000  # iteration index used to seed the surrogate check


@contextmanager
def torch_threads(n: int | None) -> Iterator[None]:
    """Temporarily sets torch's intra-op thread count (None: unchanged)."""
    if n is None:
        yield
        return
    previous = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def _seed(master: int, iteration: int, purpose: int) -> int:
    return int(np.random.SeedSequence([master, iteration, purpose]).generate_state(1)[0])


def _impute(y: np.ndarray) -> np.ndarray:
    if np.any(y == math.inf):
        raise ValueError("evaluate: returned +inf, which is not a valid log-likelihood")
    finite = np.isfinite(y)
    if not finite.any():
        raise RuntimeError("every log L evaluation failed (NaN/-inf): nothing to fit")
    return np.where(finite, y, np.min(y[finite]))


def _evaluate(evaluate: Evaluate, w: np.ndarray) -> np.ndarray:
    out = np.asarray(evaluate(np.array(w, dtype=np.float64)), dtype=np.float64).reshape(-1)
    if out.shape != (w.shape[0],):
        raise ValueError(f"evaluate: returned shape {out.shape}, expected ({w.shape[0]},)")
    return np.where(out == -math.inf, np.nan, out)


def _refinement_candidates(
    surrogate: Surrogate, settings: CalibrationSettings, seed: int
) -> tuple[torch.Tensor, int]:
    """:func:`.acquisition.refinement_candidates` with the settings' count, estimator, optimism."""
    return refinement_candidates(
        surrogate, settings.candidate_count, settings.estimator, settings.refine_optimism, seed
    )


def _fit(
    x: np.ndarray,
    y: np.ndarray,
    box: np.ndarray,
    settings: CalibrationSettings,
    iteration: int,
    boxed: bool = False,
    laplace: Laplace | None = None,
) -> Surrogate:
    """The surrogate in ``box``'s unit cube, seeded by ``iteration``.

    Fitted on every evaluation so far (failures imputed) or, with a trust region, on those
    in and near the box (:func:`.trust_region.training_mask`), when ``boxed``. With the
    local phase's Laplace approximation, that bowl is the GP's fixed prior mean.
    """
    y = _impute(y)
    if boxed:
        # with the Laplace bowl as the mean, far points (thousands of nats below it) only
        # inflate the GP's scale: keep the box's neighbourhood, at least q + 2 points
        q = x.shape[1]
        keep = training_mask(x, box, min_points=q + 2 if laplace is not None else 2 * q + 2)
        x, y = x[keep], y[keep]
    bowl = None if laplace is None else laplace.bowl(box)
    return fit_surrogate(
        to_unit(x, box), y, settings.surrogate, _seed(settings.seed, iteration, 1), bowl
    )


@dataclass(frozen=True)
class _Step:
    phase: Phase
    proposal: torch.Tensor | None
    criterion: float
    stop_reason: str
    box: np.ndarray


def _propose(
    x: np.ndarray,
    y: np.ndarray,
    bounds: np.ndarray,
    box: np.ndarray,
    phase: Phase,
    size: int,
    iteration: int,
    ego_exhausted: bool,
    settings: CalibrationSettings,
    boxed: bool,
    laplace: Laplace | None = None,
) -> _Step:
    """Refits the surrogate and proposes the next batch (None when a stopping rule fires).

    With a trust region, every refinement step may move the search box first
    (:func:`.trust_region.next_box`); the returned step carries the box its proposal is in.
    """
    seed = settings.seed
    surrogate = _fit(x, y, box, settings, iteration, boxed, laplace)
    if phase == "ego":
        u, criterion = propose_ei_batch(
            surrogate,
            size,
            _seed(seed, iteration, 2),
            settings.acquisition_restarts,
            settings.acquisition_raw_samples,
        )
        converged = criterion < settings.ei_tolerance
        if not (converged or ego_exhausted):
            return _Step("ego", u, criterion, "", box)
        if not settings.refine:
            return _Step("ego", None, criterion, "ego_converged" if converged else "budget", box)
    candidates, n_post = _refinement_candidates(surrogate, settings, _seed(seed, iteration, 3))
    if boxed:
        finite = np.isfinite(y)
        best = x[finite][int(np.argmax(y[finite]))]
        moved = next_box(
            candidates[:n_post].numpy(), box, bounds, best, settings.trust_region_half_width_sd
        )
        if moved is not None:
            logger.info("search box: %s", np.array2string(moved, precision=4))
            box = moved
            surrogate = _fit(x, y, box, settings, iteration, boxed, laplace)
            candidates, n_post = _refinement_candidates(
                surrogate, settings, _seed(seed, iteration, 3)
            )
    u, criterion = select_uncertainty_batch(
        surrogate, candidates, size, n_post, optimism=settings.refine_optimism
    )
    if criterion < settings.refine_tolerance:
        return _Step("refine", None, criterion, "converged", box)
    return _Step("refine", u, criterion, "", box)


@dataclass(frozen=True)
class Laplace:
    """The local phase's Laplace approximation in physical units: mode (q,), covariance (q x q)."""

    mode: np.ndarray
    covariance: np.ndarray

    @classmethod
    def of(cls, local: LocalSearchResult, bounds: np.ndarray) -> Laplace:
        """From the local phase's unit-cube result and C_w's bounds."""
        span = bounds[1] - bounds[0]
        return cls(bounds[0] + local.mode * span, local.covariance * np.outer(span, span))

    def bowl(self, box: np.ndarray) -> Bowl:
        """The bowl −½ (v − c)ᵀ P (v − c) in ``box``'s unit cube (v)."""
        width = box[1] - box[0]
        cov = self.covariance / np.outer(width, width)
        precision = np.linalg.inv(cov)
        return Bowl((self.mode - box[0]) / width, 0.5 * (precision + precision.T))


def _hold_best(box: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``box`` widened to hold the best evaluated point (physical units)."""
    finite = np.isfinite(y)
    best = x[finite][int(np.argmax(y[finite]))]
    return np.stack([np.minimum(box[0], best), np.maximum(box[1], best)])


def _run_basin_phase(
    evaluate: Evaluate,
    bounds: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    main_budget: int,
    iteration: int,
    settings: CalibrationSettings,
    history: list[IterationReport],
    on_iteration: Callable[[IterationReport], None] | None,
    bar: Any,
) -> tuple[np.ndarray, np.ndarray, int, list[ClimbReport]]:
    """The basin phase (:mod:`.basin_search`) on C_w; its runs join the data."""
    data = PhaseRecorder(x, y, iteration, history, on_iteration, bar)

    def fit(x_unit: np.ndarray, values: np.ndarray) -> Surrogate:
        # the same data as (x_unit, values), as evaluated (no unit-cube round trip)
        return _fit(data.x, data.y, bounds, settings, data.iteration + 1)

    def run(u: np.ndarray) -> np.ndarray:
        w = from_unit(u, bounds)
        values = _evaluate(evaluate, w)
        finite = values[np.isfinite(values)]
        data.add("basin", w, values, float(finite.max()) if finite.size else math.nan)
        return values

    with torch_threads(settings.num_threads):
        climbs = basin_phase(
            to_unit(x, bounds),
            y,
            int(settings.basin.budget_fraction * (main_budget - x.shape[0])),
            settings.batch_size,
            settings.basin,
            fit,
            run,
            lambda: _seed(settings.seed, data.iteration + 1, 6),
            settings.acquisition_restarts,
            settings.acquisition_raw_samples,
        )
    for report in climbs:
        logger.info(
            "basin search: climbed from log L %.6g to %.6g in %d evaluations (%s)",
            report.start_log_likelihood,
            report.end_log_likelihood,
            report.n_evaluations,
            report.stop_reason,
        )
    return data.x, data.y, data.iteration, climbs


def _run_local_phase(
    evaluate: SpectraEvaluator,
    bounds: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    main_budget: int,
    iteration: int,
    settings: CalibrationSettings,
    history: list[IterationReport],
    on_iteration: Callable[[IterationReport], None] | None,
    bar: Any,
) -> tuple[np.ndarray, np.ndarray, LocalSearchResult, int]:
    """The local phase (:mod:`.local_search`) from the best point; its runs join the data."""
    finite = np.isfinite(y)
    start = x[finite][int(np.argmax(y[finite]))]
    cap = int(settings.local_search_fraction * (main_budget - x.shape[0]))
    data = PhaseRecorder(x, y, iteration, history, on_iteration, bar)

    def record(w: np.ndarray, values: np.ndarray, gain: float) -> None:
        data.add("local", w, values, gain)

    result = local_search(evaluate, bounds, start, cap, on_evaluations=record)
    return data.x, data.y, result, data.iteration


class BudgetTooSmallError(ValueError):
    """The budget leaves no room for refinement and the check (raised before any evaluation)."""


def _propose_check(
    x: np.ndarray,
    y: np.ndarray,
    bounds: np.ndarray,
    size: int,
    settings: CalibrationSettings,
    boxed: bool,
    laplace: Laplace | None = None,
) -> tuple[torch.Tensor, np.ndarray, np.ndarray, np.ndarray]:
    """Edge points of the current surrogate posterior, the predictions and noise sd there."""
    surrogate = _fit(x, y, bounds, settings, _CHECK, boxed, laplace)
    post, _ = posterior_candidates(
        surrogate, settings.candidate_count, settings.estimator, _seed(settings.seed, _CHECK, 3)
    )
    u = edge_points(post, surrogate_log_likelihood(surrogate, settings.estimator)(post), size)
    mean, sd = surrogate.log_likelihood_uncertainty(u)
    return u, mean.numpy(), sd.numpy(), observation_noise_sd(surrogate, u)


def calibrate(
    evaluate: Evaluate,
    bounds: np.ndarray,
    names: Sequence[str],
    settings: CalibrationSettings | None = None,
    progress: bool = True,
    on_iteration: Callable[[IterationReport], None] | None = None,
    design: np.ndarray | None = None,
    expected_at_truth: tuple[float, float] | None = None,
    initial_points: np.ndarray | None = None,
) -> CalibrationResult:
    """Bayesian calibration of w on C_w from log L evaluations (the paper's four steps).

    Args:
        evaluate: maps W (b x q, physical units) to (b,) log L; NaN marks a failed run.
            Called with whole batches (the design, then ``batch_size`` points).
        bounds: (2 x q) lower/upper bounds of C_w (uniform prior).
        names: (q,) parameter names.
        settings: calibration settings (defaults if None).
        progress: show a progress bar of evaluations on stderr (susp_bo.progress).
        on_iteration: called with an :class:`IterationReport` after every batch.
        design: (n0 x q) initial design in physical units, inside C_w, instead of the
            space-filling one (a warm start, :mod:`susp_bo.monitoring.warm_start`);
            None = the space-filling design of ``initial_design_size`` points.
        expected_at_truth: (mean, sd) of log L at the true parameters expected under the
            output-error model (needs the model, not the truth), when it provides one; the
            verdict then also checks the best log L against it.
        initial_points: (m x q) points (physical units, clipped to the bounds) evaluated
            with the design, which has m points fewer (a warm start: e.g. a previous
            fit's maximum); None = none.

    Returns:
        The :class:`CalibrationResult` (with its reliability verdict).

    Raises:
        BudgetTooSmallError: the budget is below the minimum for q and
            ``settings.allow_small_budget`` is False (before any evaluation).
    """
    settings = settings or CalibrationSettings()
    b = check_bounds(bounds)
    q = b.shape[1]
    if len(names) != q:
        raise ValueError(f"names: {len(names)} names for q = {q} parameters")
    budget = settings.max_evaluations or 50 * (q + 2)
    requirement = budget_requirement(
        q, settings.initial_design_size, settings.batch_size, settings.check_points
    )
    if budget < requirement.minimum:
        if not settings.allow_small_budget:
            raise BudgetTooSmallError(
                budget_message(budget, requirement, "max_evaluations", "set allow_small_budget")
            )
        logger.warning(
            "budget of %d evaluations below the minimum %s: running anyway on request; the "
            "result will not be trusted",
            budget,
            requirement.describe(),
        )
    n0 = min(settings.initial_design_size or default_design_size(q), budget)
    n_check = min(settings.check_points, budget - n0)
    main_budget = budget - n_check
    bar = progress_bar(total=budget, desc="log L evaluations", unit="eval", disable=not progress)
    extra = np.empty((0, q)) if initial_points is None else np.atleast_2d(initial_points)
    if design is None:
        if extra.shape[1:] != (q,) or extra.shape[0] >= n0:
            raise ValueError(
                f"initial_points: shape {extra.shape}; expected (m x {q}) with m < {n0}"
            )
        x = space_filling_design(
            n0 - len(extra), b, _seed(settings.seed, 0, 0), settings.design_method
        )
        x = np.vstack([x, np.clip(extra, b[0], b[1])])
    else:
        if initial_points is not None:
            raise ValueError("design, initial_points: give one of them, not both")
        x = np.array(design, dtype=np.float64, copy=True)
        if x.ndim != 2 or x.shape[1] != q or not 2 <= x.shape[0] <= budget:
            raise ValueError(f"design: shape {x.shape}; expected (n0 x {q}), 2 <= n0 <= {budget}")
        if np.any(x < b[0]) or np.any(x > b[1]):
            raise ValueError("design: points outside the bounds C_w")
        n0 = x.shape[0]
        n_check = min(settings.check_points, budget - n0)
        main_budget = budget - n_check
    y = _evaluate(evaluate, x)
    bar.update(n0)
    box = b.copy()
    phase: Phase = "ego"
    ego_cap = n0 + int(settings.max_ego_fraction * (main_budget - n0))
    history: list[IterationReport] = []
    stop_reason = "budget"
    iteration = 0
    boxed = settings.trust_region
    local: LocalSearchResult | None = None
    laplace: Laplace | None = None
    basins_done = False
    climbs: list[ClimbReport] = []
    wants_local = settings.local_search and isinstance(evaluate, SpectraEvaluator)
    if settings.local_search and not wants_local:
        logger.warning(
            "local_search: the evaluator exposes no spectra (spectra/log_likelihood_of); "
            "running without the local phase"
        )
    while x.shape[0] < main_budget:
        iteration += 1
        size = min(settings.batch_size, main_budget - x.shape[0])
        with torch_threads(settings.num_threads):
            step = _propose(
                x,
                y,
                b,
                box,
                phase,
                size,
                iteration,
                x.shape[0] >= ego_cap,
                settings,
                boxed,
                laplace,
            )
        phase, box = step.phase, step.box
        if settings.basin_search and not basins_done and phase == "refine":
            basins_done = True
            n_before = x.shape[0]
            x, y, iteration, new_climbs = _run_basin_phase(
                evaluate, b, x, y, main_budget, iteration, settings, history, on_iteration, bar
            )
            climbs.extend(new_climbs)
            if x.shape[0] > n_before:
                continue
        if wants_local and local is None and phase == "refine":
            x, y, local, iteration = _run_local_phase(
                evaluate, b, x, y, main_budget, iteration, settings, history, on_iteration, bar
            )
            box = from_unit(local.box(settings.trust_region_half_width_sd), b)
            box = _hold_best(box, x, y)
            boxed = True
            laplace = Laplace.of(local, b) if settings.laplace_mean else None
            logger.info(
                "local phase: %s after %d evaluations; search box %s",
                local.stop_reason,
                local.n_evaluations,
                np.array2string(box, precision=5),
            )
            continue
        if step.proposal is None:
            stop_reason = step.stop_reason
            break
        w_new = from_unit(step.proposal.numpy(), box)
        y_new = _evaluate(evaluate, w_new)
        x, y = np.vstack([x, w_new]), np.concatenate([y, y_new])
        bar.update(size)
        record_iteration(iteration, phase, x, y, step.criterion, history, on_iteration)
    check = None
    if n_check > 0:
        with torch_threads(settings.num_threads):
            u, predicted, sd, noise = _propose_check(x, y, box, n_check, settings, boxed, laplace)
        w_new = from_unit(u.numpy(), box)
        y_new = _evaluate(evaluate, w_new)
        check = SurrogateCheck(u.numpy(), predicted, sd, y_new, settings.check_tolerance, noise)
        x, y = np.vstack([x, w_new]), np.concatenate([y, y_new])
        bar.update(n_check)
        record_iteration(iteration + 1, "check", x, y, check.max_abs_error, history, on_iteration)
        (logger.info if check.verdict == "ok" else logger.warning)(check.line())
    bar.close()
    with torch_threads(settings.num_threads):
        surrogate = _fit(x, y, box, settings, _FINAL, boxed, laplace)
        draws_u, diag = sample_surrogate_posterior(
            surrogate,
            n_chains=settings.mcmc_chains,
            warmup_steps=settings.mcmc_warmup,
            num_samples=settings.mcmc_samples,
            seed=(
                _seed(settings.seed, _FINAL, 4)
                if settings.mcmc_seed is None
                else _seed(settings.mcmc_seed, _FINAL, 5)
            ),
            estimator=settings.estimator,
            backend=settings.mcmc_backend,
            progress=progress,
        )
        log_l = surrogate_log_likelihood(surrogate, settings.estimator)
        summary = summarize(draws_u.numpy(), box, list(names), log_l)
        u_map = torch.as_tensor(to_unit(summary.joint_map[None, :], box), dtype=torch.float64)
        with torch.no_grad():
            predicted_max = float(log_l(u_map)[0])
            predicted_max_sd = float(surrogate.log_likelihood_uncertainty(u_map)[1][0])
    searched = [h for h in history if h.phase != "check"]
    reliability = assess(
        names=names,
        bounds=b,
        budget=budget,
        requirement=requirement,
        best_log_likelihood=float(np.nanmax(y)) if np.isfinite(y).any() else -math.inf,
        predicted_max=predicted_max,
        predicted_max_sd=predicted_max_sd,
        stop_reason=stop_reason,
        last_phase=searched[-1].phase if searched else None,
        last_criterion=searched[-1].criterion if searched else math.nan,
        draws_unit=to_global_unit(draws_u.numpy(), box, b),
        r_hat=summary.r_hat,
        ess=summary.ess,
        check=check,
        expected_at_truth=expected_at_truth,
        box_edge=box_edge(draws_u.numpy().reshape(-1, q), box, b, names),
        modes=int(diag.get("modes", 1) or 1),
    )
    logger.info(reliability.sentence)
    draws = from_unit(draws_u.numpy().reshape(-1, q), box).reshape(draws_u.shape)
    return CalibrationResult(
        names=tuple(names),
        bounds=b,
        X=x,
        y=y,
        surrogate=surrogate,
        draws=draws,
        summary=summary,
        n_evaluations=int(x.shape[0]),
        stop_reason=stop_reason,
        history=tuple(history),
        mcmc=diag,
        check=check,
        reliability=reliability,
        search_box=box if boxed else None,
        local_search=local,
        basins=tuple(climbs),
    )
