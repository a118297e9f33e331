"""Bad input on every command: exit code 2, one message naming the flag/file, the value and
what is allowed, no traceback, nothing simulated (the README's bad-input table, as tests)."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import pytest
import tomli_w

from susp_bo.cli import main
from susp_bo.data.measured import MeasuredRun, load_runs, save_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.catalog import rig_path
from susp_bo.rig.spec import load_rig_spec
from susp_bo.store import EvaluationStore
from susp_bo.store_fingerprint import study_fingerprint


def _rig_copy(folder: Path, name: str, **changes: object) -> Path:
    """The reference rig with short records (4 s after 0.5 s warm-up), renamed."""
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    document["rig"]["name"] = name
    document["simulation"].update(duration_s=4.0, warm_up_s=0.5)
    document["spectrum"].update(segment_s=2.0, f_min_hz=1.0, n_frequencies=8)
    document.update(changes)
    path = folder / f"{name}.toml"
    path.write_text(tomli_w.dumps(document))
    return path


@pytest.fixture(scope="module")
def rigs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("rigs")
    return {name: _rig_copy(folder, name) for name in ("short_a", "short_b")}


@pytest.fixture(scope="module")
def runs_by_rig(rigs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Two synthetic runs of each short rig, one folder per rig."""
    folders = {}
    for name, path in rigs.items():
        folder = tmp_path_factory.mktemp(f"data_{name}")
        for index, run in enumerate(synthesize_runs(load_rig_spec(path), {}, nu=2, seed=1)):
            save_run(run, folder / f"run_{index:03d}.h5")
        folders[name] = folder
    return folders


@pytest.fixture(scope="module")
def short_a_runs(runs_by_rig: dict[str, Path]) -> tuple[MeasuredRun, ...]:
    """The two runs of the ``short_a`` rig's folder, loaded (tests replace fields, never
    mutate them)."""
    return tuple(load_runs(runs_by_rig["short_a"]))


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str], *needles: str) -> str:
    """Run the CLI in-process; assert exit code 2, one message with every needle, no traceback."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


# --- --out pointing at an existing file -------------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "hst_trailer", "--out", "{file}"],
        ["synth", "hst_trailer", "--out", "{file}"],
        ["demo", "--smoke", "--out", "{file}"],
        ["calibrate", "hst_trailer", "{tmp}", "--out", "{file}"],
        ["synth", "hst_trailer", "--out", "{file}/sub"],
    ],
    ids=["simulate", "synth", "demo", "calibrate", "synth-parent"],
)
def test_out_that_is_a_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    file = tmp_path / "results.txt"
    file.write_text("not a folder")
    argv = [a.replace("{file}", str(file)).replace("{tmp}", str(tmp_path)) for a in argv]
    _refused(capsys, argv, "--out:", str(file), "is an existing file, expected a folder")
    assert file.read_text() == "not a folder"


def test_out_that_is_the_data_folder_is_refused(
    rigs: dict[str, Path],
    short_a_runs: tuple[MeasuredRun, ...],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The store, results, figures and log were written among the measured runs."""
    runs = short_a_runs
    data = _data_folder(tmp_path, {"run_000.h5": runs[0], "run_001.h5": runs[1]})
    before = sorted(p.name for p in data.iterdir())
    argv = ["calibrate", str(rigs["short_a"]), str(data), "--out", str(data)]
    _refused(capsys, argv, "out:", "is the data folder")
    assert sorted(p.name for p in data.iterdir()) == before


def test_study_out_that_is_a_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "data").mkdir()
    (tmp_path / "out").write_text("x")
    study = tmp_path / "study.toml"
    study.write_text('rig = "hst_trailer"\ndata = "data"\nout = "out"\n')
    _refused(capsys, ["calibrate", str(study)], "out:", "is an existing file")


# --- flag values --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "needles"),
    [
        (["calibrate", "hst_trailer", "d", "--out", "o", "--budget", "0"], ["--budget", "'0'"]),
        (["calibrate", "hst_trailer", "d", "--out", "o", "--budget", "ten"], ["--budget", "ten"]),
        (["calibrate", "hst_trailer", "d", "--out", "o", "--workers", "-1"], ["--workers", ">= 0"]),
        (["diagnose", "r", "--out", "o", "--budget", "-5"], ["--budget", "integer >= 2"]),
        (["simulate", "hst_trailer", "--out", "o", "--speed", "-3"], ["--speed", "> 0 m/s"]),
        (["simulate", "hst_trailer", "--out", "o", "--speed", "nan"], ["--speed", "finite"]),
        (["simulate", "hst_trailer", "--out", "o", "--duration", "0"], ["--duration", "> 0 s"]),
        (["simulate", "hst_trailer", "--out", "o", "--seed", "-1"], ["--seed", ">= 0"]),
        (["synth", "hst_trailer", "--out", "o", "--nu", "0"], ["--nu", "integer >= 1"]),
        (["synth", "hst_trailer", "--out", "o", "--noise", "-0.1"], ["--noise", ">= 0 m/s^2"]),
        (["synth", "hst_trailer", "--out", "o", "--noise", "inf"], ["--noise", "finite"]),
        (["synth", "hst_trailer", "--out", "o", "--seed", "1.5"], ["--seed", "integer"]),
        (["demo", "--seed", "-2"], ["--seed", ">= 0"]),
    ],
)
def test_bad_flag_values_are_refused_when_parsed(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    needles: list[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    _refused(capsys, argv, *needles, "is not allowed")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("command", "flag", "value"),
    [("simulate", "--speed", "500"), ("synth", "--speed", "300")],
)
def test_speed_above_the_rigs_range_names_the_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, flag: str, value: str
) -> None:
    out = tmp_path / "o"
    _refused(
        capsys,
        [command, "hst_trailer", "--out", str(out), flag, value],
        flag,
        "allowed range (0, 200] m/s",
    )
    assert not out.exists()


def test_study_toml_that_does_not_exist_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "nostudy.toml"
    _refused(capsys, ["calibrate", str(missing)], str(missing), "does not exist")


def test_rig_section_in_a_study_file_says_where_it_belongs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "data").mkdir()
    study = tmp_path / "study.toml"
    study.write_text(
        'rig = "hst_trailer"\ndata = "data"\nout = "o"\n[simulation]\nspeed_m_s = 80\n'
    )
    _refused(capsys, ["calibrate", str(study)], "simulation: unknown key", "belongs in the rig")


def test_missing_data_folder_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["calibrate", "hst_trailer", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]
    _refused(capsys, argv, "data:", "no folder at")


# --- rig files ----------------------------------------------------------------------------------


def test_rig_with_a_typo_key_is_refused_with_a_hint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = rig_path("hst_trailer").read_text().replace("cg_height = 1.70", "cg_hieght = 1.9")
    rig = tmp_path / "typo.toml"
    rig.write_text(text)
    _refused(
        capsys,
        ["simulate", str(rig), "--out", str(tmp_path / "o")],
        "typo.toml",
        "[carbody] cg_hieght: unknown key (did you mean 'cg_height'?)",
    )


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ('track_quality = "low"', 'track_qualty = "low"', "did you mean 'track_quality'"),
        ('unit = "N/m"', 'units = "N/m"', "[[calibration.parameters]] primary_vertical_stiffness"),
    ],
)
def test_rig_typo_in_simulation_or_calibration_entry_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, needle: str
) -> None:
    rig = tmp_path / "typo.toml"
    rig.write_text(rig_path("hst_trailer").read_text().replace(old, new, 1))
    data = tmp_path / "data"
    data.mkdir()
    _refused(
        capsys, ["calibrate", str(rig), str(data), "--out", str(tmp_path / "o")], needle, "unknown"
    )


def test_rig_that_is_not_toml_names_file_and_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = tmp_path / "broken.toml"
    rig.write_text('[rig]\nname = "x"\nmass = = 3\n')
    _refused(capsys, ["simulate", str(rig), "--out", str(tmp_path / "o")], "broken.toml", "line 3")


@pytest.mark.parametrize(
    ("section", "change", "needle"),
    [
        ("carbody", {"mass": -1.0}, "parameter carbody_mass: got -1.0; must be > 0"),
        ("simulation", {"time_step_s": 0.0}, "[simulation] time_step_s: got 0;"),
        ("spectrum", {"f_min_hz": 30.0}, "[spectrum] f_max_hz: got"),
    ],
    ids=["negative-mass", "zero-step", "band"],
)
def test_a_bad_rig_value_names_the_rig_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], section: str, change: dict, needle: str
) -> None:
    # the entries check themselves without knowing their file; the loader adds it
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    document[section].update(change)
    rig = tmp_path / "edited_rig.toml"
    rig.write_text(tomli_w.dumps(document))
    err = _refused(capsys, ["simulate", str(rig), "--out", str(tmp_path / "o")], needle)
    assert f"{rig}: " in err


def test_a_rig_whose_own_sampling_and_band_disagree_is_blamed_not_duration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    document["simulation"]["sample_rate_hz"] = 10.0  # Nyquist 5 Hz, below the band's f_max
    rig = tmp_path / "slow_sampling.toml"
    rig.write_text(tomli_w.dumps(document))
    err = _refused(
        capsys,
        ["simulate", str(rig), "--out", str(tmp_path / "o")],
        f"{rig}: its [simulation] and [spectrum] settings do not fit together",
        "sample_rate_hz: got 10 Hz",
    )
    assert "--duration" not in err


# --- measured runs of another rig, resume on another study --------------------------------------


def test_runs_of_another_rig_are_refused(
    rigs: dict[str, Path],
    runs_by_rig: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "o"
    argv = ["calibrate", str(rigs["short_a"]), str(runs_by_rig["short_b"]), "--out", str(out)]
    _refused(capsys, argv, "recorded on rig 'short_b'", "calibrates rig 'short_a'")
    assert not out.exists()


def test_a_folder_mixing_two_rigs_is_refused(
    rigs: dict[str, Path],
    runs_by_rig: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for name, folder in runs_by_rig.items():
        (mixed / f"{name}.h5").write_bytes((folder / "run_000.h5").read_bytes())
    argv = ["calibrate", str(rigs["short_a"]), str(mixed), "--out", str(tmp_path / "o")]
    _refused(capsys, argv, "mixes runs of 2 rigs", "'short_a': short_a.h5", "'short_b': short_b.h5")


def test_resume_on_a_folder_of_another_study_is_a_message(
    rigs: dict[str, Path],
    runs_by_rig: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "o"
    EvaluationStore(
        out / "evaluations.sqlite", study_fingerprint("another-rig", "other-data", ["x"])
    ).close()
    argv = ["calibrate", str(rigs["short_a"]), str(runs_by_rig["short_a"]), "--out", str(out)]
    err = _refused(capsys, [*argv, "--resume"], "--resume:", "holds the evaluations of another")
    assert "new output folder" in err
    assert not (out / "study.toml").exists()  # nothing written over the other study


def test_debug_prints_the_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    file = tmp_path / "f"
    file.write_text("")
    assert main(["--debug", "synth", "hst_trailer", "--out", str(file)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and "UsageError" in err and "--out:" in err


# --- study settings against the rig, measured runs that disagree -------------------------------


def test_a_sigma_table_with_an_unknown_channel_names_it_and_the_allowed_ones(
    rigs: dict[str, Path],
    runs_by_rig: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(
        tomli_w.dumps(
            {
                "rig": str(rigs["short_a"]),
                "data": str(runs_by_rig["short_a"]),
                "out": str(tmp_path / "o"),
                "output_error": {"sigma": {"nochannel": 0.1}},
            }
        )
    )
    channels = load_rig_spec(rigs["short_a"]).channels
    _refused(
        capsys,
        ["calibrate", str(study)],
        "output_error.sigma: unknown channel(s) 'nochannel'",
        f"allowed: {', '.join(channels)}",
    )
    assert not (tmp_path / "o").exists()


def _data_folder(tmp_path: Path, runs: dict[str, MeasuredRun]) -> Path:
    """A folder ``tmp_path/data`` holding ``runs`` under their file names."""
    data = tmp_path / "data"
    data.mkdir()
    for name, run in runs.items():
        save_run(run, data / name)
    return data


def test_runs_at_different_sample_rates_are_named_by_file(
    rigs: dict[str, Path],
    short_a_runs: tuple[MeasuredRun, ...],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    runs = short_a_runs
    fast = dataclasses.replace(runs[1], sample_rate_hz=2 * runs[1].sample_rate_hz)
    data = _data_folder(tmp_path, {"slow.h5": runs[0], "fast.h5": fast})
    rate = runs[0].sample_rate_hz
    out = tmp_path / "o"
    _refused(
        capsys,
        ["calibrate", str(rigs["short_a"]), str(data), "--out", str(out)],
        "sampled at different rates",
        f"{rate:g} Hz: slow.h5",
        f"{2 * rate:g} Hz: fast.h5",
    )
    assert not out.exists()
    # also with the sensor noise given: the noise floor and the spectra assume one rate
    study = tmp_path / "study.toml"
    study.write_text(
        f'rig = "{rigs["short_a"]}"\ndata = "{data}"\nout = "{out}"\n'
        "[output_error]\nsensor_noise_m_s2 = 0.01\n"
    )
    _refused(capsys, ["calibrate", str(study)], "sampled at different rates", "fast.h5")
    assert not out.exists()


def test_an_empty_monitoring_folder_argument_is_refused_as_empty(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # "" must not mean the current folder
    err = _refused(capsys, ["monitor", "", "--out", "o"], "FOLDER: '' is not allowed (empty)")
    assert "holds no campaign" not in err
    assert not (tmp_path / "o").exists()


def test_a_run_that_does_not_fit_the_band_is_named_by_its_file(
    rigs: dict[str, Path],
    short_a_runs: tuple[MeasuredRun, ...],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    runs = short_a_runs
    short = dataclasses.replace(  # 1 s: shorter than one Welch segment
        runs[1], accelerations_m_s2=runs[1].accelerations_m_s2[:, : int(runs[1].sample_rate_hz)]
    )
    data = _data_folder(tmp_path, {"good.h5": runs[0], "cut_short.h5": short})
    out = tmp_path / "o"
    argv = ["calibrate", str(rigs["short_a"]), str(data), "--out", str(out)]
    _refused(capsys, argv, f"data: {data / 'cut_short.h5'}: ", "Welch segment")
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "prefix"),
    [
        (["simulate", "hst_trailer", "--out", "{o}", "--params", "{b}"], "--params: "),
        (["synth", "hst_trailer", "--out", "{o}", "--truth", "{b}"], "--truth: "),
        (["simulate", "{b}", "--out", "{o}"], ""),
        (["simulate", "hst_trailer", "--out", "{o}", "--line", "{b}"], "--line: "),
        (["calibrate", "{b}"], ""),
    ],
    ids=["params", "truth", "rig", "line", "study"],
)
def test_a_toml_file_that_is_not_utf8_text_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], prefix: str
) -> None:
    binary = tmp_path / "b.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    out = tmp_path / "o"
    argv = [a.replace("{b}", str(binary)).replace("{o}", str(out)) for a in argv]
    _refused(capsys, argv, f"{prefix}{binary}: not a UTF-8 text file (byte 0xff at position 0")
    assert not out.exists()


# --- --params / --truth files --------------------------------------------------------------

PARAMETER_FLAGS = [("simulate", "--params"), ("synth", "--truth")]


@pytest.mark.parametrize(("command", "flag"), PARAMETER_FLAGS)
@pytest.mark.parametrize(
    ("text", "needles"),
    [
        (
            "yaw_damper_damping = -5.0\n",
            ["yaw_damper_damping = -5 is not allowed; must be >= 0 (a damping cannot be negative)"],
        ),
        (
            "yaw_damper_damping = 1.0\n",
            ["yaw_damper_damping = 1 N·s/m is not allowed; allowed: the rig's admissible interval"],
        ),
        (
            '"yaw_damper_damping@bogie_front_lef" = 4.0e6\n',
            ["unknown component 'bogie_front_lef'", "(did you mean 'bogie_front_left'?)"],
        ),
    ],
    ids=["negative", "outside-bounds", "component-typo"],
)
def test_a_bad_parameter_value_names_the_flag_and_the_file(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
    flag: str,
    text: str,
    needles: list[str],
) -> None:
    # the message named neither: "parameter yaw_damper_damping: got -5.0; must be >= 0"
    path = tmp_path / "p.toml"
    path.write_text(text)
    out = tmp_path / "out"
    err = _refused(capsys, [command, "hst_trailer", "--out", str(out), flag, str(path)], *needles)
    assert f"susp-bo {command}: {flag} {path}: " in err
    assert not out.exists()


@pytest.mark.parametrize(("command", "flag"), PARAMETER_FLAGS)
def test_an_unknown_parameter_name_gets_a_did_you_mean_and_a_list_by_section(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, flag: str
) -> None:
    path = tmp_path / "p.toml"
    path.write_text("yaw_damper_dampin = 4.9e6\n")
    argv = [command, "hst_trailer", "--out", str(tmp_path / "out"), flag, str(path)]
    err = _refused(
        capsys,
        argv,
        f"{flag} {path}: unknown parameter 'yaw_damper_dampin' (did you mean "
        "'yaw_damper_damping'?)",
        "[yaw_damper] damping, series_stiffness",
        "[carbody] mass, ",
        "<parameter>@<component>",
    )
    assert "carbody_mass" not in err  # grouped by section, not 52 full names in a row


@pytest.mark.parametrize(("command", "flag"), PARAMETER_FLAGS)
def test_a_folder_given_as_parameter_file_is_called_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, flag: str
) -> None:
    folder = tmp_path / "p.toml"
    folder.mkdir()
    argv = [command, "hst_trailer", "--out", str(tmp_path / "out"), flag, str(folder)]
    err = _refused(capsys, argv, f"{flag}: {str(folder)!r} is a folder; expected a TOML file")
    assert "does not exist" not in err
