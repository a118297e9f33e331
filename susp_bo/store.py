"""The evaluation store: every simulator run of a study, in one SQLite file.

Simulator runs are the expensive resource, so every evaluation is written as it
completes — one committed transaction per evaluation, WAL journal — and a study
that is killed at any moment (``kill -9`` included) loses nothing that finished:
a row is either committed whole or absent. On ``--resume`` the study looks every
point up before running it (:meth:`EvaluationStore.lookup`); spectra come back
bit-for-bit, so a resumed study computes exactly what an uninterrupted one does.

A store belongs to one study. Its ``study`` table holds a fingerprint — rig,
data, calibration parameter names and whatever else the caller passes, plus the
store schema version and the package's major.minor version — and a store made
for another rig, data set or an incompatible version is refused with
:class:`StoreMismatchError` naming the key and both values.

Failed evaluations, and what a resumed study does with them:

- ``error`` — the task itself raised (the simulation diverged, the parameters
  were refused). The simulator is deterministic, so running it again gives the
  same failure: the failure is kept and reused on resume, exactly as an
  uninterrupted run would have seen it.
- ``crash`` — the worker process died or was lost (segfault, OOM killer, a
  cluster node gone). That says nothing reliable about the parameters, so on
  resume the evaluation is run again (:meth:`EvaluationStore.lookup` skips
  crash rows unless asked); a success then replaces the crash row.

A successful row is never overwritten. Only the process that owns the study
writes to the store; workers return results and never open it.

The evaluation record, its key and the checks of its fields are
:mod:`susp_bo.store_evaluation`; the SQLite tables and the write transaction,
:mod:`susp_bo.store_tables`.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType

import numpy as np

from susp_bo import __version__

# ``name as name``: re-exported, importable from susp_bo.store as before the split.
from susp_bo.store_evaluation import FAILURE_KINDS as FAILURE_KINDS
from susp_bo.store_evaluation import Evaluation as Evaluation
from susp_bo.store_evaluation import FailureKind as FailureKind
from susp_bo.store_evaluation import _check_status, _finite_real, _parameter_array
from susp_bo.store_evaluation import evaluation_key as evaluation_key
from susp_bo.store_fingerprint import fingerprint_difference
from susp_bo.store_tables import _COLUMNS, _SCHEMA, _Transaction
from susp_bo.store_tables import STORE_SCHEMA_VERSION as STORE_SCHEMA_VERSION


class StoreMismatchError(ValueError):
    """The store on disk was made for another study (rig, data, names or version).

    Attributes:
        key: the fingerprint key that differs (``rig``, ``data``, ``parameter_names`` …).
        stored: its value in the store.
        current: its value for the study now.
    """

    def __init__(self, message: str, key: str = "", stored: str = "", current: str = "") -> None:
        super().__init__(message)
        self.key, self.stored, self.current = key, stored, current


class StoreFileError(ValueError):
    """The file is not a readable evaluation store (another file, or a damaged one)."""


def _major_minor(version: str) -> str:
    return ".".join(version.split(".")[:2])


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


class EvaluationStore:
    """One SQLite file per study holding every simulator evaluation.

    Args:
        path: the ``.sqlite`` file; created (with its folder) when absent.
        fingerprint: what identifies the study (see
            :func:`susp_bo.store_fingerprint.study_fingerprint`); the store adds
            ``store_schema_version`` and ``package_version`` (major.minor) itself.
        code_version: version string written on every row.
        create: False to open only a store that already holds a study (a resume, a
            finished result read back): an absent or empty file, or one without the
            fingerprint, is then refused instead of being made a new store (outside probe,
            session 29: an emptied store took the fingerprint of other data, and the
            result beside it was reused for those data).

    Raises:
        StoreMismatchError: the existing file was made for another study; the
            message names the key that differs and both values.
        StoreFileError: the file exists but is not a readable evaluation store (not
            SQLite, damaged, a database of other tables, or evaluations without the
            fingerprint that says whose they are), or, with ``create=False``, holds no
            study; the file is left as it was.
    """

    def __init__(
        self,
        path: str | Path,
        fingerprint: Mapping[str, str],
        code_version: str = __version__,
        *,
        create: bool = True,
    ) -> None:
        self.path = Path(path)
        self.code_version = code_version
        self._create = create
        if not isinstance(fingerprint, Mapping):
            raise TypeError(
                f"fingerprint: {fingerprint!r} ({type(fingerprint).__name__}) is not allowed; "
                "expected a mapping of key to value (study_fingerprint)"
            )
        if self.path.is_dir():
            raise StoreFileError(
                f"path: {self.path} is a folder; expected the store's .sqlite file"
            )
        if not create and (not self.path.is_file() or self.path.stat().st_size == 0):
            raise StoreFileError(
                f"{self.path}: {'empty' if self.path.is_file() else 'absent'}; expected the "
                "evaluation store of the study (nothing in it can be checked or reused)"
            )
        self.fingerprint: dict[str, str] = {
            **{str(k): str(v) for k, v in fingerprint.items()},
            "store_schema_version": STORE_SCHEMA_VERSION,
            "package_version": _major_minor(__version__),
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # isolation_level=None: autocommit; every write is an explicit BEGIN IMMEDIATE … COMMIT.
        self._db = sqlite3.connect(self.path, isolation_level=None)
        try:
            self._open()
        except sqlite3.DatabaseError as error:  # e.g. a damaged file: "disk image is malformed"
            self._db.close()
            message = f"{self.path}: not a readable evaluation store ({error})"
            raise StoreFileError(message) from error
        except BaseException:
            self._db.close()
            raise

    def _foreign_tables(self) -> set[str]:
        """Tables of an existing file that is not an evaluation store, read without writing
        (the WAL switch below rewrites the header: second review, session 29)."""
        if not self.path.is_file() or self.path.stat().st_size == 0:
            return set()
        try:
            db = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True)
            try:
                tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master")}
            finally:
                db.close()
        except sqlite3.DatabaseError:
            return set()  # not SQLite at all: the WAL switch below refuses it, unchanged
        return tables if tables and "study" not in tables else set()

    def _open(self) -> None:
        foreign = self._foreign_tables()
        if foreign:
            raise StoreFileError(
                f"{self.path}: not an evaluation store (tables {sorted(foreign)}, no 'study')"
            )
        try:
            mode = self._db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        except sqlite3.DatabaseError as error:
            message = f"{self.path}: not a readable evaluation store ({error})"
            raise StoreFileError(message) from error
        if str(mode).lower() != "wal":
            raise ValueError(f"{self.path}: SQLite refused WAL mode (journal_mode={mode})")
        # FULL: a committed evaluation survives power loss too, not only a killed process.
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.execute("PRAGMA busy_timeout=30000")
        with self._transaction():
            tables = {r[0] for r in self._db.execute("SELECT name FROM sqlite_master")}
            if tables and "study" not in tables:
                raise StoreFileError(
                    f"{self.path}: not an evaluation store (tables {sorted(tables)}, no 'study')"
                )
            if not tables and self._create:
                for statement in _SCHEMA:
                    self._db.execute(statement)
            stored = (
                dict(self._db.execute("SELECT key, value FROM study").fetchall()) if tables else {}
            )
            if not stored:
                # made in one transaction with its schema, the fingerprint is missing only from
                # a damaged or edited file: whose evaluations it holds cannot be told
                held = (
                    int(self._db.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0])
                    if ("evaluations" in tables)
                    else 0
                )
                if held or not self._create:
                    raise StoreFileError(
                        f"{self.path}: no study fingerprint ({held} evaluation(s) of a study "
                        "it cannot name), so nothing in it can be checked or reused"
                    )
                self._db.executemany(
                    "INSERT INTO study (key, value) VALUES (?, ?)", sorted(self.fingerprint.items())
                )
                return
        self._check_fingerprint(stored)

    def _check_fingerprint(self, stored: dict[str, str]) -> None:
        difference = fingerprint_difference(stored, self.fingerprint)
        if difference is not None:
            name, old, new = difference
            raise StoreMismatchError(
                f"{self.path}: store was made for another study: {name!r} is {old!r} in the "
                f"store but {new!r} now; use a new results folder, or the same "
                f"{name} as the stored study",
                key=name,
                stored=old,
                current=new,
            )

    def _transaction(self) -> _Transaction:
        return _Transaction(self._db)

    # -- writing ---------------------------------------------------------------------------------

    def record_ok(
        self,
        parameters: np.ndarray | list[float],
        track_id: str,
        spectra: np.ndarray | None,
        seconds: float,
        log_likelihood: float | None = None,
    ) -> Evaluation:
        """Record a successful evaluation (one committed transaction).

        Args:
            parameters: (q,) physical units, calibration order.
            track_id: track realization id.
            spectra: (C x F) float64 log-amplitude spectra, or None when only the
                log-likelihood contribution is kept.
            seconds: wall time of the simulation (s).
            log_likelihood: log-likelihood contribution, optional.

        Returns:
            The stored evaluation. When the key is already recorded ok, the
            stored row is kept unchanged and returned (first success wins).

        Raises:
            ValueError: NaN or inf in ``spectra`` or ``log_likelihood`` (not a successful
                evaluation: record it with :meth:`record_failure`), empty spectra, or
                ``seconds`` not finite and >= 0.
        """
        if spectra is None and log_likelihood is None:
            raise ValueError("record_ok: spectra and log_likelihood are both None; give one")
        if log_likelihood is not None:
            log_likelihood = _finite_real("log_likelihood", log_likelihood)
        blob = shape = None
        if spectra is not None:
            try:
                array = np.ascontiguousarray(spectra, dtype="<f8")
            except (TypeError, ValueError) as error:
                message = f"spectra: {spectra!r} is not allowed; expected (C x F) real numbers"
                raise TypeError(message) from error
            if array.ndim != 2 or array.size == 0:
                raise ValueError(
                    f"spectra: shape {array.shape} is not allowed; expected (C x F), C, F >= 1"
                )
            if not np.all(np.isfinite(array)):
                raise ValueError(
                    "spectra: contains NaN or inf; an evaluation without finite spectra "
                    "is a failure (record_failure), not ok"
                )
            blob, shape = array.tobytes(), f"{array.shape[0]},{array.shape[1]}"
        return self._record(
            parameters, track_id, "ok", None, None, blob, shape, log_likelihood, seconds
        )

    def record_failure(
        self,
        parameters: np.ndarray | list[float],
        track_id: str,
        reason: str,
        seconds: float,
        kind: FailureKind = "error",
    ) -> Evaluation:
        """Record a failed evaluation (one committed transaction).

        Args:
            parameters: (q,) physical units, calibration order.
            track_id: track realization id.
            reason: why it failed (exception type and message).
            seconds: wall time until the failure (s).
            kind: ``"error"`` (deterministic; reused on resume) or ``"crash"``
                (worker lost; re-run on resume).

        Returns:
            The stored evaluation (the existing one if the key is already ok).
        """
        if kind not in FAILURE_KINDS:
            raise ValueError(f"kind: {kind!r} is not allowed; expected one of {FAILURE_KINDS}")
        if not isinstance(reason, str):
            raise TypeError(f"reason: {reason!r} is not allowed; expected a str")
        return self._record(parameters, track_id, "failed", kind, reason, None, None, None, seconds)

    def _record(
        self,
        parameters: np.ndarray | list[float],
        track_id: str,
        status: str,
        kind: str | None,
        reason: str | None,
        blob: bytes | None,
        shape: str | None,
        log_likelihood: float | None,
        seconds: float,
    ) -> Evaluation:
        values = _parameter_array(parameters)
        key = evaluation_key(values, track_id)
        seconds = _finite_real("seconds", seconds, minimum=0.0)
        row = (
            key,
            values.tobytes(),
            json.dumps(values.tolist()),
            track_id,
            status,
            kind,
            reason,
            blob,
            shape,
            None if log_likelihood is None else float(log_likelihood),
            float(seconds),
            self.code_version,
            _now(),
        )
        with self._transaction():
            # An ok row is never overwritten; a failed row is replaced and its attempts counted.
            self._db.execute(
                "INSERT INTO evaluations (key, parameters, parameters_json, track_id, status, "
                "failure_kind, failure_reason, spectra, spectra_shape, log_likelihood, seconds, "
                "code_version, created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
                "ON CONFLICT(key) DO UPDATE SET status=excluded.status, "
                "failure_kind=excluded.failure_kind, failure_reason=excluded.failure_reason, "
                "spectra=excluded.spectra, spectra_shape=excluded.spectra_shape, "
                "log_likelihood=excluded.log_likelihood, seconds=excluded.seconds, "
                "attempts=evaluations.attempts + 1, code_version=excluded.code_version, "
                "created_at=excluded.created_at WHERE evaluations.status != 'ok'",
                row,
            )
        stored = self.lookup(values, track_id, include_crashes=True)
        assert stored is not None
        return stored

    # -- reading ---------------------------------------------------------------------------------

    def lookup(
        self, parameters: np.ndarray | list[float], track_id: str, include_crashes: bool = False
    ) -> Evaluation | None:
        """The recorded evaluation of exactly these parameters on this track.

        Args:
            parameters: (q,) float64; matched bit-for-bit.
            track_id: track realization id.
            include_crashes: also return ``crash`` failures (which a resumed
                study re-runs, so by default they read as not evaluated).

        Returns:
            The evaluation with spectra bit-for-bit as recorded, or None.
        """
        row = self._db.execute(
            f"SELECT {_COLUMNS} FROM evaluations WHERE key = ?",
            (evaluation_key(parameters, track_id),),
        ).fetchone()
        if row is None:
            return None
        evaluation = _from_row(row, self.path)
        if evaluation.failure_kind == "crash" and not include_crashes:
            return None
        return evaluation

    def evaluations(self, status: str | None = None) -> Iterator[Evaluation]:
        """Every recorded evaluation in first-recorded order, optionally of one status."""
        _check_status(status)
        query = f"SELECT {_COLUMNS} FROM evaluations"
        args: tuple[str, ...] = ()
        if status is not None:
            query, args = query + " WHERE status = ?", (status,)
        for row in self._db.execute(query + " ORDER BY id", args).fetchall():
            yield _from_row(row, self.path)

    def count(self, status: str | None = None) -> int:
        """Number of recorded evaluations, optionally of one status (``"ok"``/``"failed"``)."""
        _check_status(status)
        if status is None:
            return int(self._db.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0])
        query = "SELECT COUNT(*) FROM evaluations WHERE status = ?"
        return int(self._db.execute(query, (status,)).fetchone()[0])

    def close(self) -> None:
        """Close the database (a checkpoint folds the WAL back into the file)."""
        self._db.close()

    def __enter__(self) -> EvaluationStore:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()


def _from_row(row: tuple, path: Path) -> Evaluation:
    """One stored row as an :class:`Evaluation`.

    Raises:
        StoreFileError: a row whose parameters or spectra cannot be decoded (a damaged or
            hand-edited store: outside probe, session 29, a 1-byte spectra blob gave a
            bare ``ValueError`` traceback), naming the store, the row and what is wrong.
    """
    (key, params, track_id, status, kind, reason, blob, shape, loglik, seconds, attempts,
     code_version, created_at) = row  # fmt: skip
    spectra = None
    try:
        if blob is not None:
            rows, cols = (int(n) for n in str(shape).split(","))
            spectra = np.frombuffer(blob, dtype="<f8").reshape(rows, cols).astype(np.float64)
        parameters = np.frombuffer(params, dtype="<f8").astype(np.float64)
    except (TypeError, ValueError) as error:
        raise StoreFileError(
            f"{path}: the evaluation on track {track_id!r} (key {str(key)[:16]}…) is damaged "
            f"({error}); the store is left as it was: restore it from a copy, or move it away "
            "to compute the study afresh"
        ) from None
    return Evaluation(
        key=key,
        parameters=parameters,
        track_id=track_id,
        status=status,
        spectra=spectra,
        log_likelihood=loglik,
        failure_kind=kind,
        failure_reason=reason,
        seconds=seconds,
        attempts=attempts,
        code_version=code_version,
        created_at=created_at,
    )
