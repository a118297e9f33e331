"""``susp-bo simulate``: one rig run on a synthetic track — signals, spectra, a figure."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from susp_bo.cli import UsageError
from susp_bo.commands._common import (
    apply_parameter_file,
    checked_output_folder,
    diverged_message,
    listed,
    out_of_range,
    output_folder,
    read_line_file,
    read_parameter_file,
    refuse_unstable_speed,
)
from susp_bo.json_files import write_json
from susp_bo.rig.response import SimulationFailed
from susp_bo.rig.simulator import Rig, synthetic_track
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.track import SpeedProfile


def prepared_spec(args: argparse.Namespace) -> tuple[RigSpec, dict[str, float]]:
    """The rig of the command line with --speed/--duration/--params applied, validated.

    Raises:
        UsageError: unknown rig, bad parameter file or values, bad speed/duration.
    """
    try:
        spec = load_rig_spec(args.rig)
    except (FileNotFoundError, ValueError) as error:
        raise UsageError(str(error)) from error
    for flag, key in (("--speed", "speed_m_s"), ("--duration", "duration_s")):
        value = getattr(args, flag[2:])
        if value is not None:
            try:
                spec = spec.with_simulation(**{key: value})
            except ValueError:
                raise UsageError(out_of_range(flag, key, value)) from None
    try:
        spec.spectrum.check_sample_rate(spec.simulation.sample_rate_hz, spec.simulation.duration_s)
    except ValueError as error:
        too_short = str(error).startswith("duration_s")
        if too_short and getattr(args, "duration", None) is not None:
            raise UsageError(
                f"--duration: {spec.simulation.duration_s:g} s is too short ({error})"
            ) from None
        remedy = "edit the rig file, or give a longer --duration" if too_short else "edit it"
        raise UsageError(  # the rig file's own [simulation] and [spectrum] disagree
            f"{args.rig}: its [simulation] and [spectrum] settings do not fit together "
            f"({error}); {remedy}"
        ) from None
    parameters = read_parameter_file(args.params, "--params") if args.params else {}
    checked_output_folder(args.out)
    spec = apply_parameter_file(spec, parameters, args.params, "--params")
    refuse_unstable_speed(spec, args, parameters, "--params")
    return spec, parameters


SIMULATE_FILES = ("signals.npz", "spectra.json", "simulate.png")
"""What ``simulate`` writes into ``--out``."""


def refuse_earlier_run(out: str | Path) -> None:
    """Refuses an ``--out`` that holds an earlier ``simulate`` run's files (never replaced).

    Raises:
        UsageError: naming ``--out``, the folder, the files and what to do.
    """
    folder = Path(out)
    earlier = [folder / name for name in SIMULATE_FILES if (folder / name).exists()]
    if earlier:
        raise UsageError(
            f"--out: {folder} already holds a simulate run ({listed(earlier)}); choose another "
            "folder, or delete those files first (a run's files are never replaced)"
        )


def run_simulate(args: argparse.Namespace) -> int:
    """Simulate the rig once and write ``signals.npz``, ``spectra.json`` and ``simulate.png``.

    A run that diverges is refused (exit code 2) naming ``--params`` and the values
    simulated, before ``--out`` is created: nothing is written.
    """
    from susp_bo.response_plots import plot_response

    spec, parameters = prepared_spec(args)
    refuse_earlier_run(args.out)
    design = read_line_file(getattr(args, "line", None), spec)
    settings = spec.simulation
    speed = SpeedProfile.constant(settings.speed_m_s, settings.warm_up_s + settings.duration_s)
    geometry = synthetic_track(spec, seed=args.seed)
    print(
        f"susp-bo simulate: {spec.name}, {settings.speed_m_s:.1f} m/s, "
        f"{settings.duration_s:.1f} s after {settings.warm_up_s:.1f} s warm-up, seed {args.seed}",
        file=sys.stderr,
    )
    try:
        with Rig(spec) as rig:
            response = rig.simulate(geometry, speed, design=design)
    except SimulationFailed as failure:
        raise UsageError(
            diverged_message(spec, failure, args.params, parameters, "--params", rig=args.rig)
        ) from None
    spectra = response.spectra(spec.spectrum)
    out = output_folder(args.out)  # created only now: a failed run leaves nothing behind
    np.savez_compressed(
        out / "signals.npz",
        time_s=response.time_s,
        accelerations_m_s2=response.accelerations_m_s2,
        channels=np.array(response.channels),
    )
    write_json(
        out / "spectra.json",
        {
            "rig": spec.name,
            "parameters": spec.parameter_values(),
            "speed_m_s": settings.speed_m_s,
            "seed": args.seed,
            "line": str(args.line) if getattr(args, "line", None) else None,
            "frequencies_hz": spectra.frequencies_hz.tolist(),
            "channels": list(spectra.channels),
            "log_amplitude": spectra.log_amplitude.tolist(),
            "units": "natural log of amplitude spectral density in (m/s^2)/sqrt(Hz)",
        },
    )
    figure = plot_response(response, spectra, Path(out) / "simulate.png", title=spec.name)
    print(
        f"susp-bo simulate: wrote {out}/signals.npz, spectra.json, {figure.name}", file=sys.stderr
    )
    return 0
