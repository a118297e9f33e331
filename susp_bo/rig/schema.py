"""The allowed keys of a rig file, section by section: unknown keys are errors with a hint.

A typo in a rig file must not pass silently: ``[carbody] cg_hieght = 1.9`` would
otherwise become a new named parameter while ``cg_height`` kept its value.
:func:`check_rig_keys` runs on the parsed TOML document before anything is
built and raises ``ValueError("<file>: [carbody] cg_hieght: unknown key (did you
mean 'cg_height'?); allowed keys: …")``.

Allowed keys:

- top level: the sections ``[rig]``, ``[[sensors]]``, ``[simulation]``,
  ``[spectrum]``, ``[effects]``, ``[calibration]`` and the parameter sections;
- ``[rig]``: ``name``, ``topology``, ``description``, ``reference``;
- a parameter section (``[carbody]`` …): the named parameters the topology uses
  (required and optional, :func:`susp_bo.rig.assembly.allowed_parameters`);
- ``[[sensors]]``: ``name``, ``body``, ``position_m``, ``direction``;
- ``[simulation]`` / ``[spectrum]``: the fields of
  :class:`~susp_bo.rig.spec.SimulationSettings` / :class:`~susp_bo.rig.spectra.SpectrumSettings`;
- ``[calibration]``: ``parameters``; each ``[[calibration.parameters]]`` entry:
  ``name``, ``lower``, ``upper``, ``reference``, ``unit``, ``description`` and the
  optional ``acceptable = [lo, hi]`` (maintenance limits); a per-component name
  ``<parameter>@<component>`` may leave ``reference`` out (the shared value);
- ``[effects.<name>]``: checked by the effect registry when the rig is built
  (the keys depend on the effect).
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from dataclasses import fields
from typing import Any

RIG_KEYS = ("name", "topology", "description", "reference")
SENSOR_KEYS = ("name", "body", "position_m", "direction")
CALIBRATION_KEYS = ("parameters",)
CALIBRATION_ENTRY_KEYS = (
    "name",
    "lower",
    "upper",
    "reference",
    "unit",
    "description",
    "acceptable",
)


def did_you_mean(value: str, allowed: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` naming the closest allowed name (difflib, cutoff 0.6),
    else ``""``."""
    close = difflib.get_close_matches(value, list(allowed), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def repeated(names: Iterable[str]) -> list[str]:
    """The names that occur more than once in ``names``, each once, in first-seen order."""
    seen: set[str] = set()
    again: dict[str, None] = {}
    for name in names:
        if name in seen:
            again[name] = None
        seen.add(name)
    return list(again)


def repeated_phrase(names: list[str]) -> str:
    """``'a' is`` or ``'a', 'b' are``: the subject of a "given more than once" message."""
    return f"{', '.join(map(repr, names))} {'is' if len(names) == 1 else 'are'}"


def check_keys(where: str, given: Iterable[str], allowed: Iterable[str]) -> None:
    """Raise ValueError for the first key of ``given`` not in ``allowed``.

    Args:
        where: prefix of the message, e.g. ``"hst_trailer.toml: [carbody]"``.
        given: the keys found.
        allowed: the keys allowed there.

    Raises:
        ValueError: ``"<where> <key>: unknown key (did you mean 'x'?); allowed keys: …"``.
    """
    allowed = list(allowed)
    for key in given:
        if key not in allowed:
            hint = did_you_mean(str(key), allowed)
            raise ValueError(
                f"{where} {key}: unknown key{hint}; allowed keys: {', '.join(allowed)}"
            )


def _table(where: str, value: Any) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: got {value!r}; expected a table")
    return value


def _entries(where: str, value: Any) -> list[Mapping[str, Any]]:
    if not isinstance(value, list) or not all(isinstance(v, Mapping) for v in value):
        raise ValueError(f"{where}: got {value!r}; expected an array of tables [[...]]")
    return value


def check_rig_keys(data: Mapping[str, Any], source: str) -> None:
    """Check every key of a parsed rig document against the schema (see the module doc).

    Args:
        data: the TOML document as nested dicts.
        source: the file name, used in messages.

    Raises:
        ValueError: an unknown section or key (with the closest allowed one), or a
            section of the wrong TOML type.
    """
    from susp_bo.rig.assembly import allowed_parameters
    from susp_bo.rig.spec import PARAMETER_SECTIONS, SimulationSettings
    from susp_bo.rig.spectra import SpectrumSettings

    sections = ("rig", "sensors", "simulation", "spectrum", "effects", "calibration")
    check_keys(f"{source}: top level:", data, (*sections, *PARAMETER_SECTIONS))
    rig = _table(f"{source}: [rig]", data.get("rig", {}))
    check_keys(f"{source}: [rig]", rig, RIG_KEYS)
    topology = str(rig.get("topology", "two_bogie_car"))
    by_section = allowed_parameters(topology)
    for section in PARAMETER_SECTIONS:
        table = _table(f"{source}: [{section}]", data.get(section, {}))
        check_keys(f"{source}: [{section}]", table, by_section.get(section, ()))
    for index, entry in enumerate(_entries(f"{source}: [[sensors]]", data.get("sensors", []))):
        check_keys(f"{source}: [[sensors]] entry {index + 1}:", entry, SENSOR_KEYS)
    for name, cls in (("simulation", SimulationSettings), ("spectrum", SpectrumSettings)):
        table = _table(f"{source}: [{name}]", data.get(name, {}))
        check_keys(f"{source}: [{name}]", table, [f.name for f in fields(cls)])
    for name, table in _table(f"{source}: [effects]", data.get("effects", {})).items():
        _table(f"{source}: [effects.{name}]", table)
    calibration = _table(f"{source}: [calibration]", data.get("calibration", {}))
    check_keys(f"{source}: [calibration]", calibration, CALIBRATION_KEYS)
    entries = _entries(f"{source}: [[calibration.parameters]]", calibration.get("parameters", []))
    for index, entry in enumerate(entries):
        label = entry.get("name", f"entry {index + 1}")
        check_keys(f"{source}: [[calibration.parameters]] {label}:", entry, CALIBRATION_ENTRY_KEYS)
        needed = ("name", "lower", "upper", "reference")
        if "@" in str(entry.get("name", "")):  # per-component: reference defaults to shared
            needed = needed[:3]
        missing = [k for k in needed if k not in entry]
        if missing:
            raise ValueError(
                f"{source}: [[calibration.parameters]] {label}: missing {', '.join(missing)}; "
                "each entry needs name, lower, upper and reference (a per-component name "
                "<parameter>@<component> may leave reference out: the shared value)"
            )
