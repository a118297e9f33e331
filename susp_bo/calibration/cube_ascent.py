"""Two unit-cube tools the basin phase and its hunt share: max-norm distances, and a
projected gradient ascent of a surrogate-derived objective."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch


def chebyshev(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n x m) max-norm distances between the rows of a (n x q) and b (m x q)."""
    return np.max(np.abs(a[:, None, :] - b[None, :, :]), axis=-1)


def projected_ascent(
    objective: Callable[[torch.Tensor], torch.Tensor], u: np.ndarray, steps: int
) -> np.ndarray:
    """Where gradient ascent on ``objective`` takes each start, kept in the unit cube.

    Args:
        objective: (n x q) points -> (n,) values to maximise (differentiable).
        u: (n x q) starts in the unit cube.
        steps: Adam steps (learning rate 0.01 unit-cube lengths; each followed by a
            projection on the cube).

    Returns:
        (n x q) end points. Deterministic: no random draw.
    """
    x = torch.tensor(u, dtype=torch.float64, requires_grad=True)
    optimiser = torch.optim.Adam([x], lr=0.01)
    for _ in range(steps):
        optimiser.zero_grad()
        (-objective(x).sum()).backward()
        optimiser.step()
        with torch.no_grad():
            x.clamp_(0.0, 1.0)
    return x.detach().numpy()
