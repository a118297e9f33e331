"""``susp-bo calibrate``: arguments and study files are checked before any simulation."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from susp_bo.cli import build_parser, main
from susp_bo.rig.catalog import rig_path


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


def test_a_study_file_without_its_rig_line_is_told_so(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "study.toml"
    study.write_text('data = "data"\nout = "out"\n[budget]\nmax_evaluations = 60\n')
    assert main(["calibrate", str(study)]) == 2
    assert "study.toml: rig: missing" in capsys.readouterr().err


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


def test_a_malformed_scheduler_is_refused_naming_the_flag(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["calibrate", "hst_trailer", str(data_dir), "--out", str(out)]
    assert main([*argv, "--scheduler", "notanaddress"]) == 2
    err = capsys.readouterr().err
    assert "--scheduler: 'notanaddress' is not allowed: no port number" in err
    assert "tcp://10.0.0.5:8786" in err and not out.exists()


def test_resume_without_a_store_is_refused(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        ["calibrate", "hst_trailer", str(data_dir), "--out", str(tmp_path / "o"), "--resume"]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert "nothing to resume" in err and "run without --resume" in err


@pytest.mark.parametrize(("budget", "design"), [(51, 35), (55, 39), (56, 40), (200, 40)])
def test_budget_shrinks_the_design_down_to_what_q_needs(
    data_dir: Path, tmp_path: Path, budget: int, design: int
) -> None:
    """q = 7, design 40, batches of 8, 8 check points: room for one batch and the check."""
    from susp_bo.commands.calibrate import config_from_arguments

    command = ["calibrate", "hst_trailer", str(data_dir), "--out", str(tmp_path / "o")]
    args = build_parser().parse_args([*command, "--budget", str(budget)])
    config = config_from_arguments(args)
    assert (config.budget.max_evaluations, config.budget.initial_design) == (budget, design)
    assert not config.budget.allow_small


def test_a_budget_below_the_minimum_is_refused_or_allowed_on_request(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "o"
    assert (
        main(["calibrate", "hst_trailer", str(data_dir), "--out", str(out), "--budget", "40"]) == 2
    )
    err = capsys.readouterr().err
    assert "--budget 40 is below the minimum 51 for q = 7 parameters" in err
    from susp_bo.commands.calibrate import config_from_arguments

    command = ["calibrate", "hst_trailer", str(data_dir), "--out", str(out), "--budget", "40"]
    args = build_parser().parse_args([*command, "--allow-small-budget"])
    config = config_from_arguments(args)
    assert config.budget.allow_small and config.budget.initial_design == 35


def test_summary_reads_in_prefixed_units_and_says_which_reference_is_outside() -> None:
    from susp_bo.commands.calibrate import format_summary

    payload = {
        "parameters": ["secondary_vertical_damping", "yaw_damper_damping"],
        "units": ["N·s/m", "N·s/m"],
        "marginal_map": [27.855e3, 4.388e6],
        "interval95": [[27.201e3, 28.509e3], [4.058e6, 4.718e6]],
        "reference": [28.0e3, 3.7e6],
        "n_simulations": 600,
        "n_evaluations": 200,
        "wall_time_s": 1414.0,
        "reliability": {"verdict": "not_trusted", "sentence": "Not trusted: a reason."},
    }
    lines = format_summary(payload).splitlines()
    assert "27.9 [27.2, 28.5] kN·s/m" in lines[1] and "28.0 kN·s/m (inside)" in lines[1]
    assert "4.39 [4.06, 4.72] MN·s/m" in lines[2] and "3.70 MN·s/m (OUTSIDE)" in lines[2]
    assert lines[-1] == "Not trusted: a reason."


def test_summary_columns_widen_for_per_component_names() -> None:
    from susp_bo.commands.calibrate import format_summary

    name = "yaw_damper_damping@bogie_front_right"  # 36 characters, wider than the column
    payload = {
        "parameters": ["yaw_damper_damping", name],
        "units": ["N·s/m", "N·s/m"],
        "marginal_map": [4.388e6, 2.45e6],
        "interval95": [[4.058e6, 4.718e6], [2.2e6, 2.7e6]],
        "n_simulations": 10,
        "n_evaluations": 10,
        "wall_time_s": 1.0,
    }
    header, first, second = format_summary(payload).splitlines()[:3]
    column = header.index("marginal MAP")
    assert column == len(name) + 1
    assert first[column:].startswith("4.39 [4.06, 4.72] MN·s/m")
    assert second.startswith(f"{name} 2.45 [2.20, 2.70] MN·s/m")


def test_a_study_file_with_a_data_folder_is_told_to_drop_it(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``calibrate study.toml data`` got "give RIG DATA_DIR --out DIR, or a study .toml"
    (outside probe, session 23): the study names its data itself."""
    study = tmp_path / "study.toml"
    study.write_text('rig = "hst_trailer"\ndata = "data"\nout = "out"\n')
    assert main(["calibrate", str(study), str(data_dir)]) == 2
    err = capsys.readouterr().err
    assert "DATA_DIR: " in err and "names its own data (data = ...); drop DATA_DIR" in err


def test_one_run_on_the_command_line_is_told_where_sigma_goes(
    fast_rig: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One measured run with the rig form of the command line was told to "give sigma as a
    number", which has no flag (outside probe, session 23): the message says where."""
    data = tmp_path / "data"
    assert main(["synth", str(fast_rig), "--out", str(data), "--nu", "2", "--seed", "1"]) == 0
    (data / "run_001.h5").unlink()
    capsys.readouterr()
    out = tmp_path / "out"
    assert main(["calibrate", str(fast_rig), str(data), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "'estimate' needs at least 2 measured runs (found 1)" in err
    assert "in the [output_error] section of a study .toml" in err
    assert not (out / "evaluations.sqlite").exists()


def _edited_rig(folder: Path, edit: str) -> Path:
    """The reference rig with one change (see the parametrisations below)."""
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    if edit == "empty-calibration":
        document["calibration"]["parameters"] = []
    elif edit == "no-calibration":
        del document["calibration"]
    elif edit == "sensor-body":
        document["sensors"][0]["body"] = "roof"
    else:
        document["effects"] = {"nosuch": {}}
    path = folder / f"{edit}.toml"
    path.write_text(tomli_w.dumps(document))
    return path


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        ("empty-calibration", "[[calibration.parameters]]: none given; calibrating (and "),
        ("no-calibration", "needs at least one calibration parameter"),
        ("sensor-body", "body 'roof' is not allowed; allowed bodies: carbody, bogie_front"),
        ("effect", "[effects.nosuch]: unknown effect 'nosuch'"),
    ],
)
def test_a_rig_that_cannot_be_calibrated_is_refused_before_anything_is_written(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], edit: str, needle: str
) -> None:
    # these used to create the store and fail with a traceback (no calibration parameter),
    # or run all 80 design simulations and say "every log L evaluation failed"
    rig = _edited_rig(tmp_path, edit)
    out = tmp_path / "out"
    code = main(["calibrate", str(rig), str(data_dir), "--out", str(out), "--workers", "0"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert needle in err and str(rig) in err
    assert "Traceback" not in err and not out.exists()


def test_measured_runs_slower_than_the_time_step_allows_are_refused_before_any_simulation(
    fast_rig: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Helper's note, session 29: a run slower than the explicit step can simulate failed
    evaluation by evaluation; the slowest run is now named before the store is made."""
    import dataclasses

    from susp_bo.data.measured import load_run, save_run
    from susp_bo.rig.track import SpeedProfile

    data = tmp_path / "data"
    assert main(["synth", str(fast_rig), "--out", str(data), "--nu", "2", "--seed", "1"]) == 0
    run = load_run(data / "run_001.h5")
    slow = SpeedProfile(time_s=np.array([0.0, 5.0, 30.0]), speed_m_s=np.array([83.33, 20.0, 20.0]))
    (data / "run_001.h5").unlink()
    save_run(dataclasses.replace(run, speed=slow), data / "run_001.h5")
    capsys.readouterr()
    out = tmp_path / "out"
    assert main(["calibrate", str(fast_rig), str(data), "--out", str(out)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"data: {data / 'run_001.h5'}: " in err and "below the minimum speed 24.99 m/s" in err
    assert "Traceback" not in err and not (out / "evaluations.sqlite").exists()
