"""The reliability verdict's one plain sentence (:func:`.reliability.assess`), with advice.

Trusted: why (the search converged, the held-out check agreed, the MCMC mixed — naming
HMC when its draws were assessed). Not trusted: the first reason's message, the other
reasons' codes, and what to do about the first (``_ADVICE``, with the budget to give).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

_ADVICE = {
    "budget_too_small": "rerun with --resume --budget {minimum} or more (the evaluations "
    "already made are reused)",
    "not_converged": "rerun with --resume --budget {more}",
    "below_expected_fit": "run susp-bo diagnose on this result to look for the missing "
    "physics; if the search may sit in a local optimum, rerun with --resume --budget {more}",
    "failed_region": "look at the failed evaluations (the log, evaluations.sqlite): narrow "
    "the admissible interval to where the simulator runs, or make the failing simulations "
    "run, then rerun",
    "at_bound": "widen that parameter's admissible interval if its value may lie outside, "
    "or rerun with --resume --budget {more}",
    "surrogate_misfit": "rerun with --resume --budget {more}",
    "surrogate_unchecked": "rerun with check points ([budget] check_points)",
    "search_box_edge": "rerun with --resume --budget {more}",
    "poor_mixing": "rerun with more MCMC draws ([mcmc] draws, chains)",
    "multimodal": "look at the pair plot; rerun with --resume --budget {more} so that the "
    "search refines every mode; modes that persist mean the data do not identify the "
    "parameters uniquely",
}


def sentence(reasons: Sequence[Mapping[str, Any]], evidence: Mapping[str, Any]) -> str:
    """One plain sentence: what is wrong first (or why it is trusted), then what to do."""
    if not reasons:
        gap = float(evidence.get("optimum_gap_nats", math.nan))
        where = "above" if gap < 0 else "below"
        return (
            f"Trusted: the search converged (best log L {abs(gap):.2f} nats {where} the "
            "surrogate's predicted maximum), "
            f"the held-out check agreed at {evidence.get('check_points', 0)} posterior-edge "
            f"points and the MCMC mixed ({'HMC, ' if evidence.get('sampler') == 'hmc' else ''}"
            f"R-hat <= {evidence.get('r_hat_max', math.nan):.3f}, "
            f"ESS >= {evidence.get('ess_min', math.nan):.0f})."
        )
    first = reasons[0]
    budget = int(evidence.get("budget", 0))
    advice = _ADVICE.get(first["code"], "rerun with a larger budget").format(
        minimum=evidence.get("minimum_budget", budget),
        more=max(2 * budget, int(evidence.get("minimum_budget", 0))),
    )
    others = [r["code"] for r in reasons[1:]]
    also = f" (also: {', '.join(others)})" if others else ""
    return f"Not trusted: {first['message']}{also}; {advice}."
