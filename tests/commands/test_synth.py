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
        # session 29's probe: no upper limit, and 100 000 runs started
        (["--nu", "100000"], "--nu: got 100000; expected an integer in 1 … 1000"),
        (["--noise", "1e9"], "--noise: got 1e+09; expected 0 … 100 m/s^2"),
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


def test_an_out_holding_a_data_set_is_refused_before_simulating(
    fast_rig: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "data"
    assert main(["synth", str(fast_rig), "--out", str(out), "--nu", "2", "--seed", "1"]) == 0
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    capsys.readouterr()
    assert main(["synth", str(fast_rig), "--out", str(out), "--nu", "1"]) == 2
    err = capsys.readouterr().err
    assert f"--out: {out} already holds a data set (run_000.h5, run_001.h5, truth.json)" in err
    assert "choose another folder" in err and "runs of" not in err  # refused before simulating
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before


def _unusable_outs(tmp_path: Path) -> list[str]:
    """An empty path, a name too long for the file system, and (on Linux) a folder that
    cannot be made under /proc."""
    outs = ["", str(tmp_path / ("x" * 300) / "out")]
    if Path("/proc/self").is_dir():
        outs.append("/proc/susp_bo_no_such_folder/out")
    return outs


@pytest.mark.parametrize("command", ["synth", "simulate"])
def test_an_out_that_is_empty_or_cannot_be_made_is_refused_first(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    command: str,
) -> None:
    monkeypatch.chdir(tmp_path)  # --out "" would write here
    for out in _unusable_outs(tmp_path):
        assert main([command, "hst_trailer", "--out", out, "--seed", "1"]) == 2
        err = capsys.readouterr().err
        assert f"--out: {out!r} is not allowed" in err and "expected" in err, err
        assert "Errno" not in err and f"susp-bo {command}: " in err
        assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("effects", "needle"),
    [
        (["carbody_bending", "carbody_bending"], "effect 'carbody_bending' is already given"),
        (["carbody_bending:frequency_hz=9,frequency_hz=10"], "gives 'frequency_hz' twice"),
    ],
)
def test_an_effect_or_effect_value_given_twice_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], effects: list[str], needle: str
) -> None:
    flags = [part for effect in effects for part in ("--effect", effect)]
    assert main(["synth", "hst_trailer", "--out", str(tmp_path / "d"), *flags]) == 2
    err = capsys.readouterr().err
    assert f"--effect: {effects[-1]!r} is not allowed" in err and needle in err, err
    assert "expected each" in err
    assert not (tmp_path / "d").exists()


def test_a_missing_line_file_names_the_flag_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = str(tmp_path / "nosuch.toml")
    assert main(["synth", "hst_trailer", "--out", str(tmp_path / "d"), "--line", missing]) == 2
    err = capsys.readouterr().err
    assert f"susp-bo synth: --line: file {missing!r} does not exist" in err
    assert err.count("--line") == 1


def test_a_truth_that_diverges_is_refused_naming_the_file_and_values_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = tmp_path / "hunting.toml"
    truth.write_text("contact_equivalent_conicity = 0.9\n")  # the wheelsets hunt at 83 m/s
    out = tmp_path / "d"
    code = main(["synth", "hst_trailer", "--out", str(out), "--truth", str(truth), "--nu", "1"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert (
        f"--truth {truth}: the simulation of rig 'hst_trailer' with "
        "contact_equivalent_conicity = 0.9, at 83.33 m/s with a time step of 0.002 s, failed: "
        "diverged at t = 1." in err
    )
    assert "nothing was written" in err
    assert not out.exists()


def test_a_speed_below_the_time_steps_minimum_is_refused_naming_it(
    fast_rig: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "d"
    assert main(["synth", str(fast_rig), "--out", str(out), "--speed", "20", "--nu", "1"]) == 2
    err = capsys.readouterr().err
    assert "--speed: 20 m/s is not allowed: below the minimum speed 24.99 m/s" in err
    assert "Traceback" not in err and not out.exists()
