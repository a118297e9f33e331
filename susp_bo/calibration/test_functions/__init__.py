"""Analytic test log-likelihoods with exact posteriors (uniform prior on a box).

They stand in for the rig in tests and benchmarks of the calibration core: each
target gives ``log L(w)`` for a batch of parameter vectors, exact posterior
draws and the exact marginal posterior densities, so that a calibration can be
scored by the mean marginal total variation (MMTV, Acerbi 2020):

    MMTV = (1/q) Σ_k ½ ∫ |p_k(w_k) − p̂_k(w_k)| dw_k

Every target is a product of independent blocks, each of which is either a
correlated Gaussian (marginals analytic; the box is checked to hold ±6 σ, so the
truncation is negligible) or a two-dimensional density whose marginals are
integrated on a fine grid over the box (exact to quadrature error, truncation
included).

Targets of issue 3 (:mod:`.classic`):

- :func:`banana_2d` — a curved 2-D posterior (Rosenbrock-like banana);
- :func:`correlated_gaussian_7d` — a 7-D Gaussian with strong correlations;
- :func:`weakly_identified_7d` — 5 well identified parameters plus a pair whose
  sum is identified but whose difference is only bounded by the box (the
  paper's components 2 and 3 behave like that);
- :func:`oscillator_2d` — a spectral likelihood of a base-excited oscillator.

Targets of issue 10, part 3 (surrogate robustness, :mod:`.robustness`):
:func:`curved_chain_5d`, :func:`student_t_6d`, :func:`trimodal_5d` and
:func:`noisy_gaussian_7d` (log L observed with 1 nat of noise per evaluation).

Building blocks and the MMTV are in :mod:`.blocks`.

Parameters live in physical-looking units (boxes are not the unit cube) so the
normalisation of the calibration core is exercised too.
"""

from __future__ import annotations

from collections.abc import Callable

from susp_bo.calibration.test_functions.blocks import (
    AnalyticTarget,
    Block,
    GaussianBlock,
    PlanarBlock,
    grid_sampler,
    marginal_total_variation,
)
from susp_bo.calibration.test_functions.classic import (
    banana_2d,
    correlated_gaussian_7d,
    oscillator_2d,
    weakly_identified_7d,
)
from susp_bo.calibration.test_functions.robustness import (
    CurvedChainBlock,
    GaussianMixtureBlock,
    NoisyTarget,
    StudentTBlock,
    curved_chain_5d,
    noisy_gaussian_7d,
    student_t_6d,
    trimodal_5d,
)

Target = AnalyticTarget | NoisyTarget

TARGETS: dict[str, Callable[[], Target]] = {
    "banana_2d": banana_2d,
    "correlated_gaussian_7d": correlated_gaussian_7d,
    "weakly_identified_7d": weakly_identified_7d,
    "oscillator_2d": oscillator_2d,
    "curved_chain_5d": curved_chain_5d,
    "student_t_6d": student_t_6d,
    "trimodal_5d": trimodal_5d,
    "noisy_gaussian_7d": noisy_gaussian_7d,
}

__all__ = [
    "TARGETS",
    "AnalyticTarget",
    "Block",
    "CurvedChainBlock",
    "GaussianBlock",
    "GaussianMixtureBlock",
    "NoisyTarget",
    "PlanarBlock",
    "StudentTBlock",
    "Target",
    "banana_2d",
    "correlated_gaussian_7d",
    "curved_chain_5d",
    "grid_sampler",
    "marginal_total_variation",
    "noisy_gaussian_7d",
    "oscillator_2d",
    "student_t_6d",
    "trimodal_5d",
    "weakly_identified_7d",
]
