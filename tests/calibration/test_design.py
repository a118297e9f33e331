"""Space-filling designs: inside the box, reproducible, space-filling."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
import torch

from susp_bo.calibration.design import (
    default_design_size,
    from_unit,
    sobol_first_point,
    space_filling_design,
    to_unit,
)

BOUNDS = np.array([[1.0e5, -2.0, 0.0], [4.0e5, 2.0, 1.0e-3]])


@pytest.mark.parametrize("method", ["sobol", "lhs"])
def test_design_is_inside_the_box_and_reproducible(method: str) -> None:
    a = space_filling_design(37, BOUNDS, seed=3, method=method)
    assert a.shape == (37, 3)
    assert np.all(a >= BOUNDS[0]) and np.all(a <= BOUNDS[1])
    np.testing.assert_array_equal(a, space_filling_design(37, BOUNDS, seed=3, method=method))
    assert not np.array_equal(a, space_filling_design(37, BOUNDS, seed=4, method=method))


def test_lhs_has_one_point_per_stratum() -> None:
    u = to_unit(space_filling_design(20, BOUNDS, seed=0, method="lhs"), BOUNDS)
    for k in range(3):
        assert sorted(np.floor(u[:, k] * 20).astype(int)) == list(range(20))


def test_sobol_fills_space_better_than_random(rng: np.random.Generator) -> None:
    u = to_unit(space_filling_design(64, BOUNDS, seed=0), BOUNDS)
    r = rng.uniform(size=(64, 3))

    def min_dist(x: np.ndarray) -> float:
        d = np.linalg.norm(x[:, None] - x[None], axis=-1)
        return float(d[np.triu_indices(64, 1)].min())

    assert min_dist(u) > min_dist(r)


def test_unit_round_trip_and_default_size() -> None:
    w = space_filling_design(5, BOUNDS, seed=1)
    np.testing.assert_allclose(from_unit(to_unit(w, BOUNDS), BOUNDS), w)
    assert default_design_size(7) == 35 and default_design_size(1) == 10


def test_invalid_inputs_name_the_field() -> None:
    with pytest.raises(ValueError, match="bounds"):
        space_filling_design(5, np.array([[0.0, 1.0], [1.0, 1.0]]), seed=0)
    with pytest.raises(ValueError, match="method"):
        space_filling_design(5, BOUNDS, seed=0, method="grid")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="n"):
        space_filling_design(0, BOUNDS, seed=0)


@pytest.fixture
def default_dtype_restored() -> Iterator[None]:
    previous = torch.get_default_dtype()
    yield
    torch.set_default_dtype(previous)


def _sobol_draw(q: int, seed: int, n: int, default: torch.dtype) -> np.ndarray:
    """torch's own scrambled Sobol' points (n x q), float64, under a given default dtype."""
    torch.set_default_dtype(default)
    engine = torch.quasirandom.SobolEngine(q, scramble=True, seed=seed)
    return engine.draw(n, dtype=torch.float64).numpy()


@pytest.mark.parametrize("q", [1, 3, 7])
def test_sobol_design_is_the_same_whatever_torchs_default_dtype(
    q: int, default_dtype_restored: None
) -> None:
    """torch's SobolEngine makes its first point in the default dtype (the quirk: under a
    float64 default it differs from the stock float32 one); the design must not depend on
    what the caller set, and is the one torch's stock float32 default gives."""
    bounds = np.array([np.full(q, -3.0), np.linspace(1.0, 9.0, q)])
    stock = _sobol_draw(q, 2024, 35, torch.float32)
    other = _sobol_draw(q, 2024, 35, torch.float64)
    assert not np.array_equal(stock[0], other[0])  # the quirk itself
    np.testing.assert_array_equal(stock[1:], other[1:])  # the other points do not depend on it
    designs = {}
    for default in (torch.float32, torch.float64):
        torch.set_default_dtype(default)
        designs[default] = [space_filling_design(n, bounds, s) for s in (0, 2024) for n in (1, 35)]
    for a, b in zip(designs[torch.float32], designs[torch.float64], strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(designs[torch.float64][3], from_unit(stock, bounds))


def test_sobol_first_point_needs_a_fresh_engine() -> None:
    engine = torch.quasirandom.SobolEngine(2, scramble=True, seed=1)
    first = sobol_first_point(engine)
    assert first.dtype == np.float64 and np.all((first >= 0) & (first < 1))
    engine.draw(1)
    with pytest.raises(ValueError, match="drawn points already"):
        sobol_first_point(engine)
