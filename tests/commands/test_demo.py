"""``susp-bo demo --smoke``: the main job end to end, as a new user runs it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from susp_bo.commands.demo import DEMO_RIG, DEMO_TRUTH, check_demo_folder, demo_runs_setting
from susp_bo.rig.spec import load_rig_spec

pytestmark = pytest.mark.slow


def test_demo_smoke_writes_a_result_with_the_truth_and_figures(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    done = subprocess.run(
        [sys.executable, "-m", "susp_bo", "demo", "--smoke", "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    payload = json.loads((out / "result.json").read_text())
    assert payload["parameters"] == list(DEMO_TRUTH)
    assert payload["reference"] == [DEMO_TRUTH[name] for name in payload["parameters"]]
    assert payload["n_simulations"] == 2 * payload["n_evaluations"]
    assert len(list((out / "data").glob("run_*.h5"))) == 2
    assert len(list(out.glob("*.png"))) >= 3
    # progress and the summary table go to stderr
    assert "marginal MAP" in done.stderr
    assert "simulations" in done.stderr
    # stderr is a pipe here: plain progress lines, no escape codes, no PyBullet banners
    assert "log L evaluations: 10/10 eval (100 %)" in done.stderr
    for output in (done.stdout, done.stderr):
        assert "\x1b" not in output and "\r" not in output
        assert "argv[0]" not in output and "pybullet build time" not in output
    # its runs are recognised: a rerun with the same flags continues on them (none to make),
    # one with another seed is refused before any work and leaves the folder as it is
    setting = demo_runs_setting(load_rig_spec(DEMO_RIG), smoke=True, seed=2024)
    assert check_demo_folder(out, setting, smoke=True) == []
    before = {path: path.read_bytes() for path in out.rglob("*") if path.is_file()}
    again = subprocess.run(
        [sys.executable, "-m", "susp_bo", "demo", "--smoke", "--seed", "7", "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert again.returncode == 2 and "seed 2024, the demo's 7" in again.stderr, again.stderr
    assert {path: path.read_bytes() for path in out.rglob("*") if path.is_file()} == before
