"""The pooled rank test of an SBC run, with the ranks' within-experiment dependence.

``coverage.py`` reports the textbook KS p-value of the E x q pooled quantiles, which
treats them as independent. They are not: the q parameters' posteriors are correlated
(on the demo's problem up to |ρ| ≈ 0.9), and one noise draw moves correlated truths into
the same tails. This script reads a finished ``coverage.py --out OUT`` (paired model),
rebuilds each experiment's data, takes B's Laplace correlation at the truth (the loop's
posterior sd agree with the Laplace ones within 1–9 %, ``laplace_sd`` in the records)
and calibrates the pooled KS statistic under exact calibration with those correlations
(:func:`susp_bo.calibration.rank_uniformity.pooled_rank_ks`). About 3 s an experiment.

    python benchmarks/sbc_rank_dependence.py --out OUT [--simulations 20000]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fast_path import FastPathProblem, Options, laplace_at_truth, sbc_draw

from susp_bo.calibration.rank_uniformity import pooled_rank_ks
from susp_bo.commands.demo import DEMO_RIG
from susp_bo.rig.spec import RigSpec, load_rig_spec


def laplace_correlation(spec: RigSpec, options: Options, experiment: int) -> np.ndarray:
    """(q x q) B's Laplace posterior correlation at experiment ``experiment``'s truth."""
    names, bounds = spec.calibration_names, spec.calibration_bounds
    u_true, data_seed = sbc_draw(options.seed, experiment, len(names))
    truth = dict(zip(names, (bounds[0] + u_true * (bounds[1] - bounds[0])).tolist()))
    problem = FastPathProblem(spec, truth, options, data_seed)
    _, information, _ = laplace_at_truth(problem, bounds, u_true)
    covariance = np.linalg.inv(information)
    sd = np.sqrt(np.diag(covariance))
    correlation = covariance / np.outer(sd, sd)
    return 0.5 * (correlation + correlation.T)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="a coverage.py output folder")
    parser.add_argument("--simulations", type=int, default=20000)
    args = parser.parse_args(argv)
    config_path = args.out / "config.json"
    if not config_path.is_file():
        parser.error(f"--out: {args.out} has no config.json (not a coverage.py output folder)")
    options = Options(**json.loads(config_path.read_text()))
    if options.error != "paired":
        parser.error(f"--out: {args.out} is an SBC of the {options.error!r} model; "
                     "this script needs 'paired'")  # fmt: skip
    if args.simulations < 100:
        parser.error(f"--simulations: got {args.simulations}; expected an integer >= 100")
    records = [json.loads(p.read_text()) for p in sorted((args.out / "experiments").glob("*.json"))]
    records = [r for r in records if "quantile" in r]
    if not records:
        parser.error(f"--out: {args.out}/experiments holds no finished experiment")
    spec = load_rig_spec(DEMO_RIG)
    correlations = []
    for r in records:
        correlations.append(laplace_correlation(spec, options, int(r["experiment"])))
        print(f"sbc_rank_dependence: experiment {r['experiment']}", file=sys.stderr, flush=True)
    corr = np.array(correlations)
    quantiles = np.array([r["quantile"] for r in records])
    test = pooled_rank_ks(quantiles, corr, n_simulations=args.simulations)
    off = np.abs(corr[:, ~np.eye(corr.shape[1], dtype=bool)])
    print(f"{len(records)} experiments (ν = {options.nu}, noise {options.noise} m/s², seed "
          f"{options.seed}); posterior |correlation| median {np.median(off):.2f}, "
          f"largest {off.max():.2f}")  # fmt: skip
    print(f"pooled KS D = {test.statistic:.4f}: textbook p {test.p_independent:.3g}, "
          f"with the dependence p {test.p_dependent:.3g}; under exact calibration the "
          f"textbook p is < {test.alpha} in {100 * test.false_alarm_rate:.1f} % of SBC runs "
          f"like this one ({test.n_simulations} simulated)")  # fmt: skip
    payload = {"n_experiments": len(records), **test.__dict__,
               "abs_correlation_median": float(np.median(off)),
               "abs_correlation_max": float(off.max())}  # fmt: skip
    (args.out / "rank_dependence.json").write_text(json.dumps(payload, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
