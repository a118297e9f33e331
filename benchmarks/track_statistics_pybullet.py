"""The summary likelihood for tracks known only by their statistics, on PyBullet data.

:mod:`susp_bo.calibration.track_statistics` was measured through the calibration loop on
the linearised rig (``coverage.py --error statistics --unknown-tracks``). Its assumptions —
a run's log spectrum scatters about its mean by a covariance that hardly changes with w,
and the mean is smooth in w — are the rig's; this benchmark checks them on the demo's
PyBullet rig, without the surrogate (the exact summary likelihood's Laplace posterior):

1. a truth from the prior (:func:`coverage_pybullet.truth_of`, demo's q = 7) and ν = 3
   measured runs synthesised with PyBullet (sensor noise 0.005 m/s²);
2. the model simulates μ = 3 *other* realizations of the track process;
3. the two-stage pilot (:func:`track_statistics_pilot.two_stage_error`, M PyBullet runs on
   fresh tracks at the middle of C_w, then at the first Gauss–Newton fit);
4. the Gauss–Newton fit of the summaries with the final error, the Laplace sd from the
   whitened Jacobian there, z = (fit − truth) / sd per parameter, and the p of the test of
   the summaries the fit does not use (:mod:`susp_bo.calibration.summary_misfit`) there.

``--change NAME`` synthesises the measured runs with a vehicle the model lacks something
of (``track_statistics_misfit.CHANGES``: a conicity, a carbody bending mode, an air-spring
reservoir; the model stays the demo's rig): the power of that test on PyBullet data.
``--fast-rig`` uses the test suite's cheap variant of the demo's rig (8 s records, 5 ms
step, 32 bands; ``coverage_pybullet.fast_rig``).

Usage::

    python benchmarks/track_statistics_pybullet.py --experiments 6 --workers 2 --out OUT
    python benchmarks/track_statistics_pybullet.py --experiments 6 --fast-rig \
        --change carbody_bending_9hz --out OUT

Each experiment writes ``OUT/NNN.json`` (a rerun skips finished ones); the summary (z
rms, |z| < 1.96 count against its binomial range, fits at a bound of C_w) is printed.
About 500–700 PyBullet runs an experiment (≈ 10–14 min on one core).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from coverage_pybullet import fast_rig, truth_of  # noqa: E402
from fast_path import sbc_draw  # noqa: E402
from scipy.stats import binom  # noqa: E402
from track_statistics_misfit import CHANGES, data_spec  # noqa: E402
from track_statistics_pilot import (  # noqa: E402
    PILOT_RUNS,
    summary_fit,
    two_stage_error,
    whitened_jacobian,
)

from susp_bo.calibration.evaluation import simulate_spectra  # noqa: E402
from susp_bo.calibration.study_inputs import measured_log_spectra  # noqa: E402
from susp_bo.calibration.summary_misfit import P_LIMIT, summary_misfit  # noqa: E402
from susp_bo.commands.demo import DEMO_RIG  # noqa: E402
from susp_bo.data.synthetic import synthesize_runs, track_seed  # noqa: E402
from susp_bo.rig.simulator import synthetic_track  # noqa: E402
from susp_bo.rig.spec import RigSpec, load_rig_spec  # noqa: E402
from susp_bo.rig.spectra import with_noise_floor  # noqa: E402
from susp_bo.rig.track import SpeedProfile  # noqa: E402

NU = 3
NOISE_M_S2 = 0.005
OTHER_TRACKS = 10_000  # added to the data seed for the model's track realizations
PILOT_SEED = 20_000  # added to the data seed for the pilot's


class PyBulletProblem:
    """ν PyBullet runs of one truth; the model on μ = ν other track realizations."""

    def __init__(
        self, spec: RigSpec, truth: np.ndarray, data_seed: int, vehicle: RigSpec | None = None
    ):
        self.spec = spec
        self.names = spec.calibration_names
        runs = synthesize_runs(
            spec if vehicle is None else vehicle, dict(zip(self.names, truth.tolist())),
            nu=NU, seed=data_seed, noise_m_s2=NOISE_M_S2,
        )  # fmt: skip
        self.measured = measured_log_spectra(spec, runs)
        self.rate = runs[0].sample_rate_hz
        sim = spec.simulation
        speed = SpeedProfile.constant(sim.speed_m_s, sim.warm_up_s + sim.duration_s)
        self.tracks = tuple(
            (synthetic_track(spec, seed=track_seed(data_seed + OTHER_TRACKS, i)), speed)
            for i in range(NU)
        )
        self.evaluations = 0

    def spectra(self, W: np.ndarray) -> np.ndarray:
        """(b x μ x C x F) model spectra of the rows of W on the model's tracks."""
        out = []
        for w in np.atleast_2d(W):
            parameters = dict(zip(self.names, w.tolist()))
            h = np.stack([simulate_spectra(self.spec, parameters, g, s) for g, s in self.tracks])
            out.append(with_noise_floor(h, NOISE_M_S2, self.rate))
        self.evaluations += len(out)
        return np.stack(out)


def pybullet_pilot(problem: PyBulletProblem, w: np.ndarray, runs: int, seed: int) -> np.ndarray:
    """(runs x C x F) spectra at w on fresh track realizations with sensor noise."""
    pilot = synthesize_runs(
        problem.spec, dict(zip(problem.names, w.tolist())), nu=runs, seed=seed,
        noise_m_s2=NOISE_M_S2,
    )  # fmt: skip
    return measured_log_spectra(problem.spec, pilot)


def record_path(out: Path, index: int, change: str, fast: bool) -> Path:
    """OUT/NNN.json for the demo's rig and unchanged data (as before ``--change``), else
    OUT/CHANGE[-fast]-NNN.json: a folder reused with other options never mixes records."""
    if change == "none" and not fast:
        return out / f"{index:03d}.json"
    return out / f"{change}{'-fast' if fast else ''}-{index:03d}.json"


def experiment(args: tuple[int, int, int, Path, str, Path | None]) -> dict:
    """One experiment's record (module docstring), written to :func:`record_path`."""
    seed, index, runs, out, change, rig = args
    path = record_path(out, index, change, rig is not None)
    if path.exists():
        return json.loads(path.read_text())
    started = time.perf_counter()
    spec = load_rig_spec(DEMO_RIG if rig is None else rig)
    bounds = spec.calibration_bounds
    truth = truth_of(seed, index, bounds)
    u_true = (truth - bounds[0]) / (bounds[1] - bounds[0])
    _, data_seed = sbc_draw(seed, index, len(truth))
    problem = PyBulletProblem(spec, truth, data_seed, data_spec(spec, change))
    error, pilot = two_stage_error(problem, data_seed + PILOT_SEED, runs, pybullet_pilot)
    u, converged = summary_fit(problem, error, np.array(pilot.first_fit))
    _, jac = whitened_jacobian(problem, error, u)
    sd = np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    z = (u - u_true) / sd
    misfit_p = (
        math.nan
        if error.misfit is None
        else summary_misfit(
            problem.measured,
            problem.spectra((bounds[0] + u * (bounds[1] - bounds[0]))[None])[0],
            error.misfit,
        )[1]
    )
    record = {
        "experiment": index,
        "change": change,
        "summary_misfit_p": misfit_p,
        "z": z.tolist(),
        "sd_share_of_box": sd.tolist(),
        "fit": u.tolist(),
        "truth": u_true.tolist(),
        "at_bound": bool(np.any((u <= 0.0) | (u >= 1.0))),
        "fit_converged": converged,
        "first_fit_converged": pilot.converged,
        "pilot_simulations": pilot.simulations,
        "shrinkage": pilot.shrinkage,
        "seconds": time.perf_counter() - started,
    }
    path.write_text(json.dumps(record, indent=1))
    print(
        f"experiment {index}: max |z| {np.max(np.abs(z)):.2f}, z {np.round(z, 2).tolist()}, "
        f"summary misfit p {misfit_p:.1e}, "
        f"{record['seconds']:.0f} s",
        file=sys.stderr,
        flush=True,
    )
    return record


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=6)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--seed", type=int, default=33, help="master seed of truths and data")
    parser.add_argument("--pilot-runs", type=int, default=PILOT_RUNS)
    parser.add_argument("--workers", type=int, default=1, help="experiments in parallel")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--change", default="none", choices=list(CHANGES))
    parser.add_argument("--fast-rig", action="store_true", help="the test suite's cheap rig")
    args = parser.parse_args(argv)
    for flag, value, low in (("--experiments", args.experiments, 1), ("--workers", args.workers, 1),
                             ("--pilot-runs", args.pilot_runs, 70)):  # fmt: skip
        if value < low:
            parser.error(f"{flag}: got {value}; expected an integer >= {low}")
    args.out.mkdir(parents=True, exist_ok=True)
    rig = fast_rig(args.out) if args.fast_rig else None  # written once, before the workers
    tasks = [
        (args.seed, i, args.pilot_runs, args.out, args.change, rig)
        for i in range(args.first, args.first + args.experiments)
    ]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        records = list(pool.map(experiment, tasks))
    z = np.array([r["z"] for r in records])
    n = z.size
    low, high = binom.ppf(0.025, n, 0.95), binom.ppf(0.975, n, 0.95)
    print(f"{len(records)} experiments (seed {args.seed}), {n} parameters:")
    print(f"  z rms {math.sqrt(np.mean(z**2)):.2f}; per parameter "
          f"{np.round(np.sqrt(np.mean(z**2, axis=0)), 2).tolist()}")  # fmt: skip
    print(f"  |z| < 1.96: {int(np.sum(np.abs(z) < 1.96))}/{n} (binomial range "
          f"[{int(low)}, {int(high)}]); largest |z| {np.max(np.abs(z)):.2f}")  # fmt: skip
    print(f"  fits at a bound of C_w: {sum(r['at_bound'] for r in records)}")
    p = np.array([r.get("summary_misfit_p", math.nan) for r in records], dtype=float)
    tested = p[np.isfinite(p)]
    span = f"p {tested.min():.1e}–{tested.max():.1e}, " if tested.size else "no p, "
    print(
        f"  summary misfit ({args.change}): {span}{int(np.sum(tested < P_LIMIT))} of "
        f"{len(p)} below the limit {P_LIMIT:g} ({len(p) - tested.size} not tested)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
