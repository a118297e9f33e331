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
- ``runs_not_reproduced`` (:func:`.track_match.runs_not_reproduced`, applied by
  :func:`.loop.calibrate` under the unpaired B to a result no other rule refused): the
  simulation leaves residuals on the scale of the scatter between runs on different
  tracks (each run against its nearest simulated spectrum): the tracks are not the runs'
  own — and on tracks known only by their statistics the unpaired model's intervals are
  too narrow — or the model misses an effect that large.
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
  ``underconfident``: lower, narrower; ``mixed``: both, misplaced or misshapen;
  ``misplaced``: an error beyond 10 nats, outside the posterior's region, whatever its
  sign).
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
from susp_bo.calibration.reliability_rules import (
    NARROW_SHARE,
    POOR_MIXING_R_HAT,
    Reason,
    at_bound,
    below_expected_fit,
    checked_expected_at_truth,
    multimodal,
    not_converged,
    plausible_max_log_likelihood,
    poor_mixing,
    surrogate_misfit,
)
from susp_bo.calibration.reliability_sentence import AdviceFor, sentence
from susp_bo.calibration.surrogate_check import SurrogateCheck

__all__ = [
    "NARROW_SHARE",
    "ORDER",
    "POOR_MIXING_R_HAT",
    "Reason",
    "Reliability",
    "Verdict",
    "assess",
    "at_bound",
    "below_expected_fit",
    "budget_too_small",
    "checked_expected_at_truth",
    "failed_region",
    "multimodal",
    "not_converged",
    "plausible_max_log_likelihood",
    "poor_mixing",
    "surrogate_misfit",
]
"""The verdict, and the rules re-exported from :mod:`.reliability_rules` (one import)."""

Verdict = Literal["trusted", "not_trusted"]


ORDER = (
    "budget_too_small",
    "not_converged",
    "below_expected_fit",
    "runs_not_reproduced",
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

    def with_rule(
        self, reason: Mapping[str, Any] | None, evidence: Mapping[str, Any]
    ) -> Reliability:
        """The verdict after a rule applied once the others had (the lack of fit, the
        track match): ``evidence`` recorded and, when ``reason`` is not None, that reason
        the only one of a now ``not_trusted`` verdict, its sentence in Python terms (a
        study words it again). A verdict that stays trusted is worded again from the new
        evidence (its caveats may change; a trusted sentence has no advice, so it reads the
        same to every caller); one that stays not trusted keeps its sentence and wording."""
        if reason is None:
            kept = dataclasses.replace(self, evidence=dict(evidence))
            return kept.worded_for("python") if kept.trusted else kept
        refused = dataclasses.replace(
            self, verdict="not_trusted", reasons=(dict(reason),), evidence=dict(evidence)
        )
        return refused.worded_for("python")

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
    expectation_bounds_maximum: bool = False,
    mass_outside_box: float | None = None,
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
        expectation_bounds_maximum: ``expected_at_truth`` comes from an output-error model
            whose scale is the residual's own (the paired B), so it also bounds the
            maximum of log L (:func:`plausible_max_log_likelihood`, used by
            :func:`not_converged`'s message). Not under the unpaired B, where the truth's
            log L sits far above that expectation (second review, session 27).
        mass_outside_box: with ``searched_in_box``, the lower estimate of the posterior
            mass outside the box (:func:`.box_mass.share_outside_box`), written to the
            evidence; None when it could not be estimated (evidence null; also the
            default, so a caller that forgets it never records "estimated, none").
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
            plausible_max=(
                plausible_max_log_likelihood(expected_at_truth, q)
                if expectation_bounds_maximum
                else math.nan
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
    if searched_in_box:
        share = None if mass_outside_box is None else float(mass_outside_box)
        evidence["mass_outside_box"] = share if share is not None and math.isfinite(share) else None
    return Reliability(
        verdict="not_trusted" if reasons else "trusted",
        reasons=tuple(reasons),
        sentence=sentence(reasons, evidence, advice_for),
        evidence=evidence,
    )
