"""Fixtures for the monitoring tests: small synthetic campaigns on the suite's ``fast_rig``
(tests/conftest.py)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest
import tomli_w

from susp_bo.monitoring.scenario import write_campaign
from susp_bo.rig.spec import load_rig_spec

PARAMETERS = ["secondary_vertical_damping", "yaw_damper_damping"]
TRUTH = {"secondary_vertical_damping": 30.0e3, "yaw_damper_damping": 3.5e6}


def add_campaign(folder: Path, rig: Path, vehicle: str, date: str, seed: int) -> Path:
    """Two synthetic runs of ``vehicle`` on ``date`` (truth :data:`TRUTH`) under ``folder``."""
    return write_campaign(
        load_rig_spec(rig),
        folder / vehicle / date,
        vehicle=vehicle,
        date=dt.date.fromisoformat(date),
        truth=TRUTH,
        nu=2,
        seed=seed,
        noise_m_s2=0.005,
    )


def write_monitor_config(folder: Path, rig: Path) -> Path:
    """``monitor.toml``: q = 2, 8 evaluations per campaign in batches of 2 (below the minimum,
    allowed: the verdicts are not trusted), short MCMC."""
    path = folder / "monitor.toml"
    path.write_text(
        tomli_w.dumps(
            {
                "rig": str(rig),
                "parameters": PARAMETERS,
                "budget": {
                    "max_evaluations": 8,
                    "initial_design": 6,
                    "batch_size": 2,
                    "check_points": 2,
                    "allow_small": True,  # below the minimum on purpose: fast, not trusted
                },
                "mcmc": {"chains": 8, "draws": 300, "warmup": 200},
            }
        )
    )
    return path


@pytest.fixture(scope="session")
def campaign_adder():
    """:func:`add_campaign`, as a fixture (test modules cannot import each other)."""
    return add_campaign


@pytest.fixture(scope="session")
def monitor_config_writer():
    """:func:`write_monitor_config`, as a fixture."""
    return write_monitor_config


@pytest.fixture(scope="session")
def one_campaign_folder(fast_rig: Path, tmp_path_factory: pytest.TempPathFactory):
    """``make(name)``: a new monitoring folder of one campaign (TRAIN-1, 2026-01-10) with
    the :func:`write_monitor_config` ``monitor.toml``."""

    def make(name: str) -> Path:
        root = tmp_path_factory.mktemp(name) / "campaigns"
        add_campaign(root, fast_rig, "TRAIN-1", "2026-01-10", seed=1)
        write_monitor_config(root, fast_rig)
        return root

    return make
