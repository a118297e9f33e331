"""A study killed with SIGKILL mid-batch resumes to exactly the uninterrupted result; what
``--resume`` refuses before any simulation, touching nothing (a budget below the finished
result's evaluations, a damaged store); a scheduler that cannot be reached leaves a new
results folder unmade."""

from __future__ import annotations

import json
import shutil
import signal
import sqlite3
import tomllib
from pathlib import Path

import pytest

from tests.integration.conftest import calibrate_killed

pytestmark = pytest.mark.slow

VOLATILE = ("wall_time_s",)


def _stable(result_json: Path) -> dict:
    payload = json.loads(result_json.read_text())
    return {k: v for k, v in payload.items() if k not in VOLATILE}


def _rows(store: Path) -> list[tuple[str, str, int, str]]:
    db = sqlite3.connect(f"file:{store}?mode=ro", uri=True)
    try:
        return db.execute(
            "SELECT key, status, attempts, created_at FROM evaluations ORDER BY id"
        ).fetchall()
    finally:
        db.close()


def test_uninterrupted_study_writes_the_results_folder(uninterrupted: Path) -> None:
    payload = json.loads((uninterrupted / "result.json").read_text())
    for field in (
        "parameters",
        "bounds",
        "joint_map",
        "marginal_map",
        "interval95",
        "n_simulations",
        "mcmc",
        "reference",
    ):
        assert field in payload, field
    assert payload["parameters"] == ["secondary_vertical_damping", "yaw_damper_damping"]
    assert payload["reference"] == [30.0e3, 3.5e6]
    assert payload["n_simulations"] == 2 * payload["n_evaluations"] == 20
    for (lo, hi), (b_lo, b_hi) in zip(payload["interval95"], payload["bounds"]):
        assert b_lo <= lo < hi <= b_hi
    for name in ("study.toml", "study.log", "evaluations.sqlite"):
        assert (uninterrupted / name).is_file(), name
    assert sorted(p.name for p in uninterrupted.glob("*.png"))


def test_kill_9_mid_batch_then_resume_gives_the_same_result(
    uninterrupted: Path, fast_rig, fast_data, study_writer, calibrate_command, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    config = study_writer(tmp_path, fast_rig, fast_data, out)
    store = out / "evaluations.sqlite"
    # the first batch is the 6-point design on 2 tracks (12 simulations): kill inside it
    returncode = calibrate_killed(config, store, rows=5)
    assert returncode == -signal.SIGKILL
    before = {key: created for key, _, _, created in _rows(store)}
    assert 5 <= len(before) < 20
    assert not (out / "result.json").exists()

    refused = calibrate_command(config)
    assert refused.returncode == 2
    assert "--resume" in refused.stderr

    resumed = calibrate_command(config, "--resume")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert _stable(out / "result.json") == _stable(uninterrupted / "result.json")

    after = _rows(store)
    reference_rows = _rows(uninterrupted / "evaluations.sqlite")
    assert len(after) == len(reference_rows) == 20
    assert {key for key, *_ in after} == {key for key, *_ in reference_rows}
    assert all(attempts == 1 for _, _, attempts, _ in after)
    # finished evaluations were reused, not re-run: their rows are untouched
    created_after = {key: created for key, _, _, created in after}
    assert all(created_after[key] == created for key, created in before.items())


def _snapshot(folder: Path, sqlite_aux: bool = True) -> dict[str, bytes]:
    """Every file's bytes; without SQLite's own ``-wal``/``-shm`` files if not ``sqlite_aux``."""
    return {
        p.name: p.read_bytes()
        for p in sorted(folder.iterdir())
        if p.is_file() and (sqlite_aux or not p.name.endswith(("-wal", "-shm")))
    }


@pytest.fixture
def finished_copy(uninterrupted: Path, tmp_path: Path) -> Path:
    """A private copy of the finished small study (10 evaluations, q = 2)."""
    copy = tmp_path / "finished"
    shutil.copytree(uninterrupted, copy)
    return copy


def test_a_resume_below_the_finished_evaluations_is_refused(
    finished_copy: Path, calibrate_command
) -> None:
    done = json.loads((finished_copy / "result.json").read_text())["n_evaluations"]
    before = _snapshot(finished_copy)
    refused = calibrate_command(
        finished_copy / "study.toml", "--out", str(finished_copy), "--resume",
        "--budget", str(done - 2), "--allow-small-budget",
    )  # fmt: skip
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "Traceback" not in refused.stderr
    assert f"--budget (budget.max_evaluations): {done - 2} is below the {done}" in refused.stderr
    # it said "the same {done} rewrites the same result": another budget is another search
    ran_with = tomllib.loads((finished_copy / "study.toml").read_text())["budget"]
    assert f"{ran_with['max_evaluations']}, the budget it ran with, gives the same result" in (
        " ".join(refused.stderr.split())
    )
    assert "rewrites the same result" not in refused.stderr
    assert _snapshot(finished_copy) == before  # result, draws, figures and store as they were


def test_a_folder_another_process_writes_into_is_refused(
    finished_copy: Path, calibrate_command, held_elsewhere
) -> None:
    """Two runs into one --out both ran on one store and left study.toml of one run beside
    result.json of the other (outside probe, session 23); a fresh run was told to --resume."""
    with held_elsewhere(finished_copy) as pid:
        before = _snapshot(finished_copy)
        for extra in (["--resume", "--budget", "40"], []):
            refused = calibrate_command(
                finished_copy / "study.toml", "--out", str(finished_copy), *extra
            )
            assert refused.returncode == 2, refused.stderr[-2000:]
            assert "Traceback" not in refused.stderr
            assert f"is in use by process {pid}" in refused.stderr
            assert "resume it with --resume" not in refused.stderr
            assert _snapshot(finished_copy) == before


def test_a_damaged_store_is_named_and_left_as_it_was(
    finished_copy: Path, calibrate_command
) -> None:
    store = finished_copy / "evaluations.sqlite"
    store.write_bytes(store.read_bytes()[:3000])  # cut short: "disk image is malformed"
    # SQLite's -wal/-shm files are its own: earlier read-only readers of the shared fixture
    # can leave an empty WAL, which SQLite removes when the refused connection closes; the
    # store file and every result file must stay as they were
    before = _snapshot(finished_copy, sqlite_aux=False)
    refused = calibrate_command(
        finished_copy / "study.toml", "--out", str(finished_copy), "--resume"
    )
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "Traceback" not in refused.stderr
    assert f"{store}: not a readable evaluation store" in refused.stderr
    assert "move it away" in refused.stderr
    assert _snapshot(finished_copy, sqlite_aux=False) == before


@pytest.mark.parametrize("damage", ["emptied", "fingerprint_deleted", "removed"])
def test_a_result_whose_store_says_no_study_is_neither_resumed_nor_overwritten(
    finished_copy: Path, calibrate_command, damage: str
) -> None:
    """Outside probe, session 29: a resume on an emptied store started again and rewrote the
    result; on a store without its fingerprint it accepted other data and mixed two data
    sets in one store; a plain run beside a result whose store was removed overwrote it."""
    store = finished_copy / "evaluations.sqlite"
    if damage == "emptied":
        store.write_bytes(b"")
    elif damage == "fingerprint_deleted":
        db = sqlite3.connect(store)
        with db:
            db.execute("DELETE FROM study")
        db.close()
    else:
        store.unlink()
    before = _snapshot(finished_copy, sqlite_aux=False)
    extra = [] if damage == "removed" else ["--resume"]
    refused = calibrate_command(finished_copy / "study.toml", "--out", str(finished_copy), *extra)
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "Traceback" not in refused.stderr
    expected = {
        "emptied": f"{store}: empty",
        "fingerprint_deleted": f"{store}: no study fingerprint",
        "removed": "already holds a result (result.json) without its evaluations.sqlite",
    }[damage]
    assert expected in " ".join(refused.stderr.split()), refused.stderr[-2000:]
    assert _snapshot(finished_copy, sqlite_aux=False) == before


def test_a_store_killed_while_being_made_is_resumed_afresh(
    fast_rig: Path, fast_data: Path, tmp_path: Path, study_writer, calibrate_command
) -> None:
    """Second review, session 29: a run killed between creating its store file and writing
    its schema leaves an empty file; with no result beside it, --resume starts the study
    afresh (the refusal above is for a store that would seem to vouch for a result)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "evaluations.sqlite").write_bytes(b"")
    config = study_writer(tmp_path, fast_rig, fast_data, out)
    resumed = calibrate_command(config, "--resume")
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert json.loads((out / "result.json").read_text())["n_evaluations"] > 0


def test_an_unreachable_scheduler_leaves_no_results_folder(
    fast_rig: Path, fast_data: Path, tmp_path: Path, study_writer, calibrate_command
) -> None:
    pytest.importorskip("distributed")
    out = tmp_path / "never_made"
    config = study_writer(tmp_path, fast_rig, fast_data, out, executor="")
    refused = calibrate_command(config, "--scheduler", "tcp://127.0.0.1:9")
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "scheduler 'tcp://127.0.0.1:9': cannot connect" in refused.stderr
    assert not out.exists()


@pytest.mark.parametrize("blocked", ["result.json", "fig1_parameters.png"])
def test_a_results_file_blocked_by_a_folder_is_named_before_any_simulation(
    fast_rig: Path, fast_data: Path, tmp_path: Path, study_writer, calibrate_command, blocked: str
) -> None:
    """Outside probe, session 29: found only when written, after the whole calibration."""
    out = tmp_path / "out"
    (out / blocked).mkdir(parents=True)
    config = study_writer(tmp_path, fast_rig, fast_data, out)
    refused = calibrate_command(config)
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert f"out: {out / blocked} is a folder, where the results file {blocked} goes" in (
        " ".join(refused.stderr.split())
    )
    assert "Traceback" not in refused.stderr
    assert sorted(p.name for p in out.iterdir()) == [blocked]  # no store, nothing run


def test_an_out_that_cannot_be_created_is_named(
    fast_rig: Path, fast_data: Path, tmp_path: Path, study_writer, calibrate_command
) -> None:
    if not Path("/proc/self").is_dir():
        pytest.skip("needs Linux's /proc, where no folder can be created")
    config = study_writer(tmp_path, fast_rig, fast_data, Path("/proc/susp_bo_out"), "workers = 0")
    refused = calibrate_command(config)
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "out: '/proc/susp_bo_out' cannot be created" in refused.stderr


def test_a_resume_killed_while_writing_leaves_no_result_of_another_run(
    finished_copy: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Files were written draws → result.json → figures over the old ones: a resume killed
    in between left result.json saying `trusted` beside figures titled NOT TRUSTED (outside
    probe, session 23). Now the old result and figures go first: a kill leaves an unfinished
    folder, and the next resume writes the same result again."""
    import dataclasses

    import susp_bo.calibration.study as study_module
    from susp_bo.output_folder import FIGURE_NAMES
    from susp_bo.study_config import load_study_config

    before = json.loads((finished_copy / "result.json").read_text())
    assert all((finished_copy / name).is_file() for name in FIGURE_NAMES)
    config = dataclasses.replace(load_study_config(finished_copy / "study.toml"), out=finished_copy)

    def killed(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt  # as if killed right after the draws were written

    with monkeypatch.context() as patch:
        patch.setattr(study_module, "write_json", killed)
        with pytest.raises(KeyboardInterrupt):
            study_module.run_study(config, resume=True, progress=False)
    assert not (finished_copy / "result.json").exists()  # unfinished, not a mixed result
    assert not any((finished_copy / name).exists() for name in FIGURE_NAMES)
    payload, _ = study_module.run_study(config, resume=True, progress=False)
    assert {k: v for k, v in payload.items() if k != "wall_time_s"} == {
        k: v for k, v in before.items() if k != "wall_time_s"
    }
    assert all((finished_copy / name).is_file() for name in FIGURE_NAMES)
