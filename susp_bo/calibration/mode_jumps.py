"""Jumps between separated posterior modes: mode detection and a frozen mixture proposal.

The random-walk kernel (:mod:`.mcmc`) explores one mode well but does not cross
between modes that lie many standard deviations apart, so the share of chains in
each mode stays where the chains started (measured on a trimodal 5-D target:
0.70 / 0.13 / 0.17 of the mass against the exact 0.5 / 0.3 / 0.2).

:func:`find_modes` looks at the chains' positions half-way through warm-up and
splits them into clusters that are clearly separated (bisecting 2-means in
whitened coordinates, best of several deterministic starts; a split is kept only
when the two halves' means lie more than ``separation`` pooled within-cluster
standard deviations apart and each half holds at least ``min_share`` of the
chains). A Gaussian cloud is not split (its halves lie about 2.7 sd apart); a
strongly curved mode seen through few chains can be (the 2-D banana of the tests
with 64 chains): the jumps then move between its arms, still an exact MH chain.

With two or more modes, :class:`MixtureProposal` is a Gaussian mixture with one
component per mode (its mean, its covariance inflated by ``inflation``², equal
weights). It is built once and then **frozen**, and the kernel uses it as an
independence proposal with probability ``jump_probability`` per chain and step,
accepting with the Metropolis–Hastings ratio
min(1, π(x') q(x) / (π(x) q(x'))). A kernel that picks between two π-invariant
moves with a probability that does not depend on the state is π-invariant, so the
sampling phase stays an exact MH chain; the jumps start half-way through warm-up,
so the mode shares have settled before any draw is kept. When no split is found
nothing changes (no extra random numbers are drawn: the draws are bit-identical to
the kernel without jumps).

A mode fewer chains reached than ``min_share`` is not jumped to, and its chains stay
apart. :func:`stuck_modes` finds such modes after the run, among the chains' last
positions (clusters no chain moved between); the sampler's mode pass
(:func:`~.sampling.sample_surrogate_posterior`) then runs the kernel again with
:meth:`MixtureProposal.of_chains` over them, and the verdict counts them
(:func:`modes_chains_stayed_in`). Where the jumps knew some modes and the chains still
did not mix (a small mode folded into a neighbour's component), the mode pass's mixture
has one component per cluster of the last positions instead
(:func:`mixture_of_last_positions`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

SEPARATION = 6.0
"""Pooled within-cluster sds between two cluster means for a split to count as two modes."""
STUCK_MIN_CHAINS = 2
"""Smallest cluster of chains' last positions :func:`stuck_modes` counts. Not q + 2 (the
warm-up jumps' floor): the mode pass fits each mode's mixture component to every draw of
its chains, so two chains suffice, and a mode that fewer than q + 2 of 512 chains reached
(0.8 % of the draws in a mode of half the exact mass; session 25, the needle with a trust
region, seed 5) was left to HMC, which mixed inside the other mode or not at all. A stray
chain in a tail or a curved arm is not split off: it lies within the 6 pooled sds."""


def _covariance(x: torch.Tensor) -> torch.Tensor:
    q = x.shape[1]
    centred = x - x.mean(0)
    n = max(x.shape[0] - 1, 1)
    return centred.T @ centred / n + 1e-12 * torch.eye(q, dtype=x.dtype)


def _lloyd(z: torch.Tensor, centres: torch.Tensor, iterations: int) -> torch.Tensor:
    """Boolean labels after Lloyd iterations of 2-means from ``centres`` (2 x q)."""
    labels = torch.cdist(z, centres).argmin(1).bool()
    for _ in range(iterations):
        if bool(labels.all()) or not bool(labels.any()):
            break
        centres = torch.stack([z[~labels].mean(0), z[labels].mean(0)])
        new = torch.cdist(z, centres).argmin(1).bool()
        if torch.equal(new, labels):
            break
        labels = new
    return labels


def _two_means(x: torch.Tensor, iterations: int = 25, restarts: int = 8) -> torch.Tensor:
    """Boolean labels of a deterministic 2-means split of ``x`` (m x q), the best of several
    starts (k-means++ from a fixed generator, and the farthest pair), by within-group sum
    of squares, in coordinates whitened by the total covariance. Whitened, a separated
    group carries most of the variance along its direction (between share
    p (1 - p) d² / (1 + p (1 - p) d²), 0.86 for 8 % of the points at d = 9 sd), more
    than any cut through one Gaussian mode (2/π), so 2-means finds it even when the modes
    are elongated in other directions."""
    chol, info = torch.linalg.cholesky_ex(_covariance(x))
    if int(info) != 0 or x.shape[0] < 2:
        return torch.zeros(x.shape[0], dtype=torch.bool)
    z = torch.linalg.solve_triangular(chol, (x - x.mean(0)).T, upper=False).T
    generator = torch.Generator().manual_seed(0)
    starts = []
    first = int(torch.argmax((z * z).sum(1)))
    starts.append(torch.stack([z[first], z[int(torch.argmax(((z - z[first]) ** 2).sum(1)))]]))
    for _ in range(restarts):  # k-means++: a point, then one drawn ∝ squared distance
        i = int(torch.randint(z.shape[0], (1,), generator=generator))
        weights = ((z - z[i]) ** 2).sum(1)
        if not float(weights.sum()) > 0.0:  # every point at z[i]: nothing to split
            continue
        j = int(torch.multinomial(weights / weights.sum(), 1, generator=generator))
        starts.append(torch.stack([z[i], z[j]]))
    best, best_ss = torch.zeros(z.shape[0], dtype=torch.bool), math.inf
    for centres in starts:
        labels = _lloyd(z, centres, iterations)
        if bool(labels.all()) or not bool(labels.any()):
            continue
        ss = float(
            ((z[labels] - z[labels].mean(0)) ** 2).sum()
            + ((z[~labels] - z[~labels].mean(0)) ** 2).sum()
        )
        if ss < best_ss:
            best, best_ss = labels, ss
    return best


def separation(a: torch.Tensor, b: torch.Tensor) -> float:
    """Distance between the means of ``a`` and ``b`` (m x q each) in pooled within-sd units."""
    pooled = ((a.shape[0] - 1) * _covariance(a) + (b.shape[0] - 1) * _covariance(b)) / max(
        a.shape[0] + b.shape[0] - 2, 1
    )
    chol, info = torch.linalg.cholesky_ex(pooled)
    if int(info) != 0:
        return 0.0
    d = torch.linalg.solve_triangular(chol, (a.mean(0) - b.mean(0))[:, None], upper=False)
    return float(torch.linalg.vector_norm(d))


def find_modes(
    x: torch.Tensor,
    *,
    max_modes: int = 5,
    min_share: float = 0.02,
    separation_sd: float = SEPARATION,
    min_chains: int | None = None,
) -> list[torch.Tensor]:
    """Clusters of chain positions that are separated modes (module docstring).

    Args:
        x: (n_chains x q) positions.
        max_modes: at most this many clusters.
        min_share: smallest share of the chains in a cluster (and at least ``min_chains``).
        separation_sd: smallest separation of a split (pooled within-cluster sds).
        min_chains: smallest number of chains in a cluster; None: q + 2 (a cluster whose own
            covariance the warm-up jumps' mixture can estimate).

    Returns:
        Index tensors, one per cluster (a single cluster of every chain when unimodal).
    """
    n, q = x.shape
    smallest = max(math.ceil(min_share * n), q + 2 if min_chains is None else min_chains)
    clusters = [torch.arange(n)]
    tried: set[tuple[int, ...]] = set()
    while len(clusters) < max_modes:
        candidates = [c for c in clusters if tuple(c.tolist()) not in tried]
        if not candidates:
            break
        largest = max(candidates, key=len)
        tried.add(tuple(largest.tolist()))
        if len(largest) < 2 * smallest:
            continue
        labels = _two_means(x[largest])
        a, b = largest[~labels], largest[labels]
        if min(len(a), len(b)) < smallest or separation(x[a], x[b]) < separation_sd:
            continue
        clusters = [c for c in clusters if c is not largest] + [a, b]
    return sorted(clusters, key=lambda c: int(c[0]))


@dataclass(frozen=True)
class MixtureProposal:
    """A frozen Gaussian mixture over the modes: an independence MH proposal.

    Attributes:
        means: (K x q) component means.
        chols: (K x q x q) Cholesky factors of the component covariances.
    """

    means: torch.Tensor
    chols: torch.Tensor

    @classmethod
    def of(
        cls, x: torch.Tensor, clusters: list[torch.Tensor], inflation: float = 1.5
    ) -> MixtureProposal:
        """One component per cluster: its mean and covariance × ``inflation``²."""
        means = torch.stack([x[c].mean(0) for c in clusters])
        chols = []
        for c in clusters:
            cov = _covariance(x[c]) * inflation**2
            chol, info = torch.linalg.cholesky_ex(cov)
            if int(info) != 0:
                scale = float(torch.diagonal(cov).mean().clamp(min=1e-12))
                chol = math.sqrt(scale) * torch.eye(x.shape[1], dtype=x.dtype)
            chols.append(chol)
        return cls(means, torch.stack(chols))

    @property
    def n_modes(self) -> int:
        """K."""
        return int(self.means.shape[0])

    @classmethod
    def of_chains(
        cls, draws: torch.Tensor, modes: list[torch.Tensor], inflation: float = 1.5
    ) -> MixtureProposal:
        """One component per mode from all the draws of the chains that stayed in it (a mode
        held by a few chains gets its covariance from their draws, not from a few points).

        Args:
            draws: (chains x draws x q) draws.
            modes: index tensors of chains, one per mode (:func:`stuck_modes`).
            inflation: factor on the components' standard deviations.
        """
        n_draws = draws.shape[1]
        rows = [(c[:, None] * n_draws + torch.arange(n_draws)).reshape(-1) for c in modes]
        return cls.of(draws.reshape(-1, draws.shape[2]), rows, inflation)

    def _component_log_densities(self, x: torch.Tensor) -> torch.Tensor:
        """(K x m) log N(x; mean_k, cov_k) of (m x q) points."""
        k, q = self.means.shape
        terms = []
        for i in range(k):
            z = torch.linalg.solve_triangular(self.chols[i], (x - self.means[i]).T, upper=False).T
            log_det = torch.log(torch.diagonal(self.chols[i])).sum()
            terms.append(-0.5 * (z * z).sum(1) - log_det - 0.5 * q * math.log(2 * math.pi))
        return torch.stack(terms)

    def log_density(self, x: torch.Tensor) -> torch.Tensor:
        """(m,) log q(x) of (m x q) points (equal component weights)."""
        k = self.means.shape[0]
        return torch.logsumexp(self._component_log_densities(x), dim=0) - math.log(k)

    def separated_modes(self, x: torch.Tensor, min_share: float) -> int:
        """The number of separated modes among the (m x q) points ``x`` (at least 1): the
        components that are the most probable one for at least ``min_share`` of them, two
        counted as one when their points lie less than :data:`SEPARATION` pooled sds apart
        (pieces of one mode, as :func:`mixture_of_last_positions` can give)."""
        nearest = self._component_log_densities(x).argmax(0)
        shares = torch.bincount(nearest, minlength=self.n_modes).double() / x.shape[0]
        held = {k: x[nearest == k] for k in range(self.n_modes) if float(shares[k]) >= min_share}
        parent = list(range(self.n_modes))
        for a in held:
            for b in held:
                if a < b and separation(held[a], held[b]) < SEPARATION:
                    parent[_root(parent, a)] = _root(parent, b)
        return max(1, len({_root(parent, k) for k in held}))

    def draw(self, n: int, generator: torch.Generator) -> torch.Tensor:
        """(n x q) draws: a component uniformly at random, then its Gaussian."""
        k, q = self.means.shape
        which = torch.randint(k, (n,), generator=generator)
        noise = torch.randn((n, q), generator=generator, dtype=self.means.dtype)
        return self.means[which] + torch.einsum("nij,nj->ni", self.chols[which], noise)


def _root(parent: list[int], k: int) -> int:
    """The representative of ``k``'s group in a union-find forest (``parent[k] == k`` at a
    root): the groups of clusters joined by :func:`stuck_modes` and of components joined
    by :meth:`MixtureProposal.separated_modes`."""
    while parent[k] != k:
        k = parent[k]
    return k


def _checkpoints(draws: torch.Tensor, count: int) -> torch.Tensor:
    """Indices of ``count`` evenly spaced draws per chain, the last included (distinct)."""
    return torch.linspace(0, draws.shape[1] - 1, max(count, 1)).round().long().unique()


def _last_position_clusters(
    draws: torch.Tensor,
) -> tuple[list[torch.Tensor], torch.Tensor, Callable[[torch.Tensor], torch.Tensor]] | None:
    """The separated clusters of the chains' last positions (:func:`find_modes`, any cluster
    of :data:`STUCK_MIN_CHAINS` chains counting), each chain's cluster label, and the
    whitening by the last positions' covariance (points (m x q) -> (m x q)); None where
    they form a single cluster."""
    end = draws[:, -1, :]
    clusters = find_modes(end, min_share=0.0, min_chains=STUCK_MIN_CHAINS)
    if len(clusters) < 2:
        return None
    chol, info = torch.linalg.cholesky_ex(_covariance(end))
    if int(info) != 0:  # cannot happen where find_modes split (it whitened the same points)
        return None
    centre = end.mean(0)

    def whitened(x: torch.Tensor) -> torch.Tensor:
        return torch.linalg.solve_triangular(chol, (x - centre).T, upper=False).T

    label = torch.empty(end.shape[0], dtype=torch.long)
    for k, c in enumerate(clusters):
        label[c] = k
    return clusters, label, whitened


def stuck_modes(draws: torch.Tensor, checkpoints: int = 10) -> list[torch.Tensor]:
    """Separated modes among the chains' last positions that no chain moved between.

    The jumps start from the modes :func:`find_modes` saw half-way through warm-up, among
    clusters holding ``min_share`` of the chains. A mode that only a few chains reached (the
    chains start ∝ exp(log L) at evaluated points, so a taller, narrower mode takes nearly
    all) is not jumped to, and its chains stay apart: split R-hat 3 where half the exact
    mass sat in the mode 1 % of the chains held (outside probe, session 24). Here the last
    positions are split by :func:`find_modes` with any cluster of at least
    :data:`STUCK_MIN_CHAINS` chains counting; then two clusters are joined when some chain
    lay, at one of ``checkpoints`` evenly spaced draws, nearest (whitened by the last
    positions' covariance) to the other cluster's last positions than to its own: a chain
    went from one to the other, so the random walk connects them. The join is what tells a
    curved mode from separated ones: on the exact curved 5-D target (512 chains x 2 000
    draws, R-hat 1.35–1.44) the last positions split into three clusters on two of three
    seeds, but 94–100 % of the chains in the small clusters had come from the large one; two
    separated modes share no chain.

    Args:
        draws: (chains x draws x q) draws.
        checkpoints: draws per chain looked at (evenly spaced, the last included).

    Returns:
        Index tensors of chains, one per mode, ordered by their first chain (a single one of
        every chain when the chains did not stay apart).
    """
    split = _last_position_clusters(draws)
    if split is None:
        return [torch.arange(draws.shape[0])]
    clusters, label, whitened = split
    parent = list(range(len(clusters)))
    z_end = whitened(draws[:, -1, :])
    for j in _checkpoints(draws, checkpoints).tolist():
        near = label[torch.cdist(whitened(draws[:, j, :]), z_end).argmin(1)]
        for a, b in torch.unique(torch.stack([label, near], 1)[near != label], dim=0).tolist():
            parent[_root(parent, a)] = _root(parent, b)
    groups: dict[int, list[torch.Tensor]] = {}
    for k, c in enumerate(clusters):
        groups.setdefault(_root(parent, k), []).append(c)
    modes = [torch.sort(torch.cat(g)).values for g in groups.values()]
    return sorted(modes, key=lambda c: int(c[0]))


def mixture_of_last_positions(
    draws: torch.Tensor, checkpoints: int = 10, inflation: float = 1.5
) -> MixtureProposal | None:
    """A mixture with one component per separated cluster of the chains' last positions,
    each fitted to the draws nearest it: the mode pass's proposal where the warm-up jumps
    knew some modes and the chains still did not mix.

    The warm-up mixture is planned among clusters holding 2 % of the chains; a mode fewer
    chains reached is folded into a neighbour's cluster, whose inflated component then
    reaches it only in its far tail, so the chains enter it rarely: on a trimodal 5-D
    target a mode of 20 % of the mass held 1.3 % of the draws, 7 of 512 chains (session 38,
    seed 7). Here the last positions are split by :func:`find_modes` with any cluster of
    :data:`STUCK_MIN_CHAINS` chains counting (a curved mode may come out as several pieces:
    still an exact proposal), and each of ``checkpoints`` evenly spaced draws per chain is
    given to the cluster of its nearest last position (whitened by their covariance), so a
    component is fitted to the draws in its mode even where chains moved between modes.

    Args:
        draws: (chains x draws x q) draws.
        checkpoints: draws per chain looked at (evenly spaced, the last included).
        inflation: factor on the components' standard deviations.

    Returns:
        The mixture, or None where the last positions form a single cluster.
    """
    split = _last_position_clusters(draws)
    if split is None:
        return None
    clusters, label, whitened = split
    points = draws[:, _checkpoints(draws, checkpoints), :].reshape(-1, draws.shape[2])
    nearest = label[torch.cdist(whitened(points), whitened(draws[:, -1, :])).argmin(1)]
    rows = [torch.nonzero(nearest == k).reshape(-1) for k in range(len(clusters))]
    return MixtureProposal.of(points, rows, inflation)


def modes_chains_stayed_in(draws: torch.Tensor) -> int:
    """The number of separated modes the chains stayed in, for chains that did not mix
    (:func:`stuck_modes`; 1 when none): any cluster of :data:`STUCK_MIN_CHAINS` chains
    counts, so that the verdict names the modes (``multimodal``), not only the sampler.

    Args:
        draws: (chains x draws x q) draws.
    """
    return len(stuck_modes(draws))
