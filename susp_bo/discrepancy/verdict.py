"""The answer of the discrepancy workflow: one verdict vocabulary and the rules behind it.

Verdicts (``discrepancy.json["verdict"]``, the command-line summary, the notebook):

* ``consistent`` — nothing flagged: data and model agree within the output error B;
* ``named`` — a library effect explains the flagged pattern and leaves no comparable
  disagreement elsewhere (:class:`NamingRule`);
* ``unexplained_disagreement`` — flagged bands that no library effect explains: the
  bands are listed with a sentence saying what kind of physics could produce them
  (:func:`describe_band`), or a channel whose whole level is off
  (:func:`~.detection.channel_offsets`: a sensor's gain, units or mounting) that no
  effect removes; ``named_effect`` is null;
* ``calibration_not_trusted`` — the calibration's reliability verdict is not
  ``trusted`` (or absent): residuals of an unfinished fit are not model
  discrepancy, so none is reported (:func:`calibration_reliability`).

Naming rule (a candidate is named only when *all* hold, else unexplained):

1. evidence: its refit score (log-likelihood gain less the BIC penalty, nats) >
   ``min_score`` (3 nats: "strong" evidence on the Kass–Raftery scale of ln B);
2. no effect parameter of the refit within ``bound_tolerance`` (share of its
   range) of a bound — an effect pinned at a bound is being used as a knob, not
   identified;
3. it explains the pattern: the refit removes at least ``min_explained`` of the
   Σ Z² on the bins flagged before (same simulator for both fits);
4. it leaves no comparable disagreement: after the refit at most
   ``max_remaining_share`` of the previously flagged share of bins is flagged, and
   no remaining band is stronger (mean |Z| × bins) than ``max_remaining_band`` of
   the strongest band before;
5. it creates no disagreement: the refit flags no band in a channel where no bin
   was flagged before (an effect that puts energy where the data have none is not
   the data's pattern, e.g. a sensor on a bracket taken for a carbody mode);
6. it leaves no level error: a channel whose whole level was off before
   (:func:`~.detection.channel_offsets`) is not off after the refit — an effect fitted
   to the bands of a miscalibrated sensor is physics fitted to a sensor fault (a real
   effect, e.g. a compliant yaw-damper mounting at 300 km/h, can shift a channel's
   level, and then removes it).

Accept rule of an augmented model (:func:`accept_augmented`): it is the answer only
if its posterior predictive log density over *all* bins is higher than the base
model's and its flagged share of all bins is lower; otherwise the base model stays.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from susp_bo.discrepancy.detection import Detection, FlaggedBand
from susp_bo.discrepancy.effects import EFFECTS

VERDICTS = ("consistent", "named", "unexplained_disagreement", "calibration_not_trusted")
"""The verdict vocabulary, in the order a maintainer reads it."""

NO_RELIABILITY = "no reliability verdict: result from an older version"


@dataclass(frozen=True)
class NamingRule:
    """Thresholds of the naming rule (module docstring).

    Args:
        min_score: least refit score (nats) for evidence, >= 0.
        bound_tolerance: share of an effect parameter's range counted as "at a bound".
        min_explained: least share of the flagged Σ Z² the refit must remove, in (0, 1].
        max_remaining_share: most flagged share after the refit, as a share of the
            flagged share before, in [0, 1).
        max_remaining_band: most weight (mean |Z| × bins) of any band left after the
            refit, as a share of the strongest band before, in [0, 1).
    """

    min_score: float = 3.0
    bound_tolerance: float = 0.01
    min_explained: float = 0.6
    max_remaining_share: float = 0.3
    max_remaining_band: float = 0.5

    def __post_init__(self) -> None:
        if not self.min_score >= 0:
            raise ValueError(f"NamingRule.min_score: got {self.min_score}; must be >= 0 nats")
        for name in ("bound_tolerance", "min_explained"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"NamingRule.{name}: got {value}; allowed [0, 1]")
        for name in ("max_remaining_share", "max_remaining_band"):
            value = getattr(self, name)
            if not 0.0 <= value < 1.0:
                raise ValueError(f"NamingRule.{name}: got {value}; allowed [0, 1)")


@dataclass(frozen=True)
class NamingCheck:
    """The naming rule applied to the best-ranked candidate.

    Attributes:
        effect: library name.
        score: refit score (nats).
        explained_share: share of Σ Z² on the bins flagged before removed by the refit.
        flagged_fraction_before, flagged_fraction_after: share of all bins flagged by the
            check of the base refit and of the augmented refit (same simulator).
        strongest_band_before, strongest_band_after: largest mean |Z| × bins of a band.
        at_bound: effect parameters within the bound tolerance of a bound.
        reasons: ``{"code", "message"}`` for every failed condition (empty = named).
    """

    effect: str
    score: float
    explained_share: float
    flagged_fraction_before: float
    flagged_fraction_after: float
    strongest_band_before: float
    strongest_band_after: float
    at_bound: tuple[str, ...]
    reasons: tuple[dict[str, str], ...]

    @property
    def passes(self) -> bool:
        """True when the candidate may be named."""
        return not self.reasons

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "effect": self.effect,
            "passes": self.passes,
            "score": self.score,
            "explained_share": self.explained_share,
            "flagged_fraction_before": self.flagged_fraction_before,
            "flagged_fraction_after": self.flagged_fraction_after,
            "strongest_band_before": self.strongest_band_before,
            "strongest_band_after": self.strongest_band_after,
            "at_bound": list(self.at_bound),
            "reasons": [dict(r) for r in self.reasons],
        }


def _band_weight(bands: Sequence[FlaggedBand]) -> float:
    return max((b.strength_z * b.n_bins for b in bands), default=0.0)


def parameters_at_bound(
    names: Sequence[str], w: np.ndarray, bounds: np.ndarray, tolerance: float
) -> tuple[str, ...]:
    """Names whose value lies within ``tolerance`` × range of a bound (bounds 2 x q)."""
    lower, upper = np.asarray(bounds, dtype=np.float64)
    unit = (np.asarray(w, dtype=np.float64) - lower) / (upper - lower)
    return tuple(n for n, u in zip(names, unit) if u <= tolerance or u >= 1.0 - tolerance)


def check_naming(
    effect: str,
    score: float,
    effect_parameters: Sequence[str],
    fit_names: Sequence[str],
    fit_w: np.ndarray,
    fit_bounds: np.ndarray,
    bins: np.ndarray,
    base_check: Detection,
    augmented_check: Detection,
    rule: NamingRule,
) -> NamingCheck:
    """Apply the naming rule to a candidate's refit.

    Args:
        effect: library name.
        score: the candidate's refit score (nats).
        effect_parameters: names of the effect's fitted parameters.
        fit_names, fit_w, fit_bounds: the augmented refit (names (q,), values (q,), 2 x q).
        bins: (C x F) bins flagged before (the pattern to explain).
        base_check, augmented_check: predictive checks of the base and augmented refits,
            on the same simulator.
        rule: thresholds.
    """
    mask = np.asarray(bins, dtype=bool)
    before = float(np.sum(base_check.z[mask] ** 2))
    after = float(np.sum(augmented_check.z[mask] ** 2))
    explained = 1.0 - after / before if before > 0 else 0.0
    values = dict(zip(fit_names, np.asarray(fit_w, dtype=np.float64)))
    index = {n: i for i, n in enumerate(fit_names)}
    effect_names = [n for n in effect_parameters if n in index]
    at_bound = parameters_at_bound(
        effect_names,
        np.array([values[n] for n in effect_names]),
        np.asarray(fit_bounds)[:, [index[n] for n in effect_names]],
        rule.bound_tolerance,
    )
    share_before = base_check.flagged_fraction
    share_after = augmented_check.flagged_fraction
    band_before = _band_weight(base_check.bands)
    band_after = _band_weight(augmented_check.bands)
    reasons: list[dict[str, str]] = []
    if not (math.isfinite(score) and score > rule.min_score):
        reasons.append({
            "code": "weak_evidence",
            "message": f"refit score {score:.3g} nats <= {rule.min_score:g}: the data do not "
            "support the effect after paying for its parameters",
        })  # fmt: skip
    if at_bound:
        reasons.append({
            "code": "effect_parameter_at_bound",
            "message": f"{', '.join(at_bound)} at a bound of the admissible range: the effect is "
            "used as a knob, not identified",
        })  # fmt: skip
    if explained < rule.min_explained:
        reasons.append({
            "code": "weak_signature",
            "message": f"the refit removes {explained:.0%} of the disagreement on the flagged "
            f"bins (needs {rule.min_explained:.0%}): the effect does not have the pattern's shape",
        })  # fmt: skip
    if share_after > rule.max_remaining_share * share_before or (
        band_before > 0 and band_after > rule.max_remaining_band * band_before
    ):
        reasons.append({
            "code": "disagreement_left",
            "message": f"after the refit {share_after:.1%} of the bins are still flagged "
            f"({share_before:.1%} before; strongest band {band_after:.3g} vs {band_before:.3g}): "
            "comparable disagreement remains",
        })  # fmt: skip
    clean = ~np.any(mask, axis=1) & ~np.any(np.asarray(base_check.flagged, dtype=bool), axis=1)
    created = [
        band
        for band in augmented_check.bands
        if clean[augmented_check.channels.index(band.channel)]
    ]
    if created:  # the effect puts energy where the data have none: not the data's pattern
        where = "; ".join(describe_band(band) for band in created[:2])
        reasons.append({
            "code": "new_disagreement",
            "message": f"the refit creates disagreement in {len(created)} band(s) of channels "
            f"that agreed before ({where}): the effect predicts energy the data do not have",
        })  # fmt: skip
    level_left = [
        offset
        for offset in augmented_check.offsets
        if offset.channel in {o.channel for o in base_check.offsets}
    ]
    if level_left:  # a channel's whole level is still off: a sensor, not this effect
        where = ", ".join(o.label() for o in level_left)
        reasons.append({
            "code": "level_error_left",
            "message": f"the refit leaves the whole level of {where} off: a level error (a "
            "sensor's gain, units or mounting) that the effect does not explain",
        })  # fmt: skip
    return NamingCheck(
        effect=effect,
        score=float(score),
        explained_share=explained,
        flagged_fraction_before=share_before,
        flagged_fraction_after=share_after,
        strongest_band_before=band_before,
        strongest_band_after=band_after,
        at_bound=at_bound,
        reasons=tuple(reasons),
    )


# ---------------------------------------------------------------- describing bands

_PLACE = {"front": "front", "mid": "mid-car", "rear": "rear"}


def _channel_words(channel: str) -> tuple[str, str, str]:
    """(body, place, direction) from a channel name such as ``carbody_mid_lateral``."""
    parts = channel.split("_")
    body = parts[0] if parts else channel
    direction = next((p for p in parts if p in ("vertical", "lateral")), "")
    place = next((_PLACE[p] for p in parts if p in _PLACE), "")
    return body, place, direction


def physics_hint(channel: str, f_low_hz: float, f_high_hz: float, sign: str) -> str:
    """What kind of physics the model may lack, from a band's channel, frequencies and sign."""
    body, _, direction = _channel_words(channel)
    centre = math.sqrt(f_low_hz * f_high_hz)
    more = sign == "model_too_little"
    if centre > 20.0:
        hint = "a wheel/rail excitation (wheel out-of-roundness at n·V/(πD)? rail corrugation?)"
    elif body == "carbody" and direction == "lateral":
        if centre < 3.0:
            hint = (
                "a carbody lateral/roll mode the model lacks or misplaces (low-conicity carbody "
                "hunting? secondary lateral stiffness? an accelerometer rolled so that it picks "
                "up vertical motion or gravity?)"
            )
        else:
            hint = (
                "bogie-to-carbody lateral transmission (wheelset guidance: conicity, primary "
                "lateral stiffness? yaw-damper compliance? body flexibility?)"
            )
    elif body == "carbody":
        if centre < 3.0:
            hint = (
                "carbody bounce/pitch (air-spring stiffness or reservoir? an accelerometer at "
                "another position along the car than the model assumes?)"
            )
        else:
            hint = "carbody flexibility (bending/torsion modes? equipment masses?)"
    elif direction == "lateral":
        hint = (
            "wheelset guidance or bogie lateral/yaw dynamics (conicity, primary lateral or "
            "longitudinal stiffness, creep coefficients, yaw-damper dynamics?)"
        )
    else:
        hint = "the primary suspension or the wheel/rail input (primary stiffness, wheel defects?)"
    if not more:
        hint += "; the model has too much energy there: a mode at the wrong frequency or too "
        hint += "little damping in the model"
    return hint


def describe_band(band: FlaggedBand) -> str:
    """One line: channel, band, sign and the kind of physics that could produce it."""
    body, place, direction = _channel_words(band.channel)
    where = " ".join(p for p in (body, place, direction) if p) or band.channel
    above = (
        "measured above the model"
        if band.sign == "model_too_little"
        else ("measured below the model")
    )
    return (
        f"{where} {band.f_low_hz:.2g}–{band.f_high_hz:.2g} Hz, {above} "
        f"({band.residual_db:+.1f} dB, |Z| {band.strength_z:.1f}): "
        f"{physics_hint(band.channel, band.f_low_hz, band.f_high_hz, band.sign)}"
    )


def unexplained_sentence(
    bands: Sequence[FlaggedBand], tried: Sequence[str] | None = None, limit: int = 3
) -> str:
    """The sentence of an ``unexplained_disagreement`` answer (strongest bands first).

    Args:
        bands: the flagged bands, strongest first.
        tried: the library effects that were tried (None: the whole library). When some
            library effects were not tried, the sentence says which instead of claiming
            that no library effect explains the bands.
        limit: bands described in full.
    """
    lines = "; ".join(describe_band(b) for b in bands[:limit])
    more = f" (and {len(bands) - limit} more bands)" if len(bands) > limit else ""
    untried = [] if tried is None else [name for name in EFFECTS if name not in tried]
    if not untried:
        return (
            f"Data and model disagree in {len(bands)} band(s) that no library effect explains: "
            f"{lines}{more}. Look for physics outside the library before replacing parts."
        )
    assert tried is not None
    return (
        f"Data and model disagree in {len(bands)} band(s) that none of the {len(tried)} "
        f"effect(s) tried ({', '.join(tried)}) explains: {lines}{more}. The library's "
        f"other effects ({', '.join(untried)}) were not tried: try them, then look for "
        "physics outside the library, before replacing parts."
    )


# ---------------------------------------------------------------- accept rule


def accept_augmented(before: Detection, after: Detection) -> tuple[bool, list[dict[str, str]]]:
    """The accept rule: better log predictive density over all bins and fewer flagged bins.

    Returns:
        (accepted, reasons it was not).
    """
    reasons: list[dict[str, str]] = []
    if not after.log_predictive_density > before.log_predictive_density:
        reasons.append({
            "code": "log_predictive_density_not_better",
            "message": f"log predictive density over all bins {after.log_predictive_density:.4g}"
            f" <= {before.log_predictive_density:.4g} of the base model",
        })  # fmt: skip
    if not after.flagged_fraction < before.flagged_fraction:
        reasons.append({
            "code": "flagged_share_not_lower",
            "message": f"flagged share of all bins {after.flagged_fraction:.1%} >= "
            f"{before.flagged_fraction:.1%} of the base model",
        })  # fmt: skip
    return not reasons, reasons


# ---------------------------------------------------------------- reliability gate


@dataclass(frozen=True)
class CalibrationReliability:
    """What the calibration's ``result.json`` says about itself (the shared contract).

    Attributes:
        trusted: ``reliability.verdict == "trusted"``.
        verdict: the verdict string, or None when the key is absent.
        reasons: the calibration's reasons (``code``, ``message``, ...).
        sentence: the calibration's own sentence (or why there is none).
    """

    trusted: bool
    verdict: str | None
    reasons: tuple[dict[str, Any], ...]
    sentence: str

    @property
    def fit_finished(self) -> bool:
        """The fit is done: trusted, or not trusted only because it misses the data by more
        than B allows (``below_expected_fit``) or by as much as the scatter between tracks
        (``runs_not_reproduced``, the unpaired B), possibly with parameters pushed to a
        bound of C_w (``at_bound``: what a model lacking physics often does to compensate)
        — the loop finished by its own criteria, and what is left is what the discrepancy
        workflow examines. Any reason of an unfinished search or sampler keeps it out."""
        codes = {str(r.get("code")) for r in self.reasons}
        return self.trusted or (
            self.verdict == "not_trusted"
            and bool(codes & set(MISFIT_CODES))
            and codes <= {*MISFIT_CODES, "at_bound"}
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "verdict": self.verdict,
            "trusted": self.trusted,
            "fit_finished": self.fit_finished,
            "reasons": [dict(r) for r in self.reasons],
            "sentence": self.sentence,
        }


BELOW_EXPECTED = "below_expected_fit"
MISFIT_CODES = (BELOW_EXPECTED, "runs_not_reproduced")
"""Reasons that say a finished fit misses the data (what ``susp-bo diagnose`` examines)."""
"""The reliability reason that alone does not stop the workflow (CalibrationReliability)."""


def calibration_reliability(payload: Mapping[str, Any]) -> CalibrationReliability:
    """Read ``payload["reliability"]`` (a ``result.json``); absent counts as not trusted."""
    block = payload.get("reliability")
    if not isinstance(block, Mapping):
        reason = {"code": "no_reliability", "message": NO_RELIABILITY}
        return CalibrationReliability(False, None, (reason,), NO_RELIABILITY)
    verdict = block.get("verdict")
    reasons = tuple(dict(r) for r in block.get("reasons") or () if isinstance(r, Mapping))
    sentence = str(block.get("sentence") or "")
    return CalibrationReliability(verdict == "trusted", verdict, reasons, sentence)


def not_trusted_sentence(
    reliability: CalibrationReliability, result_dir: str, n_evaluations: int | None
) -> str:
    """The answer when the calibration is not trusted: why, and what to do."""
    why = "; ".join(str(r.get("message", r.get("code", ""))) for r in reliability.reasons)
    minimum = max(
        (int(r["minimum"]) for r in reliability.reasons if isinstance(r.get("minimum"), int)),
        default=0,
    )  # budget_too_small names the minimum: advice below it would be refused in turn
    larger = max(2 * n_evaluations if n_evaluations else 0, minimum)
    budget = f" --budget {larger}" if larger else " --budget N (larger)"
    if reliability.reasons and reliability.reasons[0].get("code") == "failed_region":
        return (  # more budget is not the remedy where the simulator fails
            f"calibration_not_trusted: the calibration in {result_dir} is not trusted ({why}). "
            "Disagreement between data and model would be read from a posterior that rests on "
            "failed simulations, so no band is reported as model discrepancy. Repair the "
            "calibration first: look at the failed evaluations (its log, evaluations.sqlite), "
            "narrow the admissible interval of the rig file to where the simulator runs or make "
            "the failing simulations run, calibrate again, then diagnose again (--force runs "
            "the detection anyway, for experts, labelled as such)."
        )
    return (
        f"calibration_not_trusted: the calibration in {result_dir} is not trusted ({why}). "
        "Disagreement between data and model would be read from an unfinished fit, so no band "
        "is reported as model discrepancy. Finish the calibration first: "
        f"susp-bo calibrate {result_dir}/study.toml --resume{budget} "
        "(a larger budget; --resume reuses every evaluation done), then diagnose again "
        "(--force runs the detection anyway, for experts, labelled as such)."
    )
