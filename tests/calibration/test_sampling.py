"""The surrogate posterior's sampler choice: "auto" keeps the random walk where it mixed
(bit for bit), runs a mode-jumping pass where its chains stayed in separated modes and
reflective HMC where they stayed in one, and says which it used."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pytest
import torch

from susp_bo.calibration.mcmc import RandomWalkMetropolis, chain_diagnostics, run_vectorized
from susp_bo.calibration.mode_jumps import (
    MixtureProposal,
    mixture_of_last_positions,
    stuck_modes,
)
from susp_bo.calibration.sampling import (
    HMC_CHAINS,
    MODE_PASS_JUMP_PROBABILITY,
    MODE_PASS_SEED_OFFSET,
    _mode_pass,
    initial_positions,
    mean_sd_at_draws,
    sample_surrogate_posterior,
    surrogate_potential,
)
from susp_bo.calibration.surrogate import Surrogate, SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate


def _banana(u: np.ndarray) -> np.ndarray:
    """x1 ~ N(0, 1), x2 | x1 ~ N(0.6 x1², 0.3²) (one link of the curved 5-D target)."""
    x1 = (u[:, 0] - 0.5) / 0.12
    x2 = (u[:, 1] - 0.25) / 0.1
    return -0.5 * x1**2 - 0.5 * ((x2 - 0.6 * x1**2) / 0.3) ** 2


def _gaussian(u: np.ndarray) -> np.ndarray:
    return -0.5 * np.sum(((u - 0.5) / 0.15) ** 2, axis=1)


def _surrogate(log_l: Callable[[np.ndarray], np.ndarray], seed: int) -> Surrogate:
    rng = np.random.default_rng(seed)
    t = rng.standard_normal(100)
    ridge = np.column_stack(
        [0.5 + 0.12 * t, 0.25 + 0.1 * (0.6 * t**2 + 0.3 * rng.standard_normal(100))]
    )
    x = np.vstack([rng.uniform(size=(150, 2)), np.clip(ridge, 0.0, 1.0)])
    return fit_surrogate(x, log_l(x), SurrogateSettings(), seed=0)


_BROAD, _NARROW = torch.tensor([0.3, 0.3]), torch.tensor([0.8, 0.75])


def _two_modes(u: torch.Tensor) -> torch.Tensor:
    """Equal-mass Gaussians, sd 0.08 and 0.016 (the outside probe's F3 target): log L (m,)
    of (m x 2) points, the narrow mode's peak 3.2 nats above the broad one's."""
    broad = -0.5 * (((u - _BROAD) / 0.08) ** 2).sum(-1) - 2.0 * math.log(0.08)
    narrow = -0.5 * (((u - _NARROW) / 0.016) ** 2).sum(-1) - 2.0 * math.log(0.016)
    return torch.logaddexp(broad, narrow)


class _NoWarping:
    def plug_in(self, z: torch.Tensor) -> torch.Tensor:
        return z


@dataclass
class _ExactSurrogate:
    """What the sampler reads of a :class:`Surrogate` (training points for the starts, the
    plug-in log L̃), with the exact two-mode log L as its mean: the exact mode shares are
    known (0.5 each; the box cuts off under 10⁻⁴ of the broad mode)."""

    train_x: torch.Tensor
    train_y: np.ndarray = field(init=False)
    warping: _NoWarping = field(default_factory=_NoWarping)
    log_l: Callable[[torch.Tensor], torch.Tensor] = _two_modes

    def __post_init__(self) -> None:
        self.train_y = self.log_l(self.train_x).numpy()

    def latent_mean(self, u: torch.Tensor) -> torch.Tensor:
        return self.log_l(u)


def _narrow_share(draws: torch.Tensor) -> float:
    return float(((draws - _NARROW).norm(dim=-1) < 0.1).double().mean())


def _evaluated(*points: list[float]) -> _ExactSurrogate:
    return _ExactSurrogate(torch.tensor(points, dtype=torch.float64))


# two evaluations at the narrow peak, one 1 sd off the broad one: chains start ∝ exp(log L)
# there, so 8 of 512 start in the broad mode, fewer than the 11 (2 %) that the jumps planned
# half-way through warm-up need, and more than the q + 2 = 4 a stuck mode needs
_FEW_IN_BROAD = ([0.8, 0.75], [0.805, 0.75], [0.38, 0.3])
_TWO_MODES_RUN = {"n_chains": 512, "warmup_steps": 200, "num_samples": 500, "seed": 0}


def _documented_mode_pass(
    surrogate: _ExactSurrogate, walk: torch.Tensor, mixture: MixtureProposal
) -> torch.Tensor:
    """The mode pass as documented, for ``_TWO_MODES_RUN`` (seed 0): the random walk from the
    first pass's last positions, seeded 0 + the offset, jumping with ``mixture``."""
    kernel = RandomWalkMetropolis(
        surrogate_potential(surrogate),
        walk[:, -1, :],
        proposal_cov=(0.03**2) * torch.eye(2, dtype=torch.float64),
        seed=MODE_PASS_SEED_OFFSET,
        jump_probability=MODE_PASS_JUMP_PROBABILITY,
        mixture=mixture,
    )
    return run_vectorized(kernel, 500, 200)


def test_a_mode_too_few_chains_reached_gets_its_exact_share_from_the_mode_pass() -> None:
    """The outside probe's F3: chains started almost all in the narrow mode and stayed
    there, 98 % of the draws against the exact 50 % (R-hat 3.2). "auto" jumps between the
    modes the chains ended in and keeps that pass, which mixed."""
    surrogate = _evaluated(*_FEW_IN_BROAD)
    walk, walk_diag = sample_surrogate_posterior(surrogate, sampler="random_walk", **_TWO_MODES_RUN)
    auto, diag = sample_surrogate_posterior(surrogate, sampler="auto", **_TWO_MODES_RUN)
    starts = initial_positions(surrogate.train_x.numpy(), surrogate.train_y, 512, 0)
    assert int(((starts - _BROAD).norm(dim=-1) < 0.3).sum()) == 8  # the premise
    # before: the first pass alone, no jumps planned, the shares as the chains started
    walk_r_hat = float(chain_diagnostics(walk)[0].max())
    assert walk_diag["modes"] == 1.0 and walk_r_hat > 2.0
    assert _narrow_share(walk) > 0.98
    # after: the exact shares, from the mode pass's draws, which mixed
    assert abs(_narrow_share(auto) - 0.5) < 0.03
    assert auto.shape == walk.shape and diag["sampler"] == "random_walk"
    assert diag["modes"] == 2.0 and diag["first pass R-hat"] == pytest.approx(walk_r_hat)
    r_hat, ess = chain_diagnostics(auto)
    assert diag["mode pass R-hat"] == pytest.approx(float(r_hat.max()))
    assert float(r_hat.max()) <= 1.05
    assert float(ess.min()) >= 400
    # the pass is the documented kernel: from the last positions, seed + the offset
    mixture = MixtureProposal.of_chains(walk, stuck_modes(walk))
    assert torch.equal(auto, _documented_mode_pass(surrogate, walk, mixture))


def test_a_mode_pass_that_did_not_mix_leaves_the_first_pass_bit_for_bit() -> None:
    """Eight draws per chain: too few for any pass to mix. The first pass's draws stay, and
    the diagnostics say what the mode pass gave."""
    surrogate = _evaluated(*_FEW_IN_BROAD)
    kwargs = {**_TWO_MODES_RUN, "num_samples": 8}
    walk, walk_diag = sample_surrogate_posterior(surrogate, sampler="random_walk", **kwargs)
    auto, diag = sample_surrogate_posterior(surrogate, sampler="auto", **kwargs)
    assert torch.equal(auto, walk)
    extra = {"mode pass R-hat": diag["mode pass R-hat"], "mode pass modes": diag["mode pass modes"]}
    assert diag == {**walk_diag, **extra} and float(diag["mode pass modes"]) >= 2.0
    assert float(diag["mode pass R-hat"]) > 1.05


_THREE = torch.tensor([[0.25, 0.25], [0.75, 0.3], [0.5, 0.8]])
_THREE_SHARES = (0.4, 0.4, 0.2)


def _three_modes(u: torch.Tensor) -> torch.Tensor:
    """Gaussians of sd 0.04 holding 0.4 / 0.4 / 0.2 of the mass: log L (m,) of (m x 2)."""
    terms = [
        math.log(w) - 0.5 * (((u - m) / 0.04) ** 2).sum(-1) for w, m in zip(_THREE_SHARES, _THREE)
    ]
    return torch.logsumexp(torch.stack(terms), 0)


def _shares_of_three(draws: torch.Tensor) -> list[float]:
    return [float(((draws - m).norm(dim=-1) < 0.2).double().mean()) for m in _THREE]


def test_a_small_mode_the_jumps_folded_into_a_neighbour_gets_its_share_from_a_mode_pass() -> None:
    """Session 38, trimodal seed 7: the jumps planned half-way through warm-up knew two
    modes; the third, reached by fewer than 2 % of the chains, was folded into a
    neighbour's component and held 1.3 % of the draws against the exact 20 %. "auto" runs a
    mode pass over the clusters of the chains' last positions and keeps it: it mixed."""
    evaluated = [[0.25, 0.25], [0.26, 0.25], [0.75, 0.3], [0.74, 0.3], [0.5, 0.9]]
    surrogate = _ExactSurrogate(torch.tensor(evaluated, dtype=torch.float64), log_l=_three_modes)
    starts = initial_positions(surrogate.train_x.numpy(), surrogate.train_y, 512, 0)
    assert int(((starts - _THREE[2]).norm(dim=-1) < 0.2).sum()) == 4  # the premise
    walk, walk_diag = sample_surrogate_posterior(surrogate, sampler="random_walk", **_TWO_MODES_RUN)
    auto, diag = sample_surrogate_posterior(surrogate, sampler="auto", **_TWO_MODES_RUN)
    # before: the jumps knew two modes, the small one kept about the chains it started with
    assert walk_diag["modes"] == 2.0 and float(chain_diagnostics(walk)[0].max()) > 1.3
    assert _shares_of_three(walk)[2] < 0.03
    # after: the exact shares, three modes (the small one's pieces counted once), mixed
    for share, exact in zip(_shares_of_three(auto), _THREE_SHARES):
        assert abs(share - exact) < 0.03
    assert diag["modes"] == 3.0 and diag["sampler"] == "random_walk"
    assert diag["first pass R-hat"] == pytest.approx(float(chain_diagnostics(walk)[0].max()))
    r_hat, ess = chain_diagnostics(auto)
    assert float(r_hat.max()) <= 1.05 and float(ess.min()) >= 400
    # the pass is the documented kernel: from the last positions, over their clusters
    mixture = mixture_of_last_positions(walk)
    assert mixture is not None
    assert torch.equal(auto, _documented_mode_pass(surrogate, walk, mixture))


def _bare_walk(
    surrogate: Surrogate | _ExactSurrogate,
    n_chains: int,
    warmup_steps: int,
    num_samples: int,
    seed: int,
) -> tuple[torch.Tensor, dict[str, float]]:
    """The random-walk kernel alone, as ``sample_surrogate_posterior`` builds it: its
    (chains x draws x q) draws and its diagnostics."""
    starts = initial_positions(surrogate.train_x.numpy(), surrogate.train_y, n_chains, seed)
    kernel = RandomWalkMetropolis(
        surrogate_potential(surrogate),
        starts,
        proposal_cov=(0.03**2) * torch.eye(starts.shape[1], dtype=torch.float64),
        seed=seed,
    )
    return run_vectorized(kernel, num_samples, warmup_steps), kernel.diagnostics()


def test_auto_is_the_bare_random_walk_where_the_jumps_were_planned_and_mixed() -> None:
    """Both modes at evaluated peaks: 27 of 512 chains start in the broad mode, enough for
    the jumps planned half-way through warm-up, and 1 000 draws mix (at 500, split R-hat
    1.051, and a mode pass runs). No second pass, no further random number: the draws are
    the kernel's alone, bit for bit."""
    surrogate = _evaluated([0.8, 0.75], [0.3, 0.3])
    starts = initial_positions(surrogate.train_x.numpy(), surrogate.train_y, 512, 0)
    assert int(((starts - _BROAD).norm(dim=-1) < 0.3).sum()) == 27  # the premise
    run = {**_TWO_MODES_RUN, "num_samples": 1000}
    auto, diag = sample_surrogate_posterior(surrogate, sampler="auto", **run)
    walk, walk_diag = _bare_walk(surrogate, **run)
    assert float(chain_diagnostics(walk)[0].max()) <= 1.05  # the premise: it mixed
    assert torch.equal(auto, walk)
    assert diag == {**walk_diag, "sampler": "random_walk"} and diag["modes"] == 2.0


def test_auto_keeps_the_random_walk_bit_for_bit_where_it_mixed() -> None:
    surrogate = _surrogate(_gaussian, 1)
    kwargs = {"n_chains": 64, "warmup_steps": 100, "num_samples": 400, "seed": 3}
    walk, walk_diag = sample_surrogate_posterior(surrogate, sampler="random_walk", **kwargs)
    auto, auto_diag = sample_surrogate_posterior(surrogate, sampler="auto", **kwargs)
    r_hat, ess = chain_diagnostics(walk)
    assert float(r_hat.max()) <= 1.05 and float(ess.min()) >= 400  # the premise
    assert torch.equal(walk, auto)
    assert auto_diag == walk_diag and auto_diag["sampler"] == "random_walk"
    # no second pass, no further random number: the kernel run alone, bit for bit
    bare, bare_diag = _bare_walk(surrogate, **kwargs)
    assert torch.equal(auto, bare) and auto_diag == {**bare_diag, "sampler": "random_walk"}


def test_auto_switches_to_hmc_where_the_random_walk_did_not_mix() -> None:
    surrogate = _surrogate(_banana, 0)
    kwargs = {"n_chains": 32, "warmup_steps": 100, "num_samples": 300, "seed": 0}
    walk, _ = sample_surrogate_posterior(surrogate, sampler="random_walk", **kwargs)
    auto, diag = sample_surrogate_posterior(surrogate, sampler="auto", **kwargs)
    hmc, hmc_diag = sample_surrogate_posterior(surrogate, sampler="hmc", **kwargs)
    walk_r_hat = float(chain_diagnostics(walk)[0].max())
    assert walk_r_hat > 1.05  # the premise: the random walk did not mix
    assert diag["sampler"] == "hmc" and diag["random walk R-hat"] == pytest.approx(walk_r_hat)
    assert torch.equal(auto, hmc) and hmc_diag["sampler"] == "hmc"
    assert auto.shape == (32, 150, 2)  # HMC: half the draws
    r_hat, ess = chain_diagnostics(auto)
    assert float(r_hat.max()) <= 1.05 and float(ess.min()) >= 400
    # the same posterior as a random walk 25x as long (both within 5 Monte Carlo errors)
    long_walk, _ = sample_surrogate_posterior(
        surrogate, n_chains=64, warmup_steps=500, num_samples=4000, seed=1, sampler="random_walk"
    )
    ess_long = chain_diagnostics(long_walk)[1]
    sd = long_walk.reshape(-1, 2).std(0)
    error = sd * (1.0 / ess + 1.0 / ess_long).sqrt()
    z = (auto.reshape(-1, 2).mean(0) - long_walk.reshape(-1, 2).mean(0)) / error
    assert torch.all(z.abs() < 5.0), z


def test_hmc_runs_at_most_hmc_chains_chains_for_half_the_draws() -> None:
    surrogate = _surrogate(_gaussian, 1)
    draws, diag = sample_surrogate_posterior(
        surrogate, n_chains=HMC_CHAINS + 72, warmup_steps=2, num_samples=5, seed=0, sampler="hmc"
    )
    assert draws.shape == (HMC_CHAINS, 2, 2) and diag["sampler"] == "hmc"


def test_an_unknown_sampler_is_refused_by_name() -> None:
    surrogate = _surrogate(_gaussian, 1)
    with pytest.raises(ValueError, match="sampler: 'nuts', expected one of random_walk, hmc"):
        sample_surrogate_posterior(
            surrogate, n_chains=4, warmup_steps=1, num_samples=1, seed=0, sampler="nuts"
        )


def test_mean_sd_at_draws_is_small_where_evaluated_and_large_where_not() -> None:
    """The ``not_converged`` sub-rule's number: draws among the training points against
    draws in a corner no evaluation came near (the GP knows it does not know there)."""
    rng = np.random.default_rng(4)
    x = rng.uniform(0.3, 0.7, size=(120, 2))
    y = _gaussian(x) + 2.0 * np.sin(9.0 * x[:, 0]) * np.cos(7.0 * x[:, 1])  # no quadratic
    surrogate = fit_surrogate(x, y, SurrogateSettings(), seed=0)
    inside = torch.as_tensor(rng.uniform(0.35, 0.65, size=(4, 500, 2)))
    corner = torch.as_tensor(rng.uniform(0.0, 0.08, size=(4, 500, 2)))
    near = mean_sd_at_draws(surrogate, inside)
    far = mean_sd_at_draws(surrogate, corner)
    assert near < 0.3 < far, (near, far)
    # deterministic (evenly spaced draws, no random state) and chain-pooled
    assert mean_sd_at_draws(surrogate, inside) == near
    assert mean_sd_at_draws(surrogate, inside.reshape(-1, 2)) == pytest.approx(near)
    assert np.isnan(mean_sd_at_draws(surrogate, inside[:, :0]))


_PEAK, _SPECK = torch.tensor([0.2, 0.2]), torch.tensor([0.8, 0.75])


def _peak_and_speck(u: torch.Tensor) -> torch.Tensor:
    """A mode (sd 0.03) and, 20 sd away, a speck (sd 0.01, its peak 3.1 nats lower) that
    holds 0.5 % of the mass: log L (m,) of (m x 2) points."""
    peak = -0.5 * (((u - _PEAK) / 0.03) ** 2).sum(-1)
    speck = -3.1 - 0.5 * (((u - _SPECK) / 0.01) ** 2).sum(-1)
    return torch.logaddexp(peak, speck)


def test_a_mode_with_no_share_of_the_mixed_draws_is_not_counted() -> None:
    """Review, session 25: two chains stuck at a speck of the surrogate (a tiny bump) make
    the mode pass run; it mixes, and the speck holds 0.5 % of its draws — no mode of the
    posterior, so `modes` (and the `multimodal` verdict) must not count it."""
    generator = torch.Generator().manual_seed(0)
    peak = _PEAK + 0.03 * torch.randn(510, 400, 2, generator=generator, dtype=torch.float64)
    speck = _SPECK + 0.01 * torch.randn(2, 400, 2, generator=generator, dtype=torch.float64)
    first = torch.cat([peak, speck])
    modes = stuck_modes(first)
    assert [len(m) for m in modes] == [510, 2]  # the premise: two chains stuck in the speck

    def potential(u: torch.Tensor) -> torch.Tensor:
        inside = torch.all((u >= 0) & (u <= 1), dim=-1)
        return torch.where(inside, -_peak_and_speck(u), torch.full_like(u[:, 0], math.inf))

    draws, diag = _mode_pass(
        potential,
        first,
        MixtureProposal.of_chains(first, modes),
        {"modes": 1.0, "sampler": "random_walk"},
        3.0,
        seed=0,
        num_samples=400,
        warmup_steps=200,
        backend="vectorized",
        thin=1,
        progress=False,
    )
    assert "first pass R-hat" in diag  # the pass mixed and its draws were kept
    share = float(((draws - _SPECK).norm(dim=-1) < 0.05).double().mean())
    assert 0.001 < share < 0.01
    assert diag["modes"] == 1.0


def test_a_kept_mode_pass_counts_no_fewer_modes_than_the_jumps_knew() -> None:
    """Review, session 39: ``modes`` after a mode pass merges components whose draws lie
    under 6 pooled sds apart; where the first pass's jumps had split modes (each split 6
    pooled sds wide), the count keeps at least that many, so ``multimodal`` cannot vanish."""
    generator = torch.Generator().manual_seed(5)
    first = _PEAK + 0.03 * torch.randn(64, 200, 2, generator=generator, dtype=torch.float64)
    halves = [torch.nonzero(first[:, -1, 0] < _PEAK[0]).reshape(-1)]
    halves.append(torch.nonzero(first[:, -1, 0] >= _PEAK[0]).reshape(-1))
    mixture = MixtureProposal.of_chains(first, halves)  # two pieces of one Gaussian mode

    def potential(u: torch.Tensor) -> torch.Tensor:
        return 0.5 * (((u - _PEAK) / 0.03) ** 2).sum(-1)

    run = {"seed": 0, "num_samples": 400, "warmup_steps": 100, "backend": "vectorized"}
    counts = []
    for least in (1, 2):
        _, diag = _mode_pass(
            potential, first, mixture, {"modes": 1.0}, 1.2, **run, thin=1, progress=False,
            least_modes=least,
        )  # fmt: skip
        assert "first pass R-hat" in diag  # the premise: the pass mixed and was kept
        counts.append(diag["modes"])
    assert counts == [1.0, 2.0]
