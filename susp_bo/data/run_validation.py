"""Can a measured run feed a rig? :func:`validate_run` lists every problem at once.

Checks (each problem named, with the numbers): the rig's channels are present, in
m/s², without NaN runs; the sampling rate and the record length suit the rig's band
and Welch segment; the speed record covers the accelerations; the track geometry (and
the design, when the run has one) covers the distance travelled plus the axle span; the
irregularities are in metres (:func:`irregularity_problems`). A run without geometry
(its track not measured) skips the two geometry checks; the rest stay. Run before any
simulation by the study (:mod:`susp_bo.calibration.study_preparation`) and by
``susp-bo import``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from susp_bo.data.measured import (
    MeasuredDataError,
    MeasuredRun,
    nan_problems,
    real_number,
    unit_problems,
)
from susp_bo.rig.spectra import SpectrumSettings
from susp_bo.rig.track import TrackGeometry

IRREGULARITY_LIMIT = {"vertical_m": 0.1, "alignment_m": 0.1, "gauge_m": 0.1,
                      "cross_level_rad": 0.2}  # fmt: skip
"""Largest deviation from the median a track irregularity may have (m, rad): ten times
the worst track still run on, so that a column written in millimetres (or a cross
level in mrad) is refused, not read as metres of irregularity."""


def irregularity_problems(geometry: TrackGeometry) -> list[str]:
    """Irregularities beyond :data:`IRREGULARITY_LIMIT`: a column in mm (or mrad), not m.

    Checked on import (``susp-bo import``) and on every run a study loads (outside probe,
    session 29: an HDF5 run rewritten in mm passed, every design simulation ran, and then
    "every log L evaluation failed" named neither the file nor the cause).
    """
    problems = []
    for name, limit in IRREGULARITY_LIMIT.items():
        values = np.asarray(getattr(geometry, name), dtype=np.float64)
        deviation = float(np.max(np.abs(values - np.median(values))))
        if not deviation <= limit:  # NaN too
            unit = "rad" if name.endswith("_rad") else "m"
            problems.append(
                f"{name} deviates up to {deviation:.4g} {unit} from its median; track "
                f"irregularities lie within ±{limit:g} {unit} and the unit is {unit}: was it "
                f"written in {'mrad' if unit == 'rad' else 'mm'}? (the line's curves and cant "
                "go in the design columns, not in the irregularities)"
            )
    return problems


def record_end_s(run: MeasuredRun) -> float:
    """Time of the last acceleration sample on the speed record's clock (s)."""
    return run.time_offset_s + (run.n_samples - 1) / run.sample_rate_hz


def track_needed_m(run: MeasuredRun, axle_span_m: float) -> float:
    """Track length (m) the run needs: the distance travelled up to its last acceleration
    sample plus the axle span (the leading axle is ``axle_span_m`` ahead of ``s = 0`` at
    ``t = 0``). The speed record must cover that sample (:func:`validate_run` says so)."""
    return float(run.speed.distance_m(record_end_s(run))) + float(axle_span_m)


def validate_run(
    run: MeasuredRun,
    channels: Sequence[str] | None = None,
    settings: SpectrumSettings | None = None,
    *,
    axle_span_m: float = 0.0,
    source: str = "run",
) -> None:
    """Check that a run can feed a rig; raise one error listing every problem found.

    Checks: the required channels are present; their units are m/s²; they hold
    no NaN runs; the sampling rate exceeds twice ``settings.f_max_hz`` and the
    record holds one Welch segment; the speed record covers the acceleration
    record; the track (and the design, when the run has one) covers the distance
    travelled plus the axle span (:func:`track_needed_m`); the irregularities are in
    metres. A run without geometry (``run.geometry`` None: its track not measured) skips
    the irregularity and track-length checks; the design, when given, must still cover
    ``0 … track_needed_m``.

    Args:
        run: the run.
        channels: channels the rig expects; None checks all of the run's.
        settings: spectra settings of the rig; None skips the band checks.
        axle_span_m: distance from the rearmost to the leading axle (m), >= 0;
            the track must be at least distance travelled + this long.
        source: name used in the message (e.g. the file).

    Raises:
        MeasuredDataError: naming every problem.
    """
    wanted = tuple(run.channels if channels is None else channels)
    problems: list[str] = []
    missing = [c for c in wanted if c not in run.channels]
    if missing:
        problems.append(f"missing channel(s) {missing}; the run has {list(run.channels)}")
    problems += unit_problems(run, wanted) + nan_problems(run, wanted)
    if run.geometry is not None:
        problems += irregularity_problems(run.geometry)
    if settings is not None:
        try:
            settings.check_sample_rate(run.sample_rate_hz, run.duration_s)
        except ValueError as error:
            problems.append(f"sampling rate or record too short for the band: {error}")
    span = real_number("axle_span_m", axle_span_m, "m")
    end_s = record_end_s(run)
    if end_s > run.speed.duration_s * (1 + 1e-9):
        problems.append(
            f"speed record too short: it covers 0 … {run.speed.duration_s:g} s but the "
            f"accelerations run to t = {end_s:g} s"
        )
    else:
        needed = track_needed_m(run, span)
        if run.geometry is not None and needed > run.geometry.length_m * (1 + 1e-9):
            problems.append(
                f"track shorter than the run: the geometry covers {run.geometry.length_m:g} m "
                f"but the run travels {needed - span:g} m (+ axle span {span:g} m) = {needed:g} m"
            )
        if run.design is not None and (
            run.design.start_m > 1e-9 or run.design.end_m < needed * (1 - 1e-9)
        ):
            problems.append(
                f"design record does not cover the run: it covers {run.design.start_m:g} … "
                f"{run.design.end_m:g} m but the run needs 0 … {needed:g} m"
            )
    if problems:
        raise MeasuredDataError(f"{source}: " + "; ".join(problems))
