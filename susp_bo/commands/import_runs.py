"""``susp-bo import csv|mat FILES_OR_DIR... --out DIR [--rig RIG]``: measured runs to HDF5.

Reads the runs (file naming in :mod:`susp_bo.data.collect`, layouts in
:mod:`susp_bo.data.importers`), converts their accelerations to m/s², and with
``--rig`` checks each against the rig as ``calibrate`` will (its channels, kept
in the rig's order; the band and the Welch segment; the track, when it was measured,
covering the distance travelled plus the axle span) and records the rig's name in the run
metadata. Runs without track geometry are named on stderr. Every run is read and checked
before any file is written; then ``DIR/<run>.h5`` is written per run (the measured-run
format ``calibrate`` reads).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

from susp_bo.cli import UsageError
from susp_bo.commands._common import checked_output_folder, output_folder


def refuse_ignored_speed(kind: str, inputs: list[str], speed: float) -> None:
    """Refuses ``--speed`` for runs that carry their own speed, before any run is read.

    ``--speed`` is the constant speed of CSV runs that have no speed record. A run with
    one (a ``<run>_speed.csv``, a ``speed_m_s`` column, or any ``.mat`` file) would have
    used one of the two speeds silently; a wrong speed shifts every spectrum of the run,
    so the conflict is refused instead of guessed.

    Raises:
        UsageError: naming ``--speed``, its value, the run and the file with its own speed.
    """
    from susp_bo.data.collect import csv_groups, input_files
    from susp_bo.data.importers import csv_columns

    files = input_files(kind, inputs)  # type: ignore[arg-type]
    fix = "drop --speed (each run's own speed is used)"
    if kind == "mat":
        raise UsageError(
            f"--speed: {speed:g} m/s is not allowed with 'import mat': {files[0]} carries its "
            f"own speed (variable speed_m_s, as every .mat run does); {fix}"
        )
    for name, group in csv_groups(files).items():
        if "speed" in group:
            own = f"{group['speed']} is its speed record"
        elif "speed_m_s" in csv_columns(group["accelerations"]):
            own = f"{group['accelerations']} has a speed_m_s column"
        else:
            continue
        raise UsageError(
            f"--speed: {speed:g} m/s is not allowed for run {name!r}: {own}; --speed is only "
            f"for CSV runs without a speed of their own; {fix}, or import the runs without "
            "one separately with --speed"
        )


def run_import(args: argparse.Namespace) -> int:
    """Convert, check and write the runs; returns the exit code."""
    from susp_bo.data.collect import read_runs
    from susp_bo.data.run_files import save_run
    from susp_bo.data.run_validation import validate_run

    out = checked_output_folder(args.out)
    spec = None
    if args.rig is not None:
        from susp_bo.rig.spec import load_rig_spec

        try:
            spec = load_rig_spec(args.rig)
        except (FileNotFoundError, ValueError) as error:
            raise UsageError(f"--rig: {error}") from None
    if args.speed is not None:
        refuse_ignored_speed(args.kind, args.inputs, args.speed)
    runs = read_runs(args.kind, args.inputs, speed_m_s=args.speed)
    checked = []
    for name, run in runs:  # read_runs gives them in m/s^2
        if spec is not None:
            from susp_bo.rig.simulator import axle_span_m

            source = str(run.metadata.get("source", name))
            validate_run(
                run,
                spec.channels,
                spec.spectrum,
                axle_span_m=axle_span_m(spec),
                source=f"{source} (run {name!r}, checked against rig {spec.name!r})",
            )
            recorded = run.metadata.get("rig")
            if recorded is not None and recorded != spec.name:
                raise UsageError(
                    f"--rig: run {name!r} ({source}) records rig {recorded!r} in its metadata, "
                    f"not {spec.name!r}; import it with --rig {recorded}"
                )
            run = run.select(spec.channels)
            run = dataclasses.replace(run, metadata={**run.metadata, "rig": spec.name})
        checked.append((name, run))
    targets = [out / f"{name}.h5" for name, _ in checked]
    existing = [str(path) for path in targets if path.exists()]
    if existing:
        raise UsageError(
            f"--out: {out} already holds {', '.join(existing)}; choose another folder "
            "(imported runs are never overwritten)"
        )
    output_folder(out)
    for (_, run), target in zip(checked, targets):
        save_run(run, target)
    checked_against = f", checked against rig {spec.name!r}" if spec is not None else ""
    print(
        f"susp-bo import: wrote {len(checked)} run(s) to {out}{checked_against}",
        file=sys.stderr,
    )
    untracked = [name for name, run in checked if run.geometry is None]
    if untracked:  # said, so that a geometry left out by mistake is seen here
        print(
            f"susp-bo import: {len(untracked)} of them without track geometry (the track was "
            f"not measured: {', '.join(untracked[:4])}{', …' if len(untracked) > 4 else ''});"
            ' calibrate such runs with [output_error] model = "track_statistics"',
            file=sys.stderr,
        )
    return 0
