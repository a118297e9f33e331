"""``susp-bo calibrate``: arguments and study files are checked before any simulation."""

from __future__ import annotations

from pathlib import Path

import pytest

from susp_bo.cli import main


@pytest.fixture
def data_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "data"
    folder.mkdir()
    return folder


def test_missing_arguments_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", "hst_trailer"]) == 2
    assert "RIG DATA_DIR --out DIR" in capsys.readouterr().err


def test_a_data_folder_without_runs_is_refused(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["calibrate", "hst_trailer", str(data_dir), "--out", str(tmp_path / "out")])
    assert code == 2
    assert "holds no measured runs" in capsys.readouterr().err
    assert not (tmp_path / "out" / "evaluations.sqlite").exists()


def test_a_study_file_with_a_typo_is_refused(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(
        'rig = "hst_trailer"\ndata = "data"\nout = "out"\n[budget]\nmax_evaluation = 10\n'
    )
    assert main(["calibrate", str(study)]) == 2
    assert "did you mean 'max_evaluations'" in capsys.readouterr().err


def test_an_unknown_calibration_parameter_is_refused(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(
        'rig = "hst_trailer"\ndata = "data"\nout = "out"\nparameters = ["wheel_colour"]\n'
    )
    assert main(["calibrate", str(study)]) == 2
    err = capsys.readouterr().err
    assert "wheel_colour" in err and "yaw_damper_damping" in err


def test_resume_without_a_store_is_refused(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        ["calibrate", "hst_trailer", str(data_dir), "--out", str(tmp_path / "o"), "--resume"]
    )
    assert code == 2
    assert "nothing to resume" in capsys.readouterr().err
