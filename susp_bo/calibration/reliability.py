"""Can this calibration be trusted? The reliability verdict and its rules.

A maintainer acts on a 95 % interval, so the result must say when it does not
know. :func:`assess` applies the rules below to what the loop saw and returns a
:class:`Reliability`: ``trusted`` only when no rule fires, otherwise
``not_trusted`` with one reason per rule that fired (``code``, a plain
``message`` and the numbers behind it) and one sentence an engineer reads.

Rules (each a pure function of numbers, testable alone):

- ``budget_too_small`` (:func:`budget_too_small`): the budget leaves no room for
  the loop's own structure — a design of max(10, 5 q) points (or the configured
  one when larger), one refinement batch and the held-out check. Below that the
  study and the command line refuse to start unless explicitly allowed
  (:func:`.budget.budget_requirement` names the minimum).
- ``not_converged`` (:func:`not_converged`): the search did not reach the
  optimum — the best observed log L lies more than ``gap_tolerance`` nats plus
  ``z`` GP standard deviations below the surrogate's predicted maximum (its value
  at the joint MAP); or the refinement stopped on the budget rather than on its
  criterion (no refinement at all, EGO still running, or the posterior mean of
  sd[log L̃] still above ``uncertainty_tolerance`` nats); or, however the loop
  stopped, the surrogate is unsure where the *reported* draws lie (their mean
  sd[log L̃] above ``uncertainty_tolerance``): the refinement's criterion was met on
  the random walk's candidates, but the final sampler (HMC under ``auto``) went where
  nothing was evaluated.
- ``below_expected_fit`` (:func:`below_expected_fit`): when the output-error model
  gives the log L expected at the true parameters (mean, sd), the best observed
  log L lies far below it (more than ``gap_tolerance`` + ``truth_z`` sd). The data
  are then not reproduced as well as B says they would be at the truth: either the
  model lacks physics that is in the data (``susp-bo diagnose`` looks for it), or
  the search sits in a local optimum. It is its own reason, apart from
  ``not_converged``, because the two call for different actions: when it is the
  *only* reason, the loop has finished by its own criteria and more budget alone
  is not the remedy; ``susp-bo diagnose`` accepts such a calibration (a finished
  fit that misses the data is exactly what it examines).
- ``failed_region`` (:func:`.failed_region.failed_region`): the posterior reaches where
  the simulator failed — a held-out check simulation at the posterior's edges failed, or more than
  ``share`` of the reported draws lie nearer (in the unit cube of C_w) to a failed
  evaluation than to a successful one. The surrogate fills a failed point with the
  lowest finite log L, so that part of the posterior rests on a stand-in value, not on
  a simulation.
- ``at_bound`` (:func:`at_bound`): more than ``mass`` of a parameter's posterior
  draws sit within ``strip`` (fraction of the admissible width, at most half a
  posterior sd) of one bound —
  the posterior is cut off by C_w, so the true value may lie outside it or the
  search stopped early. (A flat posterior puts ``strip`` there; a posterior one
  sd wide whose mode sits one sd inside the bound puts about 5 %.)
- ``surrogate_misfit`` (:func:`surrogate_misfit`): held-out points at the
  posterior's edges fell outside the surrogate's predictive band (see
  :class:`~susp_bo.calibration.surrogate_check.SurrogateCheck`: GP sd and
  observation noise accounted for), with the direction the signs say
  (``overconfident``: log L higher than predicted, the real posterior is wider;
  ``underconfident``: lower, narrower; ``mixed``: both, misplaced or misshapen).
- ``surrogate_unchecked``: no held-out check ran (``check_points = 0`` or no
  budget left for it), or none of its simulations succeeded. Nothing then tests the
  surrogate posterior against the simulator, so the result is not trusted on the
  surrogate's word alone.
- ``search_box_edge`` (:func:`.trust_region.box_edge`): with a trust region, the
  final posterior presses against an inner face of the search box, which cut it, or an
  evaluation outside the box has a log L within ½ χ²_q(0.999) of the best (mass the box
  left out, e.g. a second mode).
- ``poor_mixing`` (:func:`poor_mixing`): split R-hat above ``r_hat_max`` (1.05) or
  bulk ESS below ``ess_min`` (400) on any parameter, in the draws reported (with the
  default sampler "auto", HMC was tried when the random walk found one mode and did
  not mix: :mod:`.sampling`).
- ``multimodal`` (:func:`multimodal`): the sampler found two or more separated modes
  (:mod:`.mode_jumps`). It then shares the mass between them as the surrogate says,
  but the surrogate's height and width of each mode rest on wherever the search put
  points, and the held-out check probes the edges of the whole posterior, not each
  mode: a mode whose bulk was never evaluated keeps too little mass without any other
  rule firing (measured on a trimodal 5-D target: MMTV 0.19, the third mode at 5 %
  of the draws against 23 %). A maintenance answer should not rest on that.

The thresholds are the keyword defaults of the rule functions; the README lists
them with each reason. The sentence and its advice: :mod:`.reliability_sentence`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from susp_bo.calibration.budget import BudgetRequirement, budget_too_small
from susp_bo.calibration.failed_region import failed_region
from susp_bo.calibration.reliability_sentence import AdviceFor, sentence
from susp_bo.calibration.surrogate_check import SurrogateCheck

Verdict = Literal["trusted", "not_trusted"]
Reason = dict[str, Any]
"""One reason: ``code`` (str), ``message`` (str, plain words) and the numbers behind it."""

NARROW_SHARE = 0.01
"""A posterior whose widest sd is below this share of C_w needs a search box that follows it."""
POOR_MIXING_R_HAT = 1.05
"""Largest split R-hat of a mixed sampler (``poor_mixing`` above it)."""

ORDER = (
    "budget_too_small",
    "not_converged",
    "below_expected_fit",
    "failed_region",
    "at_bound",
    "surrogate_misfit",
    "surrogate_unchecked",
    "search_box_edge",
    "poor_mixing",
    "multimodal",
)
"""Reason codes, most fundamental first (the sentence leads with the first that fired)."""


@dataclass(frozen=True)
class Reliability:
    """The verdict on a calibration result.

    Attributes:
        verdict: ``"trusted"`` (no rule fired) or ``"not_trusted"``.
        reasons: one dict per rule that fired: ``code``, ``message`` and its numbers.
        sentence: one plain sentence for the end of a run.
        evidence: the numbers every rule looked at (budget, best and predicted log L,
            R-hat, ESS, ...), whether or not it fired.
    """

    verdict: Verdict
    reasons: tuple[Reason, ...] = ()
    sentence: str = ""
    evidence: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.verdict not in ("trusted", "not_trusted"):
            raise ValueError(f"verdict: {self.verdict!r}, expected 'trusted' or 'not_trusted'")
        reasons = tuple(dict(r) for r in self.reasons)
        for r in reasons:
            if not isinstance(r.get("code"), str) or not isinstance(r.get("message"), str):
                raise ValueError(f"reasons: {r!r} needs a 'code' and a 'message' (strings)")
        if (self.verdict == "trusted") != (not reasons):
            raise ValueError(
                f"verdict: {self.verdict!r} with {len(reasons)} reasons; 'trusted' means none"
            )
        object.__setattr__(self, "reasons", reasons)
        object.__setattr__(self, "evidence", dict(self.evidence))

    @property
    def trusted(self) -> bool:
        """True when no rule fired."""
        return self.verdict == "trusted"

    @property
    def codes(self) -> tuple[str, ...]:
        """The reason codes, in order."""
        return tuple(r["code"] for r in self.reasons)

    def worded_for(self, advice_for: AdviceFor) -> Reliability:
        """The same verdict with its sentence's advice in ``advice_for``'s terms."""
        return dataclasses.replace(self, sentence=sentence(self.reasons, self.evidence, advice_for))

    def to_dict(self) -> dict[str, Any]:
        """The ``result.json["reliability"]`` object (JSON-ready)."""
        return {
            "verdict": self.verdict,
            "reasons": [dict(r) for r in self.reasons],
            "sentence": self.sentence,
            "evidence": dict(self.evidence),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Reliability:
        """Inverse of :meth:`to_dict`.

        Raises:
            ValueError: ``data`` is not a mapping with a ``verdict``.
        """
        if not isinstance(data, Mapping) or "verdict" not in data:
            raise ValueError(
                f"reliability: {data!r} is not allowed; expected an object with a 'verdict' "
                "('trusted' or 'not_trusted'), as result.json['reliability'] holds"
            )
        return cls(
            verdict=data["verdict"],
            reasons=tuple(data.get("reasons", ())),
            sentence=str(data.get("sentence", "")),
            evidence=dict(data.get("evidence", {})),
        )


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
    """
    findings: list[str] = []
    reason: Reason = {"code": "not_converged"}
    gap = predicted_max - best_log_likelihood
    allowed = gap_tolerance + z * max(predicted_max_sd, 0.0)
    if not math.isfinite(best_log_likelihood) or gap > allowed:
        findings.append(
            f"the search did not reach the optimum (best log L {best_log_likelihood:.1f} is "
            f"{gap:.1f} nats below the surrogate's predicted maximum {predicted_max:.1f} "
            f"± {predicted_max_sd:.2g})"
        )
        reason.update(optimum_gap_nats=float(gap), optimum_gap_allowed_nats=float(allowed))
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


def surrogate_misfit(check: SurrogateCheck | None, gross_nats: float = 10.0) -> Reason | None:
    """``surrogate_misfit`` (check outside its band) or ``surrogate_unchecked`` (no check
    ran, or none of its simulations succeeded).

    Args:
        check: the held-out check, None when none ran.
        gross_nats: an error beyond this (nats) is called gross in the message: the point
            lies outside the posterior's region altogether (a 95 % edge in 7-D sits about
            7 nats below the maximum), so the surrogate posterior is misplaced rather than
            merely too wide or too narrow.
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
    parts = []
    if above.any():
        parts.append(
            f"{int(above.sum())} above the prediction (up to +{float(np.max(e[above])):.1f} nats: "
            "the real posterior is wider there)"
        )
    if below.any():
        parts.append(
            f"{int(below.sum())} below (down to {float(np.min(e[below])):.1f} nats: narrower there)"
        )
    gross = ""
    if float(np.max(np.abs(e[check.outside]))) > gross_nats:
        gross = (
            f"; errors beyond {gross_nats:g} nats mean the surrogate posterior is misplaced or "
            "grossly misshapen, not only too wide or too narrow"
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
            "rests on the surrogate where the search may not have looked, and no held-out "
            "point checks each mode"
        ),
        "modes": int(modes),
    }


# -- the verdict --------------------------------------------------------------------------------


def assess(
    *,
    names: Sequence[str],
    bounds: np.ndarray,
    budget: int,
    requirement: BudgetRequirement,
    best_log_likelihood: float,
    predicted_max: float,
    predicted_max_sd: float,
    stop_reason: str,
    last_phase: str | None,
    last_criterion: float,
    draws_unit: np.ndarray,
    r_hat: np.ndarray,
    ess: np.ndarray,
    check: SurrogateCheck | None,
    expected_at_truth: tuple[float, float] | None = None,
    box_edge: Reason | None = None,
    modes: int = 1,
    sampler: str = "random_walk",
    draws_sd: float = math.nan,
    evaluated_unit: np.ndarray | None = None,
    evaluated_ok: np.ndarray | None = None,
    advice_for: AdviceFor = "python",
    searched_in_box: bool = False,
) -> Reliability:
    """Applies every rule and returns the verdict (arguments as in the rule functions).

    Args:
        draws_unit: (... x q) posterior draws in the unit cube of C_w (chains pooled here).
        box_edge: the ``search_box_edge`` reason of :func:`.trust_region.box_edge`, if any.
        modes: separated modes the sampler found (``RandomWalkMetropolis.diagnostics``).
        sampler: the kernel whose draws are assessed ("random_walk" or "hmc"; the
            trusted sentence names HMC).
        searched_in_box: the search ran in a box that follows the posterior (trust region
            or local phase); when it did not and ``not_converged`` fires on a posterior under
            :data:`NARROW_SHARE` of C_w wide, the reason carries ``posterior_width`` (its
            widest sd as a share of C_w) and the advice names the trust region.
        advice_for: whose terms the sentence's advice is in (:mod:`.reliability_sentence`):
            "python" (the settings of :func:`~susp_bo.calibration.loop.calibrate`, the
            default) or "command_line" (a study: :meth:`Reliability.worded_for`).
        draws_sd: mean sd[log L̃] (nats) over the reported draws (:func:`not_converged`).
        evaluated_unit: (n x q) every evaluated point in the unit cube of C_w, and
        evaluated_ok: (n,) True where its log L was finite (:func:`failed_region`; None:
            no evaluation known to have failed but the check's).
    """
    q = len(names)
    u = np.asarray(draws_unit, dtype=np.float64).reshape(-1, q)
    if (evaluated_unit is None) != (evaluated_ok is None):
        raise ValueError("evaluated_unit, evaluated_ok: give both or neither")
    if evaluated_unit is None or evaluated_ok is None:
        evaluated_unit, evaluated_ok = np.empty((0, q)), np.empty(0, dtype=bool)
    failed, failure_evidence = failed_region(u, evaluated_unit, evaluated_ok, check)
    found = [
        budget_too_small(budget, requirement),
        not_converged(
            best_log_likelihood=best_log_likelihood,
            predicted_max=predicted_max,
            predicted_max_sd=predicted_max_sd,
            stop_reason=stop_reason,
            last_phase=last_phase,
            last_criterion=last_criterion,
            draws_sd=draws_sd,
            posterior_width=(
                math.nan if searched_in_box or not u.size else float(np.max(np.std(u, axis=0)))
            ),
        ),
        below_expected_fit(best_log_likelihood, expected_at_truth),
        failed,
        at_bound(u, names, bounds),
        surrogate_misfit(check),
        poor_mixing(r_hat, ess, names),
        box_edge,
        multimodal(modes),
    ]
    reasons = sorted((r for r in found if r is not None), key=lambda r: ORDER.index(r["code"]))
    evidence: dict[str, Any] = {
        "budget": int(budget),
        "minimum_budget": requirement.minimum,
        "best_log_likelihood": float(best_log_likelihood),
        "predicted_max_log_likelihood": float(predicted_max),
        "predicted_max_sd": float(predicted_max_sd),
        "optimum_gap_nats": float(predicted_max - best_log_likelihood),
        "stop_reason": stop_reason,
        "last_phase": last_phase,
        "last_criterion": float(last_criterion) if math.isfinite(last_criterion) else None,
        "expected_at_truth": None if expected_at_truth is None else list(expected_at_truth),
        "check_verdict": None if check is None else check.verdict,
        "check_points": 0 if check is None else int(np.sum(np.isfinite(check.observed))),
        "r_hat_max": float(np.max(r_hat)),
        "ess_min": float(np.min(ess)),
        "modes": int(modes),
        "sampler": sampler,
        "draws_sd_nats": float(draws_sd) if math.isfinite(draws_sd) else None,
        **failure_evidence,
    }
    return Reliability(
        verdict="not_trusted" if reasons else "trusted",
        reasons=tuple(reasons),
        sentence=sentence(reasons, evidence, advice_for),
        evidence=evidence,
    )
