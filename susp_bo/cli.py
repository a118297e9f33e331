"""The ``susp-bo`` command line (also ``python -m susp_bo``).

Commands (shared/DESIGN.md, "Interfaces that must stay stable"):
``demo``, ``simulate``, ``synth``, ``calibrate``, ``diagnose``. Progress goes
to stderr, results to files under ``--out``.
"""

from __future__ import annotations

import argparse
import errno
import signal
import sys
import threading
import traceback
from collections.abc import Sequence
from typing import Any

from susp_bo import __version__
from susp_bo.commands._arguments import integer, number


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


def _import(args: argparse.Namespace) -> int:
    from susp_bo.commands.import_runs import run_import

    return run_import(args)


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
    parser.add_argument("--debug", action="store_true", help="on an error, print the traceback too")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="the main job on embedded defaults: reference rig, synthetic measurement, "
        "calibration, result.json and figures",
    )
    demo.add_argument("--out", default="susp_bo_demo", help="output folder (default: %(default)s)")
    demo.add_argument("--smoke", action="store_true", help="tiny budgets, for tests")
    demo.add_argument(
        "--seed", type=integer(0), default=2024, help="random seed (default: %(default)s)"
    )
    demo.set_defaults(handler=_demo)

    simulate = sub.add_parser(
        "simulate", help="one rig run on a synthetic track: signals, spectra, figure"
    )
    simulate.add_argument("rig", help="rig name (e.g. hst_trailer) or path to a rig .toml")
    simulate.add_argument("--out", required=True)
    simulate.add_argument("--params", help="TOML file of parameter values")
    simulate.add_argument("--speed", type=number(0, strict=True, unit="m/s"), help="speed in m/s")
    simulate.add_argument(
        "--duration", type=number(0, strict=True, unit="s"), help="simulated time in s"
    )
    simulate.add_argument("--seed", type=integer(0), default=0)
    simulate.add_argument("--line", help="line design file (TOML segments: curves, cant, grades)")
    simulate.set_defaults(handler=_simulate)

    synth = sub.add_parser(
        "synth", help="synthetic measured runs from a rig, in the measured-data format"
    )
    synth.add_argument("rig")
    synth.add_argument("--out", required=True)
    synth.add_argument("--truth", help="TOML file of the true parameter values")
    synth.add_argument("--effect", action="append", default=[], help="NAME[:k=v,...], repeatable")
    synth.add_argument("--speed", type=number(0, strict=True, unit="m/s"), help="speed in m/s")
    synth.add_argument("--nu", type=integer(1), default=3, help="number of measured runs")
    synth.add_argument("--seed", type=integer(0), default=0)
    synth.add_argument(
        "--noise", type=number(0, unit="m/s^2"), default=0.0, help="sensor noise, m/s^2 rms"
    )
    synth.add_argument("--line", help="line design file (TOML segments: curves, cant, grades)")
    synth.set_defaults(handler=_synth)

    calibrate = sub.add_parser("calibrate", help="the four steps: design, kriging, EGO, MCMC")
    calibrate.add_argument("rig_or_study", help="rig name/path, or a study .toml")
    calibrate.add_argument("data_dir", nargs="?", help="folder of measured runs")
    calibrate.add_argument("--out")
    calibrate.add_argument(
        "--budget", type=integer(2), help="likelihood evaluations (design + EGO together)"
    )
    group = calibrate.add_mutually_exclusive_group()
    group.add_argument("--workers", type=integer(0), help="local worker processes (0 = in-process)")
    group.add_argument("--scheduler", help="Dask scheduler address")
    calibrate.add_argument(
        "--resume", action="store_true", help="reuse the study's evaluation store"
    )
    calibrate.add_argument(
        "--allow-small-budget",
        action="store_true",
        help="run a budget below the minimum for the number of parameters (refused "
        "otherwise); the result is then marked not trusted",
    )
    calibrate.set_defaults(handler=_calibrate)

    imports = sub.add_parser(
        "import",
        help="measured runs from CSV or MATLAB files to the HDF5 format calibrate reads",
        description="Convert measured runs to HDF5 (and check them against --rig). CSV: a run "
        "is <run>_accelerations.csv + <run>_geometry.csv (+ optional <run>_speed.csv); "
        "mat: one run per .mat file. A folder stands for the files in it.",
    )
    imports.add_argument("kind", choices=("csv", "mat"), help="file format")
    imports.add_argument("inputs", nargs="+", metavar="FILES_OR_DIR", help="files or folders")
    imports.add_argument("--out", required=True, help="folder for the <run>.h5 files")
    imports.add_argument("--rig", help="check the runs against this rig (name or .toml)")
    imports.add_argument(
        "--speed",
        type=number(0, strict=True, unit="m/s"),
        help="constant speed (m/s) of CSV runs without a speed file or speed_m_s column",
    )
    imports.set_defaults(handler=_import)

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
        type=integer(2),
        help="likelihood evaluations of the recalibration (default: the study's; "
        "--simulator pybullet only: the linear path recalibrates by least squares)",
    )
    diagnose.add_argument(
        "--force",
        action="store_true",
        help="run the detection even when the calibration is not trusted (experts; the "
        "findings are labelled and kept apart, the verdict stays calibration_not_trusted)",
    )
    diagnose.set_defaults(handler=_diagnose)

    from susp_bo.commands.monitor import add_parser as add_monitor_parser

    add_monitor_parser(sub)
    return parser


INTERRUPTED_HINTS = {
    "calibrate": "; the likelihood evaluations already stored are kept: run the same command "
    "with --resume to continue (without it only if no evaluations.sqlite was made yet)",
    "monitor": "; finished campaigns are kept and the interrupted one continues from its "
    "stored evaluations: run the same command again",
}
"""What to do after Ctrl-C, per command (where work was kept)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler's or a service manager's stop, ``kill PID``), raised in the main
    thread like Ctrl-C: the same clean-up runs (workers stopped, the store closed, the
    results folder released) and the user is told what was kept, where the default action
    of SIGTERM ended the process in silence."""


def _raise_on_sigterm() -> Any:
    """Makes SIGTERM raise :class:`Terminated`; returns the handler it replaced (None where
    none could be set: not the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def terminate(signum: int, frame: object) -> None:
        raise Terminated

    return signal.signal(signal.SIGTERM, terminate)


_STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS})
"""Write failures of the disk, not of the input: disk full, quota exceeded, read-only."""


_SQLITE_STORAGE_WORDS = ("database or disk is full", "readonly database", "disk i/o error")
"""The evaluation store's (SQLite's) words for the same failures."""


def _storage_failure(error: Exception) -> bool:
    """A write failure of the disk: an OSError of :data:`_STORAGE_ERRNOS`, or the store's
    SQLite saying the disk is full, the file read-only, or the disk failed."""
    if isinstance(error, OSError):
        return error.errno in _STORAGE_ERRNOS
    sqlite = sys.modules.get("sqlite3")
    return (
        sqlite is not None
        and isinstance(error, sqlite.OperationalError)
        and any(words in str(error).lower() for words in _SQLITE_STORAGE_WORDS)
    )


def _storage_message(error: Exception, command: str) -> str:
    """What a disk-full (quota, read-only) failure means for the work done, and what to do."""
    filename = getattr(error, "filename", None)
    where = f" ({filename})" if filename else " (the evaluation store)"
    reason = getattr(error, "strerror", None) or str(error)
    kept = {
        "calibrate": "the likelihood evaluations already stored are kept (a result being "
        "written may be missing): free space, then rerun the same command with --resume",
        "monitor": "finished campaigns and the stored evaluations of the interrupted one are "
        "kept: free space, then run the same command again",
    }.get(command, "free space, then run the command again")
    return f"cannot write{where}: {reason}; {kept}"


def _user_error_types() -> tuple[type[BaseException], ...]:
    """The exceptions that mean bad input (exit code 2, one message, no traceback).

    Each project error type is looked up only if its module was loaded (an error of a module
    never imported cannot have been raised): so refusing bad arguments does not import the
    modules that load torch and the GP stack (≈ 4 s)."""
    project = (
        ("susp_bo.calibration.study_inputs", "StudyError"),
        ("susp_bo.calibration.loop", "UninformativeDesignError"),
        ("susp_bo.data.measured", "MeasuredDataError"),
        ("susp_bo.store", "StoreMismatchError"),
        ("susp_bo.store", "StoreFileError"),
    )
    loaded = tuple(
        getattr(sys.modules[module], name) for module, name in project if module in sys.modules
    )
    return (
        UsageError,
        *loaded,
        FileNotFoundError,
        FileExistsError,
        NotADirectoryError,
        IsADirectoryError,
        PermissionError,
        ConnectionError,  # a Dask scheduler that cannot be reached (message names it)
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code.

    Bad input (:class:`UsageError` and the project's input errors, see
    :func:`_user_error_types`) is reported as one line ``susp-bo <cmd>: <message>``
    on stderr with exit code 2; ``--debug`` adds the traceback. Bad flag values
    are refused by argparse, also with exit code 2.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # argparse: --help/--version exit 0, bad flags exit 2
        if stop.code == 2:
            return 2
        raise
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    previous = _raise_on_sigterm()
    try:
        return int(args.handler(args))
    except Exception as error:
        if _storage_failure(error):
            if args.debug:
                traceback.print_exc()
            print(f"susp-bo {args.command}: {_storage_message(error, args.command)}",
                  file=sys.stderr)  # fmt: skip
            return 1
        if not isinstance(error, _user_error_types()):
            raise
        if args.debug:
            traceback.print_exc()
        print(f"susp-bo {args.command}: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:
        what = "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted"
        print(f"susp-bo {args.command}: {what}{INTERRUPTED_HINTS.get(args.command, '')}",
              file=sys.stderr)  # fmt: skip
        return 128 + signal.SIGTERM if isinstance(stop, Terminated) else 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    raise SystemExit(main())
