"""`susp-bo diagnose` end to end on PyBullet studies: silent when clean, names a hidden effect."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from susp_bo.data.measured import save_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.discrepancy.effects import with_effect
from susp_bo.rig.spec import load_rig_spec

pytestmark = pytest.mark.slow

FIELDS = ("flagged", "ranking", "named_effect", "gap_before", "gap_after")


def _diagnose(result_dir: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "susp_bo", "diagnose", str(result_dir), "--out", str(out), *extra],
        capture_output=True,
        text=True,
        check=False,
        timeout=900,
    )


def test_diagnose_names_nothing_when_nothing_is_missing(uninterrupted: Path, tmp_path: Path):
    done = _diagnose(uninterrupted, tmp_path / "diagnosis")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    for field in FIELDS:
        assert field in report, field
    assert report["named_effect"] is None
    assert report["flagged"] == []
    assert list((tmp_path / "diagnosis").glob("*.png"))


def test_diagnose_names_a_hidden_carbody_bending_mode_and_the_gap_shrinks(
    fast_rig: Path, study_writer, calibrate_command, tmp_path: Path
) -> None:
    hidden = with_effect(load_rig_spec(fast_rig), "carbody_bending", {"frequency_hz": 9.0})
    data = tmp_path / "measured"
    data.mkdir()
    runs = synthesize_runs(
        hidden, {"secondary_vertical_damping": 30.0e3}, nu=2, seed=3, noise_m_s2=0.005
    )
    for index, run in enumerate(runs):
        save_run(run, data / f"run_{index:03d}.h5")
    config = study_writer(tmp_path, fast_rig, data, tmp_path / "study")
    calibrated = calibrate_command(config)
    assert calibrated.returncode == 0, calibrated.stderr[-3000:]

    done = _diagnose(tmp_path / "study", tmp_path / "diagnosis", "--budget", "10")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "diagnosis" / "discrepancy.json").read_text())
    assert report["named_effect"] == "carbody_bending"
    assert report["ranking"][0]["effect"] == "carbody_bending"
    assert any("vertical" in band["channel"] for band in report["flagged"])
    assert report["gap_after"]["value"] <= 0.5 * report["gap_before"]["value"]
