"""What identifies a study's evaluation store: its fingerprint, made, compared and read.

A store (:class:`susp_bo.store.EvaluationStore`) belongs to one study. The fingerprint —
rig, data, calibration parameter names and whatever else changes simulator output — is
written in the store's ``study`` table when it is made; a store opened for another study
is refused, and the monitor compares a finished campaign's store with its data before it
reuses the result (:mod:`susp_bo.monitoring.campaign_results`).
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from collections.abc import Iterable, Mapping
from pathlib import Path


def study_fingerprint(
    rig: str, data: str, parameter_names: tuple[str, ...] | list[str], **extra: str
) -> dict[str, str]:
    """The fingerprint of a study, as :class:`EvaluationStore` expects it.

    Args:
        rig: the rig's fingerprint (``RigSpec.fingerprint()``).
        data: the measured data's fingerprint (e.g. :func:`files_fingerprint`).
        parameter_names: calibration parameter names, in calibration order.
        **extra: anything else that changes simulator output (speed, duration…).

    Returns:
        Mapping of fingerprint keys to strings.
    """
    return {
        "rig": rig,
        "data": data,
        "parameter_names": json.dumps(list(parameter_names)),
        **{name: str(value) for name, value in extra.items()},
    }


def files_fingerprint(paths: list[Path] | tuple[Path, ...]) -> str:
    """sha256 over the names and bytes of files, in sorted name order.

    Args:
        paths: files (for a folder of runs: ``sorted(folder.glob("*.h5"))``).

    Returns:
        64 hex characters.
    """
    digest = hashlib.sha256()
    for path in sorted(Path(p) for p in paths):
        digest.update(path.name.encode("utf-8") + b"\x00")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def fingerprint_difference(
    stored: Mapping[str, str], current: Mapping[str, str], skip: Iterable[str] = ()
) -> tuple[str, str, str] | None:
    """The first key, in sorted order and not in ``skip``, whose value differs between two
    fingerprints: (key, stored value, current value), ``"(absent)"`` for a missing one;
    None when they agree."""
    for name in sorted((set(stored) | set(current)) - set(skip)):
        old, new = stored.get(name, "(absent)"), str(current.get(name, "(absent)"))
        if old != new:
            return name, old, new
    return None


def stored_fingerprint(path: str | Path) -> dict[str, str] | None:
    """The fingerprint recorded in a store closed cleanly, read without changing the file.

    Read as an immutable file (no lock, no ``-wal``/``-shm`` file made), so what is still
    in a WAL (a store whose writer was killed) is not seen. None when it cannot be read
    (absent — no file is made —, not SQLite, or no fingerprint).
    """
    try:
        uri = f"{Path(path).resolve().as_uri()}?mode=ro&immutable=1"  # ro: never made
        db = sqlite3.connect(uri, uri=True)
        try:
            stored = dict(db.execute("SELECT key, value FROM study").fetchall())
        finally:
            db.close()
    except sqlite3.DatabaseError:
        return None
    return stored or None
