"""``susp-bo synth``: measured-format runs with the truth recorded; bad input refused early."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from susp_bo.cli import main
from susp_bo.commands.synth import parse_effect
from susp_bo.data.measured import load_runs
from susp_bo.rig.spec import load_rig_spec


def test_synth_writes_runs_that_load_with_the_truth(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = tmp_path / "truth.toml"
    truth.write_text("[parameters]\nyaw_damper_damping = 3.0e6\n")
    out = tmp_path / "data"
    code = main(
        [
            "synth",
            "hst_trailer",
            "--out",
            str(out),
            "--truth",
            str(truth),
            "--nu",
            "2",
            "--seed",
            "5",
            "--noise",
            "0.01",
            "--speed",
            "60",
        ]
    )
    assert code == 0, capsys.readouterr().err
    runs = load_runs(out)
    spec = load_rig_spec("hst_trailer")
    assert len(runs) == 2
    assert runs[0].channels == spec.channels
    assert runs[0].metadata["truth"]["yaw_damper_damping"] == 3.0e6
    assert runs[0].metadata["noise_m_s2"] == 0.01
    assert np.allclose(runs[0].speed.speed_m_s, 60.0)
    # independent track stretches: different signals
    assert not np.allclose(runs[0].accelerations_m_s2, runs[1].accelerations_m_s2)
    summary = json.loads((out / "truth.json").read_text())
    assert summary["truth"]["yaw_damper_damping"] == 3.0e6


def test_same_seed_same_runs(tmp_path: Path) -> None:
    for name in ("a", "b"):
        assert (
            main(
                ["synth", "hst_trailer", "--out", str(tmp_path / name), "--nu", "1", "--seed", "9"]
            )
            == 0
        )
    a, b = load_runs(tmp_path / "a")[0], load_runs(tmp_path / "b")[0]
    assert np.array_equal(a.accelerations_m_s2, b.accelerations_m_s2)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--nu", "0"], "--nu"),
        (["--noise", "-1"], "--noise"),
        (["--speed", "0"], "--speed"),
    ],
)
def test_bad_input_is_refused_before_simulating(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], message: str
) -> None:
    assert main(["synth", "hst_trailer", "--out", str(tmp_path / "d"), *arguments]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_effect_text_is_parsed() -> None:
    assert parse_effect("carbody_bending:frequency_hz=9,damping_ratio=0.02") == (
        "carbody_bending",
        {"frequency_hz": 9.0, "damping_ratio": 0.02},
    )
    assert parse_effect("bump_stop") == ("bump_stop", {})
