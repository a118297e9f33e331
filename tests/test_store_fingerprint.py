"""Tests of susp_bo.store_fingerprint: made, compared, and read without touching the file."""

from __future__ import annotations

import json
from pathlib import Path

from susp_bo.store import EvaluationStore
from susp_bo.store_fingerprint import (
    files_fingerprint,
    fingerprint_difference,
    stored_fingerprint,
    study_fingerprint,
)


def test_study_fingerprint_keeps_parameter_order_and_stringifies_extras() -> None:
    fingerprint = study_fingerprint("rig", "data", ("b", "a"), duration_s=12.5)
    assert fingerprint == {
        "rig": "rig",
        "data": "data",
        "parameter_names": json.dumps(["b", "a"]),
        "duration_s": "12.5",
    }
    assert study_fingerprint("rig", "data", ("a", "b")) != study_fingerprint(
        "rig", "data", ("b", "a")
    )


def test_files_fingerprint_follows_names_and_bytes(tmp_path: Path) -> None:
    a, b = tmp_path / "run-a.h5", tmp_path / "run-b.h5"
    a.write_bytes(b"\x00\x01")
    b.write_bytes(b"\x02")
    first = files_fingerprint([a, b])
    assert files_fingerprint([b, a]) == first
    b.write_bytes(b"\x03")
    assert files_fingerprint([a, b]) != first
    b.write_bytes(b"\x02")
    renamed = tmp_path / "run-c.h5"
    b.rename(renamed)
    assert files_fingerprint([a, renamed]) != first


def test_fingerprint_difference_names_the_first_differing_key_in_sorted_order() -> None:
    stored = {"a": "1", "b": "2", "c": "3"}
    assert fingerprint_difference(stored, dict(stored)) is None
    assert fingerprint_difference(stored, {"a": "1", "b": "x", "c": "y"}) == ("b", "2", "x")
    assert fingerprint_difference(stored, {"a": "1", "b": "x", "c": "y"}, skip=["b"]) == (
        "c",
        "3",
        "y",
    )
    assert fingerprint_difference(stored, {"a": "1", "b": "2"}) == ("c", "3", "(absent)")
    assert fingerprint_difference({"a": "1"}, {"a": "1", "z": "9"}) == ("z", "(absent)", "9")


def test_stored_fingerprint_reads_a_store_without_changing_its_folder(tmp_path: Path) -> None:
    path = tmp_path / "evaluations.sqlite"
    fingerprint = study_fingerprint("rig", "data", ("a",))
    with EvaluationStore(path, fingerprint):
        pass
    before = sorted(p.name for p in tmp_path.iterdir())
    content = path.read_bytes()
    stored = stored_fingerprint(path)
    assert stored is not None
    assert {k: stored[k] for k in fingerprint} == fingerprint
    assert {"store_schema_version", "package_version"} <= set(stored)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no -wal / -shm made
    assert path.read_bytes() == content


def test_stored_fingerprint_is_none_for_what_is_not_a_store(tmp_path: Path) -> None:
    text = tmp_path / "not_sqlite.sqlite"
    text.write_text("hello")
    assert stored_fingerprint(text) is None
    assert stored_fingerprint(tmp_path / "absent.sqlite") is None
    assert not (tmp_path / "absent.sqlite").exists()
