"""The study config file: one TOML file naming everything a calibration study runs with.

``susp-bo calibrate STUDY.toml`` reads it with :func:`load_study_config`; the
results folder gets the config the run actually used (:meth:`StudyConfig.to_toml`,
paths made absolute). Unknown keys are errors (they are usually typos), and
every error names the field, the value and what is allowed. Relative paths
resolve against the config file's folder.

Example (also in the README; the test suite loads this one)::

    # susp-bo study: calibrate the reference trailer's suspension on measured runs.
    # Run with: susp-bo calibrate study.toml [--resume]. Relative paths resolve against
    # this file's folder; unknown keys are errors.
    rig = "hst_trailer"            # a shipped rig's name, or a path to a rig .toml
    data = "measured"              # folder of measured runs (susp-bo synth format)
    out = "results/trailer"        # result.json, config, store, figures and log go here
    # optional subset of the rig's calibration set (default: all of it), in this order:
    parameters = ["secondary_vertical_damping", "primary_vertical_stiffness"]

    [budget]
    max_evaluations = 120   # likelihood evaluations (points w), design + EGO together
    initial_design = 40     # space-filling design size
    batch_size = 8          # EGO points per batch; match the workers
    check_points = 8        # last evaluations: held-out check of the posterior's 95 % edges

    [seeds]
    calibration = 0         # design and EGO
    mcmc = 1

    [executor]
    workers = 8             # local processes; 0 = in-process; omit = every core
    # scheduler = "tcp://scheduler.example:8786"   # a Dask cluster instead of workers

    [mcmc]
    chains = 512            # vectorised in one kernel step
    draws = 2000            # kept steps per chain
    warmup = 500            # adaptive warm-up steps per chain
    sampler = "auto"        # random walk; HMC where it did not mix ("random_walk", "hmc")

    [output_error]
    model = "unpaired"      # eq. 4 mixture (default); "paired": each run vs its own track
    sigma = "estimate"      # or one σ for all channels, or a table {channel = σ}
    # correlation_length_hz = 0.5   # unpaired only: frequency correlation length (Hz)
    sensor_noise_m_s2 = 0.005     # accelerometer noise floor; omit = from the runs' metadata

    [search]
    local = true            # Gauss–Newton on the spectra after EGO (needed for "paired")
    basins = true           # climb other modes EGO saw only at their fringe (default true)
    refine_optimism = 0.0   # > 0 (e.g. 2): also refine where the surrogate may miss mass
    kernel = "matern"       # GP covariance; "auto" also tries the pairwise additive one
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import tomli_w

from susp_bo.rig.catalog import available_rigs, rig_path
from susp_bo.rig.schema import did_you_mean


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
    """

    section: ClassVar[str] = "mcmc"
    chains: int = 512
    draws: int = 2000
    warmup: int = 500
    sampler: str = "auto"

    def __post_init__(self) -> None:
        _integer("mcmc.chains", self.chains, 1)
        _integer("mcmc.draws", self.draws, 1)
        _integer("mcmc.warmup", self.warmup, 0)
        if self.sampler not in _SAMPLERS:
            raise ValueError(
                f"mcmc.sampler: {self.sampler!r} is not allowed; expected one of "
                + ", ".join(f'"{k}"' for k in _SAMPLERS)
            )


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
    """

    section: ClassVar[str] = "output_error"
    model: str = "unpaired"
    sigma: str | float | Mapping[str, float] = "estimate"
    correlation_length_hz: float | None = None
    sensor_noise_m_s2: float | None = None

    def __post_init__(self) -> None:
        if self.model not in ("paired", "unpaired"):
            raise ValueError(
                f"output_error.model: {self.model!r} is not allowed; expected 'paired' (each "
                "run with its own measured track) or 'unpaired' (track statistics only)"
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
    """

    section: ClassVar[str] = "search"
    local: bool = False
    basins: bool = True
    refine_optimism: float = 0.0
    kernel: str = "matern"

    def __post_init__(self) -> None:
        for name in ("local", "basins"):
            value = getattr(self, name)
            if not isinstance(value, bool):
                raise ValueError(f"search.{name}: {value!r} is not allowed; expected true or false")
        kappa = self.refine_optimism
        if (
            isinstance(kappa, bool)
            or not isinstance(kappa, (int, float))
            or not (math.isfinite(kappa) and kappa >= 0.0)
        ):
            raise ValueError(
                f"search.refine_optimism: {kappa!r} is not allowed; expected a finite number >= 0"
            )
        object.__setattr__(self, "refine_optimism", float(kappa))
        if self.kernel not in _KERNELS:
            raise ValueError(
                f"search.kernel: {self.kernel!r} is not allowed; expected one of "
                + ", ".join(f'"{k}"' for k in _KERNELS)
            )


_SECTIONS: dict[str, type] = {
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


@dataclass(frozen=True)
class StudyConfig:
    """Everything a calibration study runs with.

    Attributes:
        rig: a shipped rig's name, or an absolute path to a rig ``.toml``.
        data: folder of measured runs.
        out: results folder.
        parameters: names of the calibrated subset of the rig's calibration
            set, in calibration order; None = the whole set.
        budget, seeds, executor, mcmc, output_error, search: the sections.
    """

    rig: str
    data: Path
    out: Path
    parameters: tuple[str, ...] | None = None
    budget: BudgetConfig = field(default_factory=BudgetConfig)
    seeds: SeedsConfig = field(default_factory=SeedsConfig)
    executor: ExecutorConfig = field(default_factory=ExecutorConfig)
    mcmc: MCMCConfig = field(default_factory=MCMCConfig)
    output_error: OutputErrorConfig = field(default_factory=OutputErrorConfig)
    search: SearchConfig = field(default_factory=SearchConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.rig, str) or not self.rig:
            raise ValueError(f"rig: {self.rig!r} is not allowed; expected a rig name or path")
        for name in ("data", "out"):
            value = getattr(self, name)
            if not isinstance(value, (str, Path)) or not str(value):
                raise ValueError(f"{name}: {value!r} is not allowed; expected a path")
            object.__setattr__(self, name, Path(value))
        if self.parameters is not None:
            names = self.parameters
            if (
                isinstance(names, str)
                or not isinstance(names, Sequence)
                or not names
                or not all(isinstance(n, str) and n for n in names)
                or len(set(names)) != len(names)
            ):
                raise ValueError(
                    f"parameters: {names!r} is not allowed; expected a non-empty list of distinct "
                    "calibration parameter names"
                )
            object.__setattr__(self, "parameters", tuple(names))

    def check_parameters(self, calibration_names: Sequence[str]) -> tuple[str, ...]:
        """The calibrated names, checked against the rig's calibration set.

        Args:
            calibration_names: ``RigSpec.calibration_names``.

        Returns:
            ``parameters``, or all of ``calibration_names`` when None.

        Raises:
            ValueError: naming the unknown names and the allowed ones.
        """
        if self.parameters is None:
            return tuple(calibration_names)
        unknown = [name for name in self.parameters if name not in calibration_names]
        if unknown:
            raise ValueError(
                f"parameters: {unknown} not in the calibration set of rig {self.rig!r}; "
                f"allowed: {list(calibration_names)}"
            )
        return self.parameters

    def to_dict(self) -> dict[str, Any]:
        """TOML-ready mapping (paths as strings, None values left out)."""
        result: dict[str, Any] = {"rig": self.rig, "data": str(self.data), "out": str(self.out)}
        if self.parameters is not None:
            result["parameters"] = list(self.parameters)
        for name in _SECTIONS:
            section = {k: v for k, v in asdict(getattr(self, name)).items() if v is not None}
            result[name] = section
        return result

    def to_toml(self) -> str:
        """The config as TOML text; :func:`parse_study_config` reads it back equal."""
        return tomli_w.dumps(self.to_dict())


_RIG_SECTIONS = ("simulation", "spectrum", "calibration", "sensors", "effects")


def _check_keys(where: str, given: Mapping[str, Any], allowed: Sequence[str]) -> None:
    for key in given:
        if key not in allowed:
            hint = did_you_mean(key, allowed)
            if not where and key in _RIG_SECTIONS:
                hint = f" ([{key}] belongs in the rig .toml: copy the rig, edit it, name it in rig)"
            raise ValueError(f"{where}{key}: unknown key{hint}; allowed keys: {', '.join(allowed)}")


def _resolve_rig(rig: object, base_dir: Path) -> str:
    if not isinstance(rig, str) or not rig:
        raise ValueError(f"rig: {rig!r} is not allowed; expected a rig name or a path to a .toml")
    if "/" in rig or "\\" in rig or rig.endswith(".toml"):
        path = (base_dir / rig).resolve()
        if not path.is_file():
            raise ValueError(f"rig: {rig!r} is not allowed; no rig file at {path}")
        return str(path)
    try:
        rig_path(rig)
    except FileNotFoundError:
        raise ValueError(
            f"rig: {rig!r} is not allowed; shipped rigs are {list(available_rigs())}, "
            "or give a path to a rig .toml"
        ) from None
    return rig


def parse_study_config(mapping: Mapping[str, Any], base_dir: Path) -> StudyConfig:
    """A :class:`StudyConfig` from a parsed TOML mapping.

    Args:
        mapping: the TOML document as a dict.
        base_dir: folder that relative paths resolve against.

    Returns:
        The validated config, with absolute paths.

    Raises:
        ValueError: an unknown key, a missing or invalid value, a rig that does
            not exist or a data folder that does not exist.
    """
    top = ("rig", "data", "out", "parameters", *_SECTIONS)
    _check_keys("", mapping, top)
    for name in ("rig", "data", "out"):
        if name not in mapping:
            raise ValueError(f"{name}: missing; the study config must give rig, data and out")
    sections: dict[str, Any] = {}
    for name, cls in _SECTIONS.items():
        values = mapping.get(name, {})
        if not isinstance(values, Mapping):
            raise ValueError(f"{name}: {values!r} is not allowed; expected a table [{name}]")
        _check_keys(f"{name}.", values, [f.name for f in fields(cls)])
        sections[name] = cls(**values)
    paths = {}
    for name in ("data", "out"):
        value = mapping[name]
        if not isinstance(value, str) or not value:
            raise ValueError(f"{name}: {value!r} is not allowed; expected a path")
        paths[name] = (base_dir / value).resolve()
    if not paths["data"].is_dir():
        raise ValueError(f"data: {mapping['data']!r} is not allowed; no folder at {paths['data']}")
    return StudyConfig(
        rig=_resolve_rig(mapping["rig"], base_dir),
        parameters=mapping.get("parameters"),
        **paths,
        **sections,
    )


def load_study_config(path: str | Path) -> StudyConfig:
    """Read and validate a study config file.

    Args:
        path: the ``.toml`` file; relative paths in it resolve against its folder.

    Returns:
        The validated config.

    Raises:
        FileNotFoundError: no such file.
        ValueError: ``"<file>: <field>: <value> is not allowed; expected …"``,
            also for TOML syntax errors and unknown keys.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    try:
        return parse_study_config(tomllib.loads(text), path.resolve().parent)
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path}: not valid TOML ({error})") from error
    except (ValueError, TypeError) as error:
        raise ValueError(f"{path}: {error}") from error
