"""The lack of fit between a finished study's measured runs, recomputed from its store.

For each study folder (``susp-bo demo --out DIR``, ``susp-bo calibrate ... --out DIR``):
the best stored point's log L, the weighted lack-of-fit ratio F that the verdict uses
(:func:`susp_bo.calibration.lack_of_fit.lack_of_fit_ratio`) and the equal-weight F of
session 26, from the simulations in ``evaluations.sqlite`` — no simulation runs (exit 1
if one would). So a study made before a change of the statistic can be compared with one
made after, without rerunning it. Usage::

    python benchmarks/study_lack_of_fit.py demo_out [more study folders]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from susp_bo.calibration.lack_of_fit import lack_of_fit_ratio
from susp_bo.calibration.study import study_evaluator
from susp_bo.calibration.study_preparation import STORE_NAME, prepare_study, store_fingerprint
from susp_bo.execution import make_executor
from susp_bo.store import EvaluationStore
from susp_bo.study_config import load_study_config


def study_lack_of_fit(folder: Path) -> dict[str, float]:
    """Best stored log L (nats), weighted and equal-weight F at that point, and the F that
    the folder's ``result.json`` recorded (NaN if none)."""
    config = dataclasses.replace(load_study_config(folder / "study.toml"), out=folder.resolve())
    study = prepare_study(config, resume=True)
    with (
        EvaluationStore(folder / STORE_NAME, store_fingerprint(study)) as store,
        make_executor(workers=1) as executor,
    ):
        evaluator = study_evaluator(study, store, executor, progress=False)
        points = np.unique(np.array([e.parameters for e in store.evaluations("ok")]), axis=0)
        log_l = evaluator(points)
        best = points[int(np.nanargmax(log_l))]
        simulated = evaluator.spectra(best[None])[0]
        if evaluator.simulations_run:
            raise RuntimeError(f"{folder}: {evaluator.simulations_run} simulation(s) ran")
    measured = study.measured
    recorded = float("nan")
    result = folder / "result.json"
    if result.exists():
        evidence = json.loads(result.read_text()).get("reliability", {}).get("evidence", {})
        value = evidence.get("lack_of_fit_ratio")
        recorded = float("nan") if value is None else float(value)
    return {
        "best_log_likelihood": float(np.nanmax(log_l)),
        "F": lack_of_fit_ratio(measured, simulated),
        "F_equal_weights": lack_of_fit_ratio(measured, simulated, np.ones(measured.shape[1:])),
        "F_recorded": recorded,
    }


def main(argv: list[str] | None = None) -> int:
    """Print one line per folder."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="+", type=Path, help="finished study folders")
    args = parser.parse_args(argv)
    missing = [str(f) for f in args.folders if not (f / "study.toml").is_file()]
    if missing:
        parser.error(f"folders: {', '.join(missing)} hold no study.toml (not a study folder)")
    status = 0
    for folder in args.folders:
        try:
            row = study_lack_of_fit(folder)
        except RuntimeError as error:
            print(f"study_lack_of_fit: {error}", file=sys.stderr)
            status = 1
            continue
        print(
            f"{folder}: best log L {row['best_log_likelihood']:.3f}, F {row['F']:.3f} "
            f"(equal weights {row['F_equal_weights']:.3f}; result.json {row['F_recorded']:.3f})",
            flush=True,
        )
    return status


if __name__ == "__main__":
    sys.exit(main())
