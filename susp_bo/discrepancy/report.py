"""What the discrepancy workflow found: :class:`DiagnosisReport` (``discrepancy.json``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from susp_bo.discrepancy.detection import MIN_CHANNEL_OFFSET_DB, ChannelOffset, Detection
from susp_bo.discrepancy.fitting import Fit
from susp_bo.discrepancy.problem import DiagnosisProblem
from susp_bo.discrepancy.ranking import RankedEffect
from susp_bo.discrepancy.verdict import VERDICTS, NamingCheck, describe_band, unexplained_sentence


@dataclass(frozen=True)
class DiagnosisReport:
    """Everything the workflow found (``to_dict`` is ``discrepancy.json``).

    Attributes:
        problem: data, tracks, base rig.
        base: the base model's fit.
        before: predictive check of the base model.
        ranking: candidates, best first (empty when nothing was flagged).
        named_effect: the library effect named, or None.
        augmented: the augmented model (effect added, recalibrated), or None.
        after: predictive check of ``augmented`` (None when nothing was added).
        gap_before, gap_after: :func:`~.detection.gap_metrics` on the bins flagged before
            (``gap_after`` = ``gap_before`` when nothing was added).
        simulator: the models used.
        verdict: one of :data:`~.verdict.VERDICTS`.
        naming_check: the naming rule applied to the best candidate (None when not reached).
        accepted: the augmented model passed the accept rule (None when nothing was added).
        accept_reasons: why it did not.
        extra: further JSON fields.
    """

    problem: DiagnosisProblem
    base: Fit
    before: Detection
    ranking: tuple[RankedEffect, ...]
    named_effect: str | None
    augmented: Fit | None
    after: Detection | None
    gap_before: dict[str, float]
    gap_after: dict[str, float]
    simulator: str
    verdict: str = "consistent"
    naming_check: NamingCheck | None = None
    accepted: bool | None = None
    accept_reasons: tuple[dict[str, str], ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict: got {self.verdict!r}; allowed {', '.join(VERDICTS)}")

    @property
    def gap_ratio(self) -> float:
        """gap_after / gap_before on the bins flagged before (1 when nothing was added)."""
        return self.gap_after["value"] / self.gap_before["value"]

    @property
    def gap_ratio_all_bins(self) -> float:
        """gap_after / gap_before over all bins."""
        return self.gap_after["value_all_bins"] / self.gap_before["value_all_bins"]

    @property
    def answer_model(self) -> str:
        """``augmented`` when the augmented model was accepted, else ``base``."""
        return "augmented" if self.accepted else "base"

    def sentence(self) -> str:
        """The answer in one paragraph (stderr of ``susp-bo diagnose``, notebook)."""
        n_bins = int(self.before.z.size)
        if self.verdict == "consistent":
            return (
                f"consistent: no bin of {n_bins} (channels × frequencies) disagrees beyond "
                f"the output error at the Benjamini–Hochberg level q = {self.before.q}, and "
                f"no channel's whole level is {MIN_CHANNEL_OFFSET_DB:g} dB or more off (and "
                "significant at q); nothing to name."
            )
        if self.verdict == "unexplained_disagreement" and self.before.offsets:
            bands = self.before.bands
            text = offsets_sentence(self.before.offsets)
            if bands:  # flagged too: what the best candidate could not do
                text += (
                    f" {len(bands)} band(s) are flagged as well (strongest "
                    f"{describe_band(bands[0])})"
                )
                if self.naming_check is not None:
                    why = "; ".join(r["message"] for r in self.naming_check.reasons)
                    best = self.naming_check.effect
                    text += f"; the best library candidate, {best}, was not named: {why}"
                text += ". Check the sensor, then calibrate and diagnose again."
            return f"unexplained_disagreement: {text}"
        if self.verdict == "named" and self.before.offsets:  # rule 6: it removed the level
            levels = ", ".join(o.label() for o in self.before.offsets)
            return f"{self._sentence()} It also explains the whole-level difference of {levels}."
        return self._sentence() + (
            f" Also: {offsets_sentence(self.before.offsets)}" if self.before.offsets else ""
        )

    def _sentence(self) -> str:
        if self.verdict == "unexplained_disagreement":
            text = unexplained_sentence(self.before.bands, [r.effect for r in self.ranking])
            if self.naming_check is not None:
                why = "; ".join(r["message"] for r in self.naming_check.reasons)
                text += f" Best library candidate {self.naming_check.effect} not named: {why}."
            return f"unexplained_disagreement: {text}"
        if self.verdict == "named":
            check = self.naming_check
            assert check is not None and self.after is not None
            text = (
                f"named: {self.named_effect} explains the flagged pattern (refit score "
                f"{check.score:.3g} nats, removes {check.explained_share:.0%} of the "
                "disagreement on the flagged bins; strongest band before: "
                f"{describe_band(self.before.bands[0])})."
            )
            lpd0, lpd1 = self.before.log_predictive_density, self.after.log_predictive_density
            share0, share1 = self.before.flagged_fraction, self.after.flagged_fraction
            if self.after.bands:  # what the named effect leaves, said, not only in the JSON
                runner_up = next(
                    (r for r in self.ranking[1:] if r.fit is not None and r.score > 0), None
                )
                text += (
                    f" Still flagged with it: {len(self.after.bands)} band(s), strongest "
                    f"{describe_band(self.after.bands[0])}"
                    + (
                        f"; the next candidate, {runner_up.effect}, scored "
                        f"{runner_up.score:.3g} nats: a second missing effect may remain"
                        if runner_up is not None
                        else ""
                    )
                    + "."
                )
            if self.accepted:
                return (
                    f"{text} Augmented model accepted: log predictive density over all bins "
                    f"{lpd0:.4g} -> {lpd1:.4g}, flagged share {share0:.1%} -> {share1:.1%}."
                )
            why = "; ".join(r["message"] for r in self.accept_reasons)
            return (
                f"{text} The recalibrated model with {self.named_effect} is NOT better ({why}); "
                "the base model stays the answer. Recalibrate with a larger budget before "
                "relying on the effect's values."
            )
        return str(self.extra.get("sentence", self.verdict))

    def parameter_table(self) -> list[dict[str, Any]]:
        """Base parameters before and after adding the effect, with the truth when known."""
        truth = self.problem.reference or {}
        after = self.augmented.parameters() if self.augmented is not None else {}
        rows = []
        for name, value in self.base.parameters().items():
            row: dict[str, Any] = {"name": name, "before": value, "after": after.get(name)}
            row["truth"] = truth.get(name)
            rows.append(row)
        if self.augmented is not None:
            for name, value in after.items():
                if name not in self.base.names:
                    rows.append({"name": name, "before": None, "after": value,
                                 "truth": truth.get(name)})  # fmt: skip
        return rows

    def to_dict(self) -> dict[str, Any]:
        """The ``discrepancy.json`` content (physical units)."""
        ranking = [r.to_dict() for r in self.ranking]
        scores = [r.score for r in self.ranking if math.isfinite(r.score)]
        margin = scores[0] - scores[1] if len(scores) >= 2 else None
        augmented = None
        if self.augmented is not None and self.after is not None:
            augmented = {
                "effect": self.named_effect,
                "accepted": bool(self.accepted),
                "reasons": [dict(r) for r in self.accept_reasons],
                "log_predictive_density_before": self.before.log_predictive_density,
                "log_predictive_density_after": self.after.log_predictive_density,
                "flagged_fraction_before": self.before.flagged_fraction,
                "flagged_fraction_after": self.after.flagged_fraction,
                "bounds": self.augmented.bounds.tolist(),
                "names": list(self.augmented.names),
            }
        return {
            "verdict": self.verdict,
            "sentence": self.sentence(),
            "flagged": [band.to_dict() for band in self.before.bands],
            "channel_offsets": [o.to_dict() for o in self.before.offsets],
            "flagged_descriptions": [describe_band(b) for b in self.before.bands],
            "ranking": ranking,
            "named_effect": self.named_effect,
            "margin": margin,
            "naming_check": None if self.naming_check is None else self.naming_check.to_dict(),
            "answer_model": self.answer_model,
            "augmented": augmented,
            "gap_before": self.gap_before,
            "gap_after": self.gap_after,
            "gap_ratio": self.gap_ratio,
            "gap_ratio_all_bins": self.gap_ratio_all_bins,
            "flagged_after": [] if self.after is None else [b.to_dict() for b in self.after.bands],
            "channel_offsets_after": []
            if self.after is None
            else [o.to_dict() for o in self.after.offsets],
            "parameters": self.parameter_table(),
            "detection": {
                "q": self.before.q,
                "n_bins": int(self.before.z.size),
                "flagged_fraction": self.before.flagged_fraction,
                "channels": list(self.before.channels),
                "frequencies_hz": self.before.frequencies_hz.tolist(),
            },
            "base_log_likelihood": self.base.log_likelihood,
            "augmented_log_likelihood": None
            if self.augmented is None
            else self.augmented.log_likelihood,
            "simulator": self.simulator,
            **{k: v for k, v in self.extra.items() if k != "sentence"},
        }


def offsets_sentence(offsets: tuple[ChannelOffset, ...]) -> str:
    """What the whole-channel level errors mean, in one sentence (none: "")."""
    if not offsets:
        return ""
    listed = "; ".join(
        f"{o.label()} throughout (median over its bands; channel Z {o.z:+.1f})" for o in offsets
    )
    return (
        f"the whole level of {len(offsets)} channel(s) differs from the model by "
        f"{MIN_CHANNEL_OFFSET_DB:g} dB or more: {listed}. No library effect shifts one "
        "channel's level across its band: check that sensor's gain, units, calibration "
        "sheet and mounting first (the parameters calibrated with it are biased as long as "
        "it is off); if they are right, the model misses something that scales this "
        "channel."
    )
