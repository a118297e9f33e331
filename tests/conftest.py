"""Shared test fixtures: seeded random generators, float64 torch, a headless matplotlib,
the cheap rig of the end-to-end tests (``fast_rig``); files holding ``slow`` tests run first.

Hypothesis profiles: ``ci`` (loaded when the ``CI`` environment variable is set, as
``.ci/run`` does) derandomises the examples (a fixed, reproducible set per test: CI cannot
turn red by chance on correct code) and keeps no example database (no sticky failure from
an earlier run); ``dev`` (the default elsewhere) draws fresh random examples each run and
keeps the ``.hypothesis/`` database, so local runs go on searching for real bugs. Choose
one explicitly with ``pytest --hypothesis-profile=ci``.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys

os.environ.setdefault("MPLBACKEND", "Agg")

import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import torch
from hypothesis import settings

from susp_bo.rig.catalog import rig_path

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
settings.register_profile("dev", print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Files that hold a ``slow`` test run first (a stable reorder: order within a file and
    among the other files unchanged), so that under pytest-xdist's ``--dist loadfile`` the
    longest files start first and the run does not end with one worker on a long file."""
    slow_files = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow_files)


@pytest.fixture
def rng() -> np.random.Generator:
    """A numpy generator with a fixed seed, fresh for every test."""
    return np.random.default_rng(20241122)


@pytest.fixture(autouse=True)
def _float64_and_seeded_torch() -> Iterator[None]:
    """Every test runs with float64 as torch's default dtype and a seeded torch RNG."""
    previous = torch.get_default_dtype()
    torch.set_default_dtype(torch.float64)
    torch.manual_seed(0)
    yield
    torch.set_default_dtype(previous)


@pytest.fixture
def blas_thread_counts() -> Callable[[], set[int]]:
    """A function giving the thread counts of every BLAS library loaded in this process,
    read at each call (threadpoolctl), e.g. ``{1}`` inside ``one_blas_thread()``."""
    from threadpoolctl import threadpool_info

    def counts() -> set[int]:
        return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}

    return counts


FAST_TIME_STEP_S = 0.005
"""The fast rig's PyBullet step (s): 200 Hz, the coarsest step the 100 Hz output allows.

Its spectra differ from the 2 ms reference step's by up to 0.27 in log amplitude (rms 0.05,
measured on three tracks); every test on it synthesises its data with the same rig, so the
model stays exact for them, at 2.4x less simulation time."""


@pytest.fixture(scope="session")
def fast_rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The reference rig made cheap for end-to-end tests: 8 s records after 1 s warm-up,
    4 s Welch segments, a 5 ms step (:data:`FAST_TIME_STEP_S`)."""
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    document["rig"]["name"] = "hst_trailer_fast"
    document["simulation"].update(duration_s=8.0, warm_up_s=1.0, time_step_s=FAST_TIME_STEP_S)
    document["spectrum"].update(segment_s=4.0, f_min_hz=0.5, n_frequencies=32)
    path = tmp_path_factory.mktemp("rigs") / "hst_trailer_fast.toml"
    path.write_text(tomli_w.dumps(document))
    return path


_HOLD_FOLDER = (
    "import sys, time; from pathlib import Path; "
    "from susp_bo.output_lock import hold_output_folder\n"
    "with hold_output_folder(Path(sys.argv[1])):\n"
    "    print('held', flush=True); time.sleep(120)\n"
)


@pytest.fixture
def held_elsewhere() -> Callable[[Path], contextlib.AbstractContextManager[int]]:
    """``with held_elsewhere(folder) as pid:`` — another process holds ``folder``'s results
    lock (:mod:`susp_bo.output_lock`) for the block, then is killed (kill -9: the operating
    system releases the lock)."""

    @contextlib.contextmanager
    def hold(folder: Path) -> Iterator[int]:
        holder = subprocess.Popen(
            [sys.executable, "-c", _HOLD_FOLDER, str(folder)], stdout=subprocess.PIPE, text=True
        )
        try:
            assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
            yield holder.pid
        finally:
            holder.kill()
            holder.communicate()  # waits, and closes the pipe

    return hold
