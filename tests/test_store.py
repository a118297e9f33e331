"""Tests of susp_bo.store: exact round trips, fingerprints, failure policy, kill -9 safety."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import susp_bo
from susp_bo.store import (
    STORE_SCHEMA_VERSION,
    EvaluationStore,
    StoreFileError,
    StoreMismatchError,
    evaluation_key,
)
from susp_bo.store_fingerprint import study_fingerprint

FINGERPRINT = study_fingerprint("rig-sha-1", "data-sha-1", ("primary_stiffness", "damping"))


def test_spectra_and_parameters_round_trip_bit_for_bit(tmp_path: Path) -> None:
    parameters = np.array([1.176e6, np.nextafter(40e3, 1e9)])
    spectra = np.array([[-0.0, 5e-324, 1e308], [-1.7976931348623157e308, -5e-324, 0.1 + 0.2]])
    path = tmp_path / "study.sqlite"
    with EvaluationStore(path, FINGERPRINT) as store:
        store.record_ok(parameters, "run-01", spectra, seconds=2.5, log_likelihood=-12.25)
    with EvaluationStore(path, FINGERPRINT) as store:  # reopened: read from disk
        found = store.lookup(parameters.copy(), "run-01")
    assert found is not None and found.ok
    assert found.spectra is not None
    assert found.spectra.dtype == np.float64
    assert found.spectra.tobytes() == spectra.tobytes()  # -0.0, subnormals, extremes included
    assert found.parameters.tobytes() == parameters.tobytes()
    assert (found.track_id, found.seconds, found.log_likelihood) == ("run-01", 2.5, -12.25)
    assert (found.attempts, found.code_version) == (1, susp_bo.__version__)
    assert found.key == evaluation_key(parameters, "run-01")


def test_lookup_matches_exact_float64_values_and_track(tmp_path: Path) -> None:
    parameters = np.array([0.3, 7.0])
    with EvaluationStore(tmp_path / "s.sqlite", FINGERPRINT) as store:
        store.record_ok(parameters, "run-01", np.zeros((2, 3)), seconds=1.0)
        assert store.lookup([0.3, 7.0], "run-01") is not None
        assert store.lookup(np.array([0.3, 7.0], dtype=np.float32), "run-01") is None
        assert store.lookup([np.nextafter(0.3, 1.0), 7.0], "run-01") is None
        assert store.lookup(parameters, "run-02") is None
        assert store.lookup(parameters[:1], "run-01") is None


@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=8))
def test_key_is_equal_exactly_when_the_float64_bytes_are_equal(values: list[float]) -> None:
    array = np.array(values, dtype=np.float64)
    assert evaluation_key(array, "t") == evaluation_key(list(values), "t")
    assert evaluation_key(array, "t") != evaluation_key(array, "u")
    moved = array.copy()
    moved[0] = np.nextafter(moved[0], -np.inf if moved[0] > 0 else np.inf)  # one ulp, finite
    assert evaluation_key(moved, "t") != evaluation_key(array, "t")


def test_store_of_another_study_is_refused_naming_the_key_and_values(tmp_path: Path) -> None:
    path = tmp_path / "study.sqlite"
    EvaluationStore(path, FINGERPRINT).close()
    other_rig = {**FINGERPRINT, "rig": "rig-sha-2"}
    with pytest.raises(
        StoreMismatchError, match=r"'rig' is 'rig-sha-1' in the store but 'rig-sha-2'"
    ):
        EvaluationStore(path, other_rig)
    fewer_names = study_fingerprint("rig-sha-1", "data-sha-1", ("primary_stiffness",))
    with pytest.raises(StoreMismatchError, match="'parameter_names'"):
        EvaluationStore(path, fewer_names)
    with pytest.raises(StoreMismatchError, match=r"'speed_m_s' is '\(absent\)' in the store"):
        EvaluationStore(path, {**FINGERPRINT, "speed_m_s": "83.3"})
    EvaluationStore(path, dict(FINGERPRINT)).close()  # the same study opens


@pytest.mark.parametrize(
    ("key", "value"), [("package_version", "0.0"), ("store_schema_version", "0")]
)
def test_store_of_an_incompatible_version_is_refused(tmp_path: Path, key: str, value: str) -> None:
    path = tmp_path / "study.sqlite"
    EvaluationStore(path, FINGERPRINT).close()
    with sqlite3.connect(path) as db:
        db.execute("UPDATE study SET value = ? WHERE key = ?", (value, key))
    with pytest.raises(StoreMismatchError, match=f"'{key}' is '{value}' in the store"):
        EvaluationStore(path, FINGERPRINT)


def test_fingerprint_records_schema_and_major_minor_version(tmp_path: Path) -> None:
    with EvaluationStore(tmp_path / "s.sqlite", FINGERPRINT) as store:
        assert store.fingerprint["store_schema_version"] == STORE_SCHEMA_VERSION
        major_minor = ".".join(susp_bo.__version__.split(".")[:2])
        assert store.fingerprint["package_version"] == major_minor


def test_files_that_are_not_stores_are_refused(tmp_path: Path) -> None:
    text = tmp_path / "notes.sqlite"
    text.write_text("this is not a database, it is a note about dampers\n" * 20)
    with pytest.raises(StoreFileError, match="not a readable evaluation store"):
        EvaluationStore(text, FINGERPRINT)
    other = tmp_path / "other.sqlite"
    with sqlite3.connect(other) as db:
        db.execute("CREATE TABLE wheels (diameter REAL)")
    db.close()
    before = other.read_bytes()
    with pytest.raises(StoreFileError, match=r"not an evaluation store \(tables \['wheels'\]"):
        EvaluationStore(other, FINGERPRINT)
    assert other.read_bytes() == before  # refused read-only: not switched to WAL (review)
    assert text.read_bytes() == b"this is not a database, it is a note about dampers\n" * 20


def test_a_damaged_store_is_a_store_file_error_and_is_left_as_it_was(tmp_path: Path) -> None:
    path = tmp_path / "s.sqlite"
    with EvaluationStore(path, FINGERPRINT) as store:
        for k in range(40):
            store.record_failure([1.0, float(k)], "run-01", "ValueError: diverged", 0.1)
    cut = path.read_bytes()[:3000]  # a copy cut short: "database disk image is malformed"
    path.write_bytes(cut)
    for wal in tmp_path.glob("s.sqlite-*"):
        wal.unlink()
    with pytest.raises(StoreFileError, match=r"s\.sqlite: not a readable evaluation store"):
        EvaluationStore(path, FINGERPRINT)
    assert path.read_bytes() == cut


def test_a_store_that_names_no_study_is_never_taken_for_this_one(tmp_path: Path) -> None:
    """Outside probe, session 29: an emptied store, or one whose fingerprint was deleted,
    took the fingerprint of whatever study opened it next. Evaluations without a
    fingerprint are refused always; an empty or absent file is refused where a store must
    already exist (``create=False``: a resume, a finished result read back), untouched."""
    path = tmp_path / "s.sqlite"
    with EvaluationStore(path, FINGERPRINT) as store:
        store.record_ok([1.0, 2.0], "run-01", np.zeros((2, 3)), seconds=1.0)
    with EvaluationStore(path, FINGERPRINT, create=False) as store:  # a study's store: opens
        assert store.count() == 1
    with sqlite3.connect(path) as db:
        db.execute("DELETE FROM study")
    db.close()
    for create in (True, False):
        with pytest.raises(StoreFileError, match=r"no study fingerprint \(1 evaluation"):
            EvaluationStore(path, FINGERPRINT, create=create)
    empty, absent = tmp_path / "empty.sqlite", tmp_path / "absent.sqlite"
    empty.write_bytes(b"")
    with pytest.raises(StoreFileError, match=r"empty\.sqlite: empty; expected the evaluation"):
        EvaluationStore(empty, FINGERPRINT, create=False)
    with pytest.raises(StoreFileError, match=r"absent\.sqlite: absent"):
        EvaluationStore(absent, FINGERPRINT, create=False)
    assert empty.read_bytes() == b"" and not absent.exists()
    with EvaluationStore(empty, FINGERPRINT) as store:  # a new study may start in it
        assert store.count() == 0


def test_a_damaged_row_is_named_not_a_traceback(tmp_path: Path) -> None:
    """Outside probe, session 29: a spectra blob of one byte gave ``ValueError: buffer size
    must be a multiple of element size`` from deep inside a resume."""
    path = tmp_path / "s.sqlite"
    with EvaluationStore(path, FINGERPRINT) as store:
        store.record_ok([1.0, 2.0], "run-01", np.zeros((2, 3)), seconds=1.0)
        store.record_ok([1.0, 3.0], "run-01", np.ones((2, 3)), seconds=1.0)
    with sqlite3.connect(path) as db:
        db.execute("UPDATE evaluations SET spectra = x'00' WHERE id = 1")
    db.close()
    with EvaluationStore(path, FINGERPRINT, create=False) as store:
        damaged = r"s\.sqlite: the evaluation on track 'run-01' \(key [0-9a-f]+…\) is damaged"
        with pytest.raises(StoreFileError, match=damaged):
            store.lookup([1.0, 2.0], "run-01")
        with pytest.raises(StoreFileError, match=damaged):
            list(store.evaluations())
        intact = store.lookup([1.0, 3.0], "run-01")  # the other rows still read
        assert intact is not None and intact.spectra is not None and intact.spectra[0, 0] == 1.0


def test_store_uses_wal_and_is_readable_by_another_connection(tmp_path: Path) -> None:
    path = tmp_path / "s.sqlite"
    with EvaluationStore(path, FINGERPRINT) as store:
        store.record_failure([1.0, 2.0], "run-01", "ValueError: negative stiffness", 0.1)
        with sqlite3.connect(path) as reader:  # committed, visible before close
            assert reader.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
            assert reader.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0] == 1


def test_failure_policy_errors_are_kept_crashes_are_rerun(tmp_path: Path) -> None:
    diverged, crashed = np.array([1.0, 2.0]), np.array([3.0, 4.0])
    with EvaluationStore(tmp_path / "s.sqlite", FINGERPRINT) as store:
        store.record_failure(diverged, "run-01", "SimulationFailed: roll diverged", 3.0)
        store.record_failure(crashed, "run-01", "worker process died", 1.0, kind="crash")

        kept = store.lookup(diverged, "run-01")
        assert kept is not None and not kept.ok and kept.failure_kind == "error"
        assert kept.failure_reason == "SimulationFailed: roll diverged" and kept.spectra is None
        assert store.lookup(crashed, "run-01") is None  # a resumed study runs it again
        crash = store.lookup(crashed, "run-01", include_crashes=True)
        assert crash is not None and crash.failure_kind == "crash"

        rerun = store.record_ok(crashed, "run-01", np.ones((1, 2)), seconds=2.0)
        assert (rerun.ok, rerun.attempts, rerun.failure_kind, rerun.failure_reason) == (
            True, 2, None, None
        )  # fmt: skip
        # a success is never overwritten
        again = store.record_failure(crashed, "run-01", "late duplicate", 9.0, kind="crash")
        assert (again.ok, again.attempts, again.seconds) == (True, 2, 2.0)
        assert [e.key for e in store.evaluations()] == [kept.key, rerun.key]  # first-recorded order
        assert (store.count(), store.count("ok"), store.count("failed")) == (2, 1, 1)
        assert [e.key for e in store.evaluations("failed")] == [kept.key]


def test_bad_records_are_refused(tmp_path: Path) -> None:
    with EvaluationStore(tmp_path / "s.sqlite", FINGERPRINT) as store:
        with pytest.raises(ValueError, match="contains NaN or inf"):
            store.record_ok([np.nan, 1.0], "t", np.zeros((1, 1)), 1.0)
        with pytest.raises(ValueError, match=r"spectra: shape \(3,\) is not allowed"):
            store.record_ok([1.0, 1.0], "t", np.zeros(3), 1.0)
        with pytest.raises(ValueError, match="spectra and log_likelihood are both None"):
            store.record_ok([1.0, 1.0], "t", None, 1.0)
        with pytest.raises(ValueError, match="kind: 'oom' is not allowed"):
            store.record_failure([1.0, 1.0], "t", "x", 1.0, kind="oom")  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="status: 'done' is not allowed"):
            store.count("done")
        assert store.count() == 0


@pytest.mark.parametrize(
    ("kwargs", "error", "field"),
    [
        ({"log_likelihood": float("nan")}, ValueError, "log_likelihood: nan"),
        ({"log_likelihood": float("inf")}, ValueError, "log_likelihood: inf"),
        ({"log_likelihood": "abc"}, TypeError, "log_likelihood: 'abc'"),
        ({"spectra": np.full((2, 3), np.nan)}, ValueError, "spectra: contains NaN"),
        ({"spectra": np.zeros((0, 3))}, ValueError, r"spectra: shape \(0, 3\)"),
        ({"seconds": float("nan")}, ValueError, "seconds: nan"),
        ({"seconds": -5.0}, ValueError, "seconds: -5.0"),
        ({"track_id": 3}, TypeError, "track_id: 3"),
        ({"parameters": ["a"]}, TypeError, "parameters: "),
    ],
)
def test_record_ok_refuses_what_is_not_a_successful_evaluation(
    tmp_path: Path, kwargs: dict, error: type[Exception], field: str
) -> None:
    """NaN log L was stored as NULL (status ok, no spectra, no log L), NaN spectra as ok,
    NaN seconds hit an SQLite IntegrityError, an int track id an AttributeError."""
    arguments = {
        "parameters": [1.0, 3.0],
        "track_id": "t",
        "spectra": None,
        "seconds": 1.0,
        "log_likelihood": -1.0,
        **kwargs,
    }
    with EvaluationStore(tmp_path / "s.sqlite", FINGERPRINT) as store:
        with pytest.raises(error, match=field):
            store.record_ok(**arguments)
        assert store.count() == 0


def test_store_arguments_are_named(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="fingerprint: "):
        EvaluationStore(tmp_path / "s.sqlite", ["rig"])  # type: ignore[arg-type]
    with pytest.raises(StoreFileError, match="is a folder"):
        EvaluationStore(tmp_path, FINGERPRINT)
    with EvaluationStore(tmp_path / "s.sqlite", FINGERPRINT) as store:
        with pytest.raises(TypeError, match="reason: None"):
            store.record_failure([1.0], "t", None, 1.0)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="seconds: inf"):
            store.record_failure([1.0], "t", "boom", float("inf"))
        assert store.count() == 0


_WRITER = """
import sys
import numpy as np
from susp_bo.store import EvaluationStore
from susp_bo.store_fingerprint import study_fingerprint

fingerprint = study_fingerprint("rig-sha-1", "data-sha-1", ("a", "b"))
with EvaluationStore(sys.argv[1], fingerprint) as store:
    for i in range(100_000):
        parameters = np.array([float(i), 0.5])
        spectra = np.random.default_rng(i).standard_normal((4, 500))
        store.record_ok(parameters, "run-01", spectra, seconds=0.01)
"""


def test_a_store_killed_mid_write_with_sigkill_keeps_every_committed_row_whole(
    tmp_path: Path,
) -> None:
    path = tmp_path / "killed.sqlite"
    env = {**os.environ, "PYTHONPATH": str(Path(susp_bo.__file__).resolve().parents[1])}
    writer = subprocess.Popen([sys.executable, "-c", textwrap.dedent(_WRITER), str(path)], env=env)
    try:
        deadline = time.monotonic() + 30.0
        committed = 0
        while committed < 30 and time.monotonic() < deadline:
            time.sleep(0.05)
            if path.exists():
                with sqlite3.connect(path, timeout=30.0) as reader:
                    tables = reader.execute("SELECT name FROM sqlite_master").fetchall()
                    if ("evaluations",) in tables:
                        query = "SELECT COUNT(*) FROM evaluations"
                        committed = reader.execute(query).fetchone()[0]
        assert writer.poll() is None, "the writer ended before it was killed"
        writer.send_signal(signal.SIGKILL)  # mid-write: it never stops writing on its own
    finally:
        writer.kill()
        writer.wait()
    assert committed >= 30

    fingerprint = study_fingerprint("rig-sha-1", "data-sha-1", ("a", "b"))
    with EvaluationStore(path, fingerprint) as store:
        with sqlite3.connect(path) as reader:
            assert reader.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        rows = list(store.evaluations())
        assert len(rows) >= committed
        # rows are whole and consecutive: 0, 1, …, n-1, each with its exact spectra
        for i, row in enumerate(rows):
            assert row.parameters.tolist() == [float(i), 0.5]
            expected = np.random.default_rng(i).standard_normal((4, 500))
            assert row.spectra is not None and row.spectra.tobytes() == expected.tobytes()
        # resuming writes on after the last committed row
        store.record_ok([float(len(rows)), 0.5], "run-01", np.zeros((4, 500)), seconds=0.01)
        assert store.count() == len(rows) + 1
