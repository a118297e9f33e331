"""`susp-bo diagnose` end to end (synth → calibrate → diagnose, PyBullet): one test per verdict,
each on the calibration's **real** reliability verdict.

- ``calibration_not_trusted``: the small study of the ``uninterrupted`` fixture (q = 2,
  10 evaluations, below the minimum budget on purpose), whose own verdict is
  ``not_trusted`` (``budget_too_small``).
- ``consistent``, ``named``, ``unexplained_disagreement``: a q = 1 study (secondary
  vertical damping) with the paired output-error model and the local phase, 40
  evaluations, on 8 s records. On data with nothing missing its real verdict is
  ``trusted``; on data with a hidden effect or a mis-mounted sensor it is ``not_trusted``
  with the single reason ``below_expected_fit`` (the loop finished, but the fit is far
  below what B expects at the truth), which the gate lets through as a finished fit.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import tomli_w

from susp_bo.data.measured import load_run, save_run
from susp_bo.discrepancy.out_of_library import get_modification
from susp_bo.discrepancy.verdict import VERDICTS
from susp_bo.rig.line_file import design_from_segments

FIELDS = ("verdict", "flagged", "ranking", "named_effect", "gap_before", "gap_after")
TRUTH = {"secondary_vertical_damping": 30.0e3}


def _cli(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "susp_bo", *arguments],
        capture_output=True,
        text=True,
        check=False,
        timeout=900,
    )


def _diagnose(result_dir: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return _cli("diagnose", str(result_dir), "--out", str(out), *extra)


def _set_reliability(result_dir: Path, reliability: dict | None) -> None:
    path = result_dir / "result.json"
    payload = json.loads(path.read_text())
    payload.pop("reliability", None)
    if reliability is not None:
        payload["reliability"] = reliability
    path.write_text(json.dumps(payload))


def _copy(result_dir: Path, tmp_path: Path) -> Path:
    """A private copy of a shared results folder (diagnose reads it; tests edit result.json)."""
    target = tmp_path / "result"
    shutil.copytree(result_dir, target)
    return target


def _synth(tmp_path: Path, rig: Path, *synth: str) -> Path:
    """``susp-bo synth RIG --out DIR ...``: two runs of the fast rig; the data folder."""
    truth = tmp_path / "truth.toml"
    truth.write_text(tomli_w.dumps(TRUTH))
    data = tmp_path / "measured"
    done = _cli("synth", str(rig), "--out", str(data), "--truth", str(truth), "--nu", "2",
                "--seed", "3", "--noise", "0.005", *synth)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return data


def _calibrate(tmp_path: Path, rig: Path, data: Path) -> tuple[Path, dict]:
    """``susp-bo calibrate`` of the q = 1 paired study (module docstring); the results folder
    and its real reliability verdict."""
    config = tmp_path / "study.toml"
    config.write_text(
        tomli_w.dumps(
            {
                "rig": str(rig),
                "data": str(data),
                "out": str(tmp_path / "study"),
                "parameters": list(TRUTH),
                "budget": {"max_evaluations": 40, "initial_design": 8, "batch_size": 2,
                           "check_points": 4},
                "executor": {"workers": 0},
                "mcmc": {"chains": 16, "draws": 500, "warmup": 300},
                "output_error": {"model": "paired"},
                "search": {"local": True},
            }
        )
    )  # fmt: skip
    calibrated = _cli("calibrate", str(config))
    assert calibrated.returncode == 0, calibrated.stderr[-3000:]
    result = tmp_path / "study"
    return result, json.loads((result / "result.json").read_text())["reliability"]


def _finished_below_expected(reliability: dict) -> None:
    """The real verdict of a fit that finished and misses the data: only below_expected_fit."""
    assert reliability["verdict"] == "not_trusted", reliability["sentence"]
    assert [r["code"] for r in reliability["reasons"]] == ["below_expected_fit"]


# ---------------------------------------------------------------- calibration_not_trusted


@pytest.mark.parametrize("reliability", [None, "not_trusted"])
def test_a_calibration_not_trusted_is_an_answer_with_no_bands(
    uninterrupted: Path, tmp_path: Path, reliability: str | None
) -> None:
    result = _copy(uninterrupted, tmp_path)
    reason = {"code": "budget_too_small", "message": "10 evaluations for q = 2 (need 40)"}
    block = {"verdict": "not_trusted", "reasons": [reason], "sentence": "not trusted"}
    _set_reliability(result, None if reliability is None else block)
    done = _diagnose(result, tmp_path / "diagnosis")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    for field in FIELDS:
        assert field in report, field
    assert report["verdict"] == "calibration_not_trusted"
    assert report["flagged"] == [] and report["named_effect"] is None and report["ranking"] == []
    assert report["residual_bands_untrusted_fit"] is None and report["forced"] is False
    assert "calibration_not_trusted" in done.stderr and "--resume --budget 20" in done.stderr
    expected = "no reliability verdict" if reliability is None else "10 evaluations for q = 2"
    assert expected in done.stderr and expected in report["sentence"]
    assert "Traceback" not in done.stderr


@pytest.mark.slow
def test_force_runs_the_workflow_but_the_answer_stays_not_trusted(
    uninterrupted: Path, tmp_path: Path
) -> None:
    result = _copy(uninterrupted, tmp_path)
    _set_reliability(result, None)
    done = _diagnose(result, tmp_path / "diagnosis", "--force")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    assert report["verdict"] == "calibration_not_trusted" and report["forced"] is True
    assert report["flagged"] == [] and report["named_effect"] is None
    forced = report["forced_diagnosis"]
    assert forced["verdict"] in VERDICTS[:3]
    assert report["residual_bands_untrusted_fit"] == forced["flagged"]
    assert "FORCED" in done.stderr


@pytest.mark.parametrize(
    "broken", [{"foo": 1}, {"joint_map": [-1.0e9, 1.0e30]}], ids=["no_joint_map", "outside_C_w"]
)
def test_force_on_a_result_without_a_usable_joint_map_is_refused(
    uninterrupted: Path, tmp_path: Path, broken: dict
) -> None:
    """--force runs the workflow from the result's joint MAP: a missing one was a KeyError
    traceback, one outside C_w a confident "named" verdict on nothing."""
    result = _copy(uninterrupted, tmp_path)
    payload = json.loads((result / "result.json").read_text())
    payload.pop("joint_map")
    (result / "result.json").write_text(json.dumps({**payload, **broken}))
    done = _diagnose(result, tmp_path / "diagnosis", "--force", "--simulator", "linear")
    assert done.returncode == 2, done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    assert "result.json: joint_map = " in done.stderr and "is not allowed" in done.stderr
    assert not (tmp_path / "diagnosis").exists()


# ---------------------------------------------------------------- consistent


@pytest.mark.slow
def test_diagnose_names_nothing_when_nothing_is_missing(fast_rig: Path, tmp_path: Path):
    data = _synth(tmp_path, fast_rig)
    result, reliability = _calibrate(tmp_path, fast_rig, data)
    assert reliability["verdict"] == "trusted", reliability["sentence"]  # the real verdict
    done = _diagnose(result, tmp_path / "diagnosis")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    for field in FIELDS:
        assert field in report, field
    assert report["verdict"] == "consistent"
    assert report["named_effect"] is None
    assert report["flagged"] == []
    assert report["calibration_reliability"]["trusted"] is True
    assert "consistent" in done.stderr
    assert list((tmp_path / "diagnosis").glob("*.png"))


# ---------------------------------------------------------------- named


@pytest.mark.slow
def test_diagnose_names_a_hidden_carbody_bending_mode_and_the_model_gets_better(
    fast_rig: Path, tmp_path: Path
) -> None:
    data = _synth(tmp_path, fast_rig, "--effect", "carbody_bending:frequency_hz=9.0")
    result, reliability = _calibrate(tmp_path, fast_rig, data)
    _finished_below_expected(reliability)  # the base model cannot reproduce the data
    # q = 3 in the recalibration (damper + the mode's frequency and damping): 60 evaluations
    done = _diagnose(result, tmp_path / "diagnosis", "--budget", "60")
    assert done.returncode == 0, done.stderr[-3000:]
    assert "below_expected_fit" in done.stderr
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    assert report["verdict"] == "named"
    assert report["named_effect"] == "carbody_bending"
    assert report["calibration_reliability"]["fit_finished"] is True
    assert report["ranking"][0]["effect"] == "carbody_bending"
    assert any("vertical" in band["channel"] for band in report["flagged"])
    # accepted only if better over all bins; the gap reported on the flagged bins and on all
    augmented = report["augmented"]
    assert augmented["accepted"] and report["answer_model"] == "augmented"
    assert augmented["log_predictive_density_after"] > augmented["log_predictive_density_before"]
    assert augmented["flagged_fraction_after"] < augmented["flagged_fraction_before"]
    assert report["gap_after"]["value"] <= 0.5 * report["gap_before"]["value"]
    assert report["gap_after"]["value_all_bins"] < report["gap_before"]["value_all_bins"]
    # the augmented model reproduces the data as B expects: its own real verdict is trusted,
    # and it recovers the hidden mode's frequency and the damper
    assert report["augmented_reliability"]["verdict"] == "trusted", report["augmented_reliability"][
        "sentence"
    ]
    # and the lack of fit between the runs weighed in it (session 27: before, only a study's
    # own calibration applied that rule): the augmented model leaves none
    assert 0.0 < report["augmented_reliability"]["evidence"]["lack_of_fit_ratio"] < 3.0
    recalibrated = json.loads((tmp_path / "diagnosis" / "augmented" / "result.json").read_text())
    names = recalibrated["parameters"]
    lo, hi = recalibrated["interval95"][names.index("carbody_bending_frequency_hz")]
    assert lo <= 9.0 <= hi and hi - lo < 0.1
    lo, hi = recalibrated["interval95"][names.index("secondary_vertical_damping")]
    assert lo <= TRUTH["secondary_vertical_damping"] <= hi
    assert "named: carbody_bending" in done.stderr
    assert "NOT trusted" not in report["sentence"]
    # a recalibration too small to be trusted: the effect is named, its values are no answer
    small = _diagnose(result, tmp_path / "small", "--budget", "4")
    assert small.returncode == 0, small.stderr[-3000:]
    report = json.loads((tmp_path / "small" / "discrepancy.json").read_text())
    assert report["verdict"] == "named" and report["answer_model"] == "augmented"
    assert report["augmented_reliability"]["verdict"] == "not_trusted"
    assert "The augmented model's calibration is NOT trusted (" in report["sentence"]
    assert "NOT trusted" in small.stderr


# ---------------------------------------------------------------- unexplained_disagreement


@pytest.mark.slow
def test_out_of_library_physics_is_flagged_and_not_named(fast_rig: Path, tmp_path: Path) -> None:
    """The front bogie lateral accelerometer mounted rolled by 20° (it reads vertical motion
    too): the records change, not the vehicle, and no library effect represents it."""
    data = _synth(tmp_path, fast_rig)
    change = get_modification("sensor_rolled")
    for path in sorted(data.glob("run_*.h5")):
        save_run(change.apply_run(load_run(path)), path)
    result, reliability = _calibrate(tmp_path, fast_rig, data)
    _finished_below_expected(reliability)
    done = _diagnose(result, tmp_path / "diagnosis", "--budget", "40")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    assert report["flagged"], "the rolled sensor must be flagged"
    assert any(band["channel"] == "bogie_front_lateral" for band in report["flagged"])
    assert report["verdict"] == "unexplained_disagreement"
    assert report["named_effect"] is None and report["augmented"] is None
    assert "no library effect explains" in done.stderr
    band = report["flagged"][0]
    assert band["channel"].split("_")[0] in report["sentence"]
    assert not (tmp_path / "diagnosis" / "augmented").exists()


def test_a_mis_mounted_sensor_changes_only_its_channel(fast_data: Path, tmp_path: Path) -> None:
    """The sensor modifications act on the records themselves (no library, no rig change)."""
    change = get_modification("sensor_rolled")
    run = load_run(sorted(fast_data.glob("*.h5"))[0])
    changed = change.apply_run(run)
    save_run(changed, tmp_path / "run.h5")
    again = load_run(tmp_path / "run.h5")
    index = run.channels.index("bogie_front_lateral")
    for c in range(len(run.channels)):
        same = (again.accelerations_m_s2[c] == run.accelerations_m_s2[c]).all()
        assert same == (c != index)
    assert again.metadata["out_of_library"] == "sensor_rolled"


# ---------------------------------------------------------------- refused before any work


def _own_data(result: Path, tmp_path: Path) -> Path:
    """The study of ``result`` pointed at a private copy of its data folder; the copy."""
    study = result / "study.toml"
    config = tomllib.loads(study.read_text())
    data = tmp_path / "data"
    shutil.copytree(config["data"], data)
    study.write_text(tomli_w.dumps({**config, "data": str(data)}))
    return data


def test_a_calibration_of_other_data_is_not_diagnosed(uninterrupted: Path, tmp_path: Path):
    """Runs replaced since the calibration: the disagreement with them was diagnosed as a
    model discrepancy ("look for physics outside the library") instead of refused."""
    result = _copy(uninterrupted, tmp_path)
    data = _own_data(result, tmp_path)
    first = sorted(data.glob("*.h5"))[0]
    run = load_run(first)
    save_run(dataclasses.replace(run, accelerations_m_s2=1.5 * run.accelerations_m_s2), first)
    done = _diagnose(result, tmp_path / "diagnosis", "--force", "--simulator", "linear")
    assert done.returncode == 2, done.stderr[-3000:]
    assert "was computed on other measured runs" in done.stderr
    assert "not a model discrepancy" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "diagnosis").exists()


def test_runs_on_a_curved_line_are_refused_not_a_traceback(uninterrupted: Path, tmp_path: Path):
    """The ranking's linearised rig raised LinearModelNotApplicable (exit 1) after the
    PyBullet checks, leaving an empty --out."""
    result = _copy(uninterrupted, tmp_path)
    data = _own_data(result, tmp_path)
    for path in sorted(data.glob("*.h5")):
        run = load_run(path)
        curve = design_from_segments(
            [{"type": "curve", "length_m": run.geometry.length_m + 1.0, "radius_m": 7000.0,
              "cant_mm": 150.0, "direction": "left"}]
        )  # fmt: skip
        save_run(dataclasses.replace(run, design=curve), path)
    done = _diagnose(result, tmp_path / "diagnosis", "--force")
    assert done.returncode == 2, done.stderr[-3000:]
    assert "follows a track design with curves, cant or gradient" in done.stderr
    assert "at a steady speed only (nothing was computed)" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "diagnosis").exists()


def test_a_second_diagnosis_into_the_same_folder_is_refused(uninterrupted: Path, tmp_path: Path):
    """It replaced the first one's recalibration store and result without a word."""
    result = _copy(uninterrupted, tmp_path)
    out = tmp_path / "diagnosis"
    assert _diagnose(result, out).returncode == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    done = _diagnose(result, out)
    assert done.returncode == 2 and "already holds a diagnosis (discrepancy.json)" in done.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
