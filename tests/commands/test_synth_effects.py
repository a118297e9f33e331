"""``susp-bo synth --effect``: hidden effects in the generator; bad effects refused."""

from __future__ import annotations

import json
from pathlib import Path

from susp_bo.cli import main
from susp_bo.data.measured import load_run


def test_synth_writes_runs_with_a_hidden_effect(tmp_path: Path, capsys) -> None:
    out = tmp_path / "data"
    code = main(
        ["synth", "hst_trailer", "--out", str(out), "--nu", "1", "--seed", "3",
         "--effect", "carbody_bending:frequency_hz=9.5,damping_ratio=0.03"]
    )  # fmt: skip
    assert code == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["effects"][0]["name"] == "carbody_bending"
    assert truth["effects"][0]["values"]["frequency_hz"] == 9.5
    run = load_run(out / "run_000.h5")
    assert run.metadata["effects"] == ["carbody_bending"]


def test_synth_refuses_unknown_effects_and_values_out_of_range(tmp_path: Path, capsys) -> None:
    assert main(["synth", "hst_trailer", "--out", str(tmp_path / "a"), "--effect", "warp"]) == 2
    assert "not in the library" in capsys.readouterr().err
    bad = ["--effect", "carbody_bending:frequency_hz=30"]
    assert main(["synth", "hst_trailer", "--out", str(tmp_path / "b"), *bad]) == 2
    assert "outside the admissible range" in capsys.readouterr().err
    assert not (tmp_path / "b" / "run_000.h5").exists()


def test_diagnose_refuses_a_folder_without_a_calibration(tmp_path: Path, capsys) -> None:
    assert main(["diagnose", str(tmp_path), "--out", str(tmp_path / "d")]) == 2
    assert "no finished calibration" in capsys.readouterr().err
