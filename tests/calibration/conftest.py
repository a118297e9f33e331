"""Calibration tests run torch single-threaded (as ``calibrate`` does by default).

The GP matrices here are small: on a shared 2-core machine, intra-op threads cost
far more in contention than they bring (see CalibrationSettings.num_threads).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import torch


@pytest.fixture(autouse=True)
def _single_torch_thread() -> Iterator[None]:
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)
