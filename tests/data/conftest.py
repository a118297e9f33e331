"""Fixtures for the measured-data tests: a small, fully specified run."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from susp_bo.data.measured import MeasuredRun
from susp_bo.rig.track import SpeedProfile, TrackGeometry


def make_run(
    seed: int = 0,
    channels: tuple[str, ...] = ("carbody_z", "bogie_y"),
    duration_s: float = 4.0,
    sample_rate_hz: float = 100.0,
) -> MeasuredRun:
    """A 4 s run at 20 m/s on 100 m of track, white-noise accelerations."""
    rng = np.random.default_rng(seed)
    n = round(duration_s * sample_rate_hz)
    return MeasuredRun(
        geometry=TrackGeometry.synthetic("low", length_m=100.0, seed=seed),
        speed=SpeedProfile(np.array([0.0, 2.0, duration_s]), np.array([20.0, 21.0, 19.5])),
        channels=channels,
        accelerations_m_s2=rng.normal(0.0, 0.3, size=(len(channels), n)),
        sample_rate_hz=sample_rate_hz,
        units=("m/s^2",) * len(channels),
        metadata={"rig": "hst_trailer", "truth": {"secondary_kz": 1.9e5}, "seed": seed},
    )


@pytest.fixture
def small_run() -> MeasuredRun:
    """A small valid run (2 channels, 400 samples at 100 Hz, 100 m of track)."""
    return make_run()


@pytest.fixture(scope="session")
def run_factory() -> Callable[..., MeasuredRun]:
    """The :func:`make_run` helper, for tests that need several distinct runs."""
    return make_run
