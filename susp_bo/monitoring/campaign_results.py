"""The results folder of one campaign, checked before ``susp-bo monitor`` reuses it.

A campaign's results folder ``OUT/<vehicle>/<date>/`` is reused by a later monitoring run:
a *finished* one (``result.json`` and ``posterior_samples.npy``) is read back, an
*interrupted* one (an evaluation store only) is resumed. Either is only valid for the
measured runs, rig and output-error model it was computed with, so before any simulation
:func:`check_campaign_store` compares the campaign's evaluation store fingerprint
(:func:`susp_bo.calibration.study_preparation.store_fingerprint`, the one ``calibrate
--resume`` checks) with the study as it would run now: runs replaced or edited in the
campaign folder, another rig or another output error are refused with
:class:`CampaignResultError`, naming the campaign, its results folder and what to do;
nothing is written or removed. :func:`read_finished` reads a finished result and its
posterior draws and refuses damaged files the same way.

A finished campaign whose store was made by another package version (or store schema) is
still reused: its data were checked (the store compares the ``data`` key before the
version keys) and only a resume needs the version to match.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.calibration.study_preparation import STORE_NAME, PreparedStudy, store_fingerprint
from susp_bo.output_folder import RESULT_NAME, SAMPLES_NAME
from susp_bo.store import EvaluationStore, StoreFileError, StoreMismatchError
from susp_bo.store_fingerprint import fingerprint_difference, stored_fingerprint

_NPY_MAGIC = b"\x93NUMPY"
VERSION_KEYS = frozenset({"package_version", "store_schema_version"})
"""Fingerprint keys that bar a resume but say nothing about the data of a finished result."""

_WHAT = {
    "rig": "another rig (or other rig parameter values)",
    "parameter_names": "other calibrated parameters",
    "output_error": "another output error",
    "output_error_model": "another output-error model ([output_error] model)",
    "sensor_noise_m_s2": "another sensor noise",
    "realization_length_m": "another length of the synthetic track realizations",
    "package_version": "another version of susp-bo",
    "store_schema_version": "another evaluation-store format",
}


class CampaignResultError(ValueError):
    """A campaign's results folder that cannot be reused (stale or damaged); nothing changed."""


def _recompute_hint(folder: Path) -> str:
    return (
        f"delete {folder / RESULT_NAME} and {folder / SAMPLES_NAME} (keep "
        f"{STORE_NAME}) and run the same command again: the campaign is then recomputed from "
        "its evaluation store (the simulations already run are read back, not re-run); "
        "nothing was changed"
    )


def read_finished(
    folder: Path, names: Sequence[str], units: Sequence[str] | None = None
) -> tuple[dict[str, Any], np.ndarray]:
    """The ``result.json`` payload and the (n x q) posterior draws of a finished campaign.

    Args:
        folder: the campaign's results folder.
        names: (q,) the parameters this monitoring run calibrates, in order.
        units: (q,) their units in the rig now (checked against the result's), or None.

    Returns:
        The payload and the draws (physical units, calibration order).

    Raises:
        CampaignResultError: an unreadable or damaged ``result.json`` or
            ``posterior_samples.npy``, draws that are not the ones the result summarises
            (:func:`draws_mismatch`), or a result of other parameters or units.
    """
    path = folder / RESULT_NAME
    try:
        result = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CampaignResultError(
            f"{path}: not a readable result ({error}); {_recompute_hint(folder)}"
        ) from None
    parameters = result.get("parameters") if isinstance(result, dict) else None
    if not isinstance(parameters, list):
        raise CampaignResultError(
            f"{path}: not a calibration result (no list of 'parameters'); {_recompute_hint(folder)}"
        )
    if parameters != list(names):
        raise CampaignResultError(
            f"{path} was calibrated for parameters {parameters}, this run asks for "
            f"{list(names)}; use another --out or move that folder away (nothing was changed)"
        )
    samples_path = folder / SAMPLES_NAME
    try:
        with samples_path.open("rb") as file:
            if file.read(len(_NPY_MAGIC)) != _NPY_MAGIC:
                raise ValueError("not a NumPy .npy file")
        samples = np.load(samples_path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as error:
        raise CampaignResultError(
            f"{samples_path}: not a file of posterior draws ({error}); {_recompute_hint(folder)}"
        ) from None
    problem = ""
    if samples.ndim != 2 or samples.shape[1] != len(names) or samples.shape[0] < 1:
        problem = f"shape {samples.shape}, expected (n x {len(names)}) draws of {list(names)}"
    elif samples.dtype.kind != "f" or not np.all(np.isfinite(samples)):
        problem = f"draws of dtype {samples.dtype} with non-finite or non-float values"
    if not problem:
        problem = draws_mismatch(result, samples)
    if problem:
        raise CampaignResultError(f"{samples_path}: {problem}; {_recompute_hint(folder)}")
    if units is not None and result.get("units") != list(units):
        raise CampaignResultError(
            f"{path} was calibrated with units {result.get('units')} for {list(names)}; the "
            f"rig now says {list(units)}: a unit changed in the rig file would relabel the "
            "finished results without converting them; restore the rig's unit, or use "
            "another --out (nothing was changed)"
        )
    return result, samples


MEAN_TOLERANCE_SD = 0.2
"""How far (posterior sd) the mean of the saved draws may lie from ``posterior_mean``: the
file holds the draws thinned with a regular stride (|z| <= 0.015 measured on 1 + 7-D
results), a file of another campaign or parameter lies whole sd away."""


def draws_mismatch(result: dict[str, Any], samples: np.ndarray) -> str:
    """Why the (n x q) draws cannot be the draws ``result`` summarises; "" when they can.

    The draws must lie inside the result's ``bounds`` (C_w) and have its ``posterior_mean``
    within :data:`MEAN_TOLERANCE_SD` sd and its ``posterior_sd`` within a factor 1.25:
    the file is a thinned copy of the draws the summary was computed from, so a file
    swapped with another campaign's, restored from another run or written by hand is told.
    """
    q = samples.shape[1]
    try:
        bounds = np.asarray(result["bounds"], dtype=np.float64)
        mean = np.asarray(result["posterior_mean"], dtype=np.float64)
        sd = np.asarray(result["posterior_sd"], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        return "its result.json has no usable bounds, posterior_mean and posterior_sd to check it"
    if bounds.shape != (q, 2) or mean.shape != (q,) or sd.shape != (q,):
        return "its result.json's bounds, posterior_mean or posterior_sd are not of q values"
    names = list(result["parameters"])
    span = bounds[:, 1] - bounds[:, 0]
    slack = 1e-9 * span
    outside = np.any((samples < bounds[:, 0] - slack) | (samples > bounds[:, 1] + slack), axis=0)
    if outside.any():
        which = [n for n, o in zip(names, outside, strict=True) if o]
        return f"draws outside the admissible interval C_w of {which} (result.json's bounds)"
    scale = np.maximum(sd, slack)
    z = (samples.mean(axis=0) - mean) / scale
    ratio = np.maximum(samples.std(axis=0), slack) / scale
    bad = (np.abs(z) > MEAN_TOLERANCE_SD) | (ratio > 1.25) | (ratio < 0.8)
    if bad.any():
        which = [
            f"{n} (draws' mean {m:.6g}, sd {d:.3g}; result.json {mu:.6g}, {s:.3g})"
            for n, m, d, mu, s, b in zip(
                names, samples.mean(axis=0), samples.std(axis=0), mean, sd, bad, strict=True
            )
            if b
        ]
        return (
            "not the draws its result.json summarises (another campaign's or another run's?): "
            + "; ".join(which)
        )
    return ""


def check_campaign_store(study: PreparedStudy, *, finished: bool, campaign_folder: Path) -> None:
    """Refuse a campaign's results folder whose evaluation store belongs to another study.

    Opens the store only to compare fingerprints (no row is written; the store itself
    refuses a file that is not an evaluation store).

    Args:
        study: the campaign's study as it would run now (its runs, rig, output error).
        finished: True for a finished campaign (result read back), False for an
            interrupted one (resumed from the store).
        campaign_folder: the campaign's folder of measured runs (named in the message).

    Raises:
        CampaignResultError: no store beside a finished result (its data cannot be
            checked), a store that is not readable, or a store made for other runs,
            another rig or output error (or, for an interrupted campaign, by another
            version).
    """
    out = study.config.out
    store = out / STORE_NAME
    what = "result" if finished else "interrupted calibration"
    action = (
        f"Nothing was changed. To calibrate the runs now in {campaign_folder}, move or "
        f"delete {out} (or give another --out)"
    )
    if not store.is_file():
        raise CampaignResultError(
            f"{out}: its {what} cannot be checked against the runs now in {campaign_folder}: "
            f"its {STORE_NAME} is missing, so it is not reused. {action}; to keep it, put "
            f"{STORE_NAME} back"
        )
    try:
        EvaluationStore(store, store_fingerprint(study), create=not finished).close()
    except StoreFileError as error:
        raise CampaignResultError(
            f"{error}, so its {what} is not reused. Nothing was changed: move {store} away "
            f"to calibrate the runs in {campaign_folder} afresh (or give another --out)"
        ) from None
    except StoreMismatchError as error:
        key, old, new = error.key, error.stored, error.current
        stored = stored_fingerprint(store) if finished and key in VERSION_KEYS else None
        if stored is not None:
            # the store stops at the first key that differs: compare every other key too
            other = fingerprint_difference(stored, store_fingerprint(study), skip=VERSION_KEYS)
            if other is None:
                return
            key, old, new = other
        if key == "data":
            raise CampaignResultError(
                f"{out}: its {what} was computed on other measured runs than the "
                f"{len(study.runs)} now in {campaign_folder} (runs replaced, added, removed "
                f"or edited since), so it is not reused. {action}; to keep it, put the "
                "original runs back"
            ) from None
        differs = _WHAT.get(key, f"another {key!r}")
        raise CampaignResultError(
            f"{out}: its {what} was computed with {differs} ({key}: stored "
            f"{_short(old)!r}, now {_short(new)!r}), so it is not reused. "
            f"{action}; to keep it, run with the settings it was computed with"
        ) from None


def _short(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."
