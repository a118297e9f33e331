"""Settings of the calibration loop (:func:`susp_bo.calibration.loop.calibrate`).

Every field is checked when the settings are made, so a bad value is refused with
its name, its value and what is allowed before any evaluation runs.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

from susp_bo.calibration.basin_search import BasinSettings
from susp_bo.calibration.design import DesignMethod
from susp_bo.calibration.sampling import SAMPLERS, Backend, Estimator, Sampler
from susp_bo.calibration.surrogate import SurrogateSettings

MIN_DRAWS_PER_CHAIN = 4
"""Fewest draws per chain the split R-hat (:func:`susp_bo.calibration.mcmc.chain_diagnostics`,
Pyro's ``split_gelman_rubin``) works on: each chain is split into two halves of >= 2 draws."""

_OPTIONAL = frozenset({"mcmc_seed", "max_evaluations", "initial_design_size", "num_threads"})
"""The integer fields that may also be None."""


def min_mcmc_samples(sampler: str) -> int:
    """The fewest ``mcmc_samples`` that ``sampler`` can run with.

    Every chain it returns needs :data:`MIN_DRAWS_PER_CHAIN` draws for the split R-hat of
    the summary and of "auto"'s mixing test. The random walk keeps ``mcmc_samples`` draws
    per chain; HMC (``"hmc"``, and ``"auto"`` when the random walk does not mix) keeps
    ``mcmc_samples // 2`` (:func:`susp_bo.calibration.sampling.sample_surrogate_posterior`).
    """
    return MIN_DRAWS_PER_CHAIN if sampler == "random_walk" else 2 * MIN_DRAWS_PER_CHAIN


def _samples_reason(sampler: str) -> str:
    """Why ``sampler`` needs :func:`min_mcmc_samples` draws (the end of an error message)."""
    if sampler == "random_walk":
        return f" (the split R-hat needs {MIN_DRAWS_PER_CHAIN} draws per chain)"
    return (
        f" (with mcmc_sampler {sampler!r} HMC keeps half the draws per chain and the split "
        f"R-hat needs {MIN_DRAWS_PER_CHAIN})"
    )


def _check_integer(name: str, value: object, minimum: int, optional: bool, why: str) -> None:
    """Refuses ``value`` unless it is an integer >= ``minimum`` (or None where ``optional``).

    A float is refused even when integral (``200.0``), and so is a bool: the loop passes
    these on to torch and numpy, which fail on them only after the budget is spent, and a
    silent conversion would hide a mistake in the caller.
    """
    if optional and value is None:
        return
    allowed = f"{'None or ' if optional else ''}an integer >= {minimum}{why}"
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(
            f"{name}: {value!r} ({type(value).__name__}) is not allowed; expected {allowed}"
        )
    if value < minimum:
        raise ValueError(f"{name}: {value!r} is not allowed; expected {allowed}")


@dataclass(frozen=True)
class CalibrationSettings:
    """Settings of :func:`calibrate` (defaults suit q ≈ 2–10).

    Every integer field must be a Python or NumPy integer (not a float, even an integral
    one such as ``200.0``, and not a bool).

    Args:
        seed: master seed (design, surrogate fits, acquisition, refinement), an integer >= 0.
        mcmc_seed: seed of the final MCMC (an integer >= 0); None derives it from ``seed``.
            A different value re-draws the posterior on the same surrogate (a cheap check
            of Monte Carlo error) without changing any simulator evaluation.
        batch_size: points proposed per iteration (parallel simulator calls), >= 1.
        max_evaluations: budget of log L evaluations, design included; None = 50 (q + 2).
        initial_design_size: design size; None = max(10, 5 q).
        design_method: "sobol" or "lhs".
        surrogate: GP settings (output warping etc.).
        ei_tolerance: EGO stops when batch EI / sd(latent log L) < this (> 0).
        max_ego_fraction: share of the post-design budget EGO may use, in [0, 1].
        basin_search: when EGO ends, climb from evaluated points that head basins other
            than the best point's (:mod:`.basin_search`: other modes EGO found only at
            their fringe); nothing happens when the data have no such points.
        basin: the basin phase's settings.
        audit_share: when the search converges with evaluations left, the share of them
            (at least q + 1 points, else none) spent on an audit of C_w far from every
            evaluation before the result is called converged (:mod:`.exploration_audit`):
            an audit point whose log L is near the best and above the surrogate's band
            sends the loop back to EGO. In [0, 1]; 0 = stop as soon as the criteria say so.
        refine: run the posterior-refinement phase after EGO.
        refine_tolerance: refinement stops when the posterior mean of sd[log L̃] < this (nats).
        refine_optimism: κ >= 0. 0 (default): refinement candidates are surrogate posterior
            draws and a widened copy, weighted by exp(E[log L̃] − max). κ > 0: the widened
            copy is replaced by draws of the optimistic posterior exp(E[L̃]) and the weight
            is exp(E[log L̃] + κ sd − max) (:func:`.acquisition.select_uncertainty_batch`):
            refines where the surrogate may be missing posterior mass (curved posteriors'
            arms; ``benchmarks/posterior_accuracy.py``, method ``susp_bo-optimistic``).
        kernel_switch: with the default Matérn kernel and fixed noise, q >= 3 and a search
            over C_w (no trust region, no local phase): when refinement starts, and after
            every further 10 % of the budget, compare the pairwise additive kernel's
            leave-one-out score with the Matérn's on the same points and, at +0.1 nats a
            point or more (+0.3 after the first comparison), run the rest with
            ``surrogate.kernel="auto"`` and ``refine_optimism`` >= 2
            (:mod:`.kernel_switch`; recorded in ``CalibrationResult.kernel_switch``).
            False = keep the kernel given.
        modes_refine_optimism: κ >= 0 the refinement takes on (at least) once the basin
            phase has counted two or more confirmed peaks of the surrogate (several modes
            of log L met), on a search over C_w (no trust region, no local phase) with a
            fixed observation noise: a mode's
            share of the mass then rests on the surrogate's height and width there, which
            refinement weighted by the plug-in posterior alone under-explores where the
            surrogate is too low (trimodal 5-D seed 7: the third mode's peak 1.6 nats low
            with 9 % of the draws for 20 %; with κ = 2, MMTV .115 -> .015). Recorded in
            ``CalibrationResult.modes_optimism_at``. 0 = off.
        estimator: L̃ used by MCMC: "plug_in", "mean_log" or "expected" (paper's E[L̃]).
        check_points: evaluations kept from the end of the budget for the held-out check
            of the surrogate posterior at its 95 % edges (:mod:`surrogate_check`), >= 0;
            they join the data before the final fit. 0 = no check.
        check_tolerance: largest |log L − predicted| (nats) the check calls "ok" (> 0).
        mcmc_chains: chains of the final MCMC (vectorised in one kernel step). The
            default 512 x 2000 draws (1 M) brings the Monte Carlo error of the marginals
            (MMTV of the sampler alone on the exact 7-D Gaussian) from 0.015 with 64 x 1500
            down to 0.005; a few seconds on the surrogate, which is cheap.
        mcmc_warmup: warm-up (adaptation) steps per chain (pooled over chains, so
            many chains need few steps).
        mcmc_samples: kept steps per chain: >= 4 with ``mcmc_sampler="random_walk"``, >= 8
            otherwise (HMC keeps half as many; the split R-hat needs 4 a chain:
            :func:`min_mcmc_samples`).
        mcmc_backend: "vectorized" (plain torch loop) or "pyro" (pyro.infer.MCMC); same draws.
        mcmc_sampler: "auto" (default): the random-walk kernel, and reflective HMC on the
            surrogate's gradient when the random walk found one mode but did not mix
            (R-hat > 1.05 or ESS < 400; on the curved 5-D target its R-hat is 1.3–1.5,
            HMC's ≈ 1.01–1.02; HMC runs at most 128 of the chains for half the draws,
            its draws being far less correlated); "random_walk" or "hmc" force one
            (:mod:`susp_bo.calibration.sampling`). Where the random walk mixes, "auto"
            gives its draws bit for bit. Under a budget below the minimum
            (``allow_small_budget``) "auto" is the random walk alone: such a result is
            not trusted whatever its draws, and HMC would cost more than the run.
        candidate_count: posterior candidates scored per refinement batch (and as many widened).
        acquisition_restarts: restarts of the qLogEI optimisation.
        acquisition_raw_samples: raw samples for the qLogEI restarts.
        allow_small_budget: run even when ``max_evaluations`` is below the minimum the
            loop needs for q parameters (a design of max(10, 5 q) or the configured one
            when larger, one batch, the check points:
            :func:`susp_bo.calibration.budget.budget_requirement`). False (default):
            :func:`calibrate` refuses such a budget before any evaluation; True: it runs
            and the verdict is ``not_trusted`` with ``budget_too_small``.
        trust_region: refine in a search box that follows the posterior
            (:mod:`susp_bo.calibration.trust_region`): the surrogate, acquisition, check and
            MCMC work in the box, which shrinks onto the posterior and grows where the
            posterior presses against it. Needed when the posterior is orders of magnitude
            narrower than C_w (paired data).
        trust_region_half_width_sd: half-width of a shrunk box coordinate, in posterior sd (> 0).
        local_search: when EGO ends, climb from the best point with the trust-region
            Gauss–Newton search on the spectra (:mod:`.local_search`; needs an evaluator
            that exposes its spectra, as the study's does), then refine, check and sample
            in the box of the Laplace posterior ± ``trust_region_half_width_sd`` sd.
        local_search_fraction: share of the evaluations left when EGO ends that the local
            phase may use, in (0, 1).
        laplace_mean: after the local phase, the GP's prior mean is the Laplace bowl it
            found (fixed; only its height is fitted), so the GP models only the departure
            of log L from it; False keeps ``surrogate.mean``.
        num_threads: torch intra-op threads for the surrogate, acquisition and MCMC work
            (restored afterwards, never around ``evaluate``); None leaves torch's setting.
            The default 1 is fastest for these small matrices, by far on a shared machine.
    """

    seed: int = 0
    mcmc_seed: int | None = None
    batch_size: int = 4
    max_evaluations: int | None = None
    initial_design_size: int | None = None
    design_method: DesignMethod = "sobol"
    surrogate: SurrogateSettings = field(default_factory=SurrogateSettings)
    ei_tolerance: float = 1e-3
    max_ego_fraction: float = 0.4
    basin_search: bool = True
    basin: BasinSettings = field(default_factory=BasinSettings)
    refine: bool = True
    audit_share: float = 0.5
    refine_tolerance: float = 0.02
    refine_optimism: float = 0.0
    kernel_switch: bool = True
    modes_refine_optimism: float = 2.0
    check_points: int = 8
    check_tolerance: float = 1.0
    estimator: Estimator = "plug_in"
    mcmc_chains: int = 512
    mcmc_warmup: int = 500
    mcmc_samples: int = 2000
    mcmc_backend: Backend = "vectorized"
    mcmc_sampler: Sampler = "auto"
    candidate_count: int = 512
    acquisition_restarts: int = 6
    acquisition_raw_samples: int = 256
    allow_small_budget: bool = False
    trust_region: bool = False
    trust_region_half_width_sd: float = 8.0
    local_search: bool = False
    local_search_fraction: float = 0.7
    laplace_mean: bool = True
    num_threads: int | None = 1

    def __post_init__(self) -> None:
        if self.mcmc_sampler not in SAMPLERS:  # first: the least mcmc_samples depends on it
            raise ValueError(
                f"mcmc_sampler: {self.mcmc_sampler!r}, expected one of {', '.join(SAMPLERS)}"
            )
        minimum = {
            "seed": 0,
            "mcmc_seed": 0,
            "batch_size": 1,
            "max_evaluations": 2,
            "initial_design_size": 2,
            "check_points": 0,
            "mcmc_chains": 1,
            "mcmc_warmup": 0,
            "mcmc_samples": min_mcmc_samples(self.mcmc_sampler),
            "candidate_count": 1,
            "acquisition_restarts": 1,
            "acquisition_raw_samples": 1,
            "num_threads": 1,
        }
        why = {"mcmc_samples": _samples_reason(self.mcmc_sampler)}
        for name, least in minimum.items():
            _check_integer(name, getattr(self, name), least, name in _OPTIONAL, why.get(name, ""))
        if not self.check_tolerance > 0.0:
            raise ValueError(f"check_tolerance: {self.check_tolerance} must be > 0 nats")
        if not self.ei_tolerance > 0.0:
            raise ValueError(f"ei_tolerance: {self.ei_tolerance} must be > 0")
        if not self.trust_region_half_width_sd > 0.0:
            raise ValueError(
                f"trust_region_half_width_sd: {self.trust_region_half_width_sd} must be > 0"
            )
        if not self.refine_tolerance > 0.0:
            raise ValueError(f"refine_tolerance: {self.refine_tolerance} must be > 0 nats")
        if not (math.isfinite(self.refine_optimism) and self.refine_optimism >= 0.0):
            raise ValueError(f"refine_optimism: {self.refine_optimism} must be finite and >= 0")
        if not (math.isfinite(self.modes_refine_optimism) and self.modes_refine_optimism >= 0):
            raise ValueError(
                f"modes_refine_optimism: {self.modes_refine_optimism} must be finite and >= 0"
            )
        if not 0.0 < self.local_search_fraction < 1.0:
            raise ValueError(
                f"local_search_fraction: {self.local_search_fraction} must be in (0, 1)"
            )
        if not 0.0 <= self.audit_share <= 1.0:  # also false for nan
            raise ValueError(f"audit_share: {self.audit_share} must be in [0, 1]")
        if not 0.0 <= self.max_ego_fraction <= 1.0:
            raise ValueError(f"max_ego_fraction: {self.max_ego_fraction} must be in [0, 1]")
        if self.design_method not in ("sobol", "lhs"):
            raise ValueError(f"design_method: {self.design_method!r}, expected 'sobol' or 'lhs'")
        if self.estimator not in ("plug_in", "mean_log", "expected"):
            raise ValueError(f"estimator: {self.estimator!r}, expected plug_in/mean_log/expected")
        if self.mcmc_backend not in ("vectorized", "pyro"):
            raise ValueError(f"mcmc_backend: {self.mcmc_backend!r}, expected vectorized/pyro")

    def global_fixed_noise_search(self, local_phase: bool) -> bool:
        """Whether the search runs over C_w with a fixed observation noise: no trust region,
        no local phase (``local_phase``: the run will make or made one) and no learned
        noise (a noisy log L's scores and bumps mislead). Where the run's own evidence may
        change its settings (:mod:`.kernel_switch`, ``modes_refine_optimism``)."""
        return not (local_phase or self.trust_region or self.surrogate.noise == "learned")
