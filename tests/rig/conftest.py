"""Shared fixtures of the rig tests: the reference spec and short runs on one track."""

from __future__ import annotations

import pytest

from susp_bo.rig.simulator import Rig, RigResponse, synthetic_track
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.track import TrackGeometry

SHORT_DURATION_S = 16.0


@pytest.fixture(scope="session")
def reference_spec() -> RigSpec:
    """The hst_trailer rig as shipped."""
    return load_rig_spec("hst_trailer")


@pytest.fixture(scope="session")
def short_spec(reference_spec: RigSpec) -> RigSpec:
    """hst_trailer with a 16 s record after a 4 s warm-up (tests only)."""
    return reference_spec.with_simulation(duration_s=SHORT_DURATION_S, warm_up_s=4.0)


@pytest.fixture(scope="session")
def short_track(short_spec: RigSpec) -> TrackGeometry:
    """A seeded German-PSD track long enough for one short run."""
    return synthetic_track(short_spec, seed=11)


@pytest.fixture(scope="session")
def reference_response(short_spec: RigSpec, short_track: TrackGeometry) -> RigResponse:
    """One nonlinear PyBullet run of the reference car (shared by several tests)."""
    with Rig(short_spec) as rig:
        return rig.simulate(short_track)
