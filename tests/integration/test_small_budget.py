"""``susp-bo calibrate RIG DATA --budget N`` on q = 7 data: a too-small budget is refused before
any simulation, and run on request it is never called trusted."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from susp_bo.cli import main

pytestmark = pytest.mark.slow


def _calibrate(rig: Path, data: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "susp_bo",
            "calibrate",
            str(rig),
            str(data),
            "--out",
            str(out),
            *extra,
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )


def test_budget_40_on_seven_parameters_is_refused_naming_the_minimum(
    fast_rig: Path, fast_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for budget in ("40", "3", "50"):
        out = tmp_path / "out"
        args = ["calibrate", str(fast_rig), str(fast_data), "--out", str(out), "--budget", budget]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert f"--budget {budget} is below the minimum 51 for q = 7 parameters" in err
        assert "a design of 35 + one refinement batch of 8 + 8 check points" in err
        assert "--allow-small-budget" in err and "Traceback" not in err
        assert not out.exists()  # refused before anything was written or simulated


def test_a_small_budget_run_on_request_is_not_trusted(
    fast_rig: Path, fast_data: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    done = _calibrate(
        fast_rig, fast_data, out, "--budget", "12", "--allow-small-budget", "--workers", "2"
    )
    assert done.returncode == 0, done.stderr[-3000:]
    payload = json.loads((out / "result.json").read_text())
    reliability = payload["reliability"]
    assert reliability["verdict"] == "not_trusted"
    codes = [r["code"] for r in reliability["reasons"]]
    assert codes[0] == "budget_too_small" and "not_converged" in codes
    assert "surrogate_unchecked" in codes  # 12 evaluations: all design, no check
    # the sentence is the last line on stderr and in the log
    assert done.stderr.strip().splitlines()[-1] == reliability["sentence"]
    assert reliability["sentence"].startswith("Not trusted: the budget of 12 evaluations")
    assert reliability["sentence"] in (out / "study.log").read_text()
