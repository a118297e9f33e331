"""Rig specs: a vehicle described as data (TOML), parsed and validated.

A rig file has engineer-readable sections (``[carbody]``, ``[bogie]``,
``[wheelset]``, ``[primary]``, ``[secondary]``, ``[yaw_damper]``,
``[anti_roll_bar]``, ``[bump_stop]``, ``[contact]``); every number in them is a
*named parameter* ``<section>_<key>``, e.g. ``[primary] vertical_stiffness`` is
``primary_vertical_stiffness``. Around them: ``[rig]`` (name, topology,
citation), ``[[sensors]]``, ``[simulation]``, ``[spectrum]``, ``[effects]``
(optional physical effects, parsed but interpreted by the effect registry) and
``[[calibration.parameters]]`` (the admissible set C_w: name, lower, upper,
reference, unit, description; a per-component name ``<parameter>@<component>``,
e.g. ``yaw_damper_damping@bogie_front_left``, calibrates one element and its
reference defaults to the shared value, see :mod:`susp_bo.rig.components`). The
numbers of an effect table ``[effects.<name>]`` are named parameters too,
``<name>_<key>`` (e.g. ``carbody_bending_frequency_hz``), so effect parameters can be
calibrated like any other.

Every check runs when the spec is built, so bad input fails before any
simulation: unknown names, non-finite values, non-positive masses/inertias,
negative stiffnesses/dampings, calibration values outside their interval; a parsed
rig file is also assembled (:func:`check_buildable`): unknown effects, sensors on no
rigid body and a speed its time step cannot simulate are refused at load. The entries
(calibrated parameters, sensors, simulation defaults) and the sign rules are in
:mod:`susp_bo.rig.spec_entries`; this module assembles and parses the whole rig.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.catalog import rig_path
from susp_bo.rig.components import is_component_name, split_component_name
from susp_bo.rig.schema import check_rig_keys, did_you_mean, repeated, repeated_phrase
from susp_bo.rig.spec_entries import (
    SIMULATION_LIMITS,
    CalibrationParameter,
    SensorSpec,
    SimulationSettings,
    check_parameter_value,
    require_number,
)
from susp_bo.rig.toml_files import read_toml

if TYPE_CHECKING:
    from susp_bo.rig.spectra import SpectrumSettings

__all__ = [
    "PARAMETER_SECTIONS",
    "SIMULATION_LIMITS",
    "CalibrationParameter",
    "RigSpec",
    "SensorSpec",
    "SimulationSettings",
    "check_parameter_value",
    "load_rig_spec",
    "parse_rig",
]

PARAMETER_SECTIONS = (
    "carbody",
    "bogie",
    "wheelset",
    "primary",
    "secondary",
    "yaw_damper",
    "anti_roll_bar",
    "bump_stop",
    "contact",
)


@dataclass(frozen=True)
class RigSpec:
    """A validated vehicle rig: named parameters, sensors, settings and C_w.

    Args:
        name: rig name.
        topology: body/element layout interpreted by :mod:`susp_bo.rig.assembly`
            (``two_bogie_car``).
        parameters: every named parameter ``<section>_<key>`` -> value (SI units),
            plus any per-component overrides ``<parameter>@<component>``
            (:mod:`susp_bo.rig.components`); a calibration entry with a per-component
            name that is not among them is added at the shared value.
        sensors: the accelerometers, in channel order.
        simulation: time-domain defaults.
        spectrum: the spectra settings (band Ω, Welch segments).
        calibration: the admissible set C_w, q entries in calibration order.
        effects: optional effect tables (``[effects.<name>]``), for the effect registry.
        description: free text.
        reference: the published source of the parameter set.
    """

    name: str
    topology: str
    parameters: dict[str, float]
    sensors: tuple[SensorSpec, ...]
    simulation: SimulationSettings
    spectrum: SpectrumSettings
    calibration: tuple[CalibrationParameter, ...]
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    description: str = ""
    reference: str = ""

    def __post_init__(self) -> None:
        from susp_bo.rig.assembly import required_parameters

        params = {str(k): require_number(f"parameter {k}", v) for k, v in self.parameters.items()}
        for key, value in params.items():
            check_parameter_value(key, value)
        missing = [k for k in required_parameters(self.topology) if k not in params]
        if missing:
            raise ValueError(
                f"rig {self.name!r}: missing parameters for topology {self.topology!r}: "
                f"{', '.join(missing)}"
            )
        pivot, wheelbase = (
            params.get("bogie_half_pivot_spacing"),
            params.get("bogie_half_wheelbase"),
        )
        if pivot is not None and wheelbase is not None and not pivot > wheelbase:
            raise ValueError(
                f"rig {self.name!r}: parameter bogie_half_pivot_spacing: got {pivot} m, not more "
                f"than bogie_half_wheelbase {wheelbase} m; the bogie centres must lie further "
                "from the car centre than their wheelsets from the bogie centre (else the two "
                "bogies' wheelsets overlap)"
            )
        for key in [k for k in params if is_component_name(k)]:
            split_component_name(key, params, self.topology)
        for entry in self.calibration:  # a per-component entry defaults to the shared value
            if is_component_name(entry.name) and entry.name not in params:
                base, _ = split_component_name(entry.name, params, self.topology)
                params[entry.name] = params[base]
        object.__setattr__(self, "parameters", params)
        twice = repeated(c.name for c in self.calibration)
        if twice:
            raise ValueError(
                f"rig {self.name!r}: [[calibration.parameters]] {repeated_phrase(twice)} listed "
                "more than once; give each calibration parameter one entry"
            )
        for entry in self.calibration:
            if entry.name not in params:
                raise ValueError(
                    f"rig {self.name!r}: calibration parameter {entry.name!r} is not a named "
                    f"parameter of the rig; known: {', '.join(sorted(params))}"
                )
            value = params[entry.name]
            if not entry.lower <= value <= entry.upper:
                raise ValueError(
                    f"parameter {entry.name}: got {value} {entry.unit}; outside the "
                    f"admissible interval [{entry.lower}, {entry.upper}] {entry.unit}"
                )
        if not self.sensors:
            raise ValueError(
                f"rig {self.name!r}: [[sensors]]: none given; expected at least one sensor "
                "(its channel is what is measured and calibrated against)"
            )
        for index, sensor in enumerate(self.sensors, start=1):
            if not isinstance(sensor.name, str) or not sensor.name.strip():
                raise ValueError(
                    f"rig {self.name!r}: [[sensors]] entry {index}: name {sensor.name!r} is not "
                    "allowed; expected a non-empty channel name, e.g. 'carbody_front_vertical'"
                )
        twice = repeated(s.name for s in self.sensors)
        if twice:
            raise ValueError(
                f"rig {self.name!r}: [[sensors]]: sensor name{'s' * (len(twice) > 1)} "
                f"{repeated_phrase(twice)} given more than once; expected one entry per sensor "
                "name (channel)"
            )

    def parameter_values(self) -> dict[str, float]:
        """Every named parameter -> value (a copy)."""
        return dict(self.parameters)

    @property
    def calibration_names(self) -> tuple[str, ...]:
        """Names of the q calibration parameters, in order."""
        return tuple(c.name for c in self.calibration)

    @property
    def calibration_bounds(self) -> NDArray[np.float64]:
        """Admissible box C_w, (2 x q): row 0 lower, row 1 upper bounds."""
        return np.array([[c.lower for c in self.calibration], [c.upper for c in self.calibration]])

    @property
    def calibration_reference(self) -> NDArray[np.float64]:
        """Reference values of the calibration parameters, (q,)."""
        return np.array([c.reference for c in self.calibration])

    @property
    def channels(self) -> tuple[str, ...]:
        """Sensor channel names, in order."""
        return tuple(s.name for s in self.sensors)

    def parameters_from_vector(self, w: NDArray[np.float64]) -> dict[str, float]:
        """Map a calibration vector ``w`` (q,) to ``{name: value}``."""
        values = np.asarray(w, dtype=np.float64).reshape(-1)
        if values.size != len(self.calibration):
            raise ValueError(
                f"rig {self.name!r}: calibration vector has {values.size} entries; expected "
                f"q = {len(self.calibration)} ({', '.join(self.calibration_names)})"
            )
        return dict(zip(self.calibration_names, (float(v) for v in values)))

    def with_parameters(self, mapping: Mapping[str, float] | None) -> RigSpec:
        """A copy with some named parameters changed (validated; C_w enforced).

        A per-component name ``<parameter>@<component>`` (e.g.
        ``yaw_damper_damping@bogie_front_left``, see :mod:`susp_bo.rig.components`)
        overrides the shared ``<parameter>`` for that component only.

        Raises:
            ValueError: unknown name (for a per-component name: the parameter has no
                per-component form, or the component is unknown — the message lists
                the valid ones), NaN/inf, negative stiffness or mass, or a
                calibration parameter outside its admissible interval.
        """
        if not mapping:
            return self
        params = dict(self.parameters)
        for key, value in mapping.items():
            if is_component_name(key):
                split_component_name(key, params, self.topology)
            elif key not in params:
                raise ValueError(
                    f"rig {self.name!r}: unknown parameter {key!r}"
                    f"{did_you_mean(str(key), params)}; known parameters: "
                    f"{', '.join(sorted(params))}"
                )
            params[key] = require_number(f"parameter {key}", value)
        return replace(self, parameters=params)

    def with_simulation(self, **changes: Any) -> RigSpec:
        """A copy with some :class:`SimulationSettings` fields changed."""
        return replace(self, simulation=replace(self.simulation, **changes))

    def to_dict(self) -> dict[str, Any]:
        """A canonical, JSON-serialisable description (used for the fingerprint)."""
        spectrum = self.spectrum
        spectrum_dict = (
            {k: getattr(spectrum, k) for k in spectrum.__dataclass_fields__}
            if hasattr(spectrum, "__dataclass_fields__")
            else repr(spectrum)
        )
        return {
            "name": self.name,
            "topology": self.topology,
            "parameters": dict(sorted(self.parameters.items())),
            "sensors": [
                {
                    "name": s.name,
                    "body": s.body,
                    "position_m": list(s.position_m),
                    "direction": s.direction,
                }
                for s in self.sensors
            ],
            "simulation": {
                k: getattr(self.simulation, k) for k in self.simulation.__dataclass_fields__
            },
            "spectrum": spectrum_dict,
            # ``acceptable`` (maintenance limits) is left out on purpose: it changes no
            # simulation, so editing it must not invalidate evaluation stores.
            "calibration": [
                {"name": c.name, "lower": c.lower, "upper": c.upper, "reference": c.reference}
                for c in self.calibration
            ],
            "effects": self.effects,
        }

    def fingerprint(self) -> str:
        """sha256 (hex) of the canonical content: equal specs, equal fingerprints."""
        text = json.dumps(self.to_dict(), sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()


def parse_rig(data: Mapping[str, Any], source: str = "<dict>") -> RigSpec:
    """Build a :class:`RigSpec` from the parsed TOML tables.

    Args:
        data: the TOML document as nested dicts.
        source: file name used in error messages.

    Raises:
        ValueError: unknown sections or keys, missing tables, invalid values; every
            message starts with ``source`` (the entries check themselves and do not know
            their file, so a message of theirs gets it here).
    """
    try:
        return _build_rig(data, source)
    except ValueError as error:
        if str(error).startswith(f"{source}:"):
            raise
        raise ValueError(f"{source}: {error}") from None


def _build_rig(data: Mapping[str, Any], source: str) -> RigSpec:
    """:func:`parse_rig`'s work (its messages name ``source`` where they can)."""
    from susp_bo.rig.spectra import SpectrumSettings

    check_rig_keys(data, source)
    rig = dict(data.get("rig", {}))
    if "name" not in rig:
        raise ValueError(f"{source}: [rig] needs a name")
    parameters: dict[str, float] = {}
    for section in PARAMETER_SECTIONS:
        for key, value in data.get(section, {}).items():
            parameters[f"{section}_{key}"] = require_number(f"{source}: [{section}] {key}", value)
    for effect, table in data.get("effects", {}).items():
        # effect parameters are named parameters "<effect>_<key>" (calibratable like any other)
        for key, value in dict(table).items():
            if key != "enabled" and isinstance(value, int | float) and not isinstance(value, bool):
                parameters[f"{effect}_{key}"] = require_number(
                    f"{source}: [effects.{effect}] {key}", value
                )
    sensors = []
    for entry in data.get("sensors", []):
        try:
            sensors.append(
                SensorSpec(
                    name=str(entry["name"]),
                    body=str(entry["body"]),
                    position_m=tuple(entry["position_m"]),
                    direction=str(entry["direction"]),
                )
            )
        except KeyError as error:
            raise ValueError(f"{source}: [[sensors]] entry {entry!r} lacks {error}") from None
    simulation = SimulationSettings(**data.get("simulation", {}))
    spectrum = SpectrumSettings(**data.get("spectrum", {}))
    calibration = []
    topology = str(rig.get("topology", "two_bogie_car"))
    for entry in data.get("calibration", {}).get("parameters", []):
        try:
            if is_component_name(str(entry["name"])):
                # per-component entry: its reference defaults to the shared value and,
                # given or not, is the override's value in the rig
                base, _ = split_component_name(str(entry["name"]), parameters, topology)
                entry = {"reference": parameters[base], **entry}
            calibration.append(CalibrationParameter(**entry))
        except ValueError as error:
            raise ValueError(f"{source}: [[calibration.parameters]] {error}") from None
        name = entry["name"]
        if is_component_name(name):
            parameters[name] = calibration[-1].reference
        if name in parameters and not math.isclose(
            parameters[name], calibration[-1].reference, rel_tol=1e-12
        ):
            raise ValueError(
                f"{source}: calibration parameter {name!r} reference {entry['reference']} differs "
                f"from the rig value {parameters[name]}"
            )
    spec = RigSpec(
        name=str(rig["name"]),
        topology=topology,
        parameters=parameters,
        sensors=tuple(sensors),
        simulation=simulation,
        spectrum=spectrum,
        calibration=tuple(calibration),
        effects={str(k): dict(v) for k, v in data.get("effects", {}).items()},
        description=str(rig.get("description", "")),
        reference=str(rig.get("reference", "")),
    )
    check_buildable(spec)
    return spec


def check_buildable(spec: RigSpec) -> None:
    """The checks that need the assembled vehicle, run when a rig is loaded: every effect
    is registered, every sensor sits on a rigid body of the topology, the effects' options
    are valid, and the rig's time step can simulate its speed
    (:mod:`susp_bo.rig.step_stability`).

    Args:
        spec: the rig.

    Raises:
        ValueError: naming the entry (``[effects.<name>]``, ``[[sensors]] entry i``,
            ``[simulation] speed_m_s``), the value and what is allowed.
    """
    from susp_bo.rig.assembly import build_assembly
    from susp_bo.rig.effects import check_effect_names
    from susp_bo.rig.step_stability import speed_problem

    check_effect_names(spec.effects)
    assembly = build_assembly(spec)
    problem = speed_problem(spec, spec.simulation.speed_m_s, assembly, "[simulation] speed_m_s")
    if problem is not None:
        raise ValueError(problem)


def load_rig_spec(name_or_path: str | Path) -> RigSpec:
    """Load a rig by name (``"hst_trailer"``) or path to a TOML file.

    Raises:
        FileNotFoundError: no such rig.
        ValueError: a file that is not UTF-8 text or not valid TOML, or invalid content (the
            message names the file, the field and the value).
    """
    path = rig_path(name_or_path)
    return parse_rig(read_toml(path), source=str(path))
