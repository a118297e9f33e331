"""``susp-bo monitor``'s arguments: a bad value is blamed on its flag (not on
``monitor.toml``), a bad value of ``monitor.toml`` on the file; exit code 2, no work."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomli_w

import susp_bo
from susp_bo.calibration.budget import budget_requirement, calibrated_count
from susp_bo.cli import main
from susp_bo.monitoring.runner import MonitorError, base_config


@pytest.fixture(scope="module")
def folder(one_campaign_folder: Any) -> Path:
    """A monitoring folder of one campaign with a ``monitor.toml``."""
    return one_campaign_folder("arguments")


def _refused(folder: Path, out: Path, capsys: pytest.CaptureFixture[str], *flags: str) -> str:
    assert main(["monitor", str(folder), "--out", str(out), *flags]) == 2
    assert not out.exists()
    return capsys.readouterr().err


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (["--rig", "nosuchrig"], "susp-bo monitor: --rig: 'nosuchrig' is not allowed; shipped"),
        (
            ["--parameters", "yaw_damper_damping,yaw_damper_damping"],
            "susp-bo monitor: --parameters: ['yaw_damper_damping', 'yaw_damper_damping'] is "
            "not allowed: 'yaw_damper_damping' is given more than once; expected a non-empty "
            "list of distinct",
        ),
        (
            ["--parameters", "nonexistent"],
            "susp-bo monitor: --parameters: ['nonexistent'] not in the calibration set",
        ),
        (  # the empty name was dropped: a parameter left out by mistake went unnoticed
            ["--parameters", "yaw_damper_damping,,secondary_vertical_damping"],
            "susp-bo monitor: --parameters: 'yaw_damper_damping,,secondary_vertical_damping' "
            "has an empty name",
        ),
    ],
)
def test_a_bad_flag_is_named_not_the_file(
    folder: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    flags: list[str],
    expected: str,
) -> None:
    err = _refused(folder, tmp_path / "out", capsys, *flags)
    assert expected in err and "monitor.toml" not in err


def test_a_bad_value_of_monitor_toml_is_blamed_on_the_file(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copytree(folder, tmp_path / "campaigns")
    config = tmp_path / "campaigns" / "monitor.toml"
    text = config.read_text()
    config.write_text(text.replace('"yaw_damper_damping"', '"secondary_vertical_damping"'))
    err = _refused(tmp_path / "campaigns", tmp_path / "out", capsys)
    assert f"{config}: parameters: " in err and "--parameters" not in err


def test_an_unknown_key_of_monitor_toml_lists_only_the_keys_it_allows(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copytree(folder, tmp_path / "campaigns")
    config = tmp_path / "campaigns" / "monitor.toml"
    config.write_text('rigg = "hst_trailer"\n' + config.read_text())
    err = _refused(tmp_path / "campaigns", tmp_path / "out", capsys)
    assert f"{config}: rigg: unknown key (did you mean 'rig'?); allowed keys: rig, " in err
    assert "data" not in err.split("allowed keys:")[1]  # data and out are refused there


@pytest.mark.parametrize("damage", ["folder", "utf16"])
def test_a_monitor_toml_that_is_no_utf8_file_is_named(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], damage: str
) -> None:
    """Outside probe, session 29: a folder named monitor.toml was ignored (the default rig
    was used and the error was about a rig mismatch); a UTF-16 file said "not valid TOML"."""
    shutil.copytree(folder, tmp_path / "campaigns")
    config = tmp_path / "campaigns" / "monitor.toml"
    text = config.read_text()
    config.unlink()
    if damage == "folder":
        config.mkdir()
    else:
        config.write_bytes(text.encode("utf-16"))
    err = _refused(tmp_path / "campaigns", tmp_path / "out", capsys)
    expected = (
        "not a file; expected the monitoring"
        if damage == "folder"
        else ("not a UTF-8 text file (byte 0xff at position 0")
    )
    assert f"{config}: {expected}" in err and "Traceback" not in err


def test_a_rig_path_on_the_command_line_is_relative_to_the_current_folder(
    folder: Path, fast_rig: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Not to the monitoring folder (a monitor.toml's rig path is)."""
    monkeypatch.chdir(fast_rig.parent)
    config = base_config(folder, tmp_path / "out", rig=fast_rig.name)
    assert Path(config.rig) == fast_rig.resolve()


def test_a_numpy_integer_budget_is_an_integer(folder: Path, tmp_path: Path) -> None:
    config = base_config(folder, tmp_path / "out", budget=np.int64(60))
    assert config.budget.max_evaluations == 60
    assert type(config.budget.max_evaluations) is int


@pytest.mark.parametrize("value", ["-0.5", "nan", "0", "1", "2", "abc"])
def test_the_threshold_is_a_probability(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str
) -> None:
    err = _refused(folder, tmp_path / "out", capsys, f"--threshold={value}")
    assert (
        f"argument --threshold: {value!r} is not allowed; expected a probability in (0, 1)" in err
    )


def test_the_python_api_refuses_a_threshold_outside_0_1(folder: Path, tmp_path: Path) -> None:
    with pytest.raises(
        MonitorError, match=r"threshold: got 1.5; expected a probability in \(0, 1\)"
    ):
        susp_bo.monitor(folder, tmp_path / "out", threshold=1.5, progress=False)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("arguments", "expected"),
    [
        ({"threshold": "0.5"}, r"threshold: '0.5' \(str\) is not allowed; expected a probability"),
        ({"budget": -5}, "budget: -5 is not allowed; expected an integer >= 2"),
        ({"budget": 1}, "budget: 1 is not allowed; expected an integer >= 2"),
        ({"budget": 60.0}, "budget: 60.0 is not allowed"),
        (
            {"parameters": "yaw_damper_damping"},
            r"parameters: 'yaw_damper_damping' is not allowed; expected a non-empty list .* "
            r"e\.g\. \['yaw_damper_damping'\]",
        ),
    ],
)
def test_the_python_api_names_the_bad_argument(
    folder: Path, tmp_path: Path, arguments: dict[str, Any], expected: str
) -> None:
    """A str threshold was a TypeError from '<', budget = -5 blamed budget.initial_design
    (the design size cut to the budget), a str of parameters was split into characters."""
    with pytest.raises(MonitorError, match=expected) as raised:
        susp_bo.monitor(folder, tmp_path / "out", progress=False, **arguments)
    assert "--" not in str(raised.value).split(":")[0]  # the keyword, not susp-bo's flag
    assert not (tmp_path / "out").exists()


def test_the_python_api_names_a_bad_rig_or_parameter_by_its_keyword(
    folder: Path, tmp_path: Path
) -> None:
    """Errors of susp_bo.monitor(parameters=...) told a Python caller to fix --parameters."""
    with pytest.raises(MonitorError, match=r"^parameters: .*nonexistent") as raised:
        susp_bo.monitor(folder, tmp_path / "out", parameters=["nonexistent"], progress=False)
    assert "--parameters" not in str(raised.value)
    with pytest.raises(MonitorError, match=r"^rig: 'nosuchrig' is not allowed"):
        susp_bo.monitor(folder, tmp_path / "out", rig="nosuchrig", progress=False)
    with pytest.raises(MonitorError, match=r"^workers: "):
        susp_bo.monitor(folder, tmp_path / "out", workers=-3, progress=False)


def test_the_minimum_a_small_budget_is_told_is_a_budget_that_runs(
    folder: Path, tmp_path: Path
) -> None:
    """The design was cut to the budget, so the minimum named for --budget 5 (26) was
    refused in turn (minimum 42 with a design of 26), and that one too (56)."""
    own = tmp_path / "campaigns"
    shutil.copytree(folder, own)
    settings = tomllib.loads((own / "monitor.toml").read_text())
    del settings["budget"]  # the default design of 40 points, batches of 8, 8 check points
    (own / "monitor.toml").write_text(tomli_w.dumps(settings))
    small = base_config(own, tmp_path / "out", budget=5)
    q = calibrated_count(small)
    assert q is not None
    b = small.budget
    minimum = budget_requirement(q, b.initial_design, b.batch_size, b.check_points).minimum
    assert minimum > 5
    enough = base_config(own, tmp_path / "out", budget=minimum).budget
    again = budget_requirement(q, enough.initial_design, enough.batch_size, enough.check_points)
    assert again.minimum == minimum


def test_a_campaign_folder_another_process_writes_into_is_refused_before_any_work(
    folder: Path, tmp_path: Path, held_elsewhere: Any
) -> None:
    """A campaign held by another process (a `calibrate --resume` on it) was met only when
    monitor reached it, possibly hours into the run (second review, session 23)."""
    campaign = tmp_path / "out" / "TRAIN-1" / "2026-01-10"
    campaign.mkdir(parents=True)
    with held_elsewhere(campaign) as pid:
        with pytest.raises(
            MonitorError, match=rf"campaign TRAIN-1/2026-01-10: out: .* in use by process "
            rf"{pid}"
        ):  # fmt: skip
            susp_bo.monitor(folder, tmp_path / "out", progress=False)
        assert sorted(p.name for p in campaign.iterdir()) == [".susp-bo.lock"]
