"""Helpers shared by the command implementations: parameter files, output folders, logging."""

from __future__ import annotations

import argparse
import math
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from susp_bo.cli import UsageError
from susp_bo.data.run_files import run_paths
from susp_bo.output_folder import check_output_folder
from susp_bo.rig.schema import did_you_mean
from susp_bo.rig.spec import SIMULATION_LIMITS
from susp_bo.rig.toml_files import TomlFileError, read_toml

if TYPE_CHECKING:
    from susp_bo.rig.response import SimulationFailed
    from susp_bo.rig.spec import RigSpec


def read_parameter_file(path: str | Path, flag: str = "--params/--truth") -> dict[str, float]:
    """Parameter values from a TOML file: ``name = value`` at top level or under ``[parameters]``.

    Args:
        path: the file.
        flag: the flag that gave it (``--params``, ``--truth``), named in messages.

    Raises:
        UsageError: missing file, a file that is not UTF-8 text, bad TOML, or a value that
            is not a finite number.
    """
    file = Path(path)
    if file.is_dir():
        raise UsageError(
            f"{flag}: {str(file)!r} is a folder; expected a TOML file of name = value lines "
            "(e.g. yaw_damper_damping = 4.9e6)"
        )
    if not file.is_file():
        raise UsageError(f"{flag}: file {str(file)!r} does not exist")
    try:
        data = read_toml(file)
    except TomlFileError as error:
        raise UsageError(f"{flag}: {error}") from None
    except OSError as error:
        raise UsageError(f"{flag}: cannot read {str(file)!r} ({error.strerror or error})") from None
    table = data.get("parameters", data)
    if not isinstance(table, Mapping):
        raise UsageError(f"{flag} {file}: [parameters] must be a table of name = value")
    values: dict[str, float] = {}
    for name, value in table.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise UsageError(f"{flag} {file}: parameter {name!r} = {value!r} is not a number")
        if not math.isfinite(float(value)):
            raise UsageError(f"{flag} {file}: parameter {name!r} = {value!r} is not finite")
        values[str(name)] = float(value)
    return values


def apply_parameter_file(
    spec: RigSpec, values: Mapping[str, float], path: str | Path | None, flag: str
) -> RigSpec:
    """``spec`` with the values of a parameter file (``--params``/``--truth``) applied.

    Every refusal names the flag and the file, the name or value and what is allowed:
    an unknown name (with the closest known one and the rig's parameters by section), a
    bad per-component name, a value that breaks the parameter's sign rule, or one
    outside the rig's admissible interval.

    Args:
        spec: the rig.
        values: the file's values (:func:`read_parameter_file`), name -> SI value.
        path: the file, named in messages.
        flag: the flag that gave it, e.g. ``--params``.

    Raises:
        UsageError: ``"--params p.toml: yaw_damper_damping = -5 is not allowed; …"``.
    """
    from susp_bo.rig.components import is_component_name, split_component_name
    from susp_bo.rig.spec_entries import parameter_value_rule

    where = f"{flag} {path}"
    entries = {entry.name: entry for entry in spec.calibration}
    for name, value in values.items():
        if is_component_name(name):
            try:
                split_component_name(name, spec.parameters, spec.topology)
            except ValueError as error:
                raise UsageError(f"{where}: {error}") from None
        elif name not in spec.parameters:
            raise UsageError(
                f"{where}: unknown parameter {name!r}{did_you_mean(name, spec.parameters)}; "
                f"allowed: a named parameter of rig {spec.name!r} "
                f"({parameters_by_section(spec.parameters)}), or <parameter>@<component> "
                "for one component"
            )
        rule = parameter_value_rule(name, value)
        if rule is not None:
            raise UsageError(f"{where}: {name} = {value:g} is not allowed; {rule}")
        entry = entries.get(name)
        if entry is not None and not entry.lower <= value <= entry.upper:
            unit = f" {entry.unit}" if entry.unit else ""
            raise UsageError(
                f"{where}: {name} = {value:g}{unit} is not allowed; allowed: the rig's "
                f"admissible interval [{entry.lower:g}, {entry.upper:g}]{unit} (its "
                "[[calibration.parameters]] entry)"
            )
    try:
        return spec.with_parameters(values)
    except ValueError as error:  # e.g. a bogie pivot spacing inside the wheelbase
        raise UsageError(f"{where}: {error}") from None


def parameters_by_section(names: Iterable[str]) -> str:
    """The named parameters grouped by the rig file's section they come from, for a message:
    ``[carbody] mass, cg_height; [bogie] mass; other: polygon_amplitude_m``."""
    from susp_bo.rig.spec import PARAMETER_SECTIONS

    groups: dict[str, list[str]] = {}
    for name in names:
        sections = [s for s in PARAMETER_SECTIONS if name.startswith(f"{s}_")]
        section = max(sections, key=len) if sections else ""
        groups.setdefault(section, []).append(name[len(section) + 1 :] if section else name)
    parts = [f"[{s}] {', '.join(keys)}" for s, keys in groups.items() if s]
    if "" in groups:
        parts.append(f"other: {', '.join(groups[''])}")
    return "; ".join(parts)


_ALLOWED_FOLDER = "expected a folder that exists or can be created, and can be written in"


def checked_output_folder(out: str | Path, label: str = "--out") -> Path:
    """The output folder, checked and left as it was: a folder that exists or can be
    created, and that this process can write in.

    An empty path is refused (it would write into the current folder). A folder that does
    not exist yet is created to try it, then removed again, so a refusal later (a bad flag)
    leaves nothing behind; an existing folder is tried with a temporary file.

    Raises:
        UsageError: naming ``label``, the path, the reason and what is allowed.
    """
    if not str(out):
        raise UsageError(
            f"{label}: {str(out)!r} is not allowed; expected the path of a folder (existing or "
            "new; '.' for the current folder)"
        )
    try:
        folder = check_output_folder(out, label)
        _try_writing(folder, label)
    except ValueError as error:
        raise UsageError(str(error)) from None
    except OSError as error:  # e.g. a name too long to look up
        raise UsageError(
            f"{label}: {str(out)!r} is not allowed ({_reason(error, out)}); {_ALLOWED_FOLDER}"
        ) from None
    return folder


def _try_writing(folder: Path, label: str) -> None:
    """Creates ``folder`` and removes it again, or writes a temporary file in it.

    Raises:
        UsageError: the folder cannot be created or written in (e.g. ``/proc/x``, a
            read-only file system, no permission, a name too long).
    """
    if folder.is_dir():
        try:
            with tempfile.TemporaryFile(dir=folder, prefix=".susp_bo_write_check_"):
                pass
        except OSError as error:
            raise UsageError(
                f"{label}: {str(folder)!r} is not allowed; cannot write in it "
                f"({error.strerror or error}); {_ALLOWED_FOLDER}"
            ) from None
        return
    missing = [folder]
    missing += [parent for parent in folder.parents if not parent.exists()]
    try:
        folder.mkdir(parents=True)
    except OSError as error:
        raise UsageError(
            f"{label}: {str(folder)!r} is not allowed; cannot create it "
            f"({_reason(error, folder)}); {_ALLOWED_FOLDER}"
        ) from None
    for created in missing:  # innermost first; one that another process filled stays
        try:
            created.rmdir()
        except OSError:
            break


def _reason(error: OSError, folder: str | Path) -> str:
    """``strerror`` of ``error``, with the path it is about when that is not ``folder``."""
    reason = error.strerror or str(error)
    if error.filename is None or str(error.filename) == str(folder):
        return reason
    return f"{reason}: {str(error.filename)!r}"


def output_folder(out: str | Path, label: str = "--out") -> Path:
    """Create (if needed) and return the output folder (checked first).

    Raises:
        UsageError: as :func:`checked_output_folder`, or the folder cannot be created.
    """
    folder = checked_output_folder(out, label)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise UsageError(
            f"{label}: {str(folder)!r} is not allowed; cannot create it ({_reason(error, folder)})"
        ) from None
    return folder


def existing_runs(folder: Path, also: tuple[str, ...] = ()) -> list[Path]:
    """The measured runs (``*.h5``, ``*.hdf5``, what ``calibrate`` reads) and the files named
    ``also`` that ``folder`` already holds, sorted; empty for a folder that does not exist."""
    named = [folder / name for name in also if (folder / name).is_file()]
    return sorted([*run_paths(folder), *named])


def listed(paths: list[Path], limit: int = 4) -> str:
    """``a.h5, b.h5, c.h5 and 5 more``: file names for a message."""
    names = [path.name for path in paths[:limit]]
    more = f" and {len(paths) - limit} more" if len(paths) > limit else ""
    return ", ".join(names) + more


def read_line_file(path: str | Path | None, spec: object) -> object:
    """The track design of ``--line FILE`` checked against a default run of ``spec``, or None.

    Raises:
        UsageError: missing or bad file, a design outside the limits, or one that does not
            cover the run (the message names the file, the value and what is allowed).
    """
    if path is None:
        return None
    from susp_bo.rig.design import DesignError
    from susp_bo.rig.line_file import load_line
    from susp_bo.rig.simulator import synthetic_track_length_m

    try:
        design = load_line(path)
        design.check_covers(0.0, synthetic_track_length_m(spec), "the run (--speed, --duration)")
    except DesignError as error:
        raise UsageError(f"--line: {error}") from error
    return design


def out_of_range(flag: str, key: str, value: float) -> str:
    """The refusal of a ``[simulation]`` setting given on the command line.

    E.g. ``--speed: 500 m/s is not allowed; allowed range (0, 200] m/s (the rig's
    [simulation] speed_m_s)``.
    """
    low, high, unit = SIMULATION_LIMITS[key]
    return (
        f"{flag}: {value:g} {unit} is not allowed; allowed range ({low:g}, {high:g}] {unit} "
        f"(the rig's [simulation] {key})"
    )


def diverged_message(
    spec: RigSpec,
    failure: SimulationFailed,
    path: str | Path | None,
    values: Mapping[str, float],
    flag: str,
    effects: Sequence[str] = (),
    rig: str | Path | None = None,
) -> str:
    """The refusal of a simulation that failed (diverged): what was simulated, where it
    failed, that nothing was written, and what to try.

    Args:
        spec: the rig as simulated (its speed and time step).
        failure: the failure, with its reason (``diverged at t = 1.410 s: …``).
        path: the parameter file (``--params``/``--truth``), None when none was given.
        values: the values that file gave (named parameter -> SI value).
        flag: the flag of that file, e.g. ``--params``.
        effects: the effects switched on for the run (``synth --effect``).
        rig: the rig as given on the command line (named when no file gave values).
    """
    settings = spec.simulation
    if values:
        where = f"{flag} {path}"
        # (outside C_w is refused before the run: apply_parameter_file)
        what = "with " + ", ".join(f"{name} = {value:g}" for name, value in values.items())
    else:
        where = str(rig if rig is not None else spec.name)
        what = "with the rig file's parameter values"
    if effects:
        what += f" and the effect{'s' * (len(effects) > 1)} {', '.join(effects)}"
    return (
        f"{where}: the simulation of rig {spec.name!r} {what}, at {settings.speed_m_s:g} m/s "
        f"with a time step of {settings.time_step_s:g} s, failed: {failure.reason}; nothing "
        "was written. Try values inside the rig's admissible bounds (its "
        "[[calibration.parameters]] lower/upper), a smaller [simulation] time_step_s (in a "
        "copy of the rig file) or another --speed"
    )


def refuse_unstable_speed(
    spec: RigSpec,
    args: argparse.Namespace,
    values: Mapping[str, float],
    flag: str,
    effects: Sequence[str] = (),
) -> None:
    """Refuses a speed the rig's time step cannot simulate (it would diverge), before any
    file is written (:mod:`susp_bo.rig.step_stability`).

    Args:
        spec: the rig as it will be simulated (``--speed``, the parameter file's values
            and the effects applied).
        args: the command line (``--speed``, the rig).
        values: the parameter file's values (they can raise the minimum speed).
        flag: the parameter file's flag, e.g. ``--params``.
        effects: the effects switched on.

    Raises:
        UsageError: naming ``--speed`` (or the rig file's speed), the value and the minimum.
    """
    from susp_bo.rig.step_stability import speed_problem

    given = getattr(args, "speed", None) is not None
    label = "--speed" if given else f"{args.rig}: [simulation] speed_m_s"
    try:
        problem = speed_problem(spec, spec.simulation.speed_m_s, speed_label=label)
    except ValueError as error:  # e.g. an effect's values the assembly refuses
        raise UsageError(str(error)) from None
    if problem is None:
        return
    changed = [f"the values of {flag}"] if values else []
    changed += [f"--effect {name}" for name in effects]
    with_changes = f"; that minimum is for {' and '.join(changed)}" if changed else ""
    raise UsageError(problem + with_changes)
