"""The ``susp-bo`` command line (also ``python -m susp_bo``).

Commands (shared/DESIGN.md, "Interfaces that must stay stable"):
``demo``, ``simulate``, ``synth``, ``calibrate``, ``diagnose``. Progress goes
to stderr, results to files under ``--out``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from susp_bo import __version__


class UsageError(ValueError):
    """Bad command-line input, reported as one line on stderr with exit code 2."""


def _demo(args: argparse.Namespace) -> int:
    from susp_bo.commands.demo import run_demo

    return run_demo(out=args.out, smoke=args.smoke, seed=args.seed)


def _simulate(args: argparse.Namespace) -> int:
    from susp_bo.commands.simulate import run_simulate

    return run_simulate(args)


def _synth(args: argparse.Namespace) -> int:
    from susp_bo.commands.synth import run_synth

    return run_synth(args)


def _calibrate(args: argparse.Namespace) -> int:
    from susp_bo.commands.calibrate import run_calibrate

    return run_calibrate(args)


def _diagnose(args: argparse.Namespace) -> int:
    from susp_bo.commands.diagnose import run_diagnose

    return run_diagnose(args)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every command of DESIGN.md."""
    parser = argparse.ArgumentParser(
        prog="susp-bo",
        description=(
            "Bayesian calibration of high-speed train suspensions from on-track "
            "accelerometer measurements."
        ),
    )
    parser.add_argument("--version", action="version", version=f"susp-bo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="the main job on embedded defaults: reference rig, synthetic measurement, "
        "calibration, result.json and figures",
    )
    demo.add_argument("--out", default="susp_bo_demo", help="output folder (default: %(default)s)")
    demo.add_argument("--smoke", action="store_true", help="tiny budgets, for tests")
    demo.add_argument("--seed", type=int, default=2024, help="random seed (default: %(default)s)")
    demo.set_defaults(handler=_demo)

    simulate = sub.add_parser(
        "simulate", help="one rig run on a synthetic track: signals, spectra, figure"
    )
    simulate.add_argument("rig", help="rig name (e.g. hst_trailer) or path to a rig .toml")
    simulate.add_argument("--out", required=True)
    simulate.add_argument("--params", help="TOML file of parameter values")
    simulate.add_argument("--speed", type=float, help="speed in m/s")
    simulate.add_argument("--duration", type=float, help="simulated time in s")
    simulate.add_argument("--seed", type=int, default=0)
    simulate.set_defaults(handler=_simulate)

    synth = sub.add_parser(
        "synth", help="synthetic measured runs from a rig, in the measured-data format"
    )
    synth.add_argument("rig")
    synth.add_argument("--out", required=True)
    synth.add_argument("--truth", help="TOML file of the true parameter values")
    synth.add_argument("--effect", action="append", default=[], help="NAME[:k=v,...], repeatable")
    synth.add_argument("--speed", type=float)
    synth.add_argument("--nu", type=int, default=3, help="number of measured runs")
    synth.add_argument("--seed", type=int, default=0)
    synth.add_argument("--noise", type=float, default=0.0, help="sensor noise, m/s^2 rms")
    synth.set_defaults(handler=_synth)

    calibrate = sub.add_parser("calibrate", help="the four steps: design, kriging, EGO, MCMC")
    calibrate.add_argument("rig_or_study", help="rig name/path, or a study .toml")
    calibrate.add_argument("data_dir", nargs="?", help="folder of measured runs")
    calibrate.add_argument("--out")
    calibrate.add_argument("--budget", type=int, help="simulator-evaluation budget")
    group = calibrate.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, help="local worker processes")
    group.add_argument("--scheduler", help="Dask scheduler address")
    calibrate.add_argument(
        "--resume", action="store_true", help="reuse the study's evaluation store"
    )
    calibrate.set_defaults(handler=_calibrate)

    diagnose = sub.add_parser("diagnose", help="model-discrepancy workflow on a calibration result")
    diagnose.add_argument("result_dir")
    diagnose.add_argument("--out", required=True)
    diagnose.add_argument(
        "--simulator",
        choices=("pybullet", "linear"),
        default="pybullet",
        help="simulator of the check and the recalibration: the study's PyBullet rig "
        "(default) or the linearised rig (fast path); the ranking always uses the fast path",
    )
    diagnose.add_argument(
        "--budget",
        type=int,
        help="likelihood evaluations of the recalibration (default: the study's)",
    )
    diagnose.add_argument(
        "--force",
        action="store_true",
        help="run the detection even when the calibration is not trusted (experts; the "
        "findings are labelled and kept apart, the verdict stays calibration_not_trusted)",
    )
    diagnose.set_defaults(handler=_diagnose)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args.handler(args))
    except UsageError as error:
        print(f"susp-bo {args.command}: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
