"""The store file's SQLite layout: schema version, tables, column order, write transaction.

A store (:class:`susp_bo.store.EvaluationStore`) holds two tables: ``study`` (the
fingerprint, key → value) and ``evaluations`` (one row per evaluated point and track,
parameters and spectra as little-endian float64 bytes). Every write runs in one
``BEGIN IMMEDIATE`` … ``COMMIT`` transaction (:class:`_Transaction`).
"""

from __future__ import annotations

import sqlite3
from types import TracebackType

STORE_SCHEMA_VERSION = "1"
"""Bumped whenever the tables change incompatibly; part of every fingerprint."""


_SCHEMA = (
    """CREATE TABLE study (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
)""",
    """CREATE TABLE evaluations (
    id             INTEGER PRIMARY KEY AUTOINCREMENT,
    key            TEXT NOT NULL UNIQUE,
    parameters     BLOB NOT NULL,
    parameters_json TEXT NOT NULL,
    track_id       TEXT NOT NULL,
    status         TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    failure_kind   TEXT CHECK (failure_kind IN ('error', 'crash')),
    failure_reason TEXT,
    spectra        BLOB,
    spectra_shape  TEXT,
    log_likelihood REAL,
    seconds        REAL NOT NULL,
    attempts       INTEGER NOT NULL DEFAULT 1,
    code_version   TEXT NOT NULL,
    created_at     TEXT NOT NULL
)""",
)
_COLUMNS = (
    "key, parameters, track_id, status, failure_kind, failure_reason, spectra, "
    "spectra_shape, log_likelihood, seconds, attempts, code_version, created_at"
)


class _Transaction:
    """``BEGIN IMMEDIATE`` … ``COMMIT``, or ``ROLLBACK`` on any exception."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self._db = db

    def __enter__(self) -> None:
        self._db.execute("BEGIN IMMEDIATE")

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self._db.execute("ROLLBACK" if exc_type is not None else "COMMIT")
