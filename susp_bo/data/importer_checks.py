"""The checks both importers share: a run's parts built from imported values.

The CSV (:mod:`susp_bo.data.importers`) and MATLAB (:mod:`susp_bo.data.mat_files`)
importers build the geometry (irregularities in metres, :func:`irregularity_problems`),
the speed record, the design and the run through these helpers, so that any refusal is
a :class:`~susp_bo.data.measured.MeasuredDataError` naming the file; NaN runs in the
accelerations are refused unless ``allow_nan``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.data.measured import MeasuredDataError, MeasuredRun, nan_runs
from susp_bo.data.run_validation import irregularity_problems
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.track import SpeedProfile, TrackGeometry

PathLike = str | os.PathLike[str]


def _design(path: Path, **fields: Any) -> TrackDesign:
    try:
        return TrackDesign(**fields, source=str(path))
    except ValueError as error:
        raise MeasuredDataError(str(error)) from None


def _check_nan(path: Path, run: MeasuredRun, allow_nan: bool) -> MeasuredRun:
    if not allow_nan:
        for name in run.channels:
            runs = nan_runs(run.channel(name))
            if runs:
                raise MeasuredDataError(
                    f"{path}: channel {name!r} has NaN runs ({len(runs)} run(s), "
                    f"{sum(r[1] for r in runs)} samples); a study cannot use them: cut the run "
                    "at the gaps or fill them (from Python, allow_nan=True keeps them)"
                )
    return run


def _build(path: Path, **fields: Any) -> MeasuredRun:
    try:
        return MeasuredRun(**fields)
    except ValueError as error:
        raise MeasuredDataError(f"{path}: {error}") from None


def _geometry(path: Path, **fields: Any) -> TrackGeometry:
    try:
        geometry = TrackGeometry(**fields)
    except ValueError as error:
        raise MeasuredDataError(f"{path}: {error}") from None
    problems = irregularity_problems(geometry)
    if problems:
        raise MeasuredDataError(f"{path}: {problems[0]}")
    return geometry


def _speed(path: Path, time: np.ndarray, speed: np.ndarray) -> SpeedProfile:
    try:
        return SpeedProfile(time_s=time, speed_m_s=speed)
    except ValueError as error:
        raise MeasuredDataError(f"{path}: {error}") from None
