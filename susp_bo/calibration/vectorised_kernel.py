"""The state every vectorised MCMC kernel of this package shares with ``pyro.infer.MCMC``.

Both kernels (:class:`.mcmc.RandomWalkMetropolis`, :class:`.hmc.ReflectiveHMC`) keep all
chains in one (n_chains x q) tensor under one site name, so that one kernel step
advances every chain with one batched potential call. :class:`VectorisedKernel` holds
that initial state and the ``MCMCKernel`` interface around it.
"""

from __future__ import annotations

import torch
from pyro.infer.mcmc.mcmc_kernel import MCMCKernel


class VectorisedKernel(MCMCKernel):
    """An ``MCMCKernel`` whose state is (n_chains x q) positions under ``self.site``.

    Subclasses set ``self.site`` (str) and ``self._init`` ((n_chains x q) float64).
    """

    transforms: dict = {}  # noqa: RUF012  (tells pyro.infer.MCMC there is no model)
    site: str
    _init: torch.Tensor

    @property
    def initial_params(self) -> dict[str, torch.Tensor]:
        """Initial state {site: (n_chains x q)}."""
        return {self.site: self._init}

    @initial_params.setter
    def initial_params(self, params: dict[str, torch.Tensor]) -> None:
        init = torch.as_tensor(params[self.site], dtype=torch.float64)
        if init.shape != self._init.shape:
            raise ValueError(
                f"initial_params: shape {tuple(init.shape)} != {tuple(self._init.shape)}"
            )
        self._init = init
