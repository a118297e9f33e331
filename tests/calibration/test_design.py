"""Space-filling designs: inside the box, reproducible, space-filling."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.calibration.design import (
    default_design_size,
    from_unit,
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
