"""Which candidate effect explains the flagged pattern? Rank by refit evidence.

Two numbers per candidate:

* ``signature`` — cosine similarity between the flagged residual pattern
  (Z on the flagged bins) and the effect's predicted change of the spectra
  (linearised rig, effect at its default values vs off, scaled by σ_B). Cheap,
  reported for orientation and used only to order the refits; a coincidental
  resemblance cannot decide.
* ``score`` — the evidence from refitting: the augmented rig (effect on, its
  calibrated parameters appended) and the base rig are both fitted to maximum
  likelihood with the same optimiser (:mod:`.fitting`), and

      score = max log L(base + effect) − max log L(base) − ½ k ln N − ln m

  with k the added parameters, N = ν C F the data count (the BIC penalty,
  ½ ln N ≈ 4 nats per parameter here) and m the number of discrete
  configurations tried (polygon order × wheelset for out-of-roundness). A
  positive score means the data support the effect after paying for it.

Out-of-roundness is tried only at polygon orders whose frequency n·V/(πD)
falls in a flagged band; without such a band it cannot explain the pattern.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from susp_bo.discrepancy.detection import Detection
from susp_bo.discrepancy.effects import EFFECTS, get_effect, with_effect
from susp_bo.discrepancy.fitting import Fit, fit_model
from susp_bo.discrepancy.problem import DiagnosisProblem, Simulator
from susp_bo.rig.linear import LinearisedRig

FloatArray = np.ndarray


@dataclass(frozen=True)
class RankedEffect:
    """One candidate's result.

    Attributes:
        effect: library name.
        score: penalised log-likelihood improvement (nats); -inf when not applicable.
        signature: cosine similarity of the predicted and flagged patterns, in [-1, 1].
        log_likelihood_gain: max log L(base + effect) − max log L(base) (nats).
        penalty: ½ k ln N + ln m (nats).
        options: fixed options of the best configuration (e.g. polygon order).
        fit: the augmented fit (None when not applicable).
        note: why a candidate was not applicable.
    """

    effect: str
    score: float
    signature: float
    log_likelihood_gain: float
    penalty: float
    options: dict[str, float]
    fit: Fit | None
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (no fit object; effect parameters at the maximum)."""
        fitted = {}
        if self.fit is not None:
            prefix = f"{self.effect}_"
            fitted = {n: v for n, v in self.fit.parameters().items() if n.startswith(prefix)}
        return {
            "effect": self.effect,
            "score": self.score if math.isfinite(self.score) else None,
            "signature": self.signature,
            "log_likelihood_gain": self.log_likelihood_gain
            if math.isfinite(self.log_likelihood_gain)
            else None,
            "penalty": self.penalty,
            "options": self.options,
            "fitted_effect_parameters": fitted,
            "note": self.note,
        }


def _speed(problem: DiagnosisProblem) -> float:
    track = problem.tracks[0]
    return float(np.mean(track.speed.speed_at(np.linspace(0, track.speed.duration_s, 64))))


def signature_similarity(
    problem: DiagnosisProblem, detection: Detection, base: Fit, name: str, options: dict
) -> float:
    """Cosine similarity of the effect's predicted change and the flagged residuals."""
    spec = base.spec.with_parameters(base.parameters())
    speed = _speed(problem)
    before = LinearisedRig(spec).spectra(speed_m_s=speed).log_amplitude
    after = LinearisedRig(with_effect(spec, name, options)).spectra(speed_m_s=speed).log_amplitude
    change = (after - before) / problem.sigma[:, None]
    pattern = np.where(detection.flagged, detection.z, 0.0)
    norm = float(np.linalg.norm(change) * np.linalg.norm(pattern))
    return float(np.sum(change * pattern) / norm) if norm > 0 else 0.0


def configurations(problem: DiagnosisProblem, detection: Detection, name: str) -> list[dict]:
    """Discrete options to try for an effect (polygon order × wheelset for out-of-roundness)."""
    if name != "wheel_out_of_roundness":
        return [{}]
    radius = problem.spec.parameters["wheelset_rolling_radius"]
    speed = _speed(problem)
    orders = set()
    for band in detection.bands:
        if band.sign != "model_too_little":
            continue
        for n in range(1, 21):
            if band.f_low_hz <= n * speed / (2 * math.pi * radius) <= band.f_high_hz:
                orders.add(n)
    return [
        {"order": float(n), "wheelset": float(w)}
        for n, w in itertools.product(sorted(orders), (1, 2, 3, 4))
    ]


def _starts(base: Fit, ranges: list[tuple[float, float]]) -> list[FloatArray]:
    levels = [np.linspace(lo + 0.15 * (hi - lo), hi - 0.15 * (hi - lo), 3) for lo, hi in ranges]
    return [np.concatenate([base.w, np.array(c)]) for c in itertools.product(*levels)]


def refit_with_effect(
    problem: DiagnosisProblem,
    simulator: Simulator,
    base: Fit,
    name: str,
    options: dict,
    max_iterations: int = 12,
) -> Fit:
    """Maximum-likelihood fit of the base rig plus effect ``name`` (base parameters free)."""
    effect = get_effect(name)
    spec = with_effect(base.spec, name, options)
    extra = [p for p in effect.parameters if p.calibrated]
    names = base.names + tuple(effect.parameter_name(p.key) for p in extra)
    bounds = np.hstack(
        [base.bounds, np.array([[p.lower for p in extra], [p.upper for p in extra]])]
    )
    starts = _starts(base, [(p.lower, p.upper) for p in extra])
    return fit_model(problem, simulator, spec, names, bounds, starts, max_iterations)


def rank_effects(
    problem: DiagnosisProblem,
    simulator: Simulator,
    base: Fit,
    detection: Detection,
    candidates: tuple[str, ...] | None = None,
    max_iterations: int = 12,
) -> list[RankedEffect]:
    """Rank the candidate effects by their refit score (best first)."""
    names = tuple(EFFECTS) if candidates is None else candidates
    n_data = problem.measured.size
    ranked: list[RankedEffect] = []
    for name in names:
        effect = get_effect(name)
        k = sum(p.calibrated for p in effect.parameters)
        configs = configurations(problem, detection, name)
        if not configs:
            ranked.append(
                RankedEffect(
                    name,
                    -math.inf,
                    0.0,
                    -math.inf,
                    0.0,
                    {},
                    None,
                    "no flagged band at any polygon order n·V/(πD)",
                )
            )
            continue
        penalty = 0.5 * k * math.log(n_data) + math.log(len(configs))
        best: tuple[Fit, dict] | None = None
        for options in configs:
            fit = refit_with_effect(problem, simulator, base, name, options, max_iterations)
            if best is None or fit.log_likelihood > best[0].log_likelihood:
                best = (fit, options)
        assert best is not None
        gain = best[0].log_likelihood - base.log_likelihood
        similarity = signature_similarity(problem, detection, base, name, best[1])
        ranked.append(
            RankedEffect(name, gain - penalty, similarity, gain, penalty, best[1], best[0])
        )
    ranked.sort(key=lambda r: -r.score if math.isfinite(r.score) else math.inf)
    return ranked
