"""Both kernels share the chains' state interface that ``pyro.infer.MCMC`` uses."""

from __future__ import annotations

import pytest
import torch

from susp_bo.calibration.hmc import ReflectiveHMC
from susp_bo.calibration.mcmc import RandomWalkMetropolis


def _potential(u: torch.Tensor) -> torch.Tensor:
    return 0.5 * (((u - 0.5) / 0.1) ** 2).sum(1)


@pytest.mark.parametrize("kernel_class", [RandomWalkMetropolis, ReflectiveHMC])
def test_initial_params_round_trip_and_refuse_another_shape(kernel_class: type) -> None:
    starts = torch.full((6, 3), 0.5, dtype=torch.float64)
    kernel = kernel_class(_potential, starts, seed=0)
    assert torch.equal(kernel.initial_params["w"], starts)
    moved = {"w": torch.full((6, 3), 0.4, dtype=torch.float32)}
    kernel.initial_params = moved
    assert kernel.initial_params["w"].dtype == torch.float64
    assert torch.equal(kernel.initial_params["w"], moved["w"].double())
    with pytest.raises(ValueError, match=r"initial_params: shape \(5, 3\) != \(6, 3\)"):
        kernel.initial_params = {"w": torch.zeros(5, 3)}
    assert kernel.transforms == {}
