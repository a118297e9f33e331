"""Two log L on the unit cube that tell the pairwise additive kernel from the Matérn
(shared by test_kernel_advice.py and test_kernel_switch.py)."""

from __future__ import annotations

import numpy as np

DIM = 3
UNIT_BOX = np.array([[0.0] * DIM, [1.0] * DIM])


def chain(u: np.ndarray) -> np.ndarray:
    """A banana chain (log L a sum of terms in one or two parameters), unit cube."""
    x = 6.0 * (u - 0.5)
    out = -0.5 * x[:, 0] ** 2
    for i in range(1, x.shape[1]):
        out = out - 0.5 * ((x[:, i] - 0.5 * x[:, i - 1] ** 2 + 1.0) / 0.5) ** 2
    return out


def three_way(u: np.ndarray) -> np.ndarray:
    """A log L no sum of pairwise terms can be: a radial power and a three-way product."""
    x = 6.0 * (u - 0.5)
    return -0.05 * np.sum(x**2, axis=1) ** 1.5 + 3.0 * np.sin(x[:, 0] * x[:, 1] * x[:, 2] / 3.0)
