"""Checks of a study's inputs before any simulation, and the error that reports them.

Each function refuses one kind of bad input with a :class:`StudyError` that names the
file or flag, the value and what is allowed (the command line turns it into exit code 2):
runs of another rig, CSV/.mat files where HDF5 runs are expected, a store of another
study, a budget below what q parameters need, a σ table that does not name the rig's
channels, runs sampled at different rates (named by file); plus the design's quasi-static
part that is taken off the measured accelerations before their spectra.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from susp_bo.calibration.budget import budget_message, budget_requirement
from susp_bo.data.measured import MeasuredRun
from susp_bo.data.run_files import run_paths
from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.curving import reference_specific_force
from susp_bo.rig.schema import did_you_mean
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


def run_names(runs: tuple[MeasuredRun, ...], folder: Path) -> list[str]:
    """What to call each of ``runs`` in a message: its file name when ``runs`` are the
    measured-run files of ``folder`` (as :func:`~susp_bo.data.run_files.load_runs` reads
    them, sorted by name), else ``run <index>``."""
    files = [path.name for path in run_paths(folder)]
    if len(files) != len(runs):  # not the folder load_runs read: number the runs
        return [f"run {index}" for index in range(len(runs))]
    return files


def check_sigma_table(config: StudyConfig, spec: RigSpec) -> None:
    """Refuse an ``[output_error] sigma`` table that does not give one σ per rig channel.

    A number or ``"estimate"`` passes. A table must name exactly the rig's channels: an
    unknown key (usually a typo, or a channel of another rig) is an error like a missing one.

    Raises:
        StudyError: naming the unknown keys (with a close channel name when there is one),
            the channels without a value, and the allowed channel names.
    """
    sigma = config.output_error.sigma
    if not isinstance(sigma, Mapping):
        return
    channels = spec.channels
    unknown = [f"{key!r}{did_you_mean(key, channels)}" for key in sigma if key not in channels]
    missing = [channel for channel in channels if channel not in sigma]
    problems = [f"unknown channel(s) {', '.join(unknown)}"] * bool(unknown)
    if missing:
        some = len(missing) < len(channels)
        problems.append(
            f"no value for channel(s) {missing}" if some else "it names no channel of the rig"
        )
    if problems:
        raise StudyError(
            f"output_error.sigma: {'; '.join(problems)}; allowed: {', '.join(channels)} (the "
            f"channels of rig {spec.name!r}: give each one σ, or one number for all)"
        )


def sensor_noise(config: StudyConfig, runs: tuple[MeasuredRun, ...]) -> float:
    """The configured sensor noise, else the one the runs' metadata record, else 0.

    Raises:
        StudyError: runs sampled at different rates (also with a configured noise: the
            noise floor and the spectra assume one rate), or, with no configured noise,
            runs recording different noise levels; each run named by its file
            (:func:`run_names`).
    """
    rates = {run.sample_rate_hz for run in runs}
    if len(rates) > 1:
        names = run_names(runs, config.data)
        by_rate = "; ".join(
            f"{rate:g} Hz: {', '.join(n for n, r in zip(names, runs) if r.sample_rate_hz == rate)}"
            for rate in sorted(rates)
        )
        raise StudyError(
            f"data: the runs in {config.data} are sampled at different rates ({by_rate}); "
            "resample them to one rate (the sensor-noise floor and the spectra assume one)"
        )
    if config.output_error.sensor_noise_m_s2 is not None:
        return config.output_error.sensor_noise_m_s2
    levels = [float((run.metadata or {}).get("noise_m_s2", 0.0)) for run in runs]
    recorded = set(levels)
    if len(recorded) > 1:
        names = run_names(runs, config.data)
        by_level = "; ".join(
            f"{level:g} m/s^2: {', '.join(n for n, x in zip(names, levels) if x == level)}"
            for level in sorted(recorded)
        )
        raise StudyError(
            f"data: the runs in {config.data} record different sensor noise levels "
            f"(metadata noise_m_s2: {by_level}); set output_error.sensor_noise_m_s2"
        )
    return recorded.pop()


def import_hint(folder: Path, name: str = "it", out: Path | None = None) -> str:
    """A hint when ``folder`` holds CSV or MATLAB files instead of HDF5 runs, else ``""``.

    Args:
        folder: the folder looked in.
        name: how the sentence names the folder (``"; it holds 2 .csv files: …"``).
        out: where the hint imports to (default ``<folder>_h5``; a monitoring campaign's
            runs go into its own folder, next to its ``campaign.toml``).
    """
    if not folder.is_dir():
        return ""
    found = {
        kind: sum(1 for p in folder.iterdir() if p.is_file() and p.suffix.lower() == f".{kind}")
        for kind in ("csv", "mat")
    }
    kinds = [kind for kind, count in found.items() if count]
    if not kinds:
        return ""
    listed = " and ".join(f"{found[kind]} .{kind} files" for kind in kinds)
    target = Path(f"{folder}_h5") if out is None else out
    return (
        f"; {name} holds {listed}: convert them to the HDF5 measured-run format first, e.g. "
        f"susp-bo import {kinds[0]} {folder} --out {target} --rig RIG"
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
        files = run_names(runs, folder)
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


def _from_difference(stored: str, current: str, limit: int) -> tuple[str, str]:
    """Both texts from just before their first differing character, at most ``limit`` long."""
    start = next(
        (i for i, (a, b) in enumerate(zip(stored, current)) if a != b),
        min(len(stored), len(current)),
    )
    start = max(0, start - 12)
    lead = "..." if start else ""

    def cut(text: str) -> str:
        text = text[start:]
        return lead + (text if len(text) <= limit else text[: limit - 3] + "...")

    return cut(stored), cut(current)


def fingerprint_change(stored: str, current: str, limit: int = 60) -> str:
    """Where two fingerprint values differ, readably: the first differing key of two JSON
    objects with its two values, "the same entries in another order" for two permutations,
    else both texts from just before their first differing character (so that two long
    values are never shown cut to the same text)."""
    try:
        old, new = json.loads(stored), json.loads(current)
    except (ValueError, TypeError):
        old = new = None
    if isinstance(old, dict) and isinstance(new, dict):
        for key in sorted(set(old) | set(new), key=str):
            if old.get(key, "(absent)") != new.get(key, "(absent)"):
                before = json.dumps(old[key]) if key in old else "(absent)"
                after = json.dumps(new[key]) if key in new else "(absent)"
                before, after = _from_difference(before, after, limit)
                return f"{key}: stored {before}, now {after}"
    if (
        isinstance(old, list)
        and isinstance(new, list)
        and old != new
        and sorted(map(str, old)) == sorted(map(str, new))
    ):
        before, after = _from_difference(json.dumps(old), json.dumps(new), limit)
        return (
            f"the same entries in another order (stored {before}, now {after}): the order "
            "must be the stored one"
        )
    before, after = _from_difference(stored, current, limit)
    return f"stored {before!r}, now {after!r}"


def store_mismatch(out: Path, error: StoreMismatchError) -> StudyError:
    what = {
        "rig": "the rig (its file's contents or its parameter values)",
        "data": "the measured data",
        "tracks": "the measured runs",
        "parameter_names": "the calibrated parameters",
        "output_error": "the output error ([output_error] model, sigma, correlation length; "
        "an estimated sigma and the paired model's sample counts come from the measured "
        "samples, which since session 35 are only those the simulation records, so a study "
        "of imported runs made before then is refused here)",
        "sensor_noise_m_s2": "the sensor noise",
        "realization_length_m": "the length of the model's synthetic track realizations "
        "(track_statistics; since session 35 from the runs' speed records and the rig)",
    }.get(error.key, repr(error.key))
    return StudyError(
        f"--resume: {out} holds the evaluations of another study: {what} changed "
        f"({fingerprint_change(str(error.stored), str(error.current))}); resume with the "
        "same rig, data, parameters (in the same order) and output error, or give a new "
        "output folder"
    )


def measured_log_spectra(spec: RigSpec, runs: Sequence[MeasuredRun]) -> np.ndarray:
    """(ν x C x F) log-amplitude spectra of measured runs on the rig's spectrum settings,
    each run's design force removed first (:func:`design_removal`), as a study compares them.

    Raises:
        ValueError: a run the spectrum settings cannot analyse (too short, for example).
    """
    return np.stack(
        [run.spectra(spec.spectrum, design_removal(spec, run)).log_amplitude for run in runs]
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
