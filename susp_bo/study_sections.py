"""The sections of a study config (``[budget]``, ``[seeds]``, ``[executor]``, ``[mcmc]``,
``[output_error]``, ``[search]``): one frozen dataclass each, validated on construction.

The file format, and :class:`~susp_bo.study_config.StudyConfig` that holds these sections,
are in :mod:`susp_bo.study_config`, which re-exports these classes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from susp_bo.calibration.track_statistics import MINIMUM_PILOT_RUNS


def _integer(name: str, value: object, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{name}: {value!r} is not allowed; expected an integer >= {minimum}")


def _positive(name: str, value: object) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise ValueError(f"{name}: {value!r} is not allowed; expected a finite number > 0")


MAX_EVALUATIONS = 100_000
"""Largest budget a study accepts: a GP on 10⁵ points needs 80 GB for its covariance
matrix alone, so a larger budget (outside probe, session 29: 10¹² as ``initial_design``
failed in the Sobol' allocation with a traceback) can only be a typo."""


@dataclass(frozen=True)
class BudgetConfig:
    """Simulation budget.

    Attributes:
        max_evaluations: likelihood evaluations (points w of C_w, each one
            simulator run per measured track stretch), design and EGO together.
        initial_design: size of the space-filling design (≥ 2).
        batch_size: EGO points proposed per batch (fill the workers).
        check_points: evaluations kept from the end of ``max_evaluations`` for the
            held-out check of the surrogate posterior at its 95 % edges (0 = none).
        allow_small: run a budget below the minimum for q parameters
            (``--allow-small-budget``); the result is then marked not trusted.
    """

    section: ClassVar[str] = "budget"
    max_evaluations: int = 100
    initial_design: int = 40
    batch_size: int = 8
    check_points: int = 8
    allow_small: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.allow_small, bool):
            raise ValueError(
                f"budget.allow_small: {self.allow_small!r} is not allowed; expected true or false"
            )
        _integer("budget.initial_design", self.initial_design, 2)
        _integer("budget.max_evaluations", self.max_evaluations, 2)
        _integer("budget.batch_size", self.batch_size, 1)
        _integer("budget.check_points", self.check_points, 0)
        if self.max_evaluations > MAX_EVALUATIONS:
            raise ValueError(
                f"budget.max_evaluations: {self.max_evaluations} is not allowed; expected at "
                f"most {MAX_EVALUATIONS} (the kriging surrogate's cost grows as the cube of "
                "the evaluations; the paper's study used 450)"
            )
        if self.max_evaluations < self.initial_design:
            raise ValueError(
                f"budget.max_evaluations: {self.max_evaluations} is not allowed; expected >= "
                f"budget.initial_design ({self.initial_design})"
            )


@dataclass(frozen=True)
class SeedsConfig:
    """Seeds of the stochastic steps: ``calibration`` (design, EGO) and ``mcmc``."""

    section: ClassVar[str] = "seeds"
    calibration: int = 0
    mcmc: int = 0

    def __post_init__(self) -> None:
        _integer("seeds.calibration", self.calibration, 0)
        _integer("seeds.mcmc", self.mcmc, 0)


@dataclass(frozen=True)
class ExecutorConfig:
    """Where simulations run (see :func:`susp_bo.execution.make_executor`).

    Attributes:
        workers: local worker processes; None = every core, 0 = in-process.
        scheduler: Dask scheduler address (``tcp://host:8786``); excludes workers.
    """

    section: ClassVar[str] = "executor"
    workers: int | None = None
    scheduler: str | None = None

    def __post_init__(self) -> None:
        if self.workers is not None:
            _integer("executor.workers", self.workers, 0)
        if self.scheduler is not None and (
            not isinstance(self.scheduler, str) or not self.scheduler
        ):
            raise ValueError(
                f"executor.scheduler: {self.scheduler!r} is not allowed; expected an address "
                "such as 'tcp://host:8786'"
            )
        if self.scheduler is not None:
            from susp_bo.execution import scheduler_address_problem

            problem = scheduler_address_problem(self.scheduler)
            if problem is not None:
                raise ValueError(
                    f"executor.scheduler: {self.scheduler!r} is not allowed: {problem}; "
                    "expected an address such as 'tcp://10.0.0.5:8786'"
                )
        if self.workers is not None and self.scheduler is not None:
            raise ValueError(
                f"executor: workers = {self.workers} and scheduler = {self.scheduler!r} are not "
                "allowed together; give one of them"
            )


_SAMPLERS = ("random_walk", "hmc", "auto")
"""Values of ``[mcmc] sampler`` (:data:`susp_bo.calibration.sampling.SAMPLERS`; kept here so
that reading a config does not import torch, a test checks that the two agree)."""


@dataclass(frozen=True)
class MCMCConfig:
    """MCMC on the surrogate: chains, draws and warm-up per chain, and the sampler.

    The chains are vectorised inside one kernel step, so many chains cost little
    more than one; the defaults are those of :class:`CalibrationSettings`. ``sampler``:
    "auto" (random walk, then reflective HMC where the random walk found one mode but
    did not mix), "random_walk" or "hmc" (:mod:`susp_bo.calibration.sampling`).
    ``draws`` is at least 4 with "random_walk" and 8 otherwise
    (:func:`susp_bo.calibration.settings.min_mcmc_samples`, kept here so that reading a
    config does not import torch; a test checks that the two agree).
    """

    section: ClassVar[str] = "mcmc"
    chains: int = 512
    draws: int = 2000
    warmup: int = 500
    sampler: str = "auto"

    def __post_init__(self) -> None:
        _integer("mcmc.chains", self.chains, 1)
        _integer("mcmc.warmup", self.warmup, 0)
        if self.sampler not in _SAMPLERS:
            raise ValueError(
                f"mcmc.sampler: {self.sampler!r} is not allowed; expected one of "
                + ", ".join(f'"{k}"' for k in _SAMPLERS)
            )
        # the split R-hat needs 4 draws a chain, and HMC keeps half of them
        least = 4 if self.sampler == "random_walk" else 8
        try:
            _integer("mcmc.draws", self.draws, least)
        except ValueError as error:
            why = (
                "the split R-hat needs 4 draws per chain"
                if least == 4
                else f'with sampler = "{self.sampler}" HMC keeps half the draws per chain and '
                "the split R-hat needs 4"
            )
            raise ValueError(f"{error} ({why})") from None
        steps = self.chains * (self.warmup + self.draws)
        if steps > MAX_CHAIN_STEPS:
            raise ValueError(
                f"mcmc.chains x (mcmc.warmup + mcmc.draws): {self.chains} x ({self.warmup} + "
                f"{self.draws}) = {steps:,} chain steps is not allowed; expected at most "
                f"{MAX_CHAIN_STEPS:,} (the defaults take {_DEFAULT_CHAIN_STEPS:,}; the kept "
                "draws are held in memory, 8 bytes a parameter each)"
            )


_DEFAULT_CHAIN_STEPS = MCMCConfig.chains * (MCMCConfig.warmup + MCMCConfig.draws)
MAX_CHAIN_STEPS = 10**8
"""Largest ``chains x (warmup + draws)`` a study accepts (≈ 80x the defaults): beyond it
the draws do not fit in memory or the sampler runs for hours — refused when the study file
is read, before any simulation (outside probe, session 29: 10¹² chains failed with a
MemoryError traceback after every simulation had run)."""


OUTPUT_ERROR_MODELS = ("unpaired", "paired", "track_statistics")
"""Values of ``[output_error] model``."""


@dataclass(frozen=True)
class OutputErrorConfig:
    """Output prediction error B (eq. 4).

    Attributes:
        model: ``"unpaired"`` (default: eq. 4's mixture of every run with every track,
            σ_B from the scatter between runs) or ``"paired"`` (run i is compared with
            the simulation on its own measured track, B = sensor noise of the Welch
            spectra + per-channel model error, :mod:`susp_bo.calibration.paired_error`).
            Paired is the right model when the tracks are measured, but its posterior is
            10⁻⁴–10⁻³ of C_w wide and the surrogate search does not resolve it at the
            usual budgets yet (README, "Which output-error model applies"), so it is opt-in.
            ``"track_statistics"``: the runs' tracks were not measured (their geometry in
            the run files is not used), only the track process is known (the rig's
            ``simulation.track_quality`` PSD): the model simulates ν synthetic
            realizations and compares q summaries of the mean spectra, with
            weights and covariance from a pilot of ``pilot_runs`` runs on fresh
            realizations, twice (:mod:`susp_bo.calibration.study_track_statistics`).
        sigma: ``"estimate"`` (from the data), one σ for every channel, or a
            mapping channel name → σ (log-amplitude units, > 0). Paired: the
            model-error sd τ_c, "estimate" = profiled at every w; unpaired: σ_B,
            "estimate" = from the replicate scatter of the runs.
        correlation_length_hz: frequency correlation length of B (Hz, > 0), or
            None for independent frequencies (unpaired model only; the paired model
            takes the band correlation from the Welch settings).
        sensor_noise_m_s2: white noise of the accelerometers (m/s² rms, >= 0), added
            to the simulated spectra as a noise floor before the comparison; None
            takes ``noise_m_s2`` from the runs' metadata (synthetic runs record it),
            else 0.
        pilot_runs: ``track_statistics`` only: M pilot runs per stage (None = 100; at
            least max(10 q, 50), checked when q is known); outside the budget.
    """

    section: ClassVar[str] = "output_error"
    model: str = "unpaired"
    sigma: str | float | Mapping[str, float] = "estimate"
    correlation_length_hz: float | None = None
    sensor_noise_m_s2: float | None = None
    pilot_runs: int | None = None

    def __post_init__(self) -> None:
        if self.model not in OUTPUT_ERROR_MODELS:
            raise ValueError(
                f"output_error.model: {self.model!r} is not allowed; expected 'paired' (each "
                "run with its own measured track), 'unpaired' (eq. 4's mixture over the runs' "
                "tracks) or 'track_statistics' (tracks not measured, only their statistics "
                "known)"
            )
        if self.model == "track_statistics":
            for name, default in (("sigma", "estimate"), ("correlation_length_hz", None)):
                if getattr(self, name) != default:
                    raise ValueError(
                        f"output_error.{name}: {getattr(self, name)!r} is not allowed with "
                        "model = 'track_statistics' (its covariance comes from the pilot "
                        "runs); remove it"
                    )
            if self.pilot_runs is not None:
                _integer("output_error.pilot_runs", self.pilot_runs, MINIMUM_PILOT_RUNS)
        else:
            if self.pilot_runs is not None:
                raise ValueError(
                    f"output_error.pilot_runs: {self.pilot_runs!r} is not allowed with "
                    f"model = {self.model!r}; it belongs to model = 'track_statistics'"
                )
        if self.model == "paired" and self.correlation_length_hz is not None:
            raise ValueError(
                f"output_error.correlation_length_hz: {self.correlation_length_hz!r} is not "
                "allowed with model = 'paired' (its band correlation comes from the Welch "
                "settings); remove it or set model = 'unpaired'"
            )
        if isinstance(self.sigma, Mapping):
            if not self.sigma:
                raise ValueError("output_error.sigma: {} is not allowed; name at least a channel")
            for channel, value in self.sigma.items():
                _positive(f"output_error.sigma.{channel}", value)
            object.__setattr__(self, "sigma", {k: float(v) for k, v in self.sigma.items()})
        elif self.sigma != "estimate":
            try:
                _positive("output_error.sigma", self.sigma)
            except ValueError as error:
                raise ValueError(f"{error}, 'estimate' or a table channel = σ") from None
            object.__setattr__(self, "sigma", float(self.sigma))
        if self.correlation_length_hz is not None:
            _positive("output_error.correlation_length_hz", self.correlation_length_hz)
            object.__setattr__(self, "correlation_length_hz", float(self.correlation_length_hz))
        noise = self.sensor_noise_m_s2
        if noise is not None:
            if (
                isinstance(noise, bool)
                or not isinstance(noise, int | float)
                or not (math.isfinite(noise) and noise >= 0.0)
            ):
                raise ValueError(
                    f"output_error.sensor_noise_m_s2: {noise!r} is not allowed; expected a "
                    "number >= 0 (m/s^2 rms)"
                )
            object.__setattr__(self, "sensor_noise_m_s2", float(noise))


_KERNELS = ("matern", "additive_pairs", "auto")
"""Values of ``[search] kernel`` (:class:`susp_bo.calibration.surrogate.SurrogateSettings`)."""


@dataclass(frozen=True)
class SearchConfig:
    """How the loop searches C_w after the design and EGO.

    Attributes:
        local: the local phase (:mod:`susp_bo.calibration.local_search`): trust-region
            Gauss–Newton on the spectra from EGO's best point, then refinement, check and
            MCMC in the box of its Laplace posterior with that bowl as the GP's mean.
            Needed for paired data, whose posterior is 10⁻⁴–10⁻³ of C_w wide.
        basins: the basin phase (:mod:`susp_bo.calibration.basin_search`) when EGO ends:
            local climbs from evaluated points that head other modes of log L. Does
            nothing when the surrogate has a single basin near the best point.
        refine_optimism: κ >= 0 of the refinement
            (:attr:`susp_bo.calibration.settings.CalibrationSettings.refine_optimism`).
            0 (default): refine where the surrogate posterior has mass and log L is
            uncertain. κ > 0 (2 measured): also where the surrogate may be missing mass
            it does not see, weighted by exp(E[log L̃] + κ sd); for curved posteriors
            (on a curved 5-D test target MMTV .073–.153 against .130–.160), at more
            surrogate fits a batch.
        kernel: the GP's covariance
            (:attr:`susp_bo.calibration.surrogate.SurrogateSettings.kernel`): "matern"
            (default), "additive_pairs" or "auto" (both fitted at every refit, the better
            leave-one-out score kept; for a log L made of one- and two-parameter terms,
            :mod:`susp_bo.calibration.additive_kernel`; each refit costs about 4x).
        kernel_switch: with ``kernel = "matern"``, q >= 3 and no local phase, switch the
            rest of the search to ``"auto"`` (and ``refine_optimism`` >= 2) when the
            additive kernel predicts the evaluations better
            (:mod:`susp_bo.calibration.kernel_switch`); false = keep the kernel given.
        hunt: β >= 0 of the basin phase's hunt for modes no evaluation came near
            (:attr:`susp_bo.calibration.basin_search.BasinSettings.hunt_beta`). Omitted:
            the default, 3 (session 43), in a search without the local phase. β > 0 (needs
            ``basins = true`` and ``local = false``, where the hunt runs): where the
            surrogate has two or more confirmed peaks when EGO ends, evaluate at the local
            maxima of mean + β sd that could hold posterior mass. On a trimodal 5-D test
            target it keeps the third mode on the two seeds of 0–8 that lose it without
            (MMTV .186 / .187 -> .019 / .019; session 43). 0: no hunt.
    """

    section: ClassVar[str] = "search"
    local: bool = False
    basins: bool = True
    refine_optimism: float = 0.0
    kernel: str = "matern"
    kernel_switch: bool = True
    hunt: float | None = None

    def __post_init__(self) -> None:
        for name in ("local", "basins", "kernel_switch"):
            value = getattr(self, name)
            if not isinstance(value, bool):
                raise ValueError(f"search.{name}: {value!r} is not allowed; expected true or false")
        for name, hint in (
            ("refine_optimism", ""),
            ("hunt", " (0: no hunt; omit it for the default, 3)"),
        ):
            value = getattr(self, name)
            if value is None and name == "hunt":
                continue  # the default
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not (math.isfinite(value) and value >= 0.0)
            ):
                raise ValueError(
                    f"search.{name}: {value!r} is not allowed; expected a finite number >= 0" + hint
                )
            object.__setattr__(self, name, float(value))
        if self.hunt is not None and self.hunt > 0.0 and not self.basins:
            raise ValueError(
                f"search: hunt = {self.hunt:g} and basins = false are not allowed together; "
                "the hunt is part of the basin phase (set basins = true, or hunt = 0)"
            )
        if self.hunt is not None and self.hunt > 0.0 and self.local:
            raise ValueError(
                f"search: hunt = {self.hunt:g} and local = true are not allowed together; "
                "the hunt runs in a search over C_w without the local phase (set local = "
                "false, or hunt = 0)"
            )
        if self.kernel not in _KERNELS:
            raise ValueError(
                f"search.kernel: {self.kernel!r} is not allowed; expected one of "
                + ", ".join(f'"{k}"' for k in _KERNELS)
            )


SECTIONS: dict[str, type] = {
    cls.section: cls
    for cls in (
        BudgetConfig,
        SeedsConfig,
        ExecutorConfig,
        MCMCConfig,
        OutputErrorConfig,
        SearchConfig,
    )
}
"""Each section's dataclass by its TOML table name, in file order."""
