"""Shared test fixtures: seeded random generators, float64 torch, a headless matplotlib.

Hypothesis profiles: ``ci`` (loaded when the ``CI`` environment variable is set, as
``.ci/run`` does) derandomises the examples (a fixed, reproducible set per test: CI cannot
turn red by chance on correct code) and keeps no example database (no sticky failure from
an earlier run); ``dev`` (the default elsewhere) draws fresh random examples each run and
keeps the ``.hypothesis/`` database, so local runs go on searching for real bugs. Choose
one explicitly with ``pytest --hypothesis-profile=ci``.
"""

from __future__ import annotations

import os

os.environ.setdefault("MPLBACKEND", "Agg")

from collections.abc import Iterator

import numpy as np
import pytest
import torch
from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
settings.register_profile("dev", print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


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
