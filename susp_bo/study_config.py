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
    model = "unpaired"      # eq. 4 mixture (default); "paired": each run vs its own track;
                            # "track_statistics": tracks not measured, only their PSD known
    sigma = "estimate"      # or one σ for all channels, or a table {channel = σ}
    # correlation_length_hz = 0.5   # unpaired only: frequency correlation length (Hz)
    sensor_noise_m_s2 = 0.005     # accelerometer noise floor; omit = from the runs' metadata
    # pilot_runs = 100      # track_statistics only: pilot runs per stage, outside the budget

    [search]
    local = true            # Gauss–Newton on the spectra after EGO (needed for "paired")
    basins = true           # climb other modes EGO saw only at their fringe (default true)
    refine_optimism = 0.0   # > 0 (e.g. 2): also refine where the surrogate may miss mass
    kernel = "matern"       # GP covariance; "auto" also tries the pairwise additive one
    kernel_switch = true    # "matern", no local phase: go "auto" if the additive one fits better
    hunt = 0.0              # omit: 3 where local = false (look for modes no evaluation came near)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import tomli_w

from susp_bo.rig.catalog import available_rigs, rig_path
from susp_bo.rig.schema import did_you_mean, repeated, repeated_phrase
from susp_bo.rig.toml_files import read_toml
from susp_bo.study_sections import (
    SECTIONS,
    BudgetConfig,
    ExecutorConfig,
    MCMCConfig,
    OutputErrorConfig,
    SearchConfig,
    SeedsConfig,
)

__all__ = [
    "BudgetConfig",
    "ExecutorConfig",
    "MCMCConfig",
    "OutputErrorConfig",
    "SearchConfig",
    "SeedsConfig",
    "StudyConfig",
    "load_study_config",
    "parse_study_config",
]


def _unknown_hint(name: str, calibration_names: Sequence[str], rig: str) -> str:
    """What is wrong with ``name``, a study parameter outside the calibration set: for a
    per-component name ``<parameter>@<component>`` the component check of
    :func:`~susp_bo.rig.components.split_component_name` against ``rig``'s parameters (a
    misspelled component or parameter, with the closest valid one, or one without a
    per-component form), or that a valid one needs its own ``[[calibration.parameters]]``
    entry; else the closest calibration name."""
    from susp_bo.rig.components import is_component_name, split_component_name
    from susp_bo.rig.spec import load_rig_spec

    if not is_component_name(name):
        return did_you_mean(name, calibration_names)
    try:
        spec = load_rig_spec(rig)
        known, topology = spec.parameters, spec.topology
    except (FileNotFoundError, ValueError):  # the rig's own error is reported elsewhere
        known, topology = None, "two_bogie_car"
    try:
        split_component_name(name, known, topology)
    except ValueError as error:
        return f" ({error})"
    return (
        f" ({name!r} is a valid per-component name, but the rig calibrates it only with an "
        f"entry of its own: [[calibration.parameters]] name = {name!r}, lower, upper)"
    )


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
            allowed = "expected a non-empty list of distinct calibration parameter names"
            if (
                isinstance(names, str)
                or not isinstance(names, Sequence)
                or not names
                or not all(isinstance(n, str) and n for n in names)
            ):
                raise ValueError(f"parameters: {names!r} is not allowed; {allowed}")
            twice = repeated(names)
            if twice:
                raise ValueError(
                    f"parameters: {names!r} is not allowed: {repeated_phrase(twice)} given more "
                    f"than once; {allowed}"
                )
            object.__setattr__(self, "parameters", tuple(names))

    def check_parameters(self, calibration_names: Sequence[str]) -> tuple[str, ...]:
        """The calibrated names, checked against the rig's calibration set.

        Args:
            calibration_names: ``RigSpec.calibration_names``.

        Returns:
            ``parameters``, or all of ``calibration_names`` when None.

        Raises:
            ValueError: a rig without calibration parameters (naming its file), or
                naming the unknown names and the allowed ones.
        """
        if not calibration_names:  # a calibration needs q >= 1 (simulate/synth do not)
            try:
                where = f"rig {str(rig_path(self.rig))!r}"
            except FileNotFoundError:
                where = f"rig {self.rig!r}"
            raise ValueError(
                f"{where}: [[calibration.parameters]]: none given; calibrating (and "
                "monitoring) needs at least one calibration parameter: add a "
                "[[calibration.parameters]] entry (name, lower, upper, reference) for each "
                "parameter to calibrate"
            )
        if self.parameters is None:
            return tuple(calibration_names)
        unknown = [name for name in self.parameters if name not in calibration_names]
        if unknown:
            raise ValueError(
                f"parameters: {unknown} not in the calibration set of rig {self.rig!r}"
                f"{_unknown_hint(unknown[0], calibration_names, self.rig)}; "
                f"allowed: {list(calibration_names)}"
            )
        return self.parameters

    def with_absolute_paths(self) -> StudyConfig:
        """This config with ``data``, ``out`` and a rig file's path made absolute (against
        the current folder), as a written ``study.toml`` needs them: its reader resolves
        relative paths against the file's own folder (:func:`load_study_config`)."""
        rig = Path(self.rig)
        is_file = rig.suffix == ".toml" and rig.is_file()
        return replace(
            self,
            rig=str(rig.resolve()) if is_file else self.rig,
            data=self.data.resolve(),
            out=self.out.resolve(),
        )

    def to_dict(self) -> dict[str, Any]:
        """TOML-ready mapping (paths as strings, None values left out)."""
        result: dict[str, Any] = {"rig": self.rig, "data": str(self.data), "out": str(self.out)}
        if self.parameters is not None:
            result["parameters"] = list(self.parameters)
        for name in SECTIONS:
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
    top = ("rig", "data", "out", "parameters", *SECTIONS)
    _check_keys("", mapping, top)
    for name in ("rig", "data", "out"):
        if name not in mapping:
            raise ValueError(f"{name}: missing; the study config must give rig, data and out")
    sections: dict[str, Any] = {}
    for name, cls in SECTIONS.items():
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
    data = read_toml(path)  # TomlFileError (a ValueError) names the file
    try:
        return parse_study_config(data, path.resolve().parent)
    except (ValueError, TypeError) as error:
        raise ValueError(f"{path}: {error}") from error
