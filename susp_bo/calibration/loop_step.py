"""One step of the calibration loop (:mod:`.loop`): refit the surrogate, propose a batch.

:func:`propose_step` refits the surrogate in the search box's unit cube
(:func:`fit_in_box`) and proposes the next EGO or refinement batch, or says why the
search stops (EGO converged, refinement converged); :func:`propose_check` proposes the
held-out check's edge points. Every random choice is seeded by :func:`derived_seed`
from the master seed, the iteration and its purpose, so a rerun with the same
evaluations reproduces every step.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass

import numpy as np
import torch

from susp_bo.calibration.acquisition import (
    posterior_candidates,
    propose_ei_batch,
    refinement_candidates,
    select_uncertainty_batch,
)
from susp_bo.calibration.design import to_unit
from susp_bo.calibration.local_search import LocalSearchResult
from susp_bo.calibration.result import Phase
from susp_bo.calibration.sampling import surrogate_log_likelihood
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate import Surrogate
from susp_bo.calibration.surrogate_check import (
    SurrogateCheck,
    edge_points,
    observation_noise_sd,
)
from susp_bo.calibration.surrogate_fit import Bowl, fit_surrogate
from susp_bo.calibration.trust_region import held_points, hold_points, next_box, training_mask

logger = logging.getLogger(__name__)

Evaluate = Callable[[np.ndarray], np.ndarray]
FINAL_ITERATION = 1_000_000  # iteration index used to seed the final fit and MCMC
CHECK_ITERATION = 2_000_000  # iteration index used to seed the surrogate check


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


STOCK_DEFAULT_DTYPE = torch.float32
"""torch's own default dtype, the one this tool's torch work runs under (:func:`torch_state`)."""


@contextmanager
def torch_state(
    num_threads: int | None, default_dtype: torch.dtype = STOCK_DEFAULT_DTYPE
) -> Iterator[None]:
    """The torch state of this tool's torch work (surrogate, acquisition, check, MCMC):
    ``num_threads`` intra-op threads (:func:`torch_threads`) and torch's stock default
    dtype, both restored afterwards. (With the caller's own values, the same context puts
    the caller's state back around an ``evaluate`` called from inside that work.)

    The data are float64 throughout; the default dtype reaches what torch and its libraries
    make without an explicit dtype, mainly from Python floats (the GP's prior and constraint
    parameters, botorch's defaults: float32-rounded constants, ~1e-8 relative). Pinning
    it makes a calibration the same whatever the caller set (a notebook that called
    ``torch.set_default_dtype(torch.float64)``, as BoTorch's tutorials do, got another
    result than ``susp-bo``); torch's stock float32 is the one every recorded result of
    this tool was computed under.
    """
    previous = torch.get_default_dtype()
    torch.set_default_dtype(default_dtype)
    try:
        with torch_threads(num_threads):
            yield
    finally:
        torch.set_default_dtype(previous)


def derived_seed(master: int, iteration: int, purpose: int) -> int:
    """The seed of one random choice: from the master seed, the iteration and its purpose."""
    return int(np.random.SeedSequence([master, iteration, purpose]).generate_state(1)[0])


def impute_failures(y: np.ndarray) -> np.ndarray:
    """Failed evaluations (NaN) set to the lowest finite log L, for the surrogate (n,)."""
    if np.any(y == math.inf):
        raise ValueError("evaluate: returned +inf, which is not a valid log-likelihood")
    finite = np.isfinite(y)
    if not finite.any():
        raise RuntimeError("every log L evaluation failed (NaN/-inf): nothing to fit")
    return np.where(finite, y, np.min(y[finite]))


def evaluate_checked(evaluate: Evaluate, w: np.ndarray) -> np.ndarray:
    """``evaluate`` at w (n x q, physical units) -> log L (n,), shape checked, −inf as NaN.

    Raises:
        ValueError: ``evaluate`` returned None, values that are not real numbers (complex,
            strings, booleans) or another number of values than points.
    """
    raw = evaluate(np.array(w, dtype=np.float64))
    if raw is None:
        raise ValueError(
            f"evaluate: returned None; expected {w.shape[0]} log L values (nats), one per "
            "row of its argument"
        )
    values = np.asarray(raw)
    if values.dtype.kind == "O":  # e.g. [1.0, None] (None: a failed run, as NaN), Decimal
        with suppress(TypeError, ValueError):
            values = values.astype(np.float64)
    if values.dtype.kind not in "iuf":
        raise ValueError(
            f"evaluate: returned values of type {values.dtype}; expected real numbers "
            "(log L, nats; NaN or None for a failed run)"
        )
    out = values.astype(np.float64).reshape(-1)
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


def fit_in_box(
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
    y = impute_failures(y)
    if boxed:
        # with the Laplace bowl as the mean, far points (thousands of nats below it) only
        # inflate the GP's scale: keep the box's neighbourhood, at least q + 2 points
        q = x.shape[1]
        keep = training_mask(x, box, min_points=q + 2 if laplace is not None else 2 * q + 2)
        x, y = x[keep], y[keep]
    bowl = None if laplace is None else laplace.bowl(box)
    return fit_surrogate(
        to_unit(x, box), y, settings.surrogate, derived_seed(settings.seed, iteration, 1), bowl
    )


@dataclass(frozen=True)
class Step:
    """What one step decided.

    Attributes:
        phase: "ego" or "refine".
        proposal: (b x q) the next batch in ``box``'s unit cube, or None: the search stops.
        criterion: the phase's stopping statistic (EI/spread, or the posterior mean of
            sd[log L̃] in nats).
        stop_reason: why it stops ("ego_converged", "converged", "budget"); "" otherwise.
        box: (2 x q) the search box the proposal is in (physical units).
        surrogate: the fit the step decided on (in ``box``'s unit cube).
    """

    phase: Phase
    proposal: torch.Tensor | None
    criterion: float
    stop_reason: str
    box: np.ndarray
    surrogate: Surrogate


def propose_step(
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
) -> Step:
    """Refits the surrogate and proposes the next batch (None when a stopping rule fires).

    With a trust region, every refinement step may move the search box first
    (:func:`.trust_region.next_box`); the returned step carries the box its proposal is in.
    """
    seed = settings.seed
    surrogate = fit_in_box(x, y, box, settings, iteration, boxed, laplace)
    if phase == "ego":
        u, criterion = propose_ei_batch(
            surrogate,
            size,
            derived_seed(seed, iteration, 2),
            settings.acquisition_restarts,
            settings.acquisition_raw_samples,
        )
        converged = criterion < settings.ei_tolerance
        if not (converged or ego_exhausted):
            return Step("ego", u, criterion, "", box, surrogate)
        if not settings.refine:
            return Step(
                "ego", None, criterion, "ego_converged" if converged else "budget", box, surrogate
            )
    candidates, n_post = _refinement_candidates(
        surrogate, settings, derived_seed(seed, iteration, 3)
    )
    if boxed:
        held = held_points(x, y, settings.trust_region)
        moved = next_box(
            candidates[:n_post].numpy(), box, bounds, held, settings.trust_region_half_width_sd
        )
        if settings.trust_region:  # a held point the box has left: widen the box to it
            widened = hold_points(box if moved is None else moved, held)
            moved = None if np.array_equal(widened, box) else widened
        if moved is not None:
            logger.info("search box: %s", np.array2string(moved, precision=4))
            box = moved
            surrogate = fit_in_box(x, y, box, settings, iteration, boxed, laplace)
            candidates, n_post = _refinement_candidates(
                surrogate, settings, derived_seed(seed, iteration, 3)
            )
    u, criterion = select_uncertainty_batch(
        surrogate, candidates, size, n_post, optimism=settings.refine_optimism
    )
    if criterion < settings.refine_tolerance:
        return Step("refine", None, criterion, "converged", box, surrogate)
    return Step("refine", u, criterion, "", box, surrogate)


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


def propose_check(
    x: np.ndarray,
    y: np.ndarray,
    bounds: np.ndarray,
    size: int,
    settings: CalibrationSettings,
    boxed: bool,
    laplace: Laplace | None = None,
) -> tuple[torch.Tensor, np.ndarray, np.ndarray, np.ndarray]:
    """Edge points of the current surrogate posterior, the predictions and noise sd there."""
    surrogate = fit_in_box(x, y, bounds, settings, CHECK_ITERATION, boxed, laplace)
    post, _ = posterior_candidates(
        surrogate,
        settings.candidate_count,
        settings.estimator,
        derived_seed(settings.seed, CHECK_ITERATION, 3),
    )
    u = edge_points(post, surrogate_log_likelihood(surrogate, settings.estimator)(post), size)
    mean, sd = surrogate.log_likelihood_uncertainty(u)
    return u, mean.numpy(), sd.numpy(), observation_noise_sd(surrogate, u)


def repeated_check(check: SurrogateCheck, evaluate: Evaluate, points: np.ndarray) -> SurrogateCheck:
    """A failed check with its worst points evaluated again (:mod:`.surrogate_check`).

    Args:
        check: the held-out check.
        evaluate: the caller's log L.
        points: (n x q) the checked points, physical units.

    Returns:
        ``check`` itself when it passed, else with ``repeat_difference_nats`` (the largest
        move of a repeat; the repeats do not join the data).
    """
    worst = check.worst()
    if check.verdict == "ok" or not worst.size:
        return check
    again = evaluate_checked(evaluate, points[worst])
    if not np.all(np.isfinite(again)):  # it had succeeded (``worst`` are finite ones)
        return dataclasses.replace(check, repeat_difference_nats=math.inf)
    moved = again - check.observed[worst]
    largest = moved[int(np.argmax(np.abs(moved)))]
    return dataclasses.replace(check, repeat_difference_nats=float(largest))
