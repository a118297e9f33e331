"""A campaign's results folder is reused only when it still belongs to the campaign's runs
and can be read: replaced runs, a missing store or damaged result files are refused with
exit code 2 before any work, naming the folder and what to do, and nothing is changed."""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import susp_bo
from susp_bo.cli import main

pytestmark = pytest.mark.slow  # one real (tiny) calibration, shared by the module

B = "TRAIN-1/2026-02-10"  # the campaign calibrated once by the fixture


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _simulations(out: Path) -> int:
    db = sqlite3.connect(f"file:{out / B / 'evaluations.sqlite'}?mode=ro", uri=True)
    try:
        return int(db.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0])
    finally:
        db.close()


@pytest.fixture(scope="module")
def finished(
    fast_rig: Path,
    tmp_path_factory: pytest.TempPathFactory,
    campaign_adder: Any,
    monitor_config_writer: Any,
) -> dict[str, Any]:
    """One campaign (2 runs, 8 evaluations), monitored to the end."""
    root = tmp_path_factory.mktemp("finished")
    folder, out = root / "campaigns", root / "out"
    campaign_adder(folder, fast_rig, "TRAIN-1", "2026-02-10", seed=2)
    monitor_config_writer(folder, fast_rig)
    susp_bo.monitor(folder, out, workers=0, progress=False, figures=False)
    return {"folder": folder, "out": out, "rig": fast_rig, "adder": campaign_adder}


@pytest.fixture
def copy(finished: dict[str, Any], tmp_path: Path) -> dict[str, Any]:
    """A private copy of the monitoring folder and its results."""
    folder, out = tmp_path / "campaigns", tmp_path / "out"
    shutil.copytree(finished["folder"], folder)
    shutil.copytree(finished["out"], out)
    return {**finished, "folder": folder, "out": out}


def _monitor(copy: dict[str, Any]) -> int:
    return main(["monitor", str(copy["folder"]), "--out", str(copy["out"]), "--workers", "0"])


def _replace_runs(copy: dict[str, Any]) -> None:
    """The campaign's runs replaced by other measurements (same vehicle, date, rig)."""
    copy["adder"](copy["folder"], copy["rig"], "TRAIN-1", "2026-02-10", seed=7)


def test_a_finished_campaign_whose_runs_were_replaced_is_refused_untouched(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    _replace_runs(copy)
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert f"campaign {B}" in err and str(copy["out"] / B) in err
    assert "other measured runs" in err and "move or delete" in err and "Traceback" not in err
    assert _files(copy["out"]) == before  # result, draws, store and monitor.json as they were


def test_a_finished_campaign_without_its_store_cannot_be_checked_and_is_refused(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    (copy["out"] / B / "evaluations.sqlite").unlink()
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert "evaluations.sqlite is missing" in err and str(copy["out"] / B) in err
    assert _files(copy["out"]) == before


@pytest.mark.parametrize("damage", ["emptied", "fingerprint_deleted"])
def test_a_finished_campaign_whose_store_says_no_study_is_refused_on_other_runs(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str], damage: str
) -> None:
    """Outside probe, session 29: an emptied store (0 bytes) took the fingerprint of the
    runs now in the campaign folder — other runs — and the old result was reported for
    them (exit 0). A store without a fingerprint cannot be checked, like a missing one."""
    store = copy["out"] / B / "evaluations.sqlite"
    if damage == "emptied":
        store.write_bytes(b"")
    else:
        db = sqlite3.connect(store)
        with db:
            db.execute("DELETE FROM study")
        db.close()
    _replace_runs(copy)
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert str(store) in err and "not reused" in err and "Traceback" not in err
    assert ("empty" if damage == "emptied" else "no study fingerprint") in err
    assert _files(copy["out"]) == before  # the store, result and draws as they were


def test_a_monitor_json_blocked_by_a_folder_is_named_before_any_campaign(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Outside probe, session 29: found only when written, after every campaign."""
    shutil.rmtree(copy["out"] / B)  # a campaign still to calibrate
    (copy["out"] / "monitor.json").unlink()
    (copy["out"] / "monitor.json").mkdir()
    assert _monitor(copy) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"--out: {copy['out'] / 'monitor.json'} is a folder, where the results file" in err
    assert not (copy["out"] / B).exists()  # refused before the campaign ran


@pytest.mark.parametrize("left", ["folder", "result_without_store"])
def test_a_later_campaigns_spoilt_results_folder_is_named_before_the_first_runs(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str], left: str
) -> None:
    """Second review, session 29: run_study's refusals (a results file made a folder, a
    result without its store) came on that campaign's turn, after earlier campaigns ran."""
    for date, seed in (("2026-03-10", 3), ("2026-04-10", 4)):
        copy["adder"](copy["folder"], copy["rig"], "TRAIN-1", date, seed=seed)
    later = copy["out"] / "TRAIN-1" / "2026-04-10"
    if left == "folder":
        (later / "result.json").mkdir(parents=True)
    else:
        later.mkdir(parents=True)
        (later / "result.json").write_text("{}")
    assert _monitor(copy) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "campaign TRAIN-1/2026-04-10" in err and "Traceback" not in err
    expected = {
        "folder": "is a folder, where the results file",
        "result_without_store": "already holds a result (result.json) without its evaluations",
    }[left]
    assert expected in err
    assert not (copy["out"] / "TRAIN-1" / "2026-03-10").exists()  # refused before it ran


def test_a_result_of_another_version_is_reused_only_on_the_same_runs(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    db = sqlite3.connect(copy["out"] / B / "evaluations.sqlite")
    with db:
        db.execute("UPDATE study SET value = '0.0' WHERE key = 'package_version'")
    db.close()
    before = _files(copy["out"] / B)
    assert _monitor(copy) == 0, capsys.readouterr().err
    assert _files(copy["out"] / B) == before
    _replace_runs(copy)
    assert _monitor(copy) == 2
    assert "other measured runs" in capsys.readouterr().err


def test_a_result_of_another_version_and_another_rig_is_refused(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """The store stops at the first key that differs (the version, sorted before 'rig'):
    a finished result of another version is compared on every other key too."""
    db = sqlite3.connect(copy["out"] / B / "evaluations.sqlite")
    with db:
        db.execute("UPDATE study SET value = '0.0' WHERE key = 'package_version'")
        db.execute("UPDATE study SET value = 'another-rig-sha' WHERE key = 'rig'")
    db.close()
    before = _files(copy["out"] / B)
    assert _monitor(copy) == 2
    assert "another rig" in capsys.readouterr().err
    assert _files(copy["out"] / B) == before


def test_a_damaged_store_is_named_with_its_campaign(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    store = copy["out"] / B / "evaluations.sqlite"
    store.write_bytes(b"not a database, a note about dampers\n" * 100)
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert f"campaign {B} (" in err and f"{store}: not a readable evaluation store" in err
    assert "Traceback" not in err and store.read_bytes().startswith(b"not a database")


def test_an_interrupted_campaign_on_replaced_runs_is_refused_before_any_work(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Refused before the campaign before it (new work) is calibrated."""
    for name in ("result.json", "posterior_samples.npy"):
        (copy["out"] / B / name).unlink()
    copy["adder"](copy["folder"], copy["rig"], "TRAIN-1", "2026-01-10", seed=1)
    _replace_runs(copy)
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert "interrupted calibration was computed on other measured runs" in err
    assert _files(copy["out"]) == before
    assert not (copy["out"] / "TRAIN-1" / "2026-01-10").exists()


def test_a_damaged_result_is_refused_and_recomputed_from_its_store(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """The message says what to delete; doing so recomputes it without a simulation."""
    folder = copy["out"] / B
    draws = np.load(folder / "posterior_samples.npy")
    simulations = _simulations(copy["out"])
    (folder / "result.json").write_text("{broken")
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert f"{folder / 'result.json'}: not a readable result" in err
    assert "(keep evaluations.sqlite)" in err and "Traceback" not in err
    assert _files(copy["out"]) == before
    for name in ("result.json", "posterior_samples.npy"):  # what the message says to do
        (folder / name).unlink()
    assert _monitor(copy) == 0, capsys.readouterr().err
    assert _simulations(copy["out"]) == simulations
    assert np.array_equal(np.load(folder / "posterior_samples.npy"), draws)


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (b"junk\n", "not a NumPy .npy file"),
        ("pickled", "Object arrays cannot be loaded"),
        (np.ones(5), "shape (5,), expected (n x 2) draws"),
        (np.full((4, 2), np.nan), "non-finite"),
    ],
    ids=["junk", "pickled", "one-dimensional", "nan"],
)
def test_damaged_posterior_draws_are_refused(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str], content: Any, problem: str
) -> None:
    path = copy["out"] / B / "posterior_samples.npy"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, str):
        np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    else:
        np.save(path, content)
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert f"{path}: " in err and problem in err and "Traceback" not in err
    assert _files(copy["out"]) == before


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        (lambda d, b: np.full_like(d, 1e9), "draws outside the admissible interval C_w"),
        (  # another campaign's draws: inside C_w, a whole posterior away from this one's
            lambda d, b: np.clip(d + 0.1 * (b[:, 1] - b[:, 0]), b[:, 0], b[:, 1]),
            "not the draws its result.json summarises",
        ),
    ],
    ids=["outside-C_w", "shifted"],
)
def test_draws_that_are_not_the_results_are_refused(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str], change: Any, problem: str
) -> None:
    """A swapped or hand-written posterior_samples.npy drove P(outside) and the alarms."""
    path = copy["out"] / B / "posterior_samples.npy"
    bounds = np.array(json.loads((copy["out"] / B / "result.json").read_text())["bounds"])
    np.save(path, change(np.load(path), bounds))
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert f"{path}: " in err and problem in err and "Traceback" not in err
    assert _files(copy["out"]) == before


def test_a_unit_changed_in_the_rig_does_not_relabel_finished_results(
    copy: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    result = json.loads((copy["out"] / B / "result.json").read_text())
    rig = tmp_path / "rig_kilo.toml"
    text = copy["rig"].read_text()
    unit = result["units"][0]
    assert f'unit = "{unit}"' in text
    rig.write_text(text.replace(f'unit = "{unit}"', f'unit = "k{unit}"'))
    before = _files(copy["out"])
    command = ["monitor", str(copy["folder"]), "--out", str(copy["out"]), "--workers", "0"]
    assert main([*command, "--rig", str(rig)]) == 2
    err = capsys.readouterr().err
    assert f"was calibrated with units {result['units']}" in err and "Traceback" not in err
    assert _files(copy["out"]) == before


def test_a_campaign_folder_gone_missing_is_refused_not_dropped(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """The maintenance table was rebuilt without it: an alarm it raised was cleared."""
    copy["adder"](copy["folder"], copy["rig"], "TRAIN-1", "2026-03-10", seed=3)
    shutil.rmtree(copy["folder"] / "TRAIN-1" / "2026-02-10")  # e.g. an archived campaign
    before = _files(copy["out"])
    assert _monitor(copy) == 2
    err = capsys.readouterr().err
    assert "holds finished campaign results whose campaign folders are no longer in" in err
    assert B in err and "Traceback" not in err
    assert _files(copy["out"]) == before


def test_the_table_says_when_a_vehicles_state_is_unknown(
    copy: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """The fixture's only campaign is not trusted (8 evaluations): "no alarm" alone hid it."""
    assert _monitor(copy) == 0
    err = capsys.readouterr().err
    assert "maintenance: no alarm" in err
    study = copy["out"] / B / "study.toml"
    assert f"TRAIN-1: state unknown since {B}, not trusted" in err
    assert f"susp-bo calibrate {study} --resume" in err
    monitor = json.loads((copy["out"] / "monitor.json").read_text())
    (row,) = monitor["attention"]
    assert row["last_campaign"] == B and row["last_trusted_campaign"] is None
