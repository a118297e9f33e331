"""A global look before an early stop: does log L rise anywhere the search did not look?

EGO and the refinement stop when their criteria say the surrogate has nothing left to
learn, which they judge by the surrogate itself. A mode narrower than the design's spacing
that no evaluation touched is invisible to it: the GP, fitted where log L was seen,
predicts log L low there, and a search that stopped after 22 of 200 evaluations reported a
posterior holding half the exact mass as `trusted` (outside probe, session 24: two
equal-mass modes in 2-D, the second 5× narrower).

So when the loop would stop with part of its budget unspent, it first spends a share of
what is left (:data:`AUDIT_SHARE`, at least q + 1 points) on an *audit*: points of C_w as far
as possible from every evaluation and from one another (greedy maximin over a scrambled
Sobol' set), predicted by the surrogate fitted on all of C_w, then evaluated. An audit
point whose log L is within the posterior's reach of the best value (≥ best − ½ χ²_q(0.999))
*and* above the surrogate's predictive band (the held-out check's band, noise included)
shows posterior mass the search had not seen: the loop goes back to EGO (and the basin
phase) with the audit's points in its data and the rest of the budget. Otherwise it stops
as it would have. An audit cannot prove that no narrower mode exists — nothing evaluated
at finitely many points can — but it spends the budget the caller granted on looking
before the result is called converged.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from scipy.stats import qmc

from susp_bo.calibration.design import from_unit, to_unit
from susp_bo.calibration.iteration_record import record_iteration
from susp_bo.calibration.loop_step import (
    Evaluate,
    derived_seed,
    evaluate_checked,
    fit_in_box,
    torch_state,
)
from susp_bo.calibration.result import IterationReport
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate_check import SurrogateCheck, observation_noise_sd
from susp_bo.calibration.trust_region import posterior_reach

logger = logging.getLogger(__name__)

AUDIT_SHARE = 0.5
"""Share of the evaluations left that an audit spends."""
AUDIT_CANDIDATES = 4096
"""Scrambled Sobol' candidates the maximin points are chosen from."""
AUDIT_SEED_PURPOSE = 7
"""The purpose slot of :func:`~.loop_step.derived_seed` for an audit's candidates."""


def audit_size(remaining: int, q: int, share: float = AUDIT_SHARE, reserve: int = 1) -> int:
    """Points an audit spends with ``remaining`` evaluations left (0: too few to look).

    Args:
        remaining: evaluations left before the held-out check's.
        q: number of parameters.
        share: share of ``remaining`` to spend, in [0, 1].
        reserve: evaluations always left after the audit (the loop's batch size), so that
            mass the audit finds is searched, or the run ends on the budget and says so.
    """
    n = min(int(share * remaining), remaining - reserve)
    return n if n >= q + 1 else 0


def audit_points(x_unit: np.ndarray, n: int, seed: int) -> np.ndarray:
    """(n x q) points of the unit cube far from the evaluated points and from each other.

    Greedy maximin over :data:`AUDIT_CANDIDATES` scrambled Sobol' points: each pick is the
    candidate farthest from every evaluated point and every earlier pick.

    Args:
        x_unit: (m x q) evaluated points in the unit cube.
        n: points wanted (>= 1).
        seed: seed of the scrambling.
    """
    q = x_unit.shape[1]
    candidates = qmc.Sobol(d=q, scramble=True, rng=np.random.default_rng(seed)).random(
        AUDIT_CANDIDATES
    )
    gap = np.full(len(candidates), np.inf)
    for point in x_unit:
        gap = np.minimum(gap, np.linalg.norm(candidates - point, axis=1))
    chosen = []
    for _ in range(n):
        pick = int(np.argmax(gap))
        chosen.append(candidates[pick])
        gap = np.minimum(gap, np.linalg.norm(candidates - candidates[pick], axis=1))
    return np.array(chosen)


def unseen_mass(check: SurrogateCheck, best_log_likelihood: float, q: int) -> np.ndarray:
    """(n,) True at audit points that show posterior mass the search had not seen.

    Such a point's log L is within :func:`posterior_reach` of ``best_log_likelihood`` (the
    best value before the audit) and above the surrogate's predictive band there.
    """
    observed = check.observed
    finite = np.isfinite(observed)
    near_best = np.where(finite, observed, -np.inf) >= best_log_likelihood - posterior_reach(q)
    above = np.where(finite, check.errors, -np.inf) > check.band
    return near_best & above


def propose_audit(
    x: np.ndarray,
    y: np.ndarray,
    bounds: np.ndarray,
    size: int,
    iteration: int,
    settings: CalibrationSettings,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An early stop's audit: ``size`` maximin points of C_w (:func:`audit_points`).

    Returns:
        The points (size x q) in C_w's unit cube, and the surrogate's predicted log L̃, its
        sd and the observation-noise sd there (size,) — the surrogate fitted on every
        evaluation over all of C_w, with its default mean (no search box, no Laplace bowl).
    """
    u = audit_points(
        to_unit(x, bounds), size, derived_seed(settings.seed, iteration, AUDIT_SEED_PURPOSE)
    )
    surrogate = fit_in_box(x, y, bounds, settings, iteration)
    points = torch.as_tensor(u, dtype=torch.float64)
    with torch.no_grad():
        mean, sd = surrogate.log_likelihood_uncertainty(points)
    return u, mean.numpy(), sd.numpy(), np.asarray(observation_noise_sd(surrogate, points))


def run_audit(
    evaluate: Evaluate,
    bounds: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    size: int,
    iteration: int,
    settings: CalibrationSettings,
    history: list[IterationReport],
    on_iteration: Callable[[IterationReport], None] | None,
    bar: Any,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """An early stop's audit: evaluate :func:`propose_audit`'s points; they join the data.

    Returns:
        The data with the audit's points, and whether they show posterior mass the search
        had not seen (then the loop searches again).
    """
    q = x.shape[1]
    with torch_state(settings.num_threads):
        u, predicted, sd, noise = propose_audit(x, y, bounds, size, iteration, settings)
    best = float(np.nanmax(y))
    w = from_unit(u, bounds)
    values = evaluate_checked(evaluate, w)
    audit = SurrogateCheck(u, predicted, sd, values, settings.check_tolerance, noise)
    found = unseen_mass(audit, best, q)
    x, y = np.vstack([x, w]), np.concatenate([y, values])
    bar.update(size)
    excess = audit.errors[np.isfinite(audit.errors)]
    record_iteration(
        "explore", x, y, float(excess.max()) if excess.size else math.nan, history, on_iteration
    )
    if found.any():
        logger.warning(
            "the search had converged, but %d of %d audit points far from every evaluation "
            "have log L up to %.6g (the best before: %.6g), near or above the best and above "
            "the surrogate's band: posterior mass the search had not seen; searching again",
            int(found.sum()),
            size,
            float(np.max(values[found])),
            best,
        )
    else:
        logger.info(
            "the search had converged; an audit at %d points far from every evaluation found "
            "no log L near the best above the surrogate's band",
            size,
        )
    return x, y, bool(found.any())
