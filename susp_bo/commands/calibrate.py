"""``susp-bo calibrate``: the four steps on measured runs, from arguments or a study file."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from susp_bo.cli import UsageError
from susp_bo.commands._common import checked_output_folder
from susp_bo.study_config import (
    BudgetConfig,
    ExecutorConfig,
    StudyConfig,
    load_study_config,
    parse_study_config,
)
from susp_bo.units import format_values


def config_from_arguments(args: argparse.Namespace) -> StudyConfig:
    """The study config of the command line (a study file, with command-line overrides).

    Raises:
        UsageError: missing or conflicting arguments, or an invalid config.
    """
    target = Path(args.rig_or_study)
    if args.out:
        checked_output_folder(args.out)
    if target.suffix == ".toml" and not target.exists():
        raise UsageError(
            f"RIG_OR_STUDY: {str(target)!r} does not exist; give a shipped rig's name, a rig "
            ".toml or a study .toml"
        )
    try:
        if (
            target.suffix == ".toml"
            and target.is_file()
            and args.data_dir is None
            and _is_study(target)
        ):
            config = load_study_config(target)
            if args.out:
                config = dataclasses.replace(config, out=Path(args.out).resolve())
        else:
            if (
                target.suffix == ".toml"
                and target.is_file()
                and _is_study(target, unreadable=False)
            ):
                raise UsageError(
                    f"DATA_DIR: {args.data_dir!r} given after the study file {str(target)!r}, "
                    "which names its own data (data = ...); drop DATA_DIR, or give a rig "
                    "instead of the study"
                )
            if args.data_dir is None or args.out is None:
                raise UsageError(
                    "give RIG DATA_DIR --out DIR, or a study .toml "
                    f"(got rig_or_study={args.rig_or_study!r}, data_dir={args.data_dir!r}, "
                    f"out={args.out!r})"
                )
            config = parse_study_config(
                {"rig": args.rig_or_study, "data": args.data_dir, "out": args.out}, Path.cwd()
            )
        allow_small = config.budget.allow_small or getattr(args, "allow_small_budget", False)
        if args.budget is not None:
            budget = config.budget
            from susp_bo.calibration.budget import design_for_budget

            design = design_for_budget(config, args.budget)
            if not allow_small:
                _refuse_small_budget(config, args.budget, design)
            try:
                changed = BudgetConfig(
                    max_evaluations=args.budget,
                    initial_design=design,
                    batch_size=budget.batch_size,
                    check_points=budget.check_points,
                    allow_small=allow_small,
                )
            except ValueError as error:
                raise UsageError(f"--budget: {args.budget} is not allowed ({error})") from None
            config = dataclasses.replace(config, budget=changed)
        elif allow_small:
            config = dataclasses.replace(
                config, budget=dataclasses.replace(config.budget, allow_small=True)
            )
        if args.scheduler is not None:
            _check_scheduler_flag(args.scheduler)
        if args.workers is not None or args.scheduler is not None:
            config = dataclasses.replace(
                config, executor=ExecutorConfig(workers=args.workers, scheduler=args.scheduler)
            )
    except ValueError as error:
        raise UsageError(str(error)) from error
    return config


def _check_scheduler_flag(address: str) -> None:
    """Refuses a malformed ``--scheduler`` before anything is written or connected.

    Raises:
        UsageError: naming --scheduler, the value, what is wrong and an example.
    """
    from susp_bo.execution import scheduler_address_problem

    problem = scheduler_address_problem(address) if address else "empty"
    if problem is not None:
        raise UsageError(
            f"--scheduler: {address!r} is not allowed: {problem}; expected the address of a "
            "running Dask scheduler, e.g. 'tcp://10.0.0.5:8786'"
        )


def _refuse_small_budget(config: StudyConfig, budget: int, design: int) -> None:
    """Refuses ``--budget`` below the minimum for the study's q parameters.

    Raises:
        UsageError: naming --budget, the value and the minimum.
    """
    from susp_bo.calibration.budget import budget_message, budget_requirement, calibrated_count

    q = calibrated_count(config)
    if q is None:
        return
    b = config.budget
    requirement = budget_requirement(q, design, b.batch_size, b.check_points)
    if budget < requirement.minimum:
        raise UsageError(budget_message(budget, requirement))


def _is_study(path: Path, unreadable: bool = True) -> bool:
    """A rig file has a [rig] table; any other .toml is read as a study file (so that a
    study without its ``rig`` line is told ``rig: missing``, not how to call the command).

    Args:
        path: the .toml.
        unreadable: the answer for a file that does not parse (True: a study, so that
            load_study_config reports the problem).
    """
    import tomllib

    try:
        document = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return unreadable
    return not isinstance(document.get("rig"), dict)


def run_calibrate(args: argparse.Namespace) -> int:
    """Run (or resume) the study and print where its results are."""
    config = config_from_arguments(args)
    # torch and the GP stack load only now: bad arguments are refused without them (~4 s)
    from susp_bo.calibration.study import run_study
    from susp_bo.calibration.study_inputs import StudyError

    try:
        payload, _ = run_study(config, resume=args.resume)
    except StudyError as error:
        raise UsageError(str(error)) from error
    print(f"susp-bo calibrate: results in {config.out}", file=sys.stderr)
    print(format_summary(payload), file=sys.stderr)
    return 0


def format_summary(payload: dict) -> str:
    """A plain-text table of the posterior (what a maintenance engineer reads first).

    Values in SI-prefixed units (``27.9 [27.2, 28.5] kN·s/m``); with synthetic data the
    reference and whether it lies inside the interval.

    Its last line is the reliability sentence (``payload["reliability"]["sentence"]``), or
    says that the result has no verdict (a result.json from an older version).
    """
    width = max([34, *(len(name) for name in payload["parameters"])])  # per-component names
    lines = [f"{'parameter':{width}s} {'marginal MAP [95 % interval]':36s} reference"]
    reference = payload.get("reference")
    units = payload.get("units") or [""] * len(payload["parameters"])
    for k, name in enumerate(payload["parameters"]):
        lo, hi = payload["interval95"][k]
        estimate = [payload["marginal_map"][k], lo, hi]
        (value, low, high), unit = format_values(estimate, units[k])
        ref = ""
        if reference is not None:
            (truth,), _ = format_values([reference[k]], units[k], like=estimate)
            ref = f"{truth} {unit} ({'inside' if lo <= reference[k] <= hi else 'OUTSIDE'})"
        lines.append(f"{name:{width}s} {f'{value} [{low}, {high}] {unit}':36s} {ref}".rstrip())
    lines.append(
        f"simulator runs: {payload['n_simulations']}, likelihood evaluations: "
        f"{payload['n_evaluations']}, wall time {payload['wall_time_s']:.0f} s"
    )
    reliability = payload.get("reliability") or {}
    lines.append(
        reliability.get("sentence")
        or "Not trusted: no reliability verdict (a result from an older version)."
    )
    return "\n".join(lines)
