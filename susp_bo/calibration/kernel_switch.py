"""Taking the kernel advice during the search: switch to ``kernel="auto"`` when the
pairwise additive kernel predicts log L better than the default Matérn.

Session 30's advice (:mod:`.kernel_advice`) told a user, after a finished run, to rerun
a curved posterior with ``kernel="auto"`` and ``refine_optimism=2``: on the curved chain
of ``benchmarks/posterior_accuracy.py`` the default ended with MMTV .11–.16 (worse than
PyVBMC) where those settings reach .02–.03 at the same budget. The same leave-one-out
comparison made *during* the search lets the run take that advice itself, with the
budget still left.

:class:`KernelSwitcher` compares the two kernels (:func:`.kernel_advice.additive_kernel_gain`:
the additive kernel fitted once on the Matérn fit's own points, seed and settings; the
difference of their leave-one-out scores over the best third of the evaluations, nats a
point) when the global search turns to refinement (EGO has ended: the search has found
the optimum's region, and the score is about the posterior's shape, not a surrogate wrong
everywhere) and again after every further :data:`CHECK_EVERY` of the budget, until the
held-out check. It switches the rest of the run to ``kernel="auto"`` (both kernels
fitted at every refit, the better leave-one-out score kept: a wrong switch costs fitting
time, not the Matérn) and ``refine_optimism`` of at least 2 when the gain reaches
:data:`.reliability_sentence.ADDITIVE_GAIN_NATS` (0.1, the advice's threshold) at the
first comparison, or :data:`LATER_GAIN_NATS` at a later one: refinement packs points
where the posterior has mass, and on that cluster the additive kernel's many scales
gain a little on a log L with no pairwise structure (a Student-t 6-D target, seed 0:
−0.57 when EGO ended, then −0.27, −0.28, −0.12, +0.16 at 294 of 400 evaluations — a
switch there left 106 evaluations to refine the new surrogate and gave MMTV .060,
``not_trusted``, where the Matérn gives .036–.040, ``trusted``).

It is not made:

- with a kernel other than the default ``"matern"`` (the user chose), or when
  ``CalibrationSettings.kernel_switch`` is False;
- with a learned observation noise (``SurrogateSettings(noise="learned")``, for a noisy
  log L): leave-one-out scores of noisy values do not choose reliably
  (:func:`.surrogate_fit.auto_means`); on the noisy 7-D target (1 nat per evaluation,
  seed 1) the gains jumped between −0.20 and +0.28 from one comparison to the next;
- for q < 3 (a pairwise additive kernel of two parameters has no additive structure to
  exploit);
- in a search box (``trust_region``, or the local phase's box with its Laplace bowl as the
  GP's mean), nor in a run whose local phase is still to come: there the GP models what is
  left of log L around a quadratic bowl, on the few points in the box. Measured on the
  demo's problem (``benchmarks/coverage.py --error paired --local-search``, linearised, two
  experiments): gains of −0.04 and +0.14 when EGO ended, then +0.01 to +1.18 in the box
  with 20–60 points, where the demo is ``trusted`` and right with the Matérn — no evidence
  that the additive kernel's structure is what is missing there.

Measured on the curved chain (seeds 0 / 1 / 2, 350 evaluations): +0.12 / +0.21 / +0.09
when EGO ended at 153, seed 2 +0.94 at 228; switched at 153 / 153 / 228, MMTV .024 / .019
/ .018, all ``trusted`` (``benchmarks/posterior_accuracy_results.md``, session 37). Each
comparison costs one fit with the additive kernel: 2.5–13 s on 150–330 points of the
5-D chain, two runs at a time on 2 cores.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from susp_bo.calibration.kernel_advice import additive_kernel_gain
from susp_bo.calibration.reliability_sentence import ADDITIVE_GAIN_NATS
from susp_bo.calibration.result import KernelSwitch
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate import Surrogate

logger = logging.getLogger(__name__)

CHECK_EVERY = 0.1
"""Share of the budget between two comparisons after the first (at 350 evaluations: every
35)."""

LATER_GAIN_NATS = 0.3
"""Gain a comparison after the first needs to switch (nats a point; the first needs
:data:`.reliability_sentence.ADDITIVE_GAIN_NATS`)."""

SWITCH_OPTIMISM = 2.0
"""``refine_optimism`` after a switch (at least): the curved chain's measured setting."""


class KernelSwitcher:
    """Decides, step by step, whether the run switches to ``kernel="auto"``.

    Args:
        settings: the run's settings at the start.
        q: parameters.
        budget: the run's ``max_evaluations``.
        local_phase: True when the run will (or did) go into the local phase's box.
    """

    def __init__(
        self, settings: CalibrationSettings, q: int, budget: int, local_phase: bool
    ) -> None:
        self.enabled = (
            settings.kernel_switch
            and settings.surrogate.kernel == "matern"
            and q >= 3
            and settings.global_fixed_noise_search(local_phase)
        )
        self.every = max(1, math.ceil(CHECK_EVERY * budget))
        self.checks: list[tuple[int, float]] = []
        self.switched_at: int | None = None

    def due(self, n: int, phase: str, boxed: bool) -> bool:
        """Whether a step with ``phase`` (the step's, after its refit) at ``n`` evaluations
        compares the kernels: a global refinement, first or ``every`` after the last."""
        if not self.enabled or self.switched_at is not None or boxed or phase != "refine":
            return False
        return not self.checks or n >= self.checks[-1][0] + self.every

    def consider(
        self,
        x: np.ndarray,
        y: np.ndarray,
        box: np.ndarray,
        settings: CalibrationSettings,
        iteration: int,
        matern: Surrogate,
    ) -> CalibrationSettings:
        """Compares the kernels on the step's data and returns the settings for the rest of
        the run (``settings`` itself unless it switches; a fit that fails switches nothing).

        Args:
            x: (n x q) every evaluated point (physical units); y: (n,) their log L.
            box: (2 x q) the step's box (C_w: the comparison is made only unboxed).
            settings: the current settings (kernel "matern").
            iteration: the step's iteration (its fits' seed).
            matern: the step's fitted surrogate.
        """
        try:
            gain = additive_kernel_gain(x, y, box, settings, iteration, matern)
        except Exception as error:  # BoTorch's ModelFittingError: the run goes on as it was
            logger.warning("the additive kernel could not be fitted: %s", error)
            gain = math.nan
        n = int(x.shape[0])
        needed = LATER_GAIN_NATS if self.checks else ADDITIVE_GAIN_NATS
        self.checks.append((n, gain))
        if not gain >= needed:  # also for NaN
            logger.info("additive kernel's leave-one-out gain at %d evaluations: %.3f", n, gain)
            return settings
        self.switched_at = n
        logger.info(
            "additive kernel's leave-one-out gain at %d evaluations: %.3f nats a point (>= %g):"
            ' switching to kernel="auto" and refine_optimism >= %g',
            n,
            gain,
            needed,
            SWITCH_OPTIMISM,
        )
        return dataclasses.replace(
            settings,
            surrogate=dataclasses.replace(settings.surrogate, kernel="auto"),
            refine_optimism=max(settings.refine_optimism, SWITCH_OPTIMISM),
        )

    def record(self) -> KernelSwitch | None:
        """What happened, or None when no comparison was made."""
        if not self.checks:
            return None
        return KernelSwitch(tuple(self.checks), self.switched_at)
