"""Paired data + the local phase through ``susp-bo calibrate``, on PyBullet data.

The fast rig's two runs were synthesised with a known worn state on measured tracks;
the paired posterior is 10⁻⁴ of C_w wide. With ``[search] local = true`` the loop must
reach the maximum, return intervals that hold the truth, say ``trusted`` and report
the local phase in ``result.json``; the kriging posterior's sd must agree with the
Laplace sd of the local phase (an independent estimate of the width).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.integration.conftest import FAST_PARAMETERS, FAST_TRUTH, calibrate_cli


@pytest.mark.slow
def test_paired_study_with_the_local_phase_is_trusted_and_holds_the_truth(
    fast_rig: Path, fast_data: Path, tmp_path: Path
) -> None:
    config = tmp_path / "study.toml"
    config.write_text(
        f"""rig = "{fast_rig}"
data = "{fast_data}"
out = "{tmp_path / "out"}"
parameters = {json.dumps(list(FAST_PARAMETERS))}

[budget]
max_evaluations = 60
initial_design = 10
batch_size = 2
check_points = 6

[executor]
workers = 1

[mcmc]
chains = 64
draws = 600
warmup = 300

[output_error]
model = "paired"

[search]
local = true
"""
    )
    done = calibrate_cli(config)
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    local = result["local_search"]
    assert local is not None and local["stop_reason"] == "converged"
    truth = np.array([FAST_TRUTH[n] for n in FAST_PARAMETERS])
    interval = np.array(result["interval95"])
    assert np.all((interval[:, 0] <= truth) & (truth <= interval[:, 1])), interval
    bounds = np.array(result["bounds"])
    assert np.all(interval[:, 1] - interval[:, 0] < 0.05 * (bounds[:, 1] - bounds[:, 0]))
    ratio = np.array(result["posterior_sd"]) / np.array(local["laplace_sd"])
    assert np.all((ratio > 0.67) & (ratio < 1.5)), ratio
    assert result["reliability"]["verdict"] == "trusted", result["reliability"]["sentence"]
    # the study judged the fit from its runs' residuals too (lack_of_fit.py): ≈ 1 here
    assert 0.3 < result["reliability"]["evidence"]["lack_of_fit_ratio"] < 2.0
    assert "Trusted" in done.stderr.strip().splitlines()[-1]
