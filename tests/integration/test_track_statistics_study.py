"""A study on tracks known only by their statistics (``model = "track_statistics"``), end to
end on PyBullet: the pilot runs through the store, a study killed inside its pilot resumes to
the uninterrupted result, and what the pilot gives is what ``result.json`` says."""

from __future__ import annotations

import dataclasses
import json
import math
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.integration.conftest import calibrate_killed, stored_rows

pytestmark = pytest.mark.slow

PILOT = """
[output_error]
model = "track_statistics"
pilot_runs = 50
"""


def _keys(store: Path) -> list[tuple[str, str]]:
    """(track id, status) of every stored evaluation; [] while the store is being made."""
    return stored_rows(store, "track_id, status")


def _stable(out: Path) -> dict:
    payload = json.loads((out / "result.json").read_text())
    payload.pop("wall_time_s")
    return payload


@pytest.fixture(scope="module")
def statistics_study(fast_rig, fast_data, study_writer, calibrate_command, tmp_path_factory):
    """The small study (q = 2, 10 evaluations) with the summary likelihood, run once."""
    folder = tmp_path_factory.mktemp("statistics")
    config = study_writer(folder, fast_rig, fast_data, folder / "out")
    config.write_text(config.read_text() + PILOT)
    done = calibrate_command(config)
    assert done.returncode == 0, done.stderr[-3000:]
    return folder / "out", done.stderr


def test_the_pilot_runs_through_the_store_and_result_json_records_it(statistics_study) -> None:
    out, stderr = statistics_study
    payload = json.loads((out / "result.json").read_text())
    error = payload["output_error"]
    assert error["model"] == "track_statistics"
    assert (error["pilot_runs"], error["simulated_tracks"], payload["mu"]) == (50, 2, 2)
    keys = _keys(out / "evaluations.sqlite")
    assert all(status == "ok" for _, status in keys)
    pilot = [k for k, _ in keys if k.startswith("pilot")]
    assert sorted({k.split("-")[0] for k in pilot}) == ["pilot0", "pilot1"]
    assert len(pilot) == len(set(pilot)) == 100  # 2 stages x M fresh realizations
    model = {k for k, _ in keys if not k.startswith("pilot")}
    assert model == {"model000-seed0", "model001-seed0"}  # never the runs' own tracks
    # the pilot's distinct runs (its 100 and its Gauss–Newton and Jacobian points on the
    # μ = 2 model tracks) and the loop's 10 evaluations on them are the whole store
    assert error["pilot_simulations"] + 2 * payload["n_evaluations"] == len(keys)
    assert payload["n_simulations"] == len(keys)
    assert error["pilot_simulations"] > 100 + 2 * 2 * 2 * 2  # + 2 Jacobians' 2 q points x μ
    lower, upper = np.array(payload["bounds"]).T
    point = np.array(list(error["pilot_point"].values()))
    assert np.all((lower <= point) & (point <= upper))
    # the loop evaluated the pilot's fit (its design holds it), on the model tracks: the
    # pilot itself simulates there only Gauss–Newton points and central differences
    rows = stored_rows(out / "evaluations.sqlite", "track_id, parameters_json")
    model_points = [json.loads(p) for t, p in rows if t.startswith("model")]
    assert point.tolist() in model_points  # the q calibrated values, in their order
    # the verdict's expectation of log L at the truth is the model's, from C in result.json
    covariance = np.array(error["summary_covariance"])
    kappa = 1 / payload["nu"] + 1 / payload["mu"]
    expected = -0.5 * (2 + math.log(np.linalg.det(2 * math.pi * kappa * covariance)))
    mean, sd = payload["reliability"]["evidence"]["expected_at_truth"]
    assert mean == pytest.approx(expected, rel=1e-9) and sd == pytest.approx(1.0)
    assert payload["reliability"]["verdict"] == "not_trusted"
    assert "budget_too_small" in {r["code"] for r in payload["reliability"]["reasons"]}
    # the goodness-of-fit test of the summaries the fit does not use ran at the best point:
    # M = 50 allows k <= 24, so two band groups of the fast rig's 10 channels
    evidence = payload["reliability"]["evidence"]
    assert error["misfit_summaries"] == evidence["summary_misfit_dof"] == 20
    assert 0.0 <= evidence["summary_misfit_p"] <= 1.0 and evidence["summary_misfit_t2"] > 0
    worst = evidence["summary_misfit_worst"]["summary"]  # named by the rig's channels
    assert worst.split(" ")[0] in error["channels"] and worst.endswith(" Hz")
    assert "pilot of 2 x 50 runs" in stderr and "pilot done:" in stderr


def test_a_study_killed_inside_its_pilot_resumes_to_the_uninterrupted_result(
    statistics_study, fast_rig, fast_data, study_writer, calibrate_command, tmp_path: Path
) -> None:
    reference, _ = statistics_study
    out = tmp_path / "out"
    config = study_writer(tmp_path, fast_rig, fast_data, out)
    config.write_text(config.read_text() + PILOT)
    store = out / "evaluations.sqlite"
    # stage 1's 50 pilot runs come first: kill among them
    assert calibrate_killed(config, store, rows=10) == -signal.SIGKILL
    before = _keys(store)
    assert 10 <= len(before) < 50 and all(k.startswith("pilot0-") for k, _ in before)
    resumed = calibrate_command(config, "--resume")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert _stable(out) == _stable(reference)
    assert sorted(_keys(store)) == sorted(_keys(reference / "evaluations.sqlite"))


def test_a_pilot_too_small_for_q_is_refused_before_any_simulation(
    fast_rig, fast_data, study_writer, calibrate_command, tmp_path: Path
) -> None:
    config = study_writer(tmp_path, fast_rig, fast_data, tmp_path / "out")
    text = config.read_text().replace(
        'parameters = ["secondary_vertical_damping", "yaw_damper_damping"]',
        'parameters = ["secondary_vertical_damping", "yaw_damper_damping", '
        '"primary_vertical_damping", "secondary_lateral_damping", "anti_roll_bar_stiffness", '
        '"primary_vertical_stiffness"]',
    )
    config.write_text(text + PILOT)
    refused = calibrate_command(config)
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "output_error.pilot_runs: 50 is not allowed for q = 6" in refused.stderr
    assert "at least 60" in refused.stderr
    assert "Traceback" not in refused.stderr
    assert not (tmp_path / "out" / "evaluations.sqlite").exists()
    config.write_text(text + PILOT.replace("pilot_runs = 50", "pilot_runs = 20"))
    refused = calibrate_command(config)
    assert refused.returncode == 2
    assert "output_error.pilot_runs: 20 is not allowed; expected an integer >= 50" in (
        refused.stderr
    )


def test_diagnose_refuses_a_study_without_the_runs_own_tracks(
    statistics_study, tmp_path: Path
) -> None:
    out, _ = statistics_study
    refused = subprocess.run(
        [sys.executable, "-m", "susp_bo", "diagnose", str(out), "--out", str(tmp_path / "d"),
         "--force"],
        capture_output=True, text=True, check=False, timeout=300,
    )  # fmt: skip
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert "model = 'track_statistics'" in refused.stderr
    assert "summary_misfit_worst" in refused.stderr  # where to look instead
    assert "Traceback" not in refused.stderr
    assert not (tmp_path / "d").exists()


def test_the_store_fingerprint_covers_the_runs_and_unknown_noise_is_refused(
    fast_rig, fast_data: Path, tmp_path: Path
) -> None:
    """The tracks are synthetic, so the runs themselves must identify the store (a resume
    on other runs is refused); the pilot draws the sensor noise, so it must be known."""
    from susp_bo.calibration.study_inputs import StudyError
    from susp_bo.calibration.study_preparation import prepare_study, store_fingerprint
    from susp_bo.data.run_files import load_run, save_run
    from susp_bo.study_config import OutputErrorConfig, StudyConfig
    from tests.integration.conftest import FAST_PARAMETERS

    def config(data: Path, **error: object) -> StudyConfig:
        return StudyConfig(
            rig=str(fast_rig),
            data=data,
            out=tmp_path / "out",
            parameters=FAST_PARAMETERS,
            output_error=OutputErrorConfig(model="track_statistics", **error),
        )

    files = sorted(fast_data.glob("run_*.h5"))
    edited = tmp_path / "edited"
    edited.mkdir()
    for index, file in enumerate(files):
        run = load_run(file)
        if index == 1:  # the same experiment, other accelerations
            run = dataclasses.replace(run, accelerations_m_s2=run.accelerations_m_s2 * 1.01)
        save_run(run, edited / file.name)
    before = store_fingerprint(prepare_study(config(fast_data)))
    after = store_fingerprint(prepare_study(config(edited)))
    assert before != after
    assert {k for k in before if before[k] != after[k]} == {"data"}
    silent = tmp_path / "silent"
    silent.mkdir()
    for file in files:
        run = load_run(file)
        metadata = {k: v for k, v in run.metadata.items() if k != "noise_m_s2"}
        save_run(dataclasses.replace(run, metadata=metadata), silent / file.name)
    with pytest.raises(StudyError, match="sensor_noise_m_s2: not given"):
        prepare_study(config(silent))
    assert prepare_study(config(silent, sensor_noise_m_s2=0.005)).noise_m_s2 == 0.005
