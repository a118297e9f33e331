"""The reliability verdict's rules, each a pure function of numbers, testable alone.

:func:`.reliability.assess` applies them (its module docstring says what each rule looks
at and when it fires); each returns one :data:`Reason` or None.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from susp_bo.calibration.surrogate_check import GROSS_NATS, SurrogateCheck

Reason = dict[str, Any]
"""One reason: ``code`` (str), ``message`` (str, plain words) and the numbers behind it."""

NARROW_SHARE = 0.01
"""A posterior whose widest sd is below this share of C_w needs a search box that follows it."""
POOR_MIXING_R_HAT = 1.05
"""Largest split R-hat of a mixed sampler (``poor_mixing`` above it)."""


# -- convergence ----------------------------------------------------------------------------


def not_converged(
    *,
    best_log_likelihood: float,
    predicted_max: float,
    predicted_max_sd: float,
    stop_reason: str,
    last_phase: str | None,
    last_criterion: float,
    gap_tolerance: float = 1.0,
    z: float = 2.0,
    uncertainty_tolerance: float = 0.3,
    draws_sd: float = math.nan,
    posterior_width: float = math.nan,
    plausible_max: float = math.nan,
) -> Reason | None:
    """``not_converged`` when the search did not reach the optimum (module docstring).

    Args:
        best_log_likelihood: best observed log L (nats).
        predicted_max: the final surrogate's log L̃ at its maximiser (joint MAP), nats.
        predicted_max_sd: the GP's sd of log L̃ there (nats).
        stop_reason: ``CalibrationResult.stop_reason`` ("budget", "converged", ...).
        last_phase: phase of the last EGO/refinement batch ("ego", "refine"), None if none ran.
        last_criterion: its stopping statistic (EI/spread or posterior mean sd[log L̃], nats).
        gap_tolerance: nats allowed between the predicted maximum and the best observed.
        z: GP standard deviations allowed on top of ``gap_tolerance``.
        uncertainty_tolerance: posterior mean sd[log L̃] (nats) above which a refinement
            stopped by the budget counts as unfinished, and above which the reported
            draws' mean sd[log L̃] counts as unexplored.
        draws_sd: mean sd[log L̃] (nats) over the reported posterior draws; NaN = not
            measured (the rule then looks only at the search).
        posterior_width: the draws' widest sd as a share of C_w, for a search without a box
            that follows the posterior (NaN otherwise); below :data:`NARROW_SHARE` the reason
            carries it, and the advice names the trust region.
        plausible_max: the most log L the output-error model allows at any parameters
            (:func:`plausible_max_log_likelihood`; NaN = none known). A predicted maximum
            above it, with the best observed below it, is the surrogate extrapolating: the
            search is unfinished, but the gap it quotes is no measure of how far (session
            26's probe: a predicted 1.5·10⁶ nats beside an expected 5 275 ± 27), and the
            message says so.
    """
    findings: list[str] = []
    reason: Reason = {"code": "not_converged"}
    gap = predicted_max - best_log_likelihood
    allowed = gap_tolerance + z * max(predicted_max_sd, 0.0)
    if not math.isfinite(best_log_likelihood) or gap > allowed:
        finding = (
            f"the search did not reach the optimum (best log L {best_log_likelihood:.1f} is "
            f"{gap:.1f} nats below the surrogate's predicted maximum {predicted_max:.1f} "
            f"± {predicted_max_sd:.2g})"
        )
        reason.update(optimum_gap_nats=float(gap), optimum_gap_allowed_nats=float(allowed))
        if best_log_likelihood <= plausible_max < predicted_max:
            finding += (
                f"; that maximum is above the most the output-error model allows at any "
                f"parameters (about {plausible_max:.1f}): the surrogate extrapolates where "
                "nothing was evaluated, so the gap is no measure of how far the optimum is"
            )
            reason.update(plausible_max=float(plausible_max))
        findings.append(finding)
    unfinished = None
    if stop_reason == "budget":
        if last_phase is None:
            unfinished = "the budget ran out after the design: no refinement ran"
        elif last_phase == "ego":
            unfinished = "the budget ran out while EGO was still searching (no refinement)"
        elif not last_criterion <= uncertainty_tolerance:
            unfinished = (
                f"the budget ran out before the refinement converged (posterior sd of log L "
                f"{last_criterion:.2f} nats > {uncertainty_tolerance:g})"
            )
    if unfinished is not None:
        findings.append(unfinished)
        reason.update(stopped_by="budget", last_phase=last_phase, last_criterion=last_criterion)
    if math.isfinite(draws_sd) and draws_sd > uncertainty_tolerance:
        findings.append(
            f"the surrogate is unsure where the reported posterior lies (mean sd of log L "
            f"over its draws {draws_sd:.2f} nats > {uncertainty_tolerance:g}): the evaluations "
            "there are too few to pin log L down"
        )
        reason.update(draws_sd_nats=float(draws_sd))
    if not findings:
        return None
    if posterior_width < NARROW_SHARE:  # too narrow for EGO's global surrogate (probe, F4)
        reason["posterior_width"] = float(posterior_width)
    reason["message"] = "; ".join(findings)
    return reason


def plausible_max_log_likelihood(
    expected_at_truth: tuple[float, float] | None,
    q: int,
    *,
    gap_tolerance: float = 1.0,
    truth_z: float = 3.0,
    level: float = 0.999,
) -> float:
    """The most log L the output-error model allows at any parameters (nats; NaN = none).

    Under B, log L at the true parameters is (mean ± sd) = ``expected_at_truth``, and for
    a regular model the maximum over q parameters lies ½ χ²_q above it (Wilks); so the
    maximum is below mean + ``truth_z`` sd + ½ χ²_q(``level``) + ``gap_tolerance`` but for
    a chance of about 1 − ``level``. This bound is B's word, not the data's, and only the
    paired B's expectation is on the residual's own scale: the unpaired B, whose scale is
    the scatter between tracks, puts the truth's log L ≈ 28 sd above its own expectation.
    So :func:`.reliability.assess` uses the bound only when told that the expectation
    bounds the maximum (a paired evaluator, :func:`.loop.calibrate`; second review, session
    27), and :func:`not_converged` not where the best evaluated log L already exceeds it.
    """
    if expected_at_truth is None or q < 1:
        return math.nan
    from scipy import stats  # only here: the rules module stays light to import

    mean, sd = expected_at_truth
    return mean + truth_z * sd + 0.5 * float(stats.chi2.ppf(level, q)) + gap_tolerance


def below_expected_fit(
    best_log_likelihood: float,
    expected_at_truth: tuple[float, float] | None,
    *,
    gap_tolerance: float = 1.0,
    truth_z: float = 3.0,
) -> Reason | None:
    """``below_expected_fit`` when the best log L lies far below the log L that the
    output-error model expects at the true parameters (module docstring).

    Args:
        best_log_likelihood: best observed log L (nats).
        expected_at_truth: (mean, sd) of log L at the true parameters under B; None when
            the model gives none (the rule cannot fire).
        gap_tolerance: nats allowed below the mean, on top of ``truth_z`` sd.
        truth_z: sds of the truth's log L allowed below its mean.
    """
    if expected_at_truth is None:
        return None
    mean, sd = expected_at_truth
    floor = mean - gap_tolerance - truth_z * sd
    if best_log_likelihood >= floor:
        return None
    return {
        "code": "below_expected_fit",
        "message": (
            f"the best log L {best_log_likelihood:.1f} is {mean - best_log_likelihood:.1f} nats "
            f"below the log L expected at the true parameters ({mean:.1f} ± {sd:.2g}): the "
            "model misses something in the data, or the search sits in a local optimum"
        ),
        "expected_at_truth": [float(mean), float(sd)],
        "deficit_nats": float(mean - best_log_likelihood),
    }


def checked_expected_at_truth(value: object) -> tuple[float, float] | None:
    """``expected_at_truth`` as (mean, sd) floats, or None.

    Raises:
        ValueError: not a pair of numbers with a finite mean and a finite sd >= 0.
    """
    if value is None:
        return None
    try:
        mean, sd = (float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ValueError(
            f"expected_at_truth: {value!r} is not allowed; expected (mean, sd) of log L at "
            "the true parameters in nats, two numbers, or None"
        ) from None
    if not (math.isfinite(mean) and math.isfinite(sd) and sd >= 0):
        raise ValueError(
            f"expected_at_truth: {value!r} is not allowed; expected a finite mean and a "
            "finite sd >= 0 (nats)"
        )
    return mean, sd


def at_bound(
    draws_unit: np.ndarray,
    names: Sequence[str],
    bounds: np.ndarray,
    strip: float = 0.02,
    mass: float = 0.10,
    sd_fraction: float = 0.5,
) -> Reason | None:
    """``at_bound`` when a marginal piles up against an admissible bound.

    Args:
        draws_unit: (n x q) posterior draws in the unit cube.
        names: (q,) parameter names.
        bounds: (2 x q) admissible bounds (physical units, for the message).
        strip: width of the strip at each bound, as a fraction of the admissible width;
            never wider than ``sd_fraction`` posterior sd (a posterior 10⁻⁴ of C_w wide
            whose mode sits 1 % inside a bound, a hundred sd away, is not piled at it).
        mass: share of the draws in one strip above which the rule fires (5 x a flat
            posterior's ``strip`` at the defaults).
        sd_fraction: the strip's cap in posterior sd.
    """
    u = np.asarray(draws_unit, dtype=np.float64)
    width = np.minimum(strip, sd_fraction * u.std(axis=0))
    lower = np.mean(u < width, axis=0)
    upper = np.mean(u > 1.0 - width, axis=0)
    pinned = []
    for k, name in enumerate(names):
        for side, share, value in (
            ("lower", lower[k], bounds[0, k]),
            ("upper", upper[k], bounds[1, k]),
        ):
            if share > mass:
                pinned.append((name, side, float(share), float(value)))
    if not pinned:
        return None
    parts = [f"{n} ({s:.0%} of the draws at its {side} bound {v:.4g})" for n, side, s, v in pinned]
    return {
        "code": "at_bound",
        "message": (
            "posterior mass piled at an admissible bound: " + ", ".join(parts) + "; the true "
            "value may lie outside the admissible set or the search stopped early"
        ),
        "parameters": [{"name": n, "side": side, "share": s} for n, side, s, _ in pinned],
    }


# -- surrogate and sampler --------------------------------------------------------------------


def surrogate_misfit(check: SurrogateCheck | None) -> Reason | None:
    """``surrogate_misfit`` (check outside its band) or ``surrogate_unchecked`` (no check
    ran, or none of its simulations succeeded).

    Args:
        check: the held-out check, None when none ran. Its verdict is the reason's
            ``direction``; an error beyond :data:`.surrogate_check.GROSS_NATS` makes it
            ``misplaced``, and the message then reads no width into the signs.
    """
    if check is None:
        return {
            "code": "surrogate_unchecked",
            "message": (
                "the surrogate posterior was not checked against held-out simulations "
                "(check_points = 0 or no budget left for the check)"
            ),
        }
    if not np.isfinite(check.observed).any():
        return {
            "code": "surrogate_unchecked",
            "message": (
                f"none of the {len(check.observed)} held-out check simulations succeeded, so "
                "nothing tested the surrogate posterior against the simulator"
            ),
        }
    if check.verdict == "ok":
        return None
    e = check.errors
    above = check.outside & (e > 0)
    below = check.outside & (e < 0)
    if check.verdict == "noisy":
        return {
            "code": "surrogate_misfit",
            "message": (
                f"the held-out check found {int(check.outside.sum())} of {len(e)} "
                "posterior-edge points outside the surrogate's predictive band, and log L is "
                f"noisy beyond what the surrogate models: {check.repeat_phrase()}; a "
                "surrogate that assumes less noise fits the noise, so the real posterior may "
                "be wider or narrower"
            ),
            "direction": "noisy",
            "n_above": int(above.sum()),
            "n_below": int(below.sum()),
            "max_abs_error_nats": check.max_abs_error,
            "repeat_difference_nats": check.repeat_difference_json,
        }
    misplaced = check.verdict == "misplaced"
    parts = []
    if above.any():
        parts.append(
            f"{int(above.sum())} above the prediction (up to +{float(np.max(e[above])):.1f} nats"
            + (")" if misplaced else ": the real posterior is wider there)")
        )
    if below.any():
        parts.append(
            f"{int(below.sum())} below (down to {float(np.min(e[below])):.1f} nats"
            + (")" if misplaced else ": narrower there)")
        )
    gross = ""
    if misplaced:
        gross = (
            f"; errors beyond {GROSS_NATS:g} nats mean the surrogate posterior is misplaced or "
            "grossly misshapen: neither its width nor the direction it is off can be read "
            "from them"
        )
    return {
        "code": "surrogate_misfit",
        "message": (
            f"the held-out check found {int(check.outside.sum())} of {len(e)} posterior-edge "
            f"points outside the surrogate's predictive band, {check.verdict}: "
            + " and ".join(parts)
            + gross
        ),
        "direction": check.verdict,
        "n_above": int(above.sum()),
        "n_below": int(below.sum()),
        "max_abs_error_nats": check.max_abs_error,
    }


def poor_mixing(
    r_hat: np.ndarray,
    ess: np.ndarray,
    names: Sequence[str],
    r_hat_max: float = POOR_MIXING_R_HAT,
    ess_min: float = 400.0,
) -> Reason | None:
    """``poor_mixing`` when R-hat > ``r_hat_max`` or ESS < ``ess_min`` on any parameter."""
    r = np.asarray(r_hat, dtype=np.float64)
    n = np.asarray(ess, dtype=np.float64)
    bad_r = [k for k in range(len(names)) if not r[k] <= r_hat_max]
    bad_n = [k for k in range(len(names)) if not n[k] >= ess_min]
    if not bad_r and not bad_n:
        return None
    parts = []
    if bad_r:
        k = max(bad_r, key=lambda i: r[i] if math.isfinite(r[i]) else math.inf)
        parts.append(f"R-hat {r[k]:.3f} > {r_hat_max:g} on {names[k]}")
    if bad_n:
        k = min(bad_n, key=lambda i: n[i] if math.isfinite(n[i]) else -math.inf)
        parts.append(f"ESS {n[k]:.0f} < {ess_min:g} on {names[k]}")
    return {
        "code": "poor_mixing",
        "message": "the MCMC did not mix: " + " and ".join(parts),
        "parameters": sorted({names[k] for k in bad_r + bad_n}),
    }


def multimodal(modes: int) -> Reason | None:
    """``multimodal`` when the sampler found ``modes`` >= 2 separated modes (module docstring)."""
    if modes < 2:
        return None
    return {
        "code": "multimodal",
        "message": (
            f"the posterior has {modes} separated modes: how the mass is shared between them "
            "rests on the surrogate where the search may not have looked, no held-out point "
            "checks each mode, and a further mode that no evaluation came near would not be "
            "seen (on a three-mode test target one mode was lost in 2 of 9 runs)"
        ),
        "modes": int(modes),
    }
