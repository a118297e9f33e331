"""The budget of ``susp-bo monitor`` is refused once, named as the caller set it."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import pytest
import tomli_w

import susp_bo
from susp_bo.cli import main
from susp_bo.monitoring.campaign_checks import small_budget_problem
from susp_bo.monitoring.runner import API_NAMES, CLI_NAMES, MonitorError, base_config


@pytest.fixture(scope="module")
def folder(one_campaign_folder: Any) -> Path:
    """One campaign; ``monitor.toml`` with a budget of 8, below the minimum, not allowed."""
    root = one_campaign_folder("budget")
    path = root / "monitor.toml"
    settings = tomllib.loads(path.read_text())
    settings["budget"]["allow_small"] = False
    path.write_text(tomli_w.dumps(settings))
    return root


def test_the_python_api_is_told_its_keywords_not_the_command_line_flags(
    folder: Path, tmp_path: Path
) -> None:
    """susp_bo.monitor(budget=5) was told to "give budget.max_evaluations (--budget) 14 or
    more, or set [budget] allow_small = true (--allow-small-budget)", blamed on the first
    campaign (session 23's note)."""
    with pytest.raises(MonitorError) as raised:
        susp_bo.monitor(folder, tmp_path / "out", budget=5, progress=False)
    text = str(raised.value)
    assert text.startswith("budget 5 is below the minimum 14 for q = 2 parameters")
    assert "give budget 14 or more, or pass allow_small_budget=True" in text
    assert "--" not in text and "campaign" not in text.split(":")[0]
    assert not (tmp_path / "out").exists()


def test_the_command_line_is_told_its_flags(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(["monitor", str(folder), "--out", str(out), "--budget", "5"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("susp-bo monitor: --budget 5 is below the minimum 14")
    assert "give --budget 14 or more, or pass --allow-small-budget" in err
    assert not out.exists()


def test_a_budget_of_monitor_toml_is_blamed_on_the_file(folder: Path, tmp_path: Path) -> None:
    with pytest.raises(MonitorError) as raised:
        susp_bo.monitor(folder, tmp_path / "out", progress=False)
    text = str(raised.value)
    assert text.startswith(f"{folder / 'monitor.toml'}: [budget] max_evaluations = 8 is below")
    assert "set it to 14 or more, or set [budget] allow_small = true there" in text
    base = base_config(folder, tmp_path / "out", arguments=CLI_NAMES)
    problem = small_budget_problem(base, 2, False, CLI_NAMES, folder / "missing.toml")
    assert problem is not None
    assert problem.startswith("the default budget (8) is below the minimum 14")
    assert "pass --budget 14 or more, or pass --allow-small-budget" in problem


def test_enough_or_allowed_is_no_problem(folder: Path, tmp_path: Path) -> None:
    config = folder / "monitor.toml"
    enough = base_config(folder, tmp_path / "out", budget=14, arguments=API_NAMES)
    assert small_budget_problem(enough, 2, True, API_NAMES, config) is None
    allowed = base_config(folder, tmp_path / "out", budget=5, allow_small_budget=True)
    assert small_budget_problem(allowed, 2, True, API_NAMES, config) is None
    small = base_config(folder, tmp_path / "out", budget=13, arguments=API_NAMES)
    assert small_budget_problem(small, 2, True, API_NAMES, config) is not None


def test_a_warm_budget_is_checked_like_the_budget_and_named_as_given(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--warm-budget`` (session 28): below the minimum for q, or not an integer >= 2, it is
    refused before any work, naming itself — not ``--budget``, which is enough here."""
    out = tmp_path / "out"
    assert main(["monitor", str(folder), "--out", str(out), "--budget", "14",
                 "--warm-budget", "5"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert err.startswith("susp-bo monitor: --warm-budget 5 is below the minimum 14")
    assert "give --warm-budget 14 or more, or pass --allow-small-budget" in err
    assert main(["monitor", str(folder), "--out", str(out), "--warm-budget", "1"]) == 2
    assert "argument --warm-budget: '1' is not allowed" in capsys.readouterr().err
    with pytest.raises(MonitorError, match=r"^warm_budget 5 is below the minimum 14"):
        susp_bo.monitor(folder, out, budget=14, warm_budget=5, progress=False)
    for bad in (True, 1, 2.5):
        with pytest.raises(MonitorError, match=rf"^warm_budget: {bad!r} is not allowed"):
            susp_bo.monitor(folder, out, budget=14, warm_budget=bad, progress=False)
    assert not out.exists()
    # no warm start asked for: the warm budget plays no part, so it is not refused for size
    allowed = base_config(folder, out, budget=14, arguments=API_NAMES)
    assert small_budget_problem(allowed, 2, True, API_NAMES, folder / "monitor.toml") is None
