"""Unit-cube tools shared by the basin phase and its hunt: max-norm distances, projected ascent."""

from __future__ import annotations

import numpy as np
import torch

from susp_bo.calibration.cube_ascent import chebyshev, projected_ascent


def test_chebyshev_is_the_largest_coordinate_gap() -> None:
    a = np.array([[0.0, 0.0], [0.5, 0.2]])
    b = np.array([[0.1, 0.3], [0.5, 0.2], [1.0, 0.0]])
    np.testing.assert_allclose(chebyshev(a, b), [[0.3, 0.5, 1.0], [0.4, 0.0, 0.5]])


def test_the_ascent_finds_an_inner_maximum_and_stops_at_the_cube_face() -> None:
    centre = torch.tensor([0.3, 1.4])  # the second coordinate's maximum lies outside the cube

    def objective(x: torch.Tensor) -> torch.Tensor:
        return -((x - centre) ** 2).sum(-1)

    starts = np.array([[0.9, 0.1], [0.1, 0.5]])
    ends = projected_ascent(objective, starts, steps=400)
    np.testing.assert_allclose(ends, [[0.3, 1.0], [0.3, 1.0]], atol=1e-3)
    np.testing.assert_array_equal(starts, [[0.9, 0.1], [0.1, 0.5]])  # starts untouched
