"""``susp-bo import csv|mat``: real CSV and .mat files to the HDF5 measured format, checked
against the rig, with messages naming the file and what is expected."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from susp_bo.cli import main
from susp_bo.data.importers import write_csv_run, write_mat_run
from susp_bo.data.measured import MeasuredRun, load_runs
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.track import GEOMETRY_COMPONENTS, SpeedProfile, TrackGeometry

RIG = "hst_trailer"


def _run(seed: int, channels: tuple[str, ...] | None = None, track_m: float = 300.0) -> MeasuredRun:
    """10 s at 20 m/s (200 m + 20 m axle span) at 100 Hz, in g (converted on import)."""
    channels = channels or load_rig_spec(RIG).channels
    rng = np.random.default_rng(seed)
    return MeasuredRun(
        geometry=TrackGeometry.synthetic("low", length_m=track_m, spacing_m=0.5, seed=seed),
        speed=SpeedProfile.constant(20.0, 10.0),
        channels=tuple(reversed(channels)),  # any order: the rig's order on import
        accelerations_m_s2=rng.normal(0.0, 0.02, size=(len(channels), 1000)),
        sample_rate_hz=100.0,
        units=("g",) * len(channels),
    )


def _csv(folder: Path, name: str, run: MeasuredRun) -> None:
    folder.mkdir(exist_ok=True)
    write_csv_run(
        run,
        folder / f"{name}_accelerations.csv",
        folder / f"{name}_geometry.csv",
        folder / f"{name}_speed.csv",
    )


def _code_and_err(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str]:
    code = main(argv)
    return code, capsys.readouterr().err


def test_csv_folder_imports_checked_in_the_rigs_channel_order(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "csv"
    originals = {name: _run(seed) for seed, name in enumerate(("north", "south"))}
    for name, run in originals.items():
        _csv(source, name, run)
    out = tmp_path / "h5"
    code, err = _code_and_err(
        capsys, ["import", "csv", str(source), "--out", str(out), "--rig", RIG]
    )
    assert code == 0, err
    assert "wrote 2 run(s)" in err
    assert sorted(p.name for p in out.iterdir()) == ["north.h5", "south.h5"]
    channels = load_rig_spec(RIG).channels
    runs = load_runs(out, channels=channels)
    for run, original in zip(runs, originals.values()):
        assert run.channels == channels and set(run.units) == {"m/s^2"}
        row = original.channels.index(channels[0])
        np.testing.assert_allclose(  # g -> m/s^2
            run.accelerations_m_s2[0], original.accelerations_m_s2[row] * 9.80665, rtol=1e-12
        )
        assert run.metadata["rig"] == RIG
        np.testing.assert_array_equal(run.geometry.vertical_m, original.geometry.vertical_m)


def test_mat_files_import_savemat_by_hand_and_exported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "mat"
    source.mkdir()
    write_mat_run(_run(1), source / "exported.mat")
    run = _run(2)
    scipy.io.savemat(
        source / "by_hand.mat",
        {
            "accelerations": run.accelerations_m_s2.T,  # (n_t x C)
            "channels": np.array(run.channels, dtype=object),
            "units": np.array(run.units, dtype=object),
            "sample_rate_hz": 100.0,
            "spacing_m": 0.5,
            "speed_m_s": 20.0,
            "metadata_json": json.dumps({"line": "test track"}),
            **{name: getattr(run.geometry, name) for name in GEOMETRY_COMPONENTS},
        },
    )
    out = tmp_path / "h5"
    code, err = _code_and_err(
        capsys,
        [
            "import",
            "mat",
            str(source / "by_hand.mat"),
            str(source / "exported.mat"),
            "--out",
            str(out),
            "--rig",
            RIG,
        ],
    )
    assert code == 0, err
    runs = load_runs(out)
    assert [r.metadata["line"] for r in runs[:1]] == ["test track"]
    assert all(r.metadata["rig"] == RIG for r in runs)


def test_without_a_rig_runs_are_converted_unchecked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _csv(tmp_path / "csv", "a", _run(0, channels=("x", "y")))
    out = tmp_path / "h5"
    code, err = _code_and_err(capsys, ["import", "csv", str(tmp_path / "csv"), "--out", str(out)])
    assert code == 0, err
    (run,) = load_runs(out)
    assert run.channels == ("y", "x") and "rig" not in run.metadata


def test_a_csv_geometry_file_with_s_m_alone_imports_a_run_whose_track_was_not_measured(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The geometry file stays required (a forgotten one is named), but ``s_m`` alone says
    the track was not measured: the run is written without geometry (format version 3),
    checked against the rig all the same."""
    import h5py

    source = tmp_path / "csv"
    _csv(source, "north", dataclasses.replace(_run(0), geometry=None))
    header = (source / "north_geometry.csv").read_text().splitlines()[0]
    assert header.split(",")[0].strip() == "s_m" and "vertical_m" not in header
    out = tmp_path / "h5"
    code, err = _code_and_err(
        capsys, ["import", "csv", str(source), "--out", str(out), "--rig", RIG]
    )
    assert code == 0, err
    assert "1 of them without track geometry (the track was not measured: north)" in err
    (run,) = load_runs(out)
    assert run.geometry is None and run.metadata["rig"] == RIG
    with h5py.File(out / "north.h5", "r") as file:
        assert int(file.attrs["format_version"]) == 3 and "geometry" not in file
    (source / "north_geometry.csv").unlink()
    code, err = _code_and_err(
        capsys, ["import", "csv", str(source), "--out", str(tmp_path / "h5b"), "--rig", RIG]
    )
    assert code == 2 and "missing north_geometry.csv" in err


@pytest.mark.parametrize(
    ("run", "needles"),
    [
        (_run(0, channels=("carbody_front_vertical", "x")), ["missing channel(s)", "'a'"]),
        (_run(0, track_m=150.0), ["track shorter than the run", "axle span"]),
    ],
    ids=["channels", "track"],
)
def test_runs_that_do_not_fit_the_rig_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run: MeasuredRun, needles: list[str]
) -> None:
    _csv(tmp_path / "csv", "a", run)
    out = tmp_path / "h5"
    argv = ["import", "csv", str(tmp_path / "csv"), "--out", str(out), "--rig", RIG]
    code, err = _code_and_err(capsys, argv)
    assert code == 2 and "Traceback" not in err
    assert "a_accelerations.csv" in err and f"rig '{RIG}'" in err
    for needle in needles:
        assert needle in err, err
    assert not out.exists()  # nothing written when a run is refused


def test_a_unit_that_cannot_be_converted_names_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _run(0)
    run = dataclasses.replace(run, units=("furlong/s^2", *run.units[1:]))
    _csv(tmp_path / "csv", "a", run)
    out = tmp_path / "h5"
    code, err = _code_and_err(capsys, ["import", "csv", str(tmp_path / "csv"), "--out", str(out)])
    assert code == 2 and "Traceback" not in err
    assert f"{tmp_path / 'csv' / 'a_accelerations.csv'}: unit mismatch" in err, err
    assert "'furlong/s^2'" in err and "known units" in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("files", "needle"),
    [
        ({"run1.csv": "time_s,x\n0,1\n"}, "name CSV files <run>_accelerations.csv"),
        ({"r_accelerations.csv": "time_s,x\n0,1\n"}, "missing r_geometry.csv"),
        ({}, "no .csv files found"),
        (
            {"r_geometry.csv": "s_m\n0\n1\n", "r_accelerations.csv": "t,x\n0,1\n1,1\n"},
            "first column must be 'time_s'",
        ),
    ],
)
def test_bad_csv_inputs_are_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], files: dict[str, str], needle: str
) -> None:
    source = tmp_path / "in"
    source.mkdir()
    for name, text in files.items():
        (source / name).write_text(text)
    code, err = _code_and_err(capsys, ["import", "csv", str(source), "--out", str(tmp_path / "o")])
    assert code == 2 and needle in err and "Traceback" not in err, err


def test_an_empty_input_is_refused_as_empty(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _csv(tmp_path, "a", _run(0))  # "" must not mean the current folder
    monkeypatch.chdir(tmp_path)
    code, err = _code_and_err(capsys, ["import", "csv", "", "--out", str(tmp_path / "h5")])
    assert code == 2 and "FILES_OR_DIR: '' is not allowed (empty)" in err, err
    assert not (tmp_path / "h5").exists()


def test_bad_paths_and_flags_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope"
    code, err = _code_and_err(capsys, ["import", "mat", str(missing), "--out", str(tmp_path)])
    assert code == 2 and f"{missing}: no such file or folder" in err
    text = tmp_path / "notes.txt"
    text.write_text("x")
    code, err = _code_and_err(capsys, ["import", "mat", str(text), "--out", str(tmp_path / "o")])
    assert code == 2 and "not a .mat file" in err
    code, err = _code_and_err(capsys, ["import", "xls", str(tmp_path), "--out", str(tmp_path)])
    assert code == 2 and "invalid choice: 'xls'" in err
    code, err = _code_and_err(capsys, ["import", "csv", str(tmp_path), "--out", str(text)])
    assert code == 2 and "--out:" in err and "existing file" in err
    code, err = _code_and_err(
        capsys, ["import", "csv", str(tmp_path), "--out", str(tmp_path / "o"), "--rig", "nope"]
    )
    assert code == 2 and "--rig:" in err and RIG in err


def test_speed_flag_for_runs_with_their_own_speed_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # --speed was silently ignored for a run with a speed file (and silently replaced a
    # speed_m_s column); a run without a speed of its own still takes it
    source = tmp_path / "csv"
    _csv(source, "a", _run(0, track_m=400.0))  # 30 m/s for 10 s: 300 m + the axle span
    out = tmp_path / "h5"
    argv = ["import", "csv", str(source), "--out", str(out), "--rig", RIG, "--speed", "30"]
    code, err = _code_and_err(capsys, argv)
    assert code == 2 and "Traceback" not in err, err
    assert f"--speed: 30 m/s is not allowed for run 'a': {source / 'a_speed.csv'} is its " in err
    assert "drop --speed" in err and not out.exists()

    speed = np.loadtxt(source / "a_speed.csv", delimiter=",", skiprows=1)
    (source / "a_speed.csv").unlink()
    acc = source / "a_accelerations.csv"
    lines = acc.read_text().splitlines()
    times = [float(line.split(",")[0]) for line in lines[1:]]
    column = np.interp(times, speed[:, 0], speed[:, 1])
    acc.write_text(
        "\n".join([f"{lines[0]},speed_m_s"] + [f"{row},{v}" for row, v in zip(lines[1:], column)])
    )
    code, err = _code_and_err(capsys, argv)
    assert code == 2 and f"{acc} has a speed_m_s column" in err, err
    assert main(argv[:-2]) == 0  # the column is the speed without --speed

    acc.write_text("\n".join(lines) + "\n")  # no speed of its own: --speed is its speed
    capsys.readouterr()
    code, err = _code_and_err(capsys, [*argv[:4], str(tmp_path / "h5b"), *argv[5:]])
    assert code == 0, err
    (run,) = load_runs(tmp_path / "h5b")
    assert run.speed.speed_at(1.0) == 30.0


def test_speed_flag_is_refused_for_mat_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "r.mat"
    write_mat_run(_run(0), path)
    argv = ["import", "mat", str(path), "--out", str(tmp_path / "o"), "--speed", "30"]
    code, err = _code_and_err(capsys, argv)
    assert code == 2 and "Traceback" not in err, err
    assert f"--speed: 30 m/s is not allowed with 'import mat': {path} carries its own speed" in err


def test_existing_runs_are_not_overwritten(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _csv(tmp_path / "csv", "a", _run(0))
    out = tmp_path / "h5"
    argv = ["import", "csv", str(tmp_path / "csv"), "--out", str(out), "--rig", RIG]
    assert main(argv) == 0
    before = (out / "a.h5").read_bytes()
    capsys.readouterr()
    code, err = _code_and_err(capsys, argv)
    assert code == 2 and "already holds" in err and (out / "a.h5").read_bytes() == before


def test_calibrate_on_a_csv_folder_says_how_to_import(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _csv(tmp_path / "csv", "a", _run(0))
    argv = ["calibrate", RIG, str(tmp_path / "csv"), "--out", str(tmp_path / "o")]
    code, err = _code_and_err(capsys, argv)
    assert code == 2
    assert "holds 3 .csv files" in err and "susp-bo import csv" in err


@pytest.mark.parametrize(("content", "size"), [(b"", "an empty file"), (b"not a mat", "9 bytes")])
def test_an_empty_or_truncated_mat_file_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes, size: str
) -> None:
    good = tmp_path / "mat" / "good.mat"
    good.parent.mkdir()
    write_mat_run(_run(0), good)
    bad = tmp_path / "mat" / "short.mat"
    bad.write_bytes(content)
    out = tmp_path / "h5"
    code, err = _code_and_err(capsys, ["import", "mat", str(bad.parent), "--out", str(out)])
    assert code == 2 and f"{bad}: not a readable .mat file (" in err and size in err, err
    assert "expected a MATLAB v4-v7 .mat file" in err
    assert not out.exists()  # the good run is not written either


def test_an_out_that_is_empty_or_cannot_be_made_is_refused_before_reading(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _csv(tmp_path / "csv", "a", _run(0))
    monkeypatch.chdir(tmp_path / "csv")  # --out "" would write a.h5 here
    outs = ["", str(tmp_path / ("x" * 300))]
    if Path("/proc/self").is_dir():
        outs.append("/proc/susp_bo_no_such_folder")
    for out in outs:
        code, err = _code_and_err(capsys, ["import", "csv", ".", "--out", out])
        assert code == 2 and f"susp-bo import: --out: {out!r} is not allowed" in err, err
        assert "Errno" not in err
        assert not (tmp_path / "csv" / "a.h5").exists()
