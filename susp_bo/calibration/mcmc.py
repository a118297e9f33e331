"""Step 4: the project's random-walk Metropolis–Hastings kernel and its drivers.

:class:`RandomWalkMetropolis` is a ``pyro.infer.mcmc.mcmc_kernel.MCMCKernel`` driven
by a potential function U(w) = −log π(w) (``+inf`` outside the support). Its state
is a (n_chains x q) tensor: one kernel step advances every chain at once with one
batched potential call, which is what makes millions of draws affordable (Pyro's
own MCMC loop costs ~200 µs a step, so a step must carry many chains).

Proposal: w' = w + s · L ε, ε ~ N(0, I), L the Cholesky factor of the proposal
covariance Σ shared by all chains. Accept with probability min(1, exp(U(w) − U(w'))).
During warm-up (the first ``warmup_steps`` steps) the kernel adapts:

- Σ: at the end of doubling windows (25, 50, 100, … steps) Σ is set to the sample
  covariance pooled over all chains in the window (plus 1e-10 I), with the base
  scale 2.38/√q (Roberts–Rosenthal); the last 15 % of warm-up keeps Σ fixed;
- s: Robbins–Monro on log s towards the target acceptance rate (0.234 for q ≥ 5,
  0.44 for q = 1), using the mean acceptance probability over chains.

After warm-up Σ and s are frozen, so the sampling phase is an exact MH chain (the
test suite checks moments on Gaussian and banana targets against the truth and
against emcee, through ``pyro.infer.MCMC`` and through the fast path).

Separated modes (:mod:`.mode_jumps`): half-way through warm-up the chains'
positions are split into clearly separated clusters; with two or more, each chain
and step proposes, with probability ``jump_probability``, a jump drawn from a
frozen Gaussian mixture over the modes (an independence proposal with its MH
correction) instead of the random-walk move, so the chains share the mass between
modes as the posterior does instead of as they started. When no split is found
the kernel is exactly the random-walk kernel above (same random numbers, same
draws).

Two drivers run the same ``sample`` step function (of this kernel or of
:class:`~.hmc.ReflectiveHMC`, the gradient-based kernel for long curved ridges):

- :func:`run_pyro` — through ``pyro.infer.MCMC`` (``num_chains=1``: our chains live
  inside the state tensor);
- :func:`run_vectorized` — a plain torch loop (no per-step dict/list overhead).

Given the same seed both give bit-identical draws. All randomness comes from the
kernel's own ``torch.Generator`` seeded in ``setup``; nothing touches global state.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import pyro.ops.stats as pyro_stats
import torch
from pyro.infer import MCMC

from susp_bo.calibration.hmc import ReflectiveHMC
from susp_bo.calibration.mode_jumps import MixtureProposal, find_modes
from susp_bo.calibration.vectorised_kernel import VectorisedKernel
from susp_bo.progress import progress_bar, redrawn_bars

Potential = Callable[[torch.Tensor], torch.Tensor]


def default_target_acceptance(q: int) -> float:
    """Asymptotically optimal acceptance rates of random-walk MH (0.44 in 1-D, 0.234 high-D)."""
    return {1: 0.44, 2: 0.35, 3: 0.31, 4: 0.28}.get(q, 0.234)


class RandomWalkMetropolis(VectorisedKernel):
    """Vectorised adaptive random-walk MH kernel on a potential function.

    Args:
        potential_fn: maps (n_chains x q) float64 positions to (n_chains,) potentials
            −log π (``inf`` outside the support, NaN treated as ``inf``).
        initial_params: (n_chains x q) initial positions (finite potential required).
        proposal_cov: (q x q) initial proposal covariance; default 0.01 I.
        adapt: adapt the proposal during warm-up.
        target_accept: target acceptance rate in (0, 1); default by dimension.
        seed: seed of the kernel's own generator (reset in ``setup``).
        site: name of the parameter in the params dict.
        jump_probability: per chain and step, the probability of a mode jump once
            separated modes were found half-way through warm-up (0 = never look).
        mixture: a frozen mixture proposal over modes found beforehand (K components in
            q dimensions), jumped with from the first step; none is then planned
            half-way through warm-up. Needs ``jump_probability`` > 0.
    """

    def __init__(
        self,
        potential_fn: Potential,
        initial_params: torch.Tensor,
        *,
        proposal_cov: torch.Tensor | None = None,
        adapt: bool = True,
        target_accept: float | None = None,
        seed: int = 0,
        site: str = "w",
        jump_probability: float = 0.1,
        mixture: MixtureProposal | None = None,
    ) -> None:
        init = torch.as_tensor(initial_params, dtype=torch.float64)
        if not 0.0 <= jump_probability < 1.0:
            raise ValueError(f"jump_probability: {jump_probability} must be in [0, 1)")
        self.jump_probability = float(jump_probability)
        if init.ndim != 2 or init.shape[0] < 1:
            raise ValueError(f"initial_params: shape {tuple(init.shape)}, expected (n_chains x q)")
        q = init.shape[1]
        if mixture is not None and (jump_probability == 0.0 or mixture.means.shape[1] != q):
            raise ValueError(
                f"mixture: {mixture.means.shape[1]}-D components with jump_probability "
                f"{jump_probability}, expected {q}-D components and jump_probability > 0"
            )
        self._given_mixture = mixture
        self.potential_fn = potential_fn
        self.site = site
        self.seed = int(seed)
        self.adapt = adapt
        self.target_accept = (
            target_accept if target_accept is not None else (default_target_acceptance(q))
        )
        if not 0.0 < self.target_accept < 1.0:
            raise ValueError(f"target_accept: {self.target_accept} must be in (0, 1)")
        cov = proposal_cov if proposal_cov is not None else 0.01 * torch.eye(q, dtype=torch.float64)
        self._initial_cov = torch.as_tensor(cov, dtype=torch.float64)
        if self._initial_cov.shape != (q, q):
            raise ValueError(
                f"proposal_cov: shape {tuple(self._initial_cov.shape)}, expected {q}x{q}"
            )
        self._init = init
        self.model = None
        self.setup(0)

    # -- MCMCKernel interface (initial_params: VectorisedKernel) ------------------------
    def setup(self, warmup_steps: int, *args: object, **kwargs: object) -> None:
        """Resets generator, step counter and proposal; evaluates the initial potential."""
        self.warmup_steps = int(warmup_steps)
        self._generator = torch.Generator().manual_seed(self.seed)
        self._t = 0
        q = self._init.shape[1]
        self._chol = torch.linalg.cholesky(self._initial_cov)
        self._log_scale = 0.0 if not self.adapt else math.log(1.0)
        self._base = 1.0
        self._window_start, self._window_len = 0, 25
        self._window_sum = torch.zeros(q, dtype=torch.float64)
        self._window_outer = torch.zeros(q, q, dtype=torch.float64)
        self._window_count = 0
        self._accepted = 0.0
        self._proposed = 0
        self._mixture: MixtureProposal | None = self._given_mixture
        self._jumps_proposed = 0
        self._jumps_accepted = 0.0
        self._state = self._init
        self._potential = self._evaluate(self._init)
        if not torch.all(torch.isfinite(self._potential)):
            raise ValueError("initial_params: every chain must start where the potential is finite")

    def _evaluate(self, w: torch.Tensor) -> torch.Tensor:
        u = self.potential_fn(w)
        return torch.where(torch.isnan(u), torch.full_like(u, math.inf), u)

    def sample(self, params: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """One MH step of every chain: returns a new dict (never mutates its input)."""
        x = params[self.site]
        if x is not self._state:
            self._state, self._potential = x, self._evaluate(x)
        planned = self._given_mixture is None and self.jump_probability > 0.0
        if planned and self._t == self.warmup_steps // 2:
            self._plan_jumps(x)
        noise = torch.randn(x.shape, generator=self._generator, dtype=torch.float64)
        scale = self._base * math.exp(self._log_scale)
        proposal = x + scale * noise @ self._chol.T
        jump = None
        if self._mixture is not None:  # with one mode: no extra random numbers at all
            jump = (
                torch.rand(x.shape[0], generator=self._generator, dtype=torch.float64)
                < self.jump_probability
            )
            drawn = self._mixture.draw(x.shape[0], self._generator)
            proposal = torch.where(jump[:, None], drawn, proposal)
        u_prop = self._evaluate(proposal)
        log_u = torch.log(torch.rand(x.shape[0], generator=self._generator, dtype=torch.float64))
        log_alpha = self._potential - u_prop
        if jump is not None and self._mixture is not None:  # independence-proposal correction
            correction = self._mixture.log_density(x) - self._mixture.log_density(proposal)
            log_alpha = log_alpha + torch.where(jump, correction, torch.zeros_like(correction))
        accept = log_u < log_alpha
        new_x = torch.where(accept[:, None], proposal, x)
        self._potential = torch.where(accept, u_prop, self._potential)
        self._state = new_x
        if jump is not None:
            self._jumps_proposed += int(jump.sum())
            self._jumps_accepted += float((accept & jump).sum())
        if self._t < self.warmup_steps:
            if self.adapt:
                self._adapt(new_x, log_alpha if jump is None else log_alpha[~jump])
        else:
            self._accepted += float(accept.sum())
            self._proposed += x.shape[0]
        self._t += 1
        return {self.site: new_x}

    def _plan_jumps(self, x: torch.Tensor) -> None:
        """Half-way through warm-up: the frozen mixture proposal when the chains sit in
        two or more separated modes (:func:`~.mode_jumps.find_modes`), else none."""
        finite = torch.isfinite(self._potential)
        clusters = find_modes(x[finite]) if int(finite.sum()) > 2 * (x.shape[1] + 2) else []
        if len(clusters) >= 2:
            self._mixture = MixtureProposal.of(x[finite], clusters)

    def _adapt(self, x: torch.Tensor, log_alpha: torch.Tensor) -> None:
        if log_alpha.numel() == 0:  # every chain jumped: no random-walk step to learn from
            return  # (the mean of none was NaN and stuck in the scale; review, session 25)
        q = x.shape[1]
        mean_accept = float(torch.exp(log_alpha.clamp(max=0.0)).nan_to_num(0.0).mean())
        gain = max(0.02, (self._t + 1) ** -0.5)
        self._log_scale += gain * (mean_accept - self.target_accept)
        freeze_at = int(0.85 * self.warmup_steps)
        if self._t >= freeze_at:
            return
        self._window_sum += x.sum(0)
        self._window_outer += x.T @ x
        self._window_count += x.shape[0]
        end = self._window_start + self._window_len
        if self._t + 1 >= end or self._t + 1 >= freeze_at:
            n = self._window_count
            if n > q + 1:
                mean = self._window_sum / n
                cov = (self._window_outer - n * torch.outer(mean, mean)) / (n - 1)
                cov = 0.5 * (cov + cov.T) + 1e-10 * torch.eye(q, dtype=torch.float64)
                chol, info = torch.linalg.cholesky_ex(cov)
                if int(info) == 0:
                    self._chol = chol
                    self._base = 2.38 / math.sqrt(q)
                    self._log_scale = 0.0
            self._window_start, self._window_len = self._t + 1, 2 * self._window_len
            self._window_sum.zero_()
            self._window_outer.zero_()
            self._window_count = 0

    def logging(self) -> dict[str, float]:
        """Short progress information."""
        return {"scale": self._base * math.exp(self._log_scale)}

    def diagnostics(self) -> dict[str, float]:
        """Acceptance rate over the sampling phase, the final proposal scale, the number of
        separated modes found and the acceptance rate of the jumps between them."""
        rate = self._accepted / self._proposed if self._proposed else float("nan")
        out = {
            "acceptance rate": rate,
            "scale": self._base * math.exp(self._log_scale),
            "modes": float(1 if self._mixture is None else self._mixture.n_modes),
        }
        if self._jumps_proposed:  # only when modes were found (no NaN in result dicts)
            out["jump acceptance rate"] = self._jumps_accepted / self._jumps_proposed
        return out

    @property
    def proposal_covariance(self) -> torch.Tensor:
        """Current proposal covariance s² L Lᵀ (q x q)."""
        s = self._base * math.exp(self._log_scale)
        return s * s * self._chol @ self._chol.T


def run_vectorized(
    kernel: RandomWalkMetropolis | ReflectiveHMC,
    num_samples: int,
    warmup_steps: int,
    thin: int = 1,
    progress: bool = False,
) -> torch.Tensor:
    """Runs the kernel in a plain torch loop (fast path).

    Args:
        kernel: the random-walk or HMC kernel (its state holds all chains).
        num_samples: sampling steps after warm-up (>= 1).
        warmup_steps: adaptation steps, discarded.
        thin: keep every thin-th sampling step.
        progress: a progress bar (susp_bo.progress) of kernel steps (all chains at once) on stderr.

    Returns:
        (n_chains x (num_samples // thin) x q) draws.
    """
    if num_samples < 1 or warmup_steps < 0 or thin < 1:
        raise ValueError(f"num_samples {num_samples} >= 1, warmup_steps {warmup_steps} >= 0, thin")
    kernel.setup(warmup_steps)
    params = kernel.initial_params
    n_keep = num_samples // thin
    chains, q = params[kernel.site].shape
    bar = progress_bar(
        total=warmup_steps + n_keep * thin,
        desc=f"MCMC ({chains} chains)",
        unit="step",
        disable=not progress,
        mininterval=0.5,
    )
    with bar:
        for _ in range(warmup_steps):
            params = kernel.sample(params)
            bar.update()
        out = torch.empty(n_keep, chains, q, dtype=torch.float64)
        for i in range(n_keep * thin):
            params = kernel.sample(params)
            bar.update()
            if (i + 1) % thin == 0:
                out[(i + 1) // thin - 1] = params[kernel.site]
    return out.transpose(0, 1).contiguous()


def run_pyro(
    kernel: RandomWalkMetropolis | ReflectiveHMC,
    num_samples: int,
    warmup_steps: int,
    progress: bool = False,
) -> torch.Tensor:
    """Runs the kernel through ``pyro.infer.MCMC``; returns (n_chains x num_samples x q).

    ``progress`` shows Pyro's own progress bar, on a terminal only (no redraws in logs).
    """
    mcmc = MCMC(
        kernel,
        num_samples=num_samples,
        warmup_steps=warmup_steps,
        initial_params={kernel.site: kernel.initial_params[kernel.site]},
        num_chains=1,
        disable_progbar=not (progress and redrawn_bars()),
    )
    mcmc.run()
    draws = mcmc.get_samples()[kernel.site]  # num_samples x n_chains x q
    return draws.transpose(0, 1).contiguous()


def chain_diagnostics(draws: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Split R-hat and effective sample size per parameter from Pyro's diagnostics.

    Args:
        draws: (n_chains x n_draws x q) draws.

    Returns:
        (r_hat (q,), ess (q,)). Both are NaN for a constant component (a pinned parameter,
        0 / 0); the other components' values are computed without it (Pyro's batched ESS
        would turn every component's NaN when one is constant).

    Raises:
        ValueError: ``draws`` is not 3-D or has fewer than 4 draws per chain (the split
            R-hat halves every chain and needs two draws in each half).
    """
    if draws.ndim != 3 or draws.shape[1] < 4:
        raise ValueError(
            f"draws: shape {tuple(draws.shape)} is not allowed; expected (n_chains x n_draws "
            "x q) with n_draws >= 4 (the split R-hat needs 4 draws per chain)"
        )
    q = draws.shape[2]
    constant = torch.all(draws.reshape(-1, q) == draws[0, 0], dim=0)
    if bool(constant.any()):
        r_hat = torch.full((q,), math.nan, dtype=draws.dtype)
        ess = torch.full((q,), math.nan, dtype=draws.dtype)
        if not bool(constant.all()):
            r_hat[~constant], ess[~constant] = chain_diagnostics(draws[:, :, ~constant])
        return r_hat, ess
    r_hat = pyro_stats.split_gelman_rubin(draws, chain_dim=0, sample_dim=1)
    ess = pyro_stats.effective_sample_size(draws, chain_dim=0, sample_dim=1)
    return r_hat, ess
