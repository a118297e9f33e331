"""Fixtures for end-to-end runs of the real stack on a short, cheap version of the reference rig."""

from __future__ import annotations

import contextlib
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from susp_bo.data.measured import save_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.spec import load_rig_spec

FAST_TRUTH = {"secondary_vertical_damping": 30.0e3, "yaw_damper_damping": 3.5e6}
FAST_PARAMETERS = ("secondary_vertical_damping", "yaw_damper_damping")


@pytest.fixture(scope="session")
def fast_data(fast_rig: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two synthetic measured runs of the fast rig with a known worn state."""
    folder = tmp_path_factory.mktemp("measured")
    runs = synthesize_runs(load_rig_spec(fast_rig), FAST_TRUTH, nu=2, seed=7, noise_m_s2=0.005)
    for index, run in enumerate(runs):
        save_run(run, folder / f"run_{index:03d}.h5")
    return folder


def write_study(
    folder: Path, rig: Path, data: Path, out: Path, executor: str = "workers = 2"
) -> Path:
    """A small study config (q = 2, 10 evaluations in batches of 2, below the minimum on
    purpose: ``allow_small``) in ``folder``."""
    path = folder / "study.toml"
    path.write_text(
        f"""rig = "{rig}"
data = "{data}"
out = "{out}"
parameters = {list(FAST_PARAMETERS)!r}

[budget]
max_evaluations = 10
initial_design = 6
batch_size = 2
allow_small = true

[executor]
{executor}

[mcmc]
chains = 8
draws = 300
warmup = 200
""".replace("'", '"')
    )
    return path


@pytest.fixture(scope="session")
def study_writer():
    """:func:`write_study`, as a fixture (test modules cannot import each other)."""
    return write_study


def calibrate_cli(config: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """``python -m susp_bo calibrate CONFIG [extra]`` in a subprocess, output captured."""
    return subprocess.run(
        [sys.executable, "-m", "susp_bo", "calibrate", str(config), *extra],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )


@pytest.fixture(scope="session")
def calibrate_command():
    """:func:`calibrate_cli`, as a fixture."""
    return calibrate_cli


@pytest.fixture(scope="session")
def uninterrupted(fast_rig, fast_data, tmp_path_factory) -> Path:
    """Results folder of the small study run once without interruption (2 worker processes)."""
    folder = tmp_path_factory.mktemp("uninterrupted")
    config = write_study(folder, fast_rig, fast_data, folder / "out")
    done = calibrate_cli(config)
    assert done.returncode == 0, done.stderr[-3000:]
    return folder / "out"


def stored_rows(store: Path, columns: str = "key") -> list[tuple]:
    """``columns`` of every evaluation in ``store``, in the order recorded; [] while the
    file or its tables are still being made (read-only: a running study may hold it)."""
    if not store.exists():
        return []
    try:
        db = sqlite3.connect(f"file:{store}?mode=ro", uri=True)
        try:
            return db.execute(f"SELECT {columns} FROM evaluations ORDER BY id").fetchall()
        finally:
            db.close()
    except sqlite3.DatabaseError:
        return []


def calibrate_killed(config: Path, store: Path, rows: int, timeout_s: float = 300) -> int:
    """``python -m susp_bo calibrate CONFIG``, killed with SIGKILL (its pool workers too) as
    soon as ``store`` holds ``rows`` evaluations; returns its exit status.

    Fails the test if the study ends before it could be killed.
    """
    process = subprocess.Popen(
        [sys.executable, "-m", "susp_bo", "calibrate", str(config)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline and len(stored_rows(store)) < rows:
            assert process.poll() is None, "the study ended before it could be killed"
            time.sleep(0.05)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)  # its orphaned pool workers too
        process.wait(timeout=30)
    return process.returncode
