"""How much posterior mass a search box left out, by a surrogate of all of C_w.

A search box (the opt-in trust region, or the local phase's box) follows one hill: the
final surrogate, check and MCMC live in it. :func:`.trust_region.box_edge` sees a box that
cut its posterior when draws press against a face, or when an evaluation outside it has a
log L within reach of the best. Neither sees a *broad, low* mode: its peak can lie far
below the best (beyond the reach) and still hold much of the mass, because it is wide
(outside probe, session 25: a spike of sd 0.015 and a slab of sd 0.3 whose peak is 7 nats
lower and which holds 22 % of the mass — `trusted` with the slab cut away).

:func:`share_outside_box` fits one more surrogate, on every evaluation over all of C_w,
and compares

- the mass outside the box it is *sure of*: ∫ exp(mean − 2 sd) of log L̃ over C_w minus
  the box, by scrambled Sobol' points (the lower confidence bound: where the global fit
  cannot resolve — near a box 10⁻⁴ of C_w wide, or far from every evaluation — its sd is
  large and nothing is counted), with
- the mass inside: the Laplace value exp(best log L) (2π)^{q/2} |Σ|^{1/2}, Σ the
  reported draws' covariance,

both in the unit cube of C_w. The returned share M_out / (M_in + M_out) is a lower
estimate of the mass the box left out.

The lower confidence bound is one only where the global fit holds its own data: a
stationary GP fitted to a spike 10⁻⁴ of C_w wide beside a far field thousands of nats
lower is ill-conditioned, and between the evaluations its mean can swing thousands of
nats *above* the best with a comparatively small sd. Measured (session 28, the
monitoring benchmark's wearing train, campaigns 5 and 8, q = 2, paired B): mean − 2 sd
up to 9 000 nats above the best at the edge of C_w, a "share" of 1.0 and a refused
right answer. So the share is *not estimated* (None; the evidence says so) rather than
counted when the fit is shown to be no lower bound, by either of two tests (the limit of
both is :func:`.trust_region.posterior_reach`, ½ χ²_q(0.999)):

- each successful evaluation predicted by the global fit without it (closed-form
  leave-one-out): a lower bound (mean − 2 sd) above the evaluation it predicts by more
  than the limit (these fits: 83–118 nats at one thread, at 1 of 75 points; the
  session-25 spike and slab: 0.04; failed evaluations are left out of this fit);
- the lower bound outside the box more than the limit above the best log L: no
  evaluation supports a level above the best, so such a bound is an extrapolation (the
  second review: with that one point left out, the leave-one-out test passed and the
  fit still claimed 10⁴ nats above the best).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import torch
from scipy.stats import qmc

from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate import Surrogate
from susp_bo.calibration.surrogate_fit import fit_surrogate
from susp_bo.calibration.trust_region import posterior_reach

logger = logging.getLogger(__name__)

BOX_MASS_POINTS = 4096
"""Scrambled Sobol' points over C_w at which the global surrogate is read."""
BOX_MASS_SD = 2.0
"""GP standard deviations below the mean: only mass the global surrogate is sure of."""
BOX_MASS_SEED = 11
"""Seed of the Sobol' scrambling and of the global fit's restarts (fixed: deterministic)."""


def share_outside_box(
    x_unit: np.ndarray,
    y: np.ndarray,
    box_unit: np.ndarray,
    draws_unit: np.ndarray,
    settings: CalibrationSettings,
    ok: np.ndarray | None = None,
) -> float | None:
    """Lower estimate of the posterior mass outside the search box (module docstring).

    Args:
        x_unit: (n x q) every evaluation, unit cube of C_w.
        y: (n,) their log L (nats), failures imputed (finite).
        box_unit: (2 x q) the final search box, unit cube of C_w.
        draws_unit: (m x q) the reported posterior draws, unit cube of C_w.
        settings: the calibration's settings (the surrogate's).
        ok: (n,) True where the evaluation succeeded (None: all did). The global fit uses
            the successful ones only: a failure's imputed value (the lowest log L) is no
            measurement, and beside a spike it bends the fit (the second review: one
            imputed failure next to the spike took the slab's share from 0.04 to 3·10⁻⁵).

    Returns:
        The share in [0, 1]; 0 when the box is C_w itself; None when it cannot be
        estimated: fewer than q + 2 successful evaluations, the global fit's
        leave-one-out lower bound overshoots an evaluation by more than the reach
        (:func:`global_fit_overshoot`), or its lower bound somewhere outside the box lies
        more than the reach above the best log L (a bound above every evaluation is an
        extrapolation, not a measurement).
    """
    q = x_unit.shape[1]
    box_unit = np.asarray(box_unit, dtype=np.float64)
    if np.all(box_unit[0] <= 0.0) and np.all(box_unit[1] >= 1.0):
        return 0.0
    if ok is not None:
        keep = np.asarray(ok, dtype=bool)
        x_unit, y = x_unit[keep], np.asarray(y)[keep]
    if y.size < q + 2:  # too few measurements to fit anything over C_w
        _not_estimated(f"{y.size} successful evaluations")
        return None
    points = qmc.Sobol(d=q, scramble=True, rng=np.random.default_rng(BOX_MASS_SEED)).random(
        BOX_MASS_POINTS
    )
    outside = np.any((points < box_unit[0]) | (points > box_unit[1]), axis=1)
    if not outside.any():
        return 0.0
    best = float(np.max(y))
    reach = posterior_reach(q)
    surrogate = fit_surrogate(x_unit, y, settings.surrogate, seed=BOX_MASS_SEED)
    overshoot = global_fit_overshoot(surrogate, y)
    if not overshoot <= reach:  # NaN too
        _not_estimated(
            f"predicting a successful evaluation it was not fitted on, it puts its mean − "
            f"{BOX_MASS_SD:g} sd {overshoot:.3g} nats above it"
        )
        return None
    with torch.no_grad():
        mean, sd = surrogate.log_likelihood_uncertainty(
            torch.as_tensor(points[outside], dtype=torch.float64)
        )
    sure = (mean - BOX_MASS_SD * sd).numpy() - best
    if not float(np.max(sure)) <= reach:
        _not_estimated(
            f"its mean − {BOX_MASS_SD:g} sd lies {float(np.max(sure)):.3g} nats above the best "
            "log L outside the box, where nothing evaluated comes near"
        )
        return None
    log_out = float(np.logaddexp.reduce(sure)) - math.log(BOX_MASS_POINTS)
    cov = np.cov(np.asarray(draws_unit, dtype=np.float64), rowvar=False).reshape(q, q)
    sign, log_det = np.linalg.slogdet(cov + 1e-300 * np.eye(q))
    if sign <= 0:
        return 0.0
    log_in = 0.5 * q * math.log(2.0 * math.pi) + 0.5 * log_det
    return float(1.0 / (1.0 + math.exp(min(log_in - log_out, 700.0))))


def _not_estimated(why: str) -> None:
    logger.info(
        "posterior mass outside the search box: not estimated — a surrogate of all of C_w is "
        "no lower bound (%s; limit ½ χ²_q(0.999)), so a broad, low mode outside the box can "
        "be neither seen nor ruled out by it",
        why,
    )


def global_fit_overshoot(surrogate: Surrogate, y: np.ndarray) -> float:
    """How far (nats) the global fit's leave-one-out lower bound (mean − :data:`BOX_MASS_SD`
    sd, the predictive sd of a new evaluation) lies above the evaluation it predicts, at
    the worst one (negative: below every one).

    Args:
        surrogate: the fit over all of C_w.
        y: (n,) the log L it was fitted on (nats).
    """
    mean, sd = surrogate.loo_log_likelihood_uncertainty()
    return float(np.max(mean - BOX_MASS_SD * sd - np.asarray(y, dtype=np.float64)))
