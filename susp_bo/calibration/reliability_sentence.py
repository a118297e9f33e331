"""The reliability verdict's one plain sentence (:func:`.reliability.assess`), with advice.

Trusted: why (the search converged, the held-out check agreed, the MCMC mixed — naming
HMC when its draws were assessed), and, after a search in a box whose left-out mass could
not be estimated (``evidence.mass_outside_box`` null), that a broad, low mode outside the
box is neither seen nor ruled out; and, when the lack of fit between measured runs was
looked for but could not be computed (``evidence.lack_of_fit_ratio`` null: one run, or
spectra that failed), that a model error the output error's scale hides is neither seen nor
ruled out either. Not trusted: the first reason's message, the other
reasons' codes, and what to do about the first, in the caller's terms: a Python caller of
:func:`~susp_bo.calibration.loop.calibrate` is told the settings to change
(:data:`PYTHON_ADVICE`), a study (``susp-bo calibrate``, ``demo``, ``monitor``) the flags and
study keys (:data:`COMMAND_LINE_ADVICE`), each with the budget to give.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

AdviceFor = Literal["python", "command_line"]

KERNEL_ADVISED_REASONS = ("not_converged", "surrogate_misfit")
"""First reasons a better surrogate could remove (:mod:`.kernel_advice`); the others
(mixing, bounds, failures, the box, the model's own misfit) have remedies of their own."""
ADDITIVE_GAIN_KEY = "additive_kernel_loo_gain"
"""Evidence key: the additive kernel's leave-one-out gain over the Matérn, nats a point
(:func:`.kernel_advice.additive_kernel_gain`; absent when not computed)."""
ADDITIVE_GAIN_NATS = 0.1
"""Gain at or above which the advice names the additive kernel instead of more budget."""

COMMAND_LINE_ADVICE = {
    "budget_too_small": "rerun with --resume --budget {minimum} or more (the evaluations "
    "already made are reused)",
    "not_converged": "rerun with --resume --budget {more}",
    "below_expected_fit": "run susp-bo diagnose on this result to look for the missing "
    "physics; if the search may sit in a local optimum, rerun with --resume --budget {more}",
    "summary_misfit": "the model lacks physics these runs show; susp-bo diagnose, which "
    "names the missing effect, needs each run's measured track: measure the tracks and "
    'calibrate with [output_error] model = "paired", or add the suspected effect to the '
    "rig file and calibrate again",
    "runs_not_reproduced": "if the runs' tracks were not measured, measure them and give "
    "each with its run (the measured-data format's track geometry), then calibrate with "
    '[output_error] model = "paired" and [search] local = true, or calibrate with '
    '[output_error] model = "track_statistics" (calibrated on tracks known only by their '
    "statistics, for an exact model) — eq. 4's intervals are not calibrated there; if "
    "they were, look for the physics the model misses (the residuals of the best point, "
    "susp-bo diagnose)",
    "failed_region": "look at the failed evaluations (the log, evaluations.sqlite): narrow "
    "the admissible interval to where the simulator runs, or make the failing simulations "
    "run, then rerun",
    "at_bound": "widen that parameter's admissible interval if its value may lie outside, "
    "or rerun with --resume --budget {more}",
    "surrogate_misfit": "rerun with --resume --budget {more}",
    "surrogate_unchecked": "rerun with check points ([budget] check_points)",
    "search_box_edge": "rerun with --resume --budget {more}",
    "box_left_mass": "look at the evaluations outside the search box (study.log, "
    "evaluations.sqlite): the box follows one hill, so more budget would refine the same "
    "box; a second hill the data allow means they do not identify the parameters uniquely",
    "poor_mixing": "rerun with more MCMC draws ([mcmc] draws, chains)",
    "hmc_stuck": 'rerun with [mcmc] sampler = "auto": HMC alone does not cross between '
    "separated modes, more of its draws would not either",
    "failed_scattered": "make the failing simulations run (the log and evaluations.sqlite "
    "name them; narrowing the admissible interval will not avoid failures that strike "
    "anywhere), then rerun",
    "noisy": "make the evaluations repeatable (the same parameters must give the same log "
    "L), then rerun",
    "multimodal": "look at the pair plot; rerun with --resume --budget {more} so that the "
    "search refines every mode; modes that persist mean the data do not identify the "
    "parameters uniquely",
    "additive_kernel": "a pairwise additive kernel predicts the evaluations better than the "
    'default Matérn (leave-one-out, {gain:+.2f} nats a point): set [search] kernel = "auto" '
    "(both kernels fitted, the better kept) and refine_optimism = 2 in the study's config "
    "(study.toml; monitor.toml for monitor), then rerun with --resume --budget {more}",
}
"""Advice for a study run from the command line (or ``run_study``): flags and study keys."""

_MORE = "rerun with a larger budget, CalibrationSettings(max_evaluations={more})"
PYTHON_ADVICE = {
    "budget_too_small": "give CalibrationSettings(max_evaluations={minimum}) or more",
    "not_converged": _MORE,
    "below_expected_fit": "look for physics the model misses (susp-bo diagnose examines a "
    "study's results folder); if the search may sit in a local optimum, " + _MORE,
    "summary_misfit": "the model lacks physics these runs show: add the suspected effect "
    "to the rig (susp_bo.discrepancy.effects) and calibrate again, or measure the tracks "
    "and look for it with the paired model (susp_bo.discrepancy names effects from each "
    "run's residuals on its own track)",
    "runs_not_reproduced": "if the simulated tracks are not the runs' own, simulate each "
    "run on its own measured track and calibrate with the paired model (PairedOutputError, "
    "CalibrationSettings(local_search=True)), or, if the tracks cannot be measured, use "
    "the summary likelihood (susp_bo.calibration.track_statistics), calibrated on tracks "
    "known only by their statistics for an exact model; if they are, look for the physics "
    "the model misses",
    "failed_region": "look at the failed evaluations (result.X where result.y is NaN): "
    "narrow the bounds to where the evaluator runs, or make the failing evaluations run, "
    "then rerun",
    "at_bound": "widen that parameter's bounds if its value may lie outside, or " + _MORE,
    "surrogate_misfit": _MORE,
    "surrogate_unchecked": "rerun with check points (CalibrationSettings(check_points=8))",
    "noisy": "let the surrogate learn the noise: CalibrationSettings(surrogate="
    'SurrogateSettings(noise="learned"))',
    "search_box_edge": _MORE,
    "box_left_mass": "rerun over all of C_w (CalibrationSettings(trust_region=False); with "
    "local_search=True its box follows one hill too): more budget would refine the same box",
    "narrow": "the posterior is under 1 % of C_w wide, too narrow for a surrogate of all of "
    "C_w: CalibrationSettings(trust_region=True) refines in a box that follows it; or " + _MORE,
    "poor_mixing": "rerun with more MCMC draws (CalibrationSettings(mcmc_samples=..., "
    "mcmc_chains=...))",
    "hmc_stuck": 'rerun with CalibrationSettings(mcmc_sampler="auto"): HMC alone does not '
    "cross between separated modes, more of its draws would not either",
    "failed_scattered": "make the failing evaluations run (result.X where result.y is NaN; "
    "narrowing the bounds will not avoid failures that strike anywhere), then rerun",
    "multimodal": "look at the pair plot; " + _MORE + " so that the search refines every "
    "mode; modes that persist mean the data do not identify the parameters uniquely",
    "additive_kernel": "a pairwise additive kernel predicts the evaluations better than the "
    "default Matérn (leave-one-out, {gain:+.2f} nats a point): rerun with "
    'CalibrationSettings(surrogate=SurrogateSettings(kernel="auto"), refine_optimism=2.0, '
    "max_evaluations={more}) (both kernels fitted, the better kept)",
}
"""Advice for a caller of :func:`~susp_bo.calibration.loop.calibrate`: its settings."""


_UNBOUNDED_BOX_MASS = (
    "the posterior mass outside the search box could not be estimated "
    "(mass_outside_box null), so a broad, low mode outside it is neither seen nor ruled out"
)
"""The trusted sentence's caveat when :func:`.box_mass.share_outside_box` returned None."""

_UNCHECKED_LACK_OF_FIT = (
    "the lack of fit between measured runs could not be checked (lack_of_fit_ratio null: "
    "it needs 2 or more runs with finite spectra), so a model error that the output "
    "error's scale hides is neither seen nor ruled out"
)
"""The trusted sentence's caveat when :func:`.lack_of_fit.with_lack_of_fit` was applied but
could not compute F: one measured run, or spectra that failed at the best point."""


def _box_mass_unknown(evidence: Mapping[str, Any]) -> bool:
    """A boxed search whose share outside the box was not estimated (the key is present
    for boxed searches only, null when not estimated)."""
    return "mass_outside_box" in evidence and evidence["mass_outside_box"] is None


def _lack_of_fit_unchecked(evidence: Mapping[str, Any]) -> bool:
    """A result whose lack of fit was looked for but not computed (the key is present only
    when the evaluator exposes its spectra and the measured runs; null when not computed)."""
    return "lack_of_fit_ratio" in evidence and evidence["lack_of_fit_ratio"] is None


_UNTESTED_SUMMARIES = (
    "the summaries the fit does not use could not be tested (summary_misfit_p null: too "
    "few pilot runs for one band group per channel, or spectra that failed at the best "
    "point), so a model error the summary likelihood absorbs is neither seen nor ruled out"
)
"""The trusted sentence's caveat when :func:`.fit_rules.with_summary_misfit` was applied but
could not compute its p."""


def _summaries_untested(evidence: Mapping[str, Any]) -> bool:
    """A summary-likelihood result whose goodness of fit was looked for but not computed."""
    return "summary_misfit_p" in evidence and evidence["summary_misfit_p"] is None


def _caveats(evidence: Mapping[str, Any]) -> str:
    """What a trusted result's rules could not look at, as the sentence's tail ("" when
    every rule could)."""
    unknown = [
        text
        for text, applies in (
            (_UNBOUNDED_BOX_MASS, _box_mass_unknown(evidence)),
            (_UNCHECKED_LACK_OF_FIT, _lack_of_fit_unchecked(evidence)),
            (_UNTESTED_SUMMARIES, _summaries_untested(evidence)),
        )
        if applies
    ]
    return "; but " + "; and ".join(unknown) if unknown else ""


def advice_code(
    reasons: Sequence[Mapping[str, Any]], evidence: Mapping[str, Any], advice_for: AdviceFor
) -> str:
    """The key of the advice a not-trusted sentence gives: the first reason's code, or what
    replaces it (``noisy``, ``failed_scattered``, ``narrow``, ``additive_kernel``,
    ``hmc_stuck``, ``box_left_mass``, ``summary_misfit``); :mod:`.kernel_advice` asks it
    whether a gain would be used before paying for the fit."""
    first = reasons[0]
    table = PYTHON_ADVICE if advice_for == "python" else COMMAND_LINE_ADVICE
    # a noisy log L, or failures that strike anywhere, defeat every other remedy (more
    # budget cannot converge on noise, nor on stand-in values scattered through the data)
    noisy = any(r.get("direction") == "noisy" for r in reasons)
    scattered = any(r.get("code") == "failed_region" and r.get("scattered") for r in reasons)
    code = "noisy" if noisy else "failed_scattered" if scattered else first["code"]
    if code == "not_converged" and first.get("posterior_width") is not None:
        code = "narrow" if "narrow" in table else code
    gain = evidence.get(ADDITIVE_GAIN_KEY)
    if code in KERNEL_ADVISED_REASONS and gain is not None and gain >= ADDITIVE_GAIN_NATS:
        code = "additive_kernel"  # the default kernel's structure is the problem
    if code == "poor_mixing" and evidence.get("sampler") == "hmc":
        code = "hmc_stuck"  # the caller forced HMC (outside probe, session 25)
    if code == "search_box_edge" and (
        first.get("evaluations_outside_box")
        or first.get("mass_outside_box")
        or first.get("tail_at_face")
    ):
        code = "box_left_mass"  # more budget would refine the same box
    if code == "below_expected_fit" and "summary_misfit_dof" in evidence:
        # the summary likelihood (its fit rules ran): diagnose cannot examine it; a model
        # error (this test's, or the lack of fit's) asks for the physics, while its log L
        # alone falls short of what it expects only on a search short of the optimum
        model_error = first.get("summary_misfit_p") is not None or "lack_of_fit_ratio" in first
        code = "summary_misfit" if model_error else "not_converged"
    return code


def sentence(
    reasons: Sequence[Mapping[str, Any]],
    evidence: Mapping[str, Any],
    advice_for: AdviceFor,
) -> str:
    """One plain sentence: what is wrong first (or why it is trusted), then what to do, in
    the terms of ``advice_for`` (module docstring; no default: the caller says whom it
    advises — session 24's review found this default and :func:`.reliability.assess`'s
    disagreeing)."""
    if not reasons:
        gap = float(evidence.get("optimum_gap_nats", math.nan))
        where = (  # a gap that prints as 0.00 has no side (outside probe, session 30)
            "at the surrogate's predicted maximum (within 0.005 nats)"
            if abs(gap) < 0.005
            else f"{abs(gap):.2f} nats {'above' if gap < 0 else 'below'} the surrogate's "
            "predicted maximum"
        )
        return (
            f"Trusted: the search converged (best log L {where}), "
            f"the held-out check agreed at {evidence.get('check_points', 0)} posterior-edge "
            f"points and the MCMC mixed ({'HMC, ' if evidence.get('sampler') == 'hmc' else ''}"
            f"R-hat <= {evidence.get('r_hat_max', math.nan):.3f}, "
            f"ESS >= {evidence.get('ess_min', math.nan):.0f})"
            f"{_caveats(evidence)}."
        )
    first = reasons[0]
    budget = int(evidence.get("budget", 0))
    table = PYTHON_ADVICE if advice_for == "python" else COMMAND_LINE_ADVICE
    code = advice_code(reasons, evidence, advice_for)
    advice = table.get(code, "rerun with a larger budget").format(
        minimum=evidence.get("minimum_budget", budget),
        more=max(2 * budget, int(evidence.get("minimum_budget", 0))),
        gain=evidence.get(ADDITIVE_GAIN_KEY, math.nan),
    )
    others = [r["code"] for r in reasons[1:]]
    also = f" (also: {', '.join(others)})" if others else ""
    return f"Not trusted: {first['message']}{also}; {advice}."
