"""``susp-bo synth``: synthetic measured runs from a rig, written in the measured-data format."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from susp_bo.cli import UsageError
from susp_bo.commands._common import (
    apply_parameter_file,
    checked_output_folder,
    diverged_message,
    existing_runs,
    listed,
    out_of_range,
    output_folder,
    read_line_file,
    read_parameter_file,
    refuse_unstable_speed,
)
from susp_bo.data.run_files import save_run
from susp_bo.data.synthetic import MAX_NOISE_M_S2, MAX_RUNS, synthesize_runs
from susp_bo.discrepancy.effects import with_effect
from susp_bo.json_files import write_json
from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.response import SimulationFailed
from susp_bo.rig.spec import load_rig_spec

TRUTH_NAME = "truth.json"
"""The file that records the truth, seed and effects of the runs ``synth`` wrote."""


def parse_effect(text: str) -> tuple[str, dict[str, float]]:
    """``NAME[:k=v,...]`` -> (name, {k: v}).

    Raises:
        UsageError: malformed text or a value that is not a number.
    """
    name, _, rest = text.partition(":")
    if not name.strip():
        raise UsageError(f"--effect: {text!r} has no effect name; expected NAME[:k=v,...]")
    values: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in rest.split(","))):
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--effect: {item!r} in {text!r} is not k=v")
        if key.strip() in values:
            raise UsageError(
                f"--effect: {text!r} is not allowed: it gives {key.strip()!r} twice; "
                "expected each key once (NAME:k=v,...)"
            )
        try:
            values[key.strip()] = float(value)
        except ValueError as error:
            raise UsageError(f"--effect: {key.strip()}={value!r} is not a number") from error
    return name.strip(), values


def parse_effects(texts: list[str]) -> list[tuple[str, dict[str, float]]]:
    """Every ``--effect`` (:func:`parse_effect`), each effect at most once.

    Raises:
        UsageError: a malformed effect, or one effect given twice.
    """
    effects = [parse_effect(text) for text in texts]
    seen: dict[str, str] = {}
    for text, (name, _) in zip(texts, effects):
        if name in seen:
            raise UsageError(
                f"--effect: {text!r} is not allowed: effect {name!r} is already given "
                f"({seen[name]!r}); expected each effect once, with all its values in one "
                "--effect NAME:k=v,..."
            )
        seen[name] = text
    return effects


def refuse_existing_data(out: Path) -> None:
    """Refuses an ``--out`` that already holds measured runs or a ``truth.json``.

    New runs would replace some of them and join the others, and ``truth.json`` would
    describe only the new ones: a mixed data set.

    Raises:
        UsageError: naming ``--out``, the folder, what it holds and what to do.
    """
    existing = existing_runs(out, also=(TRUTH_NAME,))
    if existing:
        raise UsageError(
            f"--out: {out} already holds a data set ({listed(existing)}); choose another "
            "folder, or delete those files first (synth never overwrites runs or adds runs "
            "to another data set: truth.json describes the folder's runs)"
        )


def run_synth(args: argparse.Namespace) -> int:
    """Write ``run_000.h5`` … ``run_{nu-1}.h5`` and ``truth.json`` into ``--out``.

    ``--effect NAME[:k=v,...]`` switches a library effect on in the generator
    (:mod:`susp_bo.discrepancy.effects`); ``truth.json`` lists the effects with
    their values, the run metadata names them. A run that diverges is refused (exit
    code 2) naming ``--truth`` and the values simulated, before ``--out`` is created:
    nothing is written.
    """
    effects = parse_effects(args.effect)
    refuse_existing_data(checked_output_folder(args.out))
    try:
        spec = load_rig_spec(args.rig)
        truth = read_parameter_file(args.truth, "--truth") if args.truth else {}
        apply_parameter_file(spec, truth, args.truth, "--truth")
        for name, values in effects:  # the hidden physics: on in the generator only
            spec = with_effect(spec, name, values)
        if effects:
            build_assembly(spec.with_parameters(truth))  # effect values checked before any run
    except (FileNotFoundError, ValueError) as error:
        raise UsageError(str(error)) from error
    if not 1 <= args.nu <= MAX_RUNS:
        raise UsageError(f"--nu: got {args.nu}; expected an integer in 1 … {MAX_RUNS}")
    if not 0 <= args.noise <= MAX_NOISE_M_S2:
        raise UsageError(f"--noise: got {args.noise:g}; expected 0 … {MAX_NOISE_M_S2:g} m/s^2")
    if args.speed is not None:
        try:
            spec.with_simulation(speed_m_s=args.speed)
        except ValueError:
            raise UsageError(out_of_range("--speed", "speed_m_s", args.speed)) from None
    line_spec = spec.with_simulation(speed_m_s=args.speed) if args.speed is not None else spec
    names = [name for name, _ in effects]
    refuse_unstable_speed(line_spec.with_parameters(truth), args, truth, "--truth", names)
    design = read_line_file(getattr(args, "line", None), line_spec)
    print(f"susp-bo synth: {args.nu} runs of {spec.name}, seed {args.seed}", file=sys.stderr)
    try:
        runs = synthesize_runs(
            spec,
            truth,
            nu=args.nu,
            seed=args.seed,
            noise_m_s2=args.noise,
            speed_m_s=args.speed,
            design=design,
        )
    except SimulationFailed as failure:
        simulated = line_spec.with_parameters(truth)
        raise UsageError(
            diverged_message(simulated, failure, args.truth, truth, "--truth", names, args.rig)
        ) from None
    out = output_folder(args.out)  # created only now: a failed run leaves nothing behind
    for index, run in enumerate(runs):
        save_run(run, out / f"run_{index:03d}.h5")
    write_json(
        out / TRUTH_NAME,
        {
            "rig": spec.name,
            "truth": runs[0].metadata["truth"],
            "seed": args.seed,
            "nu": args.nu,
            "noise_m_s2": args.noise,
            "line": str(args.line) if getattr(args, "line", None) else None,
            "effects": [
                {
                    "name": name,
                    "values": {k: v for k, v in spec.effects[name].items() if k != "enabled"},
                }
                for name, _ in effects
            ],
        },
    )
    print(f"susp-bo synth: wrote {len(runs)} runs to {out}", file=sys.stderr)
    return 0
