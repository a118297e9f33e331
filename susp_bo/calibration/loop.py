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
      with ``basin.hunt_beta`` > 0 (3, the default since session 43) on a global search
      with fixed noise, where the surrogate has two confirmed peaks when the phase starts
      it also hunts, at the maxima of its upper bound, for modes no evaluation came near
      (:mod:`.mode_hunt`); where the phase counts two or more confirmed peaks (several
      modes met) on a global search with fixed noise, the rest of the refinement runs
      with ``refine_optimism`` >= ``modes_refine_optimism`` (2; session 42);
   a'. with ``settings.local_search`` and an evaluator that exposes its spectra
      (:class:`.local_search.SpectraEvaluator`, as the study's does): when EGO ends,
      trust-region Gauss–Newton on the spectra from the best point (up to
      ``local_search_fraction`` of the evaluations left); its runs join the data and
      its Laplace approximation sets the search box (mode ± ``trust_region_half_width_sd``
      sd, :mod:`.trust_region`) and the GP's fixed prior mean (``laplace_mean``);
   b. posterior refinement (:func:`.acquisition.select_uncertainty_batch`) until the
      posterior mean of sd[log L̃] falls below ``refine_tolerance`` nats; with
      ``settings.kernel_switch`` a global search compares the pairwise additive kernel with
      the Matérn as it starts and every 10 % of the budget after, and may go on with
      ``kernel="auto"`` (:mod:`.kernel_switch`);
   all within the budget ``max_evaluations``;
4. MH sampling of the surrogate posterior and summaries (:mod:`.mcmc`, :mod:`.posterior`).

One step of 2–3 (refit, then propose a batch or stop) is :func:`.loop_step.propose_step`.

Before the first evaluation the budget is checked against what q needs
(:func:`.budget.budget_requirement`); a smaller one raises
:class:`BudgetTooSmallError` unless ``settings.allow_small_budget``. After the MCMC
the result gets its reliability verdict (:func:`.reliability.assess`); with an evaluator
that exposes its spectra and the measured runs (``spectra`` and ``measured``, as
:class:`.evaluation.LikelihoodEvaluator` does), the verdict also weighs, under the
unpaired B, whether the simulated runs reproduce the measured ones at all
(:func:`.track_match.with_track_match`: tracks that are not the runs' own, session 32),
and the lack of fit between ν ≥ 2 runs (:func:`.lack_of_fit.with_lack_of_fit`: a model
that misses an effect every run shows; with one run it is recorded as not checked) and,
under the summary likelihood, the summaries its fit does not use
(:func:`.fit_rules.with_summary_misfit`), whoever calls — a study, ``susp-bo
diagnose``'s recalibration or the Python API (session 27: before, only a study applied it).

Failed evaluations (``evaluate`` returns NaN or −inf) are kept as NaN in the result;
for the surrogate they are imputed with the lowest finite log L observed so far
(recomputed at every refit), which steers the search away from them without
inventing structure below the data. If the whole initial design fails, or all of it
but one point, or log L is the same at all of its finite points,
:class:`UninformativeDesignError` (a ``RuntimeError``) is raised after the design, before
any more evaluations.

Determinism: every random choice (design scrambling, acquisition restarts, QMC
samplers, hyperparameter restarts, MCMC) is seeded from ``settings.seed`` and the
iteration number, and runs under ``torch.random.fork_rng`` (no global state is
changed). Given the same seed and the same ``evaluate`` results (e.g. replayed from
a cache), a rerun reproduces the result exactly.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

from susp_bo.calibration.basin_search import ClimbReport
from susp_bo.calibration.box_mass import share_outside_box
from susp_bo.calibration.budget import BudgetTooSmallError, budget_message, budget_requirement
from susp_bo.calibration.design import (
    check_bounds,
    default_design_size,
    from_unit,
    space_filling_design,
    to_unit,
)
from susp_bo.calibration.exploration_audit import audit_size, run_audit
from susp_bo.calibration.fit_rules import with_fit_rules
from susp_bo.calibration.iteration_record import record_iteration
from susp_bo.calibration.kernel_advice import with_kernel_advice
from susp_bo.calibration.kernel_switch import KernelSwitcher
from susp_bo.calibration.local_search import LocalSearchResult, SpectraEvaluator
from susp_bo.calibration.loop_phases import run_basin_phase, run_local_phase
from susp_bo.calibration.loop_step import (
    FINAL_ITERATION,
    Evaluate,
    Laplace,
    derived_seed,
    evaluate_checked,
    fit_in_box,
    impute_failures,
    propose_check,
    propose_step,
    repeated_check,
    torch_state,
)
from susp_bo.calibration.mode_jumps import modes_chains_stayed_in
from susp_bo.calibration.posterior import check_names, summarize
from susp_bo.calibration.reliability import (
    POOR_MIXING_R_HAT,
    assess,
    checked_expected_at_truth,
)
from susp_bo.calibration.result import CalibrationResult, IterationReport, Phase
from susp_bo.calibration.sampling import (
    mean_sd_at_draws,
    sample_surrogate_posterior,
    surrogate_log_likelihood,
)
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate_check import SurrogateCheck
from susp_bo.calibration.track_match import with_track_match
from susp_bo.calibration.trust_region import box_edge, held_points, hold_points, to_global_unit
from susp_bo.numerics import one_blas_thread
from susp_bo.progress import progress_bar

logger = logging.getLogger(__name__)


def _check_finite(argument: str, points: np.ndarray) -> None:
    """Refuses points with NaN or ±inf coordinates before any of them is evaluated."""
    values = np.asarray(points, dtype=np.float64)
    bad = ~np.all(np.isfinite(values), axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{argument}: row {row} is {values[row].tolist()!r}; NaN and infinite coordinates "
            f"are not allowed (in {int(bad.sum())} of {len(values)} rows); expected finite "
            "points in C_w"
        )


class UninformativeDesignError(RuntimeError):
    """The design's log L cannot inform a surrogate: every run failed, only one succeeded,
    or log L is the same at every finite point (raised right after the design; the
    evaluations made are kept in a study's store)."""


def _check_design_values(y: np.ndarray) -> None:
    """Raises as soon as the design's log L cannot inform a surrogate (before any more
    evaluations): every run failed, only one succeeded, or log L is the same everywhere.

    Raises:
        ValueError: ``evaluate`` returned +inf (as at every refit:
            :func:`.loop_step.impute_failures`).
        UninformativeDesignError: naming what happened.
    """
    if np.any(y == math.inf):
        raise ValueError("evaluate: returned +inf, which is not a valid log-likelihood")
    finite = y[np.isfinite(y)]
    n = y.size
    if finite.size == 0:
        raise UninformativeDesignError(
            f"every log L evaluation failed (NaN/-inf) at the {n} points of the design: "
            "nothing to fit"
        )
    if finite.size == 1:
        raise UninformativeDesignError(
            f"only 1 of the {n} log L evaluations of the design succeeded (log L = "
            f"{float(finite[0])!r}); the others failed (NaN/-inf): the surrogate needs at least "
            "two distinct values"
        )
    if np.all(finite == finite[0]):
        failed = f" ({n - finite.size} failed)" if finite.size < n else ""
        raise UninformativeDesignError(
            f"log L is constant ({float(finite[0])!r}) over the {finite.size} finite "
            f"evaluations of the design{failed}: the data do not inform the parameters or the "
            "evaluator ignores them"
        )


@one_blas_thread()  # main-process BLAS (log L, surrogate, chains) core-count independent
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
    lack_of_fit: bool = True,
) -> CalibrationResult:
    """Bayesian calibration of w on C_w from log L evaluations (the paper's four steps).

    Args:
        evaluate: maps W (b x q, physical units) to (b,) log L; NaN marks a failed run.
            Called with whole batches (the design, then ``batch_size`` points; an early
            stop's audit, :mod:`.exploration_audit`, up to half the evaluations left at
            once). A failed held-out check evaluates its 2 worst points once more to tell
            noise from misfit (:func:`.loop_step.repeated_check`): those 2 are beyond
            ``max_evaluations`` and not in the data.
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
        initial_points: (m x q) finite points (physical units, clipped to the bounds) evaluated
            with the design, which has m points fewer (a warm start: e.g. a previous
            fit's maximum); None = none.
        lack_of_fit: weigh the lack of fit between the measured runs in the verdict when
            ``evaluate`` exposes ``spectra(W)`` and ``measured`` ((ν x C x F), ν ≥ 2):
            F at the best point, and Gauss–Newton steps from it when F is high on an
            otherwise trusted result (:func:`.lack_of_fit.with_lack_of_fit`; those runs are
            beyond ``max_evaluations`` and not in the data); with one measured run F
            cannot be computed, ``evidence.lack_of_fit_ratio`` is null and a trusted
            sentence says the check was not made. False = the verdict of the other rules
            alone (a benchmark's "before").

    Returns:
        The :class:`CalibrationResult` (with its reliability verdict).

    Raises:
        BudgetTooSmallError: the budget is below the minimum for q and
            ``settings.allow_small_budget`` is False (before any evaluation).
        ValueError: bad input (names, bounds, ``expected_at_truth`` …; a repeated name;
            NaN or infinite coordinates in ``design`` or ``initial_points``), before any
            evaluation; ``evaluate`` returned +inf (when it does).
        UninformativeDesignError: the design's log L cannot be fitted (every evaluation failed, only
            one succeeded, or log L is constant over it), raised after the design.
    """
    settings = settings or CalibrationSettings()
    b = check_bounds(bounds)
    q = b.shape[1]
    if len(names) != q:
        raise ValueError(f"names: {len(names)} names for q = {q} parameters")
    check_names(names)
    expected_at_truth = checked_expected_at_truth(expected_at_truth)
    budget = settings.max_evaluations or 50 * (q + 2)
    requirement = budget_requirement(
        q, settings.initial_design_size, settings.batch_size, settings.check_points
    )
    sampler = settings.mcmc_sampler
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
        # no HMC on a result that cannot be trusted anyway (its poor_mixing evidence, if
        # any: the random walk's)
        if sampler == "auto":
            sampler = "random_walk"
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
        _check_finite("initial_points", extra)
        x = space_filling_design(
            n0 - len(extra), b, derived_seed(settings.seed, 0, 0), settings.design_method
        )
        x = np.vstack([x, np.clip(extra, b[0], b[1])])
    else:
        if initial_points is not None:
            raise ValueError("design, initial_points: give one of them, not both")
        x = np.array(design, dtype=np.float64, copy=True)
        if x.ndim != 2 or x.shape[1] != q or not 2 <= x.shape[0] <= budget:
            raise ValueError(f"design: shape {x.shape}; expected (n0 x {q}), 2 <= n0 <= {budget}")
        _check_finite("design", x)
        if np.any(x < b[0]) or np.any(x > b[1]):
            raise ValueError("design: points outside the bounds C_w")
        n0 = x.shape[0]
        n_check = min(settings.check_points, budget - n0)
        main_budget = budget - n_check
    y = evaluate_checked(evaluate, x)
    bar.update(n0)
    _check_design_values(y)
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
    superseded = False
    climbs: list[ClimbReport] = []
    modes_optimism_at: int | None = None
    wants_local = settings.local_search and isinstance(evaluate, SpectraEvaluator)
    if settings.local_search and not wants_local:
        logger.warning(
            "local_search: the evaluator exposes no spectra (spectra/log_likelihood_of); "
            "running without the local phase"
        )
    switcher = KernelSwitcher(settings, q, budget, local_phase=wants_local)

    def audit_left(x: np.ndarray) -> int:
        """Evaluations an early stop's audit would spend now (0: too few are left)."""
        return audit_size(main_budget - x.shape[0], q, settings.audit_share, settings.batch_size)

    while x.shape[0] < main_budget:
        iteration += 1
        size = min(settings.batch_size, main_budget - x.shape[0])
        with torch_state(settings.num_threads):
            step = propose_step(
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
        if switcher.due(x.shape[0], phase, boxed):  # the additive kernel's shape, if better
            with torch_state(settings.num_threads):
                settings = switcher.consider(x, y, box, settings, iteration, step.surrogate)
            if switcher.switched_at is not None:
                continue  # this step again, with the kernels the run goes on with
        if settings.basin_search and not basins_done and phase == "refine":
            basins_done = True
            n_before = x.shape[0]
            basin_settings = settings
            if settings.basin.hunt_beta > 0 and not settings.global_fixed_noise_search(wants_local):
                # the hunt is for a search over C_w with a fixed noise (a noisy log L's bumps
                # are confirmed too easily; a local phase or trust region looks near one mode)
                basin = dataclasses.replace(settings.basin, hunt_beta=0.0)
                basin_settings = dataclasses.replace(settings, basin=basin)
                logger.debug(
                    "basin search: no hunt for unseen modes (local phase, trust region or "
                    "learned noise: the hunt is for a search over C_w with a fixed noise)"
                )
            x, y, iteration, new_climbs, peaks = run_basin_phase(
                evaluate, b, x, y, main_budget, iteration, basin_settings, history, on_iteration,
                bar,
            )  # fmt: skip
            climbs.extend(new_climbs)
            kappa = settings.modes_refine_optimism
            if (
                peaks >= 2
                and modes_optimism_at is None
                and kappa > settings.refine_optimism
                and settings.global_fixed_noise_search(wants_local)
            ):
                modes_optimism_at = int(x.shape[0])
                settings = dataclasses.replace(settings, refine_optimism=kappa)
                logger.info(
                    "basin search: %d confirmed peaks of the surrogate (several modes);"
                    " refinement from %d evaluations with refine_optimism %g",
                    peaks,
                    modes_optimism_at,
                    kappa,
                )
            if x.shape[0] > n_before:
                continue
        if wants_local and local is None and phase == "refine":
            x, y, local, iteration = run_local_phase(
                evaluate, b, x, y, main_budget, iteration, settings, history, on_iteration, bar
            )
            box = from_unit(local.box(settings.trust_region_half_width_sd), b)
            box = hold_points(box, held_points(x, y, settings.trust_region))
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
            size = audit_left(x)
            if size and step.stop_reason in ("converged", "ego_converged"):
                x, y, found = run_audit(
                    evaluate, b, x, y, size, iteration, settings, history, on_iteration, bar
                )
                if found:  # back to EGO over C_w, with the audit's points in the data
                    phase, box, boxed, laplace = "ego", b.copy(), settings.trust_region, None
                    superseded = local is not None  # it stays done: no box around one hill
                    ego_cap = x.shape[0] + int(
                        settings.max_ego_fraction * (main_budget - x.shape[0])
                    )
                    basins_done = False
                    continue
                if audit_left(x):  # nothing found: search on with the audit's points, and if
                    continue  # the search stops again, audit again with a share of what is left
            stop_reason = step.stop_reason
            break
        w_new = from_unit(step.proposal.numpy(), box)
        y_new = evaluate_checked(evaluate, w_new)
        x, y = np.vstack([x, w_new]), np.concatenate([y, y_new])
        bar.update(size)
        record_iteration(phase, x, y, step.criterion, history, on_iteration)
    check = None
    if n_check > 0:
        with torch_state(settings.num_threads):
            u, predicted, sd, noise = propose_check(x, y, box, n_check, settings, boxed, laplace)
        w_new = from_unit(u.numpy(), box)
        y_new = evaluate_checked(evaluate, w_new)
        check = SurrogateCheck(u.numpy(), predicted, sd, y_new, settings.check_tolerance, noise)
        check = repeated_check(check, evaluate, w_new)  # a failed check: noise or misfit?
        x, y = np.vstack([x, w_new]), np.concatenate([y, y_new])
        bar.update(n_check)
        record_iteration("check", x, y, check.max_abs_error, history, on_iteration)
        (logger.info if check.verdict == "ok" else logger.warning)(check.line())
    bar.close()
    with torch_state(settings.num_threads):
        surrogate = fit_in_box(x, y, box, settings, FINAL_ITERATION, boxed, laplace)
        draws_u, diag = sample_surrogate_posterior(
            surrogate,
            n_chains=settings.mcmc_chains,
            warmup_steps=settings.mcmc_warmup,
            num_samples=settings.mcmc_samples,
            seed=(
                derived_seed(settings.seed, FINAL_ITERATION, 4)
                if settings.mcmc_seed is None
                else derived_seed(settings.mcmc_seed, FINAL_ITERATION, 5)
            ),
            estimator=settings.estimator,
            backend=settings.mcmc_backend,
            progress=progress,
            sampler=sampler,
        )
        log_l = surrogate_log_likelihood(surrogate, settings.estimator)
        summary = summarize(draws_u.numpy(), box, list(names), log_l)
        u_map = torch.as_tensor(to_unit(summary.joint_map[None, :], box), dtype=torch.float64)
        with torch.no_grad():
            predicted_max = float(log_l(u_map)[0])
            predicted_max_sd = float(surrogate.log_likelihood_uncertainty(u_map)[1][0])
        draws_sd = mean_sd_at_draws(surrogate, draws_u)
        outside_share = (  # a broad, low mode the box left out (after the MCMC: no draw moves)
            share_outside_box(
                to_unit(x, b),
                impute_failures(y),
                to_unit(box, b),
                to_global_unit(draws_u.numpy(), box, b).reshape(-1, q),
                settings,
                ok=np.isfinite(y),
            )
            if boxed
            else 0.0
        )
    if boxed and outside_share is not None:  # None: box_mass said why
        logger.info("posterior mass outside the search box (a lower estimate): %.3g", outside_share)
    modes = int(diag.get("modes", 1) or 1)
    if modes < 2 and not np.all(np.asarray(summary.r_hat) <= POOR_MIXING_R_HAT):
        modes = modes_chains_stayed_in(draws_u)  # chains left in modes the jumps never saw
    searched = [h for h in history if h.phase not in ("check", "explore")]
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
        box_edge=box_edge(
            draws_u.numpy().reshape(-1, q), box, b, names, x=x, y=y, outside_share=outside_share
        ),
        modes=modes,
        sampler=str(diag.get("sampler", "random_walk")),
        draws_sd=draws_sd,
        evaluated_unit=(x - b[0]) / (b[1] - b[0]),
        evaluated_ok=np.isfinite(y),
        searched_in_box=boxed,
        mass_outside_box=outside_share,
        # the output-error model says whether its expectation also bounds the maximum
        expectation_bounds_maximum=bool(
            getattr(getattr(evaluate, "error", None), "expectation_bounds_maximum", False)
        ),
    )
    reliability = with_kernel_advice(  # would the additive kernel do better?
        reliability, x, y, box, settings, surrogate, boxed
    )
    draws = from_unit(draws_u.numpy().reshape(-1, q), box).reshape(draws_u.shape)
    result = CalibrationResult(
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
        local_search_superseded=superseded,
        kernel_switch=switcher.record(),
        modes_optimism_at=modes_optimism_at,
    )
    measured = getattr(evaluate, "measured", None)
    spectra = getattr(evaluate, "spectra", None)  # all the rule needs of a SpectraEvaluator
    if callable(spectra) and np.ndim(measured) == 3 and len(measured) >= 1:
        result = with_track_match(result, evaluate, np.asarray(measured))
        if lack_of_fit:  # and the summary likelihood's goodness of fit
            result = with_fit_rules(result, evaluate, np.asarray(measured))  # type: ignore[arg-type]
    if result.reliability is not None:
        logger.info(result.reliability.sentence)
    return result
