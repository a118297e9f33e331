"""``susp-bo demo``: the main job on embedded defaults.

The story: a CRH380A-type trailer car whose secondary vertical dampers have
lost 30 % of their damping and whose yaw dampers have lost 25 % runs over
``ν`` stretches of low-disturbance track at 300 km/h. The demo synthesises
those measured runs from the reference rig with these "true" parameters,
forgets them, calibrates the rig's seven suspension parameters on the
measurements, and writes ``result.json`` and the paper's figures — with the
truth alongside, so you can see how well each part is identified.

Budget: 200 likelihood evaluations (600 PyBullet runs, about 6 minutes on 2 cores);
``--smoke`` runs the same path with tiny budgets (well under a minute).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from susp_bo.calibration.study import run_study
from susp_bo.calibration.study_preparation import STORE_NAME
from susp_bo.cli import UsageError
from susp_bo.commands._common import checked_output_folder, existing_runs
from susp_bo.commands.calibrate import format_summary
from susp_bo.data.measured import MeasuredRun
from susp_bo.data.run_files import save_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.output_folder import CONFIG_NAME, LOG_NAME, RESULT_NAME, SAMPLES_NAME
from susp_bo.output_lock import OutputFolderBusy, hold_output_folder
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.study_config import (
    BudgetConfig,
    MCMCConfig,
    OutputErrorConfig,
    SearchConfig,
    StudyConfig,
)

DEMO_RIG = "hst_trailer"
DEMO_TRUTH = {
    "secondary_vertical_damping": 28.0e3,  # N·s/m: 70 % of the 40 kN·s/m reference
    "yaw_damper_damping": 3.7e6,  # N·s/m: 75 % of the 4.9 MN·s/m reference
}
"""The hidden "worn" state; every other parameter keeps its rig-file value."""
DEMO_NOISE_M_S2 = 0.005
"""Sensor noise of the demo's measured runs, m/s² rms."""
STUDY_FILES = (STORE_NAME, RESULT_NAME, CONFIG_NAME, SAMPLES_NAME, LOG_NAME)
"""What a study writes into its folder (a demo folder holds them beside ``data/``)."""


def demo_config(out: Path, smoke: bool, seed: int) -> StudyConfig:
    """The demo's study: all seven parameters, or two in smoke mode."""
    if smoke:
        return StudyConfig(
            rig=DEMO_RIG,
            data=out / "data",
            out=out,
            parameters=("secondary_vertical_damping", "yaw_damper_damping"),
            budget=BudgetConfig(
                max_evaluations=10,
                initial_design=6,
                batch_size=2,
                check_points=2,
                allow_small=True,  # tiny on purpose: the verdict says budget_too_small
            ),
            mcmc=MCMCConfig(chains=8, draws=300, warmup=200),
            output_error=OutputErrorConfig(model="paired"),
            search=SearchConfig(local=True),
        )
    return StudyConfig(
        rig=DEMO_RIG,
        data=out / "data",
        out=out,
        budget=BudgetConfig(max_evaluations=200, initial_design=40, batch_size=4),
        output_error=OutputErrorConfig(model="paired"),
        search=SearchConfig(local=True),
    )


def demo_runs_setting(spec: RigSpec, smoke: bool, seed: int) -> dict[str, Any]:
    """What identifies the demo's measured runs: count, duration, seed, noise, truth."""
    truth = spec.with_parameters(DEMO_TRUTH).parameter_values()
    return {
        "nu": 2 if smoke else 3,
        "duration_s": 12.0 if smoke else spec.simulation.duration_s,
        "seed": seed,
        "noise_m_s2": DEMO_NOISE_M_S2,
        "truth": {name: truth[name] for name in spec.calibration_names},
        "rig": spec.name,
    }


def _differences(run: MeasuredRun, index: int, setting: Mapping[str, Any]) -> list[str]:
    """How run ``index`` differs from the demo's ``setting`` (empty: it is the demo's)."""
    meta = run.metadata
    found: list[str] = []
    for key in ("rig", "seed", "noise_m_s2"):
        if meta.get(key) != setting[key]:
            found.append(f"{key} {meta.get(key)!r}, the demo's {setting[key]!r}")
    if meta.get("source") != "synthetic" or meta.get("run_index") != index:
        found.append(f"not the demo's synthetic run {index}")
    truth = meta.get("truth")
    if not isinstance(truth, Mapping) or any(
        not isinstance(truth.get(name), int | float)
        or not math.isclose(truth[name], value, rel_tol=1e-12)
        for name, value in setting["truth"].items()
    ):
        found.append("another truth")
    if abs(run.duration_s - setting["duration_s"]) > 1.0 / run.sample_rate_hz:
        found.append(f"{run.duration_s:g} s long, the demo's {setting['duration_s']:g} s")
    return found


def check_demo_folder(folder: Path, setting: Mapping[str, Any], smoke: bool) -> list[int]:
    """Which of the demo's runs ``folder/data`` still lacks; refuses a folder of other data.

    A rerun with the same ``--seed`` and ``--smoke`` continues a demo in place (its runs
    are kept, its evaluation store resumed); anything else in ``--out`` would be mixed
    with the demo's runs or results.

    Raises:
        UsageError: ``data/`` holds runs that are not this demo's (another seed, ``--smoke``
            or data set), an unreadable run, or the folder holds a study but no demo runs.
    """
    from susp_bo.data.measured import MeasuredDataError
    from susp_bo.data.run_files import load_run

    data = folder / "data"
    flags = f"--seed {setting['seed']}{' --smoke' if smoke else ''}"
    advice = (
        "give another --out (a demo continues in its folder only when rerun with the --seed "
        "and --smoke that made it)"
    )
    wanted = {f"run_{index:03d}.h5": index for index in range(setting["nu"])}
    present: list[int] = []
    for path in existing_runs(data):
        if path.name not in wanted:
            raise UsageError(
                f"--out: {data} holds {path.name}, not one of the demo's measured runs "
                f"({', '.join(wanted)} for {flags}); {advice}"
            )
        try:
            run = load_run(path)
        except MeasuredDataError as error:
            raise UsageError(f"--out: {path} cannot be read ({error}); {advice}") from None
        found = _differences(run, wanted[path.name], setting)
        if found:
            raise UsageError(
                f"--out: {path} is not a measured run of this demo ({flags}): "
                f"{'; '.join(found)}; {advice}"
            )
        present.append(wanted[path.name])
    study = [folder / name for name in STUDY_FILES if (folder / name).exists()]
    if study and not present:
        raise UsageError(
            f"--out: {folder} already holds a study ({', '.join(p.name for p in study)}) but "
            f"not the demo's measured runs in {data}; {advice}"
        )
    return [index for index in range(setting["nu"]) if index not in present]


def run_demo(out: str | Path, smoke: bool = False, seed: int = 2024) -> int:
    """Synthesise the measured runs, calibrate, print the summary; returns the exit code.

    Rerun on the same ``--out`` with the same ``--seed`` and ``--smoke``, it keeps the
    runs there and resumes the evaluation store (a finished demo is replayed, not
    recomputed); a folder holding other data or another study is refused before any work.
    """
    folder = checked_output_folder(out).resolve()
    spec = load_rig_spec(DEMO_RIG)
    setting = demo_runs_setting(spec, smoke, seed)
    check_demo_folder(folder, setting, smoke)  # refusals before anything is written
    folder.mkdir(parents=True, exist_ok=True)
    try:  # one writer from the runs' synthesis to the study's last file
        with hold_output_folder(folder):
            return _run_demo(folder, spec, setting, smoke, seed)
    except OutputFolderBusy as error:
        raise UsageError(str(error)) from None


def _run_demo(
    folder: Path, spec: RigSpec, setting: Mapping[str, Any], smoke: bool, seed: int
) -> int:
    data = folder / "data"
    missing = check_demo_folder(folder, setting, smoke)  # again: nobody else writes now
    nu = setting["nu"]
    if missing:
        print(
            f"susp-bo demo: {spec.name}; synthesising {nu} measured runs with a worn secondary "
            f"vertical damper and yaw damper (seed {seed}){' [smoke]' if smoke else ''}",
            file=sys.stderr,
        )
        data.mkdir(parents=True, exist_ok=True)
        runs = synthesize_runs(
            spec,
            DEMO_TRUTH,
            nu=nu,
            seed=seed,
            noise_m_s2=DEMO_NOISE_M_S2,
            duration_s=setting["duration_s"] if smoke else None,
        )
        for index in missing:  # runs already there are kept
            save_run(runs[index], data / f"run_{index:03d}.h5")
    else:
        print(
            f"susp-bo demo: {spec.name}; continuing in {folder} on its {nu} measured runs "
            f"(seed {seed}){' [smoke]' if smoke else ''}",
            file=sys.stderr,
        )
    config = demo_config(folder, smoke, seed)
    resume = (folder / STORE_NAME).exists()
    payload, _ = run_study(config, resume=resume)
    print(f"susp-bo demo: wrote {folder / RESULT_NAME} and figures", file=sys.stderr)
    print(format_summary(payload), file=sys.stderr)
    return 0
