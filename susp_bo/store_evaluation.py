"""One recorded simulator evaluation: the :class:`Evaluation` record, its key, its checks.

An evaluation is identified by :func:`evaluation_key` — the sha256 of its parameters'
exact float64 bytes and the track id — and holds its status (``ok`` or ``failed``), the
(C x F) float64 log-amplitude spectra and/or log-likelihood contribution of a success, or
the kind (``error`` or ``crash``) and reason of a failure. The checks here refuse
parameters, track ids and numbers before they reach the file, naming the field. The
store itself, and what a resumed study does with each failure kind, is
:mod:`susp_bo.store`.
"""

from __future__ import annotations

import hashlib
import math
import numbers
from dataclasses import dataclass
from typing import Literal

import numpy as np

FailureKind = Literal["error", "crash"]
FAILURE_KINDS: tuple[str, ...] = ("error", "crash")


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields, not objects
class Evaluation:
    """One recorded simulator evaluation.

    Attributes:
        key: hex sha256 of the parameters' float64 bytes and the track id.
        parameters: (q,) float64, physical units, calibration order.
        track_id: the track realization (measured stretch) the rig ran on.
        status: ``"ok"`` or ``"failed"``.
        spectra: (C x F) float64 log-amplitude spectra, or None.
        log_likelihood: the evaluation's log-likelihood contribution, or None.
        failure_kind: ``"error"`` (deterministic, reused on resume) or
            ``"crash"`` (worker lost, re-run on resume); None when ok.
        failure_reason: human-readable reason, None when ok.
        seconds: wall time of the evaluation (s).
        attempts: how many times this key was recorded (crash retries).
        code_version: package version that produced the row.
        created_at: ISO-8601 UTC time of the last write.
    """

    key: str
    parameters: np.ndarray
    track_id: str
    status: Literal["ok", "failed"]
    spectra: np.ndarray | None
    log_likelihood: float | None
    failure_kind: FailureKind | None
    failure_reason: str | None
    seconds: float
    attempts: int
    code_version: str
    created_at: str

    @property
    def ok(self) -> bool:
        """True for a successful evaluation."""
        return self.status == "ok"


def _parameter_array(parameters: np.ndarray | list[float] | tuple[float, ...]) -> np.ndarray:
    try:
        values = np.ascontiguousarray(parameters, dtype="<f8")
    except (TypeError, ValueError) as error:
        raise TypeError(
            f"parameters: {parameters!r} is not allowed; expected (q,) real numbers"
        ) from error
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"parameters: shape {values.shape} is not allowed; expected (q,), q >= 1")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"parameters: {values.tolist()} contains NaN or inf; expected finite")
    return values


def _check_track_id(track_id: str) -> str:
    if not isinstance(track_id, str):
        raise TypeError(
            f"track_id: {track_id!r} ({type(track_id).__name__}) is not allowed; expected a str"
        )
    return track_id


def _finite_real(name: str, value: float, minimum: float | None = None) -> float:
    """``value`` as a float, refused (naming ``name``) unless a finite real ≥ ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: {value!r} is not allowed; expected a finite real number")
    number = float(value)
    if not math.isfinite(number) or (minimum is not None and number < minimum):
        bound = "" if minimum is None else f" >= {minimum:g}"
        raise ValueError(f"{name}: {number} is not allowed; expected a finite number{bound}")
    return number


def evaluation_key(parameters: np.ndarray | list[float], track_id: str) -> str:
    """Deterministic key of an evaluation: sha256 of the exact float64 bytes and the track id.

    Args:
        parameters: (q,) parameter vector; converted to little-endian float64.
        track_id: track realization id.

    Returns:
        64 hex characters. Equal iff the float64 values are bit-identical and the
        track ids equal (so 0.0 and -0.0 are different points).
    """
    values = _parameter_array(parameters)
    digest = hashlib.sha256(values.tobytes())
    digest.update(b"\x00" + _check_track_id(track_id).encode("utf-8"))
    return digest.hexdigest()


def _check_status(status: str | None) -> None:
    if status not in (None, "ok", "failed"):
        raise ValueError(f"status: {status!r} is not allowed; expected None, 'ok' or 'failed'")
