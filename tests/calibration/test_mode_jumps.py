"""Mode jumps: separated modes are found (and single modes are not split), the mixture
proposal's density is right, and the kernel shares the mass between modes as the exact
posterior does, from starts that do not."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.stats import multivariate_normal

from susp_bo.calibration.design import from_unit, to_unit
from susp_bo.calibration.mcmc import RandomWalkMetropolis, chain_diagnostics, run_vectorized
from susp_bo.calibration.mode_jumps import (
    MixtureProposal,
    find_modes,
    mixture_of_last_positions,
    modes_chains_stayed_in,
    stuck_modes,
)
from susp_bo.calibration.test_functions import TARGETS


def _cloud(rng: np.random.Generator, means: list[list[float]], counts: list[int]) -> torch.Tensor:
    parts = [np.asarray(m) + 0.3 * rng.standard_normal((c, len(m))) for m, c in zip(means, counts)]
    return torch.as_tensor(np.vstack(parts))


def test_three_separated_clusters_are_found_with_their_members() -> None:
    rng = np.random.default_rng(1)
    x = _cloud(rng, [[0.0, 0.0, 0.0], [4.0, 0.0, 1.0], [0.0, 5.0, -2.0]], [300, 120, 60])
    clusters = find_modes(x)
    assert sorted(len(c) for c in clusters) == [60, 120, 300]
    truth = np.repeat([0, 1, 2], [300, 120, 60])
    for c in clusters:  # each cluster is one true group
        assert len(set(truth[c.numpy()])) == 1


@pytest.mark.parametrize("shape", ["gaussian", "banana", "ring", "student_t"])
def test_one_mode_is_never_split(shape: str) -> None:
    rng = np.random.default_rng(2)
    z = rng.standard_normal((512, 2))
    if shape == "gaussian":
        x = rng.standard_normal((512, 7)) @ rng.standard_normal((7, 7))
    elif shape == "banana":  # strongly curved: x2 | x1 ~ N(x1², 0.3²), x1 ~ N(0, 3²)
        x = np.column_stack([3.0 * z[:, 0], 0.3 * z[:, 1] + (3.0 * z[:, 0]) ** 2 / 2])
    elif shape == "ring":
        x = np.column_stack([np.cos(2 * z[:, 0]), np.sin(2 * z[:, 0])]) + 0.05 * z
    else:  # heavy tails
        x = TARGETS["student_t_6d"]().sample(512, rng)
    assert len(find_modes(torch.as_tensor(x))) == 1


def test_a_small_group_is_not_a_mode() -> None:
    """Fewer than max(2 % of the chains, q + 2) chains far away: not worth a component."""
    rng = np.random.default_rng(3)
    x = _cloud(rng, [[0.0, 0.0], [9.0, 9.0]], [508, 3])
    assert len(find_modes(x)) == 1


def test_the_mixture_density_is_the_equal_weight_gaussian_mixture() -> None:
    rng = np.random.default_rng(4)
    x = _cloud(rng, [[0.0, 0.0], [4.0, 1.0]], [200, 100])
    clusters = find_modes(x)
    mixture = MixtureProposal.of(x, clusters, inflation=1.5)
    points = torch.as_tensor(rng.normal(2.0, 2.0, (50, 2)))
    expected = np.log(
        np.mean(
            [
                multivariate_normal(x[c].mean(0).numpy(), np.cov(x[c].numpy().T) * 2.25).pdf(
                    points.numpy()
                )
                for c in clusters
            ],
            axis=0,
        )
    )
    np.testing.assert_allclose(mixture.log_density(points).numpy(), expected, rtol=1e-9)
    draws = mixture.draw(40_000, torch.Generator().manual_seed(0))
    near_second = (draws[:, 0] > 2.0).double().mean()  # equal weights
    assert abs(float(near_second) - 0.5) < 0.02


def _trimodal_kernel(jump_probability: float) -> tuple[torch.Tensor, RandomWalkMetropolis]:
    target = TARGETS["trimodal_5d"]()
    bounds = target.bounds

    def potential(u: torch.Tensor) -> torch.Tensor:
        inside = torch.all((u >= 0) & (u <= 1), dim=-1)
        value = -torch.as_tensor(target.log_likelihood(from_unit(u.clamp(0, 1).numpy(), bounds)))
        return torch.where(inside, value, torch.full_like(value, math.inf))

    rng = np.random.default_rng(0)
    means = np.asarray(target.blocks[0].means)
    exact = target.sample(20_000, rng)
    label = np.argmin(((exact[:, None, :] - means[None]) ** 2).sum(-1), 1)
    # starts as a surrogate run left them: 70 / 13 / 17 % against the exact 50 / 30 / 20 %
    starts = np.vstack([exact[label == k][:n] for k, n in enumerate((179, 33, 44))])
    kernel = RandomWalkMetropolis(
        potential,
        torch.as_tensor(to_unit(starts, bounds)),
        proposal_cov=(0.03**2) * torch.eye(5, dtype=torch.float64),
        seed=1,
        jump_probability=jump_probability,
    )
    return run_vectorized(kernel, 1500, 500), kernel


def _shares(draws: torch.Tensor) -> np.ndarray:
    target = TARGETS["trimodal_5d"]()
    w = from_unit(draws.reshape(-1, 5).numpy(), target.bounds)
    means = np.asarray(target.blocks[0].means)
    label = np.argmin(((w[:, None, :] - means[None]) ** 2).sum(-1), 1)
    return np.bincount(label, minlength=3) / len(label)


def test_jumps_give_each_mode_its_exact_share_from_biased_starts() -> None:
    target = TARGETS["trimodal_5d"]()
    exact = _shares(
        torch.as_tensor(to_unit(target.sample(40_000, np.random.default_rng(9)), target.bounds))
    )
    stuck, _ = _trimodal_kernel(0.0)
    jumping, kernel = _trimodal_kernel(0.1)
    assert np.max(np.abs(_shares(stuck) - exact)) > 0.1  # without jumps: the starts' shares
    assert np.max(np.abs(_shares(jumping) - exact)) < 0.03
    assert kernel.diagnostics()["modes"] == 3
    assert 0.1 < kernel.diagnostics()["jump acceptance rate"] < 0.9
    r_stuck, _ = chain_diagnostics(stuck)
    r_jumping, _ = chain_diagnostics(jumping)
    assert float(r_stuck.max()) > 2.0 and float(r_jumping.max()) < 1.1


def test_with_one_mode_the_draws_are_bit_identical_to_the_kernel_without_jumps() -> None:
    def potential(w: torch.Tensor) -> torch.Tensor:
        return 0.5 * (w * w).sum(1) + 0.3 * w[:, 0] * w[:, 1]

    starts = torch.randn(64, 3, generator=torch.Generator().manual_seed(5))
    runs = []
    for p in (0.0, 0.1):
        kernel = RandomWalkMetropolis(potential, starts, seed=3, jump_probability=p)
        runs.append(run_vectorized(kernel, 300, 200))
        assert kernel.diagnostics()["modes"] == 1
    assert torch.equal(runs[0], runs[1])
    with pytest.raises(ValueError, match="jump_probability"):
        RandomWalkMetropolis(potential, starts, jump_probability=1.0)
    mixture = MixtureProposal.of(starts, [torch.arange(32), torch.arange(32, 64)])
    with pytest.raises(ValueError, match="mixture: 3-D components with jump_probability 0"):
        RandomWalkMetropolis(potential, starts, jump_probability=0.0, mixture=mixture)
    with pytest.raises(ValueError, match="expected 2-D components"):
        RandomWalkMetropolis(potential, starts[:, :2], mixture=mixture)


def test_chains_left_in_a_mode_the_jumps_never_saw_are_counted() -> None:
    """A mode 1 % of the chains reached (fewer than find_modes' least share at warm-up) left
    split R-hat at 3 and the verdict naming only the sampler (outside probe, session 24):
    the chains' last positions name it."""
    generator = torch.Generator().manual_seed(0)
    main = 0.8 + 0.016 * torch.randn(500, 50, 2, generator=generator, dtype=torch.float64)
    few = 0.3 + 0.08 * torch.randn(7, 50, 2, generator=generator, dtype=torch.float64)
    assert modes_chains_stayed_in(torch.cat([main, few])) == 2
    assert len(find_modes(torch.cat([main, few])[:, -1, :])) == 1  # the least share: unseen
    assert modes_chains_stayed_in(main) == 1  # one Gaussian cloud is one mode


def test_a_mode_fewer_than_q_plus_2_chains_reached_is_counted_too() -> None:
    """Session 25, the needle with a trust region (seed 5): a mode of half the exact mass
    held 0.8 % of the draws, three chains of 512, under the warm-up jumps' floor of q + 2;
    it was left to HMC and the verdict named only the sampler. Two chains now suffice; one
    stray chain does not make a mode."""
    generator = torch.Generator().manual_seed(2)
    main = 0.8 + 0.016 * torch.randn(509, 50, 2, generator=generator, dtype=torch.float64)
    three = 0.3 + 0.08 * torch.randn(3, 50, 2, generator=generator, dtype=torch.float64)
    assert [len(c) for c in stuck_modes(torch.cat([main, three]))] == [509, 3]
    assert modes_chains_stayed_in(torch.cat([main, three[:1]])) == 1


def test_clusters_a_chain_moved_between_are_one_mode() -> None:
    """A curved mode's arms can split the last positions (the exact curved 5-D target: three
    clusters on two of three seeds); chains that went from one cluster to another join them.
    Chains that never left their cluster keep it apart."""
    generator = torch.Generator().manual_seed(1)
    main = 0.8 + 0.016 * torch.randn(500, 50, 2, generator=generator, dtype=torch.float64)
    few = 0.3 + 0.08 * torch.randn(7, 50, 2, generator=generator, dtype=torch.float64)
    apart = torch.cat([main, few])
    assert [len(c) for c in stuck_modes(apart)] == [500, 7]
    assert torch.equal(stuck_modes(apart)[1], torch.arange(500, 507))
    moved = apart.clone()
    moved[500, :10] = main[0, :10]  # one chain began its draws in the other cluster
    assert [len(c) for c in stuck_modes(moved)] == [507]
    moved = apart.clone()
    moved[3, 27] = few[0, 27]  # a visit half-way through counts too (draw 27: a checkpoint)
    assert modes_chains_stayed_in(moved) == 1


def test_a_mixture_of_chains_takes_each_modes_covariance_from_all_its_draws() -> None:
    generator = torch.Generator().manual_seed(2)
    draws = torch.randn(12, 40, 3, generator=generator, dtype=torch.float64)
    draws[8:] = 5.0 + 0.2 * draws[8:]
    modes = [torch.arange(8), torch.arange(8, 12)]
    mixture = MixtureProposal.of_chains(draws, modes, inflation=1.5)
    for k, c in enumerate(modes):
        pooled = draws[c].reshape(-1, 3)
        torch.testing.assert_close(mixture.means[k], pooled.mean(0))
        cov = mixture.chols[k] @ mixture.chols[k].T
        torch.testing.assert_close(cov, torch.cov(pooled.T) * 2.25)


def test_a_mixture_of_last_positions_fits_each_mode_to_the_draws_in_it() -> None:
    """Chains that moved between two modes: a component per cluster of the last positions,
    fitted to the draws nearest it, not to its chains' draws (which lie in both modes)."""
    generator = torch.Generator().manual_seed(3)
    draws = 0.02 * torch.randn(40, 30, 2, generator=generator, dtype=torch.float64)
    in_b = torch.rand(40, 30, generator=generator) < 0.5  # each draw in A or in B
    draws[in_b] += torch.tensor([0.7, 0.7], dtype=torch.float64)
    draws += 0.1
    mixture = mixture_of_last_positions(draws, checkpoints=30)
    assert mixture is not None and mixture.n_modes == 2
    centres = sorted(mixture.means.tolist())
    assert centres[0] == pytest.approx([0.1, 0.1], abs=0.01)
    assert centres[1] == pytest.approx([0.8, 0.8], abs=0.01)
    sds = torch.diagonal(mixture.chols, dim1=1, dim2=2)
    assert torch.all((sds > 0.02) & (sds < 0.04))  # 1.5 x 0.02 each, not the modes' spread
    assert mixture_of_last_positions(draws[:1, :1, :].expand_as(draws).clone()) is None


def test_pieces_of_one_mode_are_counted_once_and_separated_modes_apart() -> None:
    """Two halves of one Gaussian (components of a mode split into pieces) count as one
    mode; two clouds far apart count as two, unless one holds under ``min_share``."""
    generator = torch.Generator().manual_seed(4)
    cloud = 0.05 * torch.randn(4000, 2, generator=generator, dtype=torch.float64)
    pieces = MixtureProposal.of(
        cloud,
        [torch.nonzero(cloud[:, 0] < 0).reshape(-1), torch.nonzero(cloud[:, 0] >= 0).reshape(-1)],
    )
    assert pieces.separated_modes(cloud, 0.01) == 1  # two halves of one Gaussian
    far = torch.cat([cloud, cloud + 1.0])
    both = MixtureProposal.of(far, [torch.arange(4000), torch.arange(4000, 8000)])
    assert both.separated_modes(far, 0.01) == 2
    assert both.separated_modes(torch.cat([cloud, cloud[:20] + 1.0]), 0.01) == 1  # 0.5 %
