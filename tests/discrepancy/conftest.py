"""Fixtures of the discrepancy tests: the scenario rig and the fast-path simulator."""

from __future__ import annotations

import pytest

from susp_bo.discrepancy.problem import LinearSimulator
from susp_bo.discrepancy.scenarios import scenario_spec
from susp_bo.rig.spec import RigSpec


@pytest.fixture(scope="session")
def base_spec() -> RigSpec:
    """The maintainer's base rig, 20 s records, band 0.3–40 Hz."""
    return scenario_spec(duration_s=20.0, warm_up_s=4.0)


@pytest.fixture(scope="session")
def linear_simulator() -> LinearSimulator:
    """The fast path (one instance: its per-track input transforms are reused)."""
    return LinearSimulator()
