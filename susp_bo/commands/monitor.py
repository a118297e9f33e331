"""``susp-bo monitor``: every campaign of a monitoring folder calibrated, trends and alarms."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from susp_bo.cli import UsageError
from susp_bo.commands._arguments import integer
from susp_bo.output_folder import check_output_folder


def probability(text: str) -> float:
    """``--threshold``: a probability strictly between 0 and 1 (an ``argparse`` type)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < 1.0:  # also refuses nan
        raise argparse.ArgumentTypeError(
            f"{text!r} is not allowed; expected a probability in (0, 1)"
        )
    return value


def add_parser(sub: Any) -> None:
    """Register ``susp-bo monitor`` on the command line's sub-parsers."""
    monitor = sub.add_parser(
        "monitor",
        help="calibrate every campaign (vehicle, date) of a folder, resumably; trends, "
        "P(outside the acceptable domain), maintenance table",
    )
    monitor.add_argument("folder", help="monitoring folder: one sub-folder of runs per campaign")
    monitor.add_argument("--out", required=True, help="results folder (monitor.json, figures)")
    monitor.add_argument(
        "--rig", help="rig name or path (default: monitor.toml's, else hst_trailer)"
    )
    monitor.add_argument(
        "--parameters",
        help="comma-separated subset of the rig's calibration set (default: all of it)",
    )
    monitor.add_argument("--budget", type=integer(2), help="likelihood evaluations per campaign")
    monitor.add_argument(
        "--warm-budget",
        type=integer(2),
        help="likelihood evaluations of a campaign that starts warm (default: --budget; an "
        "early stop spends what is left auditing, so only a smaller budget saves runs)",
    )
    group = monitor.add_mutually_exclusive_group()
    group.add_argument("--workers", type=integer(0), help="local worker processes")
    group.add_argument("--scheduler", help="Dask scheduler address")
    monitor.add_argument(
        "--threshold",
        type=probability,
        default=0.9,
        help="alarm when P(outside) exceeds it on a trusted calibration (default: %(default)s)",
    )
    monitor.add_argument(
        "--allow-small-budget",
        action="store_true",
        help="run campaigns below the minimum budget for q (their verdicts: not trusted)",
    )
    monitor.add_argument(
        "--cold-start",
        action="store_true",
        help="start every campaign from the space-filling design (default: a vehicle's next "
        "campaign starts around its previous trusted posterior)",
    )
    monitor.set_defaults(handler=run_monitor)


def run_monitor(args: argparse.Namespace) -> int:
    """Run (or continue) the monitoring and print the maintenance table."""
    if not args.folder:  # Path("") is the current folder: never what was meant
        raise UsageError(
            "FOLDER: '' is not allowed (empty); expected a monitoring folder of campaigns"
        )
    folder = Path(args.folder)
    if not folder.is_dir():  # before torch is loaded (discover_campaigns says the same)
        raise UsageError(f"{folder}: not a folder (expected a monitoring folder of campaigns)")
    try:
        check_output_folder(args.out)
    except ValueError as error:
        raise UsageError(str(error)) from None
    from susp_bo.monitoring.runner import CLI_NAMES, MonitorError, monitor

    parameters = None
    if args.parameters is not None:
        parameters = [p.strip() for p in args.parameters.split(",")]
        if not any(parameters):
            raise UsageError(f"--parameters: {args.parameters!r} names no parameter")
        if not all(parameters):  # "a,,b": a name left out by mistake, not dropped silently
            raise UsageError(
                f"--parameters: {args.parameters!r} has an empty name; expected names "
                "separated by single commas, e.g. 'secondary_vertical_damping,yaw_damper_damping'"
            )
    try:
        payload = monitor(
            args.folder,
            args.out,
            rig=args.rig,
            parameters=parameters,
            budget=args.budget,
            warm_budget=args.warm_budget,
            workers=args.workers,
            scheduler=args.scheduler,
            threshold=args.threshold,
            allow_small_budget=args.allow_small_budget,
            warm_start=not args.cold_start,
            argument_names=CLI_NAMES,
        )
    except MonitorError as error:
        raise UsageError(str(error)) from None
    print(format_table(payload, args.out), file=sys.stderr)
    return 0


def format_table(payload: dict[str, Any], out: str | Path = "OUT") -> str:
    """The maintenance table, what it cannot say and the campaigns not used for alarms.

    Args:
        payload: the ``monitor.json`` payload.
        out: the results folder (named in the recalibration advice).
    """
    lines = []
    rows = payload["maintenance"]
    if rows:
        lines.append("maintenance:")
        for row in rows:
            side = (
                "outside (on both sides: the posterior is wider than the domain, the side "
                "cannot be told)"
                if row["direction"] == "both"
                else row["direction"]
            )
            lines.append(
                f"  {row['vehicle']}: {row['parameter']} ({row['part']}) {side} "
                f"its acceptable domain since {row['since_campaign']}, "
                f"P = {row['probability']:.3f} "
                f"(last trusted campaign {row['last_trusted_campaign']})"
            )
    else:
        lines.append("maintenance: no alarm")
    for row in payload.get("attention", []):
        if not row["last_trusted"]:
            basis = (
                f"the table rests on {row['last_trusted_campaign']}"
                if row["last_trusted_campaign"]
                else "no campaign of this vehicle is trusted"
            )
            lines.append(
                f"  {row['vehicle']}: state unknown since {row['last_campaign']}, not "
                f"trusted ({basis}); recalibrate it as its reason says, e.g. susp-bo calibrate "
                f"{Path(out) / row['last_campaign'] / 'study.toml'} --resume [--budget N], then "
                "run this command again"
            )
        if row["no_domain"]:
            lines.append(
                f"  {row['vehicle']}: no acceptable domain for {', '.join(row['no_domain'])}: "
                "no alarm is possible (give acceptable = [lo, hi] in the rig file)"
            )
    for campaign in payload["campaigns"]:
        if not campaign["trusted"]:
            lines.append(f"  {campaign['id']}: not used for alarms — {campaign['why']}")
    return "\n".join(lines)
