"""``susp-bo demo --out``: refused before any work when it cannot be used or holds other data;
a rerun with the same settings continues in place (fast: nothing is simulated)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from susp_bo.cli import main
from susp_bo.commands.demo import DEMO_RIG, check_demo_folder, demo_runs_setting
from susp_bo.data.measured import MeasuredRun, save_run
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.track import SpeedProfile, TrackGeometry


def _demo_run(folder: Path, index: int, seed: int = 2024) -> Path:
    """A run in ``folder/data`` as ``demo --smoke --seed SEED`` writes it (random signals)."""
    spec = load_rig_spec(DEMO_RIG)
    setting = demo_runs_setting(spec, smoke=True, seed=seed)
    rate = spec.simulation.sample_rate_hz
    n = round(setting["duration_s"] * rate)
    run = MeasuredRun(
        geometry=TrackGeometry.synthetic("low", length_m=400.0, spacing_m=0.5, seed=index),
        speed=SpeedProfile.constant(20.0, setting["duration_s"] + 1.0),
        channels=spec.channels,
        accelerations_m_s2=np.random.default_rng(index).normal(0, 0.1, (len(spec.channels), n)),
        sample_rate_hz=rate,
        units=("m/s^2",) * len(spec.channels),
        metadata={
            "source": "synthetic",
            "rig": spec.name,
            "truth": setting["truth"],
            "seed": seed,
            "run_index": index,
            "noise_m_s2": setting["noise_m_s2"],
        },
    )
    return save_run(run, folder / "data" / f"run_{index:03d}.h5")


def test_a_rerun_with_the_same_settings_keeps_the_runs_there(tmp_path: Path) -> None:
    _demo_run(tmp_path, 0)
    setting = demo_runs_setting(load_rig_spec(DEMO_RIG), smoke=True, seed=2024)
    assert check_demo_folder(tmp_path, setting, smoke=True) == [1]  # only run 1 to make


@pytest.mark.parametrize(
    ("flags", "needles"),
    [
        (
            ["--smoke", "--seed", "1"],
            ["run_000.h5 is not a measured run of this demo", "seed 2024"],
        ),
        (["--seed", "2024"], ["run_000.h5 is not a measured run of this demo", "12 s long"]),
    ],
    ids=["other-seed", "not-smoke"],
)
def test_runs_of_another_demo_are_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flags: list[str], needles: list[str]
) -> None:
    run = _demo_run(tmp_path, 0)
    before = run.read_bytes()
    assert main(["demo", "--out", str(tmp_path), *flags]) == 2
    err = capsys.readouterr().err
    assert "susp-bo demo: --out: " in err and "give another --out" in err, err
    assert all(needle in err for needle in needles), err
    assert "synthesising" not in err
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == ["run_000.h5"]
    assert run.read_bytes() == before


def test_other_data_or_another_study_in_out_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "a" / "data").mkdir(parents=True)
    (tmp_path / "a" / "data" / "measured.h5").write_bytes(b"x")
    assert main(["demo", "--smoke", "--out", str(tmp_path / "a")]) == 2
    assert "holds measured.h5, not one of the demo's measured runs" in capsys.readouterr().err
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "result.json").write_text("{}")
    assert main(["demo", "--smoke", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "already holds a study (result.json) but not the demo's measured runs" in err
    assert not (tmp_path / "b" / "data").exists()


def test_an_out_that_is_empty_or_cannot_be_made_is_refused_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # --out "" would use this folder (and its data/)
    outs = ["", str(tmp_path / ("x" * 300))]
    if Path("/proc/self").is_dir():
        outs.append("/proc/susp_bo_no_such_folder")
    for out in outs:
        assert main(["demo", "--smoke", "--out", out]) == 2
        err = capsys.readouterr().err
        assert f"susp-bo demo: --out: {out!r} is not allowed" in err, err
        assert "synthesising" not in err and "Errno" not in err
        assert list(tmp_path.iterdir()) == []
