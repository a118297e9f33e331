"""Iteration reports of the calibration loop: one per evaluated batch, logged and called back.

:func:`record_iteration` appends the report of a batch to the history; a phase that runs
its own evaluations (the basin and local phases of :mod:`.loop`) keeps its growing data
in a :class:`PhaseRecorder`, which records each of its batches the same way.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from susp_bo.calibration.result import IterationReport, Phase

logger = logging.getLogger(__name__)


def record_iteration(
    phase: Phase,
    x: np.ndarray,
    y: np.ndarray,
    criterion: float,
    history: list[IterationReport],
    on_iteration: Callable[[IterationReport], None] | None,
) -> None:
    """Appends the report of the batch just evaluated to ``history``, logs it, calls back.

    Reports are numbered 1, 2, … in the order their batches were evaluated: the loop's
    own iteration counter (which seeds each step, and also advances on steps that hand
    over to a phase instead of evaluating) is not the number a reader sees.
    """
    best = int(np.nanargmax(y)) if np.isfinite(y).any() else 0
    report = IterationReport(
        len(history) + 1,
        phase,
        x.shape[0],
        float(y[best]),
        x[best].copy(),
        criterion,
        int(np.sum(~np.isfinite(y))),
    )
    history.append(report)
    logger.info(report.line())
    if on_iteration is not None:
        on_iteration(report)


@dataclass
class PhaseRecorder:
    """The data of a phase that evaluates on its own (basin, local): each batch joins it."""

    x: np.ndarray
    y: np.ndarray
    iteration: int
    history: list[IterationReport]
    on_iteration: Callable[[IterationReport], None] | None
    bar: Any

    def add(self, phase: Phase, w: np.ndarray, values: np.ndarray, criterion: float) -> None:
        """Appends a batch (physical units), advances the bar and records the iteration."""
        self.x = np.vstack([self.x, w])
        self.y = np.concatenate([self.y, values])
        self.bar.update(len(w))
        self.iteration += 1
        record_iteration(phase, self.x, self.y, criterion, self.history, self.on_iteration)
