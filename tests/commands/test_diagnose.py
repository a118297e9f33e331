"""`susp-bo diagnose` input checks and the not-trusted answer (no simulation needed)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from susp_bo.cli import main
from susp_bo.json_files import json_ready


def _result_dir(tmp_path: Path, payload: object) -> Path:
    folder = tmp_path / "result"
    folder.mkdir()
    text = payload if isinstance(payload, str) else json.dumps(payload)
    (folder / "result.json").write_text(text)
    (folder / "study.toml").write_text('rig = "hst_trailer"\ndata = "."\nout = "."\n')
    return folder


def test_a_folder_without_a_calibration_is_refused(tmp_path: Path, capsys) -> None:
    assert main(["diagnose", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    error = capsys.readouterr().err
    assert "RESULT_DIR" in error and "result.json" in error and "Traceback" not in error


def test_a_budget_below_two_is_refused(tmp_path: Path, capsys) -> None:
    folder = _result_dir(tmp_path, {})
    assert main(["diagnose", str(folder), "--out", str(tmp_path / "o"), "--budget", "1"]) == 2
    assert "argument --budget: '1' is not allowed" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_budget_with_the_linear_simulator_is_refused_not_ignored(tmp_path: Path, capsys) -> None:
    folder = _result_dir(tmp_path, {})
    arguments = ["diagnose", str(folder), "--out", str(tmp_path / "o")]
    assert main([*arguments, "--simulator", "linear", "--budget", "30"]) == 2
    error = capsys.readouterr().err
    assert "--budget: got 30 with --simulator linear" in error and "Traceback" not in error
    assert not (tmp_path / "o").exists()


def test_a_result_that_is_not_json_is_refused(tmp_path: Path, capsys) -> None:
    folder = _result_dir(tmp_path, "{not json")
    assert main(["diagnose", str(folder), "--out", str(tmp_path / "o")]) == 2
    assert "result.json is not readable JSON" in capsys.readouterr().err


def test_not_trusted_is_answered_at_once_with_exit_code_0(tmp_path: Path, capsys) -> None:
    reason = {"code": "not_converged", "message": "EGO stopped on the budget"}
    folder = _result_dir(tmp_path, {"n_evaluations": 30, "reliability": {
        "verdict": "not_trusted", "reasons": [reason], "sentence": "no"}})  # fmt: skip
    assert main(["diagnose", str(folder), "--out", str(tmp_path / "o")]) == 0
    error = capsys.readouterr().err
    assert "calibration_not_trusted" in error and "EGO stopped on the budget" in error
    assert "--resume --budget 60" in error
    document = json.loads((tmp_path / "o" / "discrepancy.json").read_text())
    assert document["verdict"] == "calibration_not_trusted"
    assert document["flagged"] == [] and document["named_effect"] is None
    assert document["calibration_reliability"]["reasons"] == [reason]


@pytest.mark.parametrize("verdict", ["not_trusted", "Trusted", None])
def test_only_the_exact_trusted_verdict_counts(tmp_path: Path, verdict, capsys) -> None:
    folder = _result_dir(tmp_path, {"reliability": {"verdict": verdict}})
    assert main(["diagnose", str(folder), "--out", str(tmp_path / "o")]) == 0
    document = json.loads((tmp_path / "o" / "discrepancy.json").read_text())
    assert document["verdict"] == "calibration_not_trusted"


def test_a_trusted_result_without_its_store_names_the_store_not_a_resume(
    tmp_path: Path, capsys
) -> None:
    """Outside probe, session 29: diagnose said "--resume: … nothing to resume … run
    without --resume", calibrate's wording for a flag diagnose does not have."""
    folder = _result_dir(tmp_path, {"reliability": {"verdict": "trusted", "reasons": []}})
    assert main(["diagnose", str(folder), "--out", str(tmp_path / "o")]) == 2
    error = capsys.readouterr().err
    assert f"RESULT_DIR: {folder / 'evaluations.sqlite'} does not exist" in error
    assert "--resume" not in error and "Traceback" not in error
    assert not (tmp_path / "o").exists()


def test_an_empty_result_dir_is_refused_as_empty(tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(_result_dir(tmp_path, {}))  # "" must not mean the current folder
    assert main(["diagnose", "", "--out", str(tmp_path / "o")]) == 2
    error = capsys.readouterr().err
    assert "RESULT_DIR: '' is not allowed" in error and "empty" in error
    assert not (tmp_path / "o").exists()


def test_a_study_file_that_is_not_toml_is_refused_even_when_not_trusted(
    tmp_path: Path, capsys
) -> None:
    """The not-trusted answer recommends `calibrate RESULT_DIR/study.toml --resume`: with a
    damaged study file that cannot run, so the file is named instead (exit code 2)."""
    folder = _result_dir(tmp_path, {"n_evaluations": 30, "reliability": {
        "verdict": "not_trusted", "reasons": [], "sentence": "no"}})  # fmt: skip
    study = folder / "study.toml"
    study.write_text('rig = = "hst_trailer"\n')
    assert main(["diagnose", str(folder), "--out", str(tmp_path / "o")]) == 2
    error = capsys.readouterr().err
    assert f"RESULT_DIR: {study}: not valid TOML" in error and "Traceback" not in error
    assert "--resume" not in error
    assert not (tmp_path / "o").exists()


def test_the_augmented_result_json_has_calibrates_layout() -> None:
    """DIR/augmented/result.json was written by hand: posterior summary keys (mean, sd,
    r_hat) where calibrate writes posterior_mean/posterior_sd/mcmc, bounds as (2 x q) rows
    where calibrate writes (q x 2) pairs, and no units."""
    from types import SimpleNamespace

    from susp_bo.calibration.loop import calibrate
    from susp_bo.calibration.settings import CalibrationSettings
    from susp_bo.calibration.test_functions import TARGETS
    from susp_bo.commands.diagnose import augmented_result_payload

    target = TARGETS["banana_2d"]()
    settings = CalibrationSettings(
        seed=0, max_evaluations=14, batch_size=2, mcmc_chains=4, mcmc_warmup=50,
        mcmc_samples=50, candidate_count=32, check_points=0,
    )  # fmt: skip
    result = calibrate(target, target.bounds, target.names, settings, progress=False)
    units = {target.names[0]: "N/m", target.names[1]: "Hz"}
    spec = SimpleNamespace(
        name="augmented_rig",
        calibration=[SimpleNamespace(name=n, unit=u) for n, u in units.items()],
    )
    study = SimpleNamespace(
        config=SimpleNamespace(data=Path("runs"), seeds=SimpleNamespace(calibration=3)),
        runs=(1, 2, 3),
    )
    start, base_w = np.array([0.1, 0.2]), np.array([0.3])
    payload = json.loads(
        json.dumps(json_ready(augmented_result_payload(result, spec, start, base_w, study)))
    )
    calibration = json.loads(json.dumps(json_ready(result.to_dict())))
    assert {k: payload[k] for k in calibration} == calibration  # calibrate's keys and layout
    assert payload["units"] == ["N/m", "Hz"] and payload["rig"] == "augmented_rig"
    assert payload["bounds"] == [[float(lo), float(hi)] for lo, hi in target.bounds.T]
    assert "posterior_mean" in payload and "mean" not in payload and "r_hat" not in payload
    assert payload["warm_start"]["ranking_refit"] == [0.1, 0.2]
    assert payload["warm_start"]["base_map"] == [0.3]
    assert payload["nu"] == 3 and payload["seed"] == 3 and payload["data"] == "runs"


def test_a_named_effect_whose_recalibration_still_lacks_fit_does_not_explain_all() -> None:
    """The sentence after a named effect whose augmented model is not trusted: refused by
    the lack of fit alone (a real reason from the rule), it says the effect does not
    explain all of the disagreement and asks for no budget; any other refusal asks for
    more budget; a trusted recalibration, an unexplained verdict, the base model's answer
    or a forced run add nothing."""
    from susp_bo.calibration.lack_of_fit import systematic_misfit
    from susp_bo.commands.diagnose import augmented_model_note

    misfit = systematic_misfit(5.2, 3)
    assert misfit is not None
    lacking = {"verdict": "not_trusted", "reasons": [misfit]}
    note = augmented_model_note("named", "augmented", lacking, fit_finished=True)
    assert "the named effect does not explain all of the disagreement" in note
    assert "lack of fit F = 5.2" in note and "--budget" not in note
    from susp_bo.calibration.track_match import runs_not_reproduced

    unmatched = runs_not_reproduced(0.6)  # session 32: the unpaired B's misfit reason
    assert unmatched is not None
    note = augmented_model_note(
        "named", "augmented", {"verdict": "not_trusted", "reasons": [unmatched]}, fit_finished=True
    )
    assert "(runs_not_reproduced: the simulation leaves residuals" in note
    assert "does not explain all" in note and "--budget" not in note
    unconverged = {"verdict": "not_trusted", "reasons": [{"code": "not_converged"}, misfit]}
    other = augmented_model_note("named", "augmented", unconverged, fit_finished=True)
    assert "(not_converged, below_expected_fit)" in other and "larger --budget" in other
    assert "does not explain all" not in other
    for args in (
        ("named", "augmented", {"verdict": "trusted", "reasons": []}, True),
        ("unexplained", "augmented", lacking, True),
        ("named", "base", lacking, True),
        ("named", "augmented", lacking, False),
        ("named", "augmented", None, True),
    ):
        assert augmented_model_note(*args[:3], fit_finished=args[3]) == ""
