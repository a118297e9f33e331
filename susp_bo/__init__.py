"""susp_bo: Bayesian calibration of high-speed train suspensions.

The state of a train's suspensions is inferred from on-track accelerometer
measurements: a PyBullet vehicle rig is the simulator ``h_sim(x, w)``, a
GPyTorch kriging surrogate models the log-likelihood of the measured spectra
(eq. 4 of Lebel et al.), BoTorch expected improvement refines it (EGO) and a
Pyro Metropolis–Hastings kernel draws the posterior of the parameters ``w``.

The public API is re-exported here and imported lazily (``import susp_bo`` does
not start torch or PyBullet):

Rig and track
    :func:`load_rig_spec`, :class:`RigSpec`, :class:`Rig`, :class:`LinearisedRig`,
    :class:`SimulationFailed`, :class:`TrackGeometry`, :class:`TrackPSD`,
    :class:`SpeedProfile`, :class:`SpectrumSettings`, :class:`Spectra`,
    :func:`log_amplitude_spectra`, :func:`available_rigs`, :func:`rig_path`.
Measured data
    :class:`MeasuredRun`, :func:`load_run`, :func:`load_runs`, :func:`save_run`,
    :func:`synthesize_runs`.
Calibration
    :class:`OutputError`, :func:`log_likelihood`, :func:`estimate_output_error`,
    :class:`CalibrationSettings`, :func:`calibrate`, :class:`CalibrationResult`,
    :class:`PosteriorSummary`, :class:`Reliability` (the verdict on a result),
    :class:`StudyConfig`, :func:`load_study_config`, :func:`run_study`.
Monitoring
    :func:`monitor` (every campaign of a folder calibrated; trends, P(outside), alarms).
Infrastructure
    :class:`EvaluationStore`, :func:`make_executor`, :func:`run_tasks`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from susp_bo.numerics import pin_code_paths

# Before NumPy, SciPy or torch load: the same code paths, so the same bits, on every
# x86-64 CPU with AVX2 (susp_bo.numerics; SUSP_BO_NATIVE_NUMERICS=1 turns it off).
pin_code_paths()

__version__ = "0.1.0"

_EXPORTS: dict[str, str] = {
    "available_rigs": "susp_bo.rig.catalog",
    "rig_path": "susp_bo.rig.catalog",
    "load_rig_spec": "susp_bo.rig.spec",
    "RigSpec": "susp_bo.rig.spec",
    "CalibrationParameter": "susp_bo.rig.spec",
    "Rig": "susp_bo.rig.simulator",
    "RigResponse": "susp_bo.rig.response",
    "SimulationFailed": "susp_bo.rig.response",
    "LinearisedRig": "susp_bo.rig.linear",
    "TrackGeometry": "susp_bo.rig.track",
    "TrackPSD": "susp_bo.rig.track",
    "SpeedProfile": "susp_bo.rig.track",
    "SpectrumSettings": "susp_bo.rig.spectra",
    "Spectra": "susp_bo.rig.spectra",
    "log_amplitude_spectra": "susp_bo.rig.spectra",
    "MeasuredRun": "susp_bo.data.measured",
    "MeasuredDataError": "susp_bo.data.measured",
    "load_run": "susp_bo.data.run_files",
    "load_runs": "susp_bo.data.run_files",
    "save_run": "susp_bo.data.run_files",
    "synthesize_runs": "susp_bo.data.synthetic",
    "OutputError": "susp_bo.calibration.likelihood",
    "log_likelihood": "susp_bo.calibration.likelihood",
    "estimate_output_error": "susp_bo.calibration.likelihood",
    "CalibrationSettings": "susp_bo.calibration.settings",
    "CalibrationResult": "susp_bo.calibration.loop",
    "calibrate": "susp_bo.calibration.loop",
    "PosteriorSummary": "susp_bo.calibration.posterior",
    "Reliability": "susp_bo.calibration.reliability",
    "StudyConfig": "susp_bo.study_config",
    "load_study_config": "susp_bo.study_config",
    "run_study": "susp_bo.calibration.study",
    "monitor": "susp_bo.monitoring.runner",
    "EvaluationStore": "susp_bo.store",
    "make_executor": "susp_bo.execution",
    "run_tasks": "susp_bo.execution",
}

__all__ = [
    "CalibrationParameter",
    "CalibrationResult",
    "CalibrationSettings",
    "EvaluationStore",
    "LinearisedRig",
    "MeasuredDataError",
    "MeasuredRun",
    "OutputError",
    "PosteriorSummary",
    "Reliability",
    "Rig",
    "RigResponse",
    "RigSpec",
    "SimulationFailed",
    "Spectra",
    "SpectrumSettings",
    "SpeedProfile",
    "StudyConfig",
    "TrackGeometry",
    "TrackPSD",
    "__version__",
    "available_rigs",
    "calibrate",
    "estimate_output_error",
    "load_rig_spec",
    "load_run",
    "load_runs",
    "load_study_config",
    "log_amplitude_spectra",
    "log_likelihood",
    "make_executor",
    "monitor",
    "rig_path",
    "run_study",
    "run_tasks",
    "save_run",
    "synthesize_runs",
]

if TYPE_CHECKING:  # pragma: no cover - static names for type checkers and IDEs
    from susp_bo.calibration.likelihood import OutputError, estimate_output_error, log_likelihood
    from susp_bo.calibration.loop import CalibrationResult, calibrate
    from susp_bo.calibration.posterior import PosteriorSummary
    from susp_bo.calibration.reliability import Reliability
    from susp_bo.calibration.settings import CalibrationSettings
    from susp_bo.calibration.study import run_study
    from susp_bo.data.measured import MeasuredDataError, MeasuredRun
    from susp_bo.data.run_files import load_run, load_runs, save_run
    from susp_bo.data.synthetic import synthesize_runs
    from susp_bo.execution import make_executor, run_tasks
    from susp_bo.monitoring.runner import monitor
    from susp_bo.rig.catalog import available_rigs, rig_path
    from susp_bo.rig.linear import LinearisedRig
    from susp_bo.rig.response import RigResponse, SimulationFailed
    from susp_bo.rig.simulator import Rig
    from susp_bo.rig.spec import CalibrationParameter, RigSpec, load_rig_spec
    from susp_bo.rig.spectra import Spectra, SpectrumSettings, log_amplitude_spectra
    from susp_bo.rig.track import SpeedProfile, TrackGeometry, TrackPSD
    from susp_bo.store import EvaluationStore
    from susp_bo.study_config import StudyConfig, load_study_config


def __getattr__(name: str) -> Any:
    """Import a public name on first use (PEP 562)."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'susp_bo' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
