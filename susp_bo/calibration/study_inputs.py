"""Checks of a study's inputs before any simulation, and the error that reports them.

Each function refuses one kind of bad input with a :class:`StudyError` that names the
file or flag, the value and what is allowed (the command line turns it into exit code 2):
runs of another rig, CSV/.mat files where HDF5 runs are expected, a store of another
study, a budget below what q parameters need; plus the design's quasi-static part that
is taken off the measured accelerations before their spectra.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from susp_bo.calibration.budget import budget_message, budget_requirement
from susp_bo.data.measured import MeasuredRun
from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.curving import reference_specific_force
from susp_bo.rig.spec import RigSpec
from susp_bo.store import StoreMismatchError
from susp_bo.study_config import StudyConfig


class StudyError(ValueError):
    """A study that cannot start: bad inputs or an output folder that is in the way."""


def reference_parameters(
    runs: tuple[MeasuredRun, ...], names: tuple[str, ...]
) -> np.ndarray | None:
    """(q,) the true parameters of synthetic runs (metadata ``truth``), else None."""
    truth = runs[0].metadata.get("truth") if runs[0].metadata else None
    if not isinstance(truth, dict) or not all(n in truth for n in names):
        return None
    return np.array([float(truth[n]) for n in names])


def sensor_noise(config: StudyConfig, runs: tuple[MeasuredRun, ...]) -> float:
    """The configured sensor noise, else the one the runs' metadata record, else 0."""
    if config.output_error.sensor_noise_m_s2 is not None:
        return config.output_error.sensor_noise_m_s2
    rates = {run.sample_rate_hz for run in runs}
    if len(rates) > 1:
        raise StudyError(
            f"data: the runs are sampled at different rates {sorted(rates)} Hz; resample them "
            "to one rate (the sensor-noise floor and the spectra assume one)"
        )
    recorded = {float((run.metadata or {}).get("noise_m_s2", 0.0)) for run in runs}
    if len(recorded) > 1:
        raise StudyError(
            f"data: the runs record different sensor noise levels {sorted(recorded)} m/s^2; "
            "set output_error.sensor_noise_m_s2"
        )
    return recorded.pop()


def import_hint(folder: Path) -> str:
    """A hint when ``folder`` holds CSV or MATLAB files instead of HDF5 runs, else ``""``."""
    if not folder.is_dir():
        return ""
    found = {
        kind: sum(1 for p in folder.iterdir() if p.suffix.lower() == f".{kind}")
        for kind in ("csv", "mat")
    }
    kinds = [kind for kind, count in found.items() if count]
    if not kinds:
        return ""
    listed = " and ".join(f"{found[kind]} .{kind} files" for kind in kinds)
    return (
        f"; it holds {listed}: convert them to the HDF5 measured-run format first, e.g. "
        f"susp-bo import {kinds[0]} {folder} --out {folder}_h5 --rig RIG"
    )


def check_runs_rig(runs: tuple[MeasuredRun, ...], rig: str, folder: Path) -> None:
    """Refuse runs whose metadata names another rig than ``rig``, or several rigs.

    Runs without a ``rig`` entry in their metadata (real measurements) pass.

    Raises:
        StudyError: naming the folder, the rigs found and the rig calibrated.
    """
    by_rig: dict[str, list[int]] = {}
    for index, run in enumerate(runs):
        name = (run.metadata or {}).get("rig")
        if name is not None:
            by_rig.setdefault(str(name), []).append(index)
    if len(by_rig) > 1:
        files = sorted(p.name for p in folder.iterdir() if p.suffix in {".h5", ".hdf5"})
        if len(files) != len(runs):  # not the folder load_runs read: number the runs
            files = [f"run {index}" for index in range(len(runs))]
        listed = "; ".join(
            f"{name!r}: {', '.join(files[i] for i in indices)}"
            for name, indices in sorted(by_rig.items())
        )
        raise StudyError(
            f"data: {folder} mixes runs of {len(by_rig)} rigs (run metadata 'rig': {listed}); "
            "keep one rig's runs per folder"
        )
    if by_rig and rig not in by_rig:
        other = next(iter(by_rig))
        raise StudyError(
            f"data: the runs in {folder} were recorded on rig {other!r} (run metadata 'rig') "
            f"but the study calibrates rig {rig!r}; calibrate rig {other!r}, or use runs of "
            f"{rig!r}"
        )


def store_mismatch(out: Path, error: StoreMismatchError) -> StudyError:
    def short(text: str) -> str:
        return text if len(text) <= 40 else text[:37] + "..."

    what = {
        "rig": "the rig (or its parameter values)",
        "data": "the measured data",
        "tracks": "the measured runs",
        "parameter_names": "the calibrated parameters",
        "output_error": "the output error",
        "sensor_noise_m_s2": "the sensor noise",
    }.get(error.key, repr(error.key))
    return StudyError(
        f"--resume: {out} holds the evaluations of another study: {what} differs "
        f"(stored {short(error.stored)!r}, now {short(error.current)!r}); resume with the "
        "same rig, data and parameters, or give a new output folder"
    )


def design_removal(spec: RigSpec, run: MeasuredRun) -> np.ndarray | None:
    """The design's quasi-static specific force at the rig's sensors over ``run`` (C x n_t).

    None for a run without a design. Removed from the measured accelerations
    before their spectra, exactly as the rig removes it from simulated ones
    (:func:`susp_bo.rig.curving.reference_specific_force`); depends on the design,
    the speed and the rig's geometry only.
    """
    if run.design is None:
        return None
    sensors = {sensor.name: sensor for sensor in spec.sensors}
    return reference_specific_force(
        build_assembly(spec),
        tuple(sensors[channel] for channel in run.channels),
        run.design,
        run.speed,
        run.time_s,
    )


def check_budget(config: StudyConfig, q: int) -> None:
    """Refuses a budget below the minimum for q parameters, unless ``budget.allow_small``.

    Raises:
        StudyError: naming ``--budget`` (``budget.max_evaluations``), the value and the
            minimum (:func:`susp_bo.calibration.budget.budget_requirement`).
    """
    budget = config.budget
    requirement = budget_requirement(
        q, budget.initial_design, budget.batch_size, budget.check_points
    )
    if budget.max_evaluations < requirement.minimum and not budget.allow_small:
        raise StudyError(
            budget_message(
                budget.max_evaluations,
                requirement,
                "budget.max_evaluations (--budget)",
                "set [budget] allow_small = true (--allow-small-budget)",
            )
        )
