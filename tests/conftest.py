"""Shared test fixtures: seeded random generators, float64 torch, a headless matplotlib."""

from __future__ import annotations

import os

os.environ.setdefault("MPLBACKEND", "Agg")

from collections.abc import Iterator

import numpy as np
import pytest
import torch


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
