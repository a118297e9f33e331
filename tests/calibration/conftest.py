"""Calibration tests run torch single-threaded (as ``calibrate`` does by default).

The GP matrices here are small: on a shared 2-core machine, intra-op threads cost
far more in contention than they bring (see CalibrationSettings.num_threads).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import torch

from susp_bo.calibration.settings import CalibrationSettings

Q1_SETTINGS = CalibrationSettings(
    seed=1,
    max_evaluations=30,
    initial_design_size=10,
    batch_size=2,
    check_points=2,
    mcmc_chains=64,
    mcmc_warmup=200,
    mcmc_samples=200,
)
"""A small q = 1 calibration on the linearised rig (the yaw damper of the discrepancy
scenarios: ``test_lack_of_fit``, ``test_track_match``)."""


@pytest.fixture(autouse=True)
def _single_torch_thread() -> Iterator[None]:
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)
