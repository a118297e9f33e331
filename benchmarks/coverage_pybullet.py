"""Simulation-based calibration on PyBullet data: the demo's study, truths from the prior.

The PyBullet version of :mod:`coverage` (whose experiments use the linearised rig). Each
experiment e:

1. draws a truth w_e uniformly on C_w of the demo's q = 7 parameters;
2. synthesises ν = 3 measured runs with the PyBullet rig, as ``susp-bo synth`` /
   ``susp-bo demo`` do (:func:`susp_bo.data.synthetic.synthesize_runs`, white sensor
   noise 0.005 m/s², data seed from e);
3. calibrates with :func:`susp_bo.calibration.study.run_study` and the demo's study
   (:func:`susp_bo.commands.demo.demo_config`: paired B, local phase, budget 200, design
   40, batches of 4), every simulator call a PyBullet run;
4. scores the posterior draws against the truth as :mod:`coverage` does (quantile, z,
   95 % interval), with the study's own verdict, and evaluates log L at the truth on the
   same tracks (in a separate store, so a resumed study never sees the truth).

Each experiment is a results folder ``OUT/experiment_NNN`` (resumable: a killed study
resumes from its store) and a record ``OUT/experiments/NNN.json`` written when it ends;
``OUT/coverage.json`` and ``OUT/ranks.png`` are rebuilt from all records after each one.
Several processes may share ``OUT`` with disjoint ``--first`` ranges.

    python benchmarks/coverage_pybullet.py --out OUT --experiments 8 [--first 0]

About 12 min an experiment on one core (600 PyBullet runs of 16 s at 83.33 m/s; 22–24
min beside three other jobs).

Measured (2026-11-25, seed 0, experiments 0–10 and 12; 11 was stopped at the session's
end, its folder resumes; two processes with ``--first 0 / 4 / 8 / 12``; 2 shared cores)::

    12 experiments: 81/84 intervals hold the truth (binomial range [76, 83]), z rms 0.93,
    pooled KS p 0.35; 12/12 trusted; log L at the truth below the best evaluated point in
    12/12 (median 3.1 nats below, the closest 0.8 below); R-hat <= 1.013
    parameter                      z rms   z mean   inside (range)   KS p
    primary_vertical_stiffness     0.86    -0.51    12 [10, 12]      0.04
    primary_vertical_damping       0.84    +0.12    12               0.46
    secondary_vertical_stiffness   0.99    -0.30    12               0.53
    secondary_vertical_damping     0.92    -0.17    12               0.18
    secondary_lateral_damping      1.18    -0.10    10               0.95
    yaw_damper_damping             0.60    -0.06    12               0.43
    anti_roll_bar_stiffness        1.04    -0.23    11               0.70

Every verdict was ``trusted`` and the intervals held the truth 81 times in 84 — as often
as 95 % intervals should. Per parameter, 12 experiments cannot separate much: the yaw
damper's intervals look ~1.6x wider than needed, the secondary lateral damper's slightly
narrow (as on the linearised rig's SBC data sets, see ``paired_noise_check.py``).

Replication with ``--seed 1`` (2026-11-27, experiments 0–7, two processes, sessions 21–22's
code; the README gives the commands)::

    8 experiments: 53/56 intervals hold the truth (binomial range [50, 56]), z rms 1.05,
    pooled KS p 0.19; 8/8 trusted; log L at the truth below the best evaluated point in
    8/8 (median 3.3 nats); R-hat <= 1.012; per-parameter z rms 0.69 to 1.40
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import tomli_w  # noqa: E402
from fast_path import sbc_draw  # noqa: E402
from sbc_summary import aggregate, rank_figure, score_draws  # noqa: E402

from susp_bo.calibration.study import run_study, study_evaluator, with_pilot  # noqa: E402
from susp_bo.calibration.study_preparation import (  # noqa: E402
    STORE_NAME,
    prepare_study,
    store_fingerprint,
)
from susp_bo.calibration.study_track_statistics import TrackStatisticsPlan  # noqa: E402
from susp_bo.commands.demo import DEMO_RIG, demo_config  # noqa: E402
from susp_bo.data.measured import save_run  # noqa: E402
from susp_bo.data.synthetic import synthesize_runs  # noqa: E402
from susp_bo.execution import make_executor  # noqa: E402
from susp_bo.rig.catalog import rig_path  # noqa: E402
from susp_bo.rig.spec import load_rig_spec  # noqa: E402
from susp_bo.store import EvaluationStore  # noqa: E402
from susp_bo.study_config import OutputErrorConfig  # noqa: E402

NU = 3
NOISE_M_S2 = 0.005  # the demo's sensor noise


def truth_of(seed: int, experiment: int, bounds: np.ndarray) -> np.ndarray:
    """(q,) truth of one experiment, uniform on C_w (the prior; the fast path's draw)."""
    u_true, _ = sbc_draw(seed, experiment, bounds.shape[1])
    return bounds[0] + u_true * (bounds[1] - bounds[0])


def truth_log_likelihood(config, truth: np.ndarray) -> float:
    """log L at the truth on the study's tracks, through a throw-away store (the summary
    likelihood's pilot replayed from the study's own store first: no new simulation)."""
    study = prepare_study(config, resume=True)
    fingerprint = store_fingerprint(study)
    if isinstance(study.error, TrackStatisticsPlan):
        with (
            EvaluationStore(config.out / STORE_NAME, fingerprint) as store,
            make_executor(workers=0) as executor,
        ):
            evaluate = study_evaluator(study, store, executor, progress=False)
            study = with_pilot(study, evaluate, logging.getLogger("coverage_pybullet"), False)
            assert evaluate.simulations_run == 0, "the pilot was not replayed from the store"
    with tempfile.TemporaryDirectory() as scratch:
        store = EvaluationStore(Path(scratch) / "truth.sqlite", fingerprint)
        with store, make_executor(workers=0) as executor:
            evaluate = study_evaluator(study, store, executor, progress=False)
            return float(np.asarray(evaluate(truth[None, :]))[0])


def fast_rig(out: Path) -> Path:
    """The demo's rig made cheap (the test suite's ``fast_rig``: 8 s records after 1 s
    warm-up, 4 s Welch segments, 32 bands from 0.5 Hz, a 5 ms step), written in ``out``."""
    document = tomllib.loads(rig_path(DEMO_RIG).read_text())
    document["rig"]["name"] = "hst_trailer_fast"
    document["simulation"].update(duration_s=8.0, warm_up_s=1.0, time_step_s=0.005)
    document["spectrum"].update(segment_s=4.0, f_min_hz=0.5, n_frequencies=32)
    path = out / "hst_trailer_fast.toml"
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(tomli_w.dumps(document))
    return path


def run_experiment(
    out: Path,
    seed: int,
    experiment: int,
    workers: int,
    error: str = "paired",
    rig: str | Path = DEMO_RIG,
) -> dict[str, Any]:
    """Synthesise, calibrate and score one experiment; returns its record.

    ``error`` ``track_statistics``: the study simulates other realizations of the track
    process, not the runs' own tracks (the summary likelihood, its pilot first).
    """
    started = time.perf_counter()
    spec = load_rig_spec(rig)
    names, bounds = spec.calibration_names, spec.calibration_bounds
    truth = truth_of(seed, experiment, bounds)
    folder = out / f"experiment_{experiment:03d}"
    data = folder / "data"
    if not any(data.glob("run_*.h5")):
        data.mkdir(parents=True, exist_ok=True)
        _, data_seed = sbc_draw(seed, experiment, len(names))
        runs = synthesize_runs(
            spec, dict(zip(names, truth.tolist())), nu=NU, seed=data_seed, noise_m_s2=NOISE_M_S2
        )
        for index, run in enumerate(runs):
            save_run(run, data / f"run_{index:03d}.h5")
    config = demo_config(folder, smoke=False, seed=seed)
    if error == "track_statistics":  # each experiment its own model and pilot tracks
        _, data_seed = sbc_draw(seed, experiment, len(names))
        config = dataclasses.replace(
            config, seeds=dataclasses.replace(config.seeds, calibration=data_seed)
        )
    config = dataclasses.replace(
        config,
        rig=str(rig),
        executor=dataclasses.replace(config.executor, workers=workers),
        output_error=OutputErrorConfig(model=error),
    )
    payload, result = run_study(config, resume=(folder / "evaluations.sqlite").exists())
    draws = result.draws.reshape(-1, len(names))
    reliability = payload["reliability"]
    evidence = reliability.get("evidence", {})
    return {
        "experiment": experiment,
        **score_draws(draws, truth, payload["interval95"], payload["equal_tailed95"]),
        "truth_log_l": truth_log_likelihood(config, truth),
        "best_log_l": float(payload["best_log_likelihood"]),
        "expected_log_l_at_truth": list(evidence.get("expected_at_truth") or [None, None]),
        "r_hat_max": float(max(payload["mcmc"]["r_hat"])),
        "ess_min": float(min(payload["mcmc"]["ess"])),
        "check": (payload.get("surrogate_check") or {}).get("verdict"),
        "verdict": reliability["verdict"],
        "reasons": [r["code"] for r in reliability.get("reasons", [])],
        "lack_of_fit_ratio": evidence.get("lack_of_fit_ratio"),
        "summary_misfit_p": evidence.get("summary_misfit_p"),  # track_statistics only
        "n_evaluations": int(payload["n_evaluations"]),
        "n_simulations": int(payload["n_simulations"]),
        "output_error": {k: v for k, v in payload["output_error"].items() if k != "channels"},
        "seconds": time.perf_counter() - started,
    }


def summarise(
    out: Path, names: tuple[str, ...], source: str = "PyBullet data, the demo's study"
) -> dict[str, Any] | None:
    """coverage.json and ranks.png from every finished record in ``out``."""
    records = [json.loads(p.read_text()) for p in sorted((out / "experiments").glob("*.json"))]
    if not records:
        return None
    summary = aggregate(records, names)
    trusted = [r for r in records if r["verdict"] == "trusted"]
    summary["verdicts"] = {
        "trusted": len(trusted),
        "of": len(records),
        "reasons": sorted({c for r in records for c in r["reasons"]}),
        "trusted_inside95": int(sum(sum(r["inside95"]) for r in trusted)),
        "trusted_intervals": len(trusted) * len(names),
    }
    (out / "coverage.json").write_text(json.dumps(summary, indent=2))
    rank_figure(records, names, out / "ranks.png", source=source)
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="work folder (resumable)")
    parser.add_argument("--experiments", type=int, default=8, help="experiments to run")
    parser.add_argument("--first", type=int, default=0, help="index of the first experiment")
    parser.add_argument("--seed", type=int, default=0, help="master seed of truths and data")
    parser.add_argument("--workers", type=int, default=0, help="simulator processes (0: here)")
    parser.add_argument(
        "--error",
        choices=("paired", "track_statistics"),
        default="paired",
        help="the study's [output_error] model: paired (the demo's, the runs' own tracks) or "
        "track_statistics (other realizations of the track process, the summary likelihood)",
    )
    parser.add_argument(
        "--fast-rig",
        action="store_true",
        help="the test suite's cheap variant of the demo's rig (8 s records, 5 ms step, 32 "
        "bands), about 15x cheaper a run",
    )
    args = parser.parse_args(argv)
    if args.experiments < 1 or args.first < 0 or args.workers < 0:
        print("coverage_pybullet: --experiments must be >= 1, --first and --workers >= 0",
              file=sys.stderr)  # fmt: skip
        return 2
    rig = fast_rig(args.out) if args.fast_rig else DEMO_RIG
    source = f"PyBullet data{' (fast rig)' if args.fast_rig else ''}, the demo's study" + (
        ", tracks known only by their statistics" if args.error == "track_statistics" else ""
    )
    names = load_rig_spec(rig).calibration_names
    (args.out / "experiments").mkdir(parents=True, exist_ok=True)
    for experiment in range(args.first, args.first + args.experiments):
        record_file = args.out / "experiments" / f"{experiment:03d}.json"
        if record_file.exists():
            continue
        print(f"coverage_pybullet: experiment {experiment}", file=sys.stderr, flush=True)
        record = run_experiment(args.out, args.seed, experiment, args.workers, args.error, rig)
        record_file.write_text(json.dumps(record, indent=1))
        print(
            f"coverage_pybullet: experiment {experiment}: {record['verdict']} "
            f"{record['reasons']}, inside {sum(record['inside95'])}/{len(names)}, "
            f"z {np.round(record['z'], 2).tolist()}, truth log L - best "
            f"{record['truth_log_l'] - record['best_log_l']:.1f}, {record['seconds']:.0f} s",
            file=sys.stderr,
            flush=True,
        )
        summary = summarise(args.out, names, source)
        if summary is not None:
            pooled = summary["pooled"]
            print(
                f"coverage_pybullet: {summary['n_experiments']} experiments: inside "
                f"{pooled['inside95']}/{pooled['of']} (binomial {pooled['binomial_range']}), "
                f"z rms {pooled['z_rms']:.2f}, KS p {pooled['ks_p']:.3g}, trusted "
                f"{summary['verdicts']['trusted']}/{summary['n_experiments']}",
                file=sys.stderr,
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
