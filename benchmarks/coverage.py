"""Simulation-based calibration (SBC) of the whole calibration on the linearised fast path.

Each experiment e:

1. draws a truth w_e uniformly on C_w of the demo's q = 7 parameters (the rig's bounds);
2. synthesises ν measured runs the way ``susp-bo synth`` does, with the linearised rig
   (:meth:`susp_bo.rig.linear.LinearisedRig.response`) on seeded German-PSD tracks,
   white sensor noise of ``--noise`` m/s² added to the accelerations;
3. calibrates with the real loop (:func:`susp_bo.calibration.loop.calibrate`: design,
   GPyTorch kriging, BoTorch qLogEI, refinement, check, MH on the surrogate) with the
   demo's :class:`CalibrationSettings` (budget included), log L from the study's error
   model (``--error paired``, default, or ``unpaired``: eq. 4 with σ_B from the replicate
   scatter, the model before issue 10) and the linearised rig on each run's own track;
4. records per parameter the truth's posterior quantile (fraction of draws below it),
   z = (mean − truth)/sd, whether the paper's 95 % interval holds the truth, and the
   truth's log L against the best evaluated one (did the search reach the maximum?).

If the model and the inference are right, the quantiles are uniform (pooled KS test),
z has rms ≈ 1 and the intervals hold the truth in a binomial 95 % range around 95 %.
Each finished experiment is written to ``OUT/experiments/NNNN.json`` at once, so a rerun
with the same ``--out`` continues where a killed run stopped (the options must match:
they are checked against ``OUT/config.json``). Outputs: ``OUT/coverage.json`` (every
figure), ``OUT/ranks.png`` (rank histograms per parameter and pooled); progress on stderr.

Example (the report's runs)::

    python benchmarks/coverage.py --experiments 40 --nu 3 --noise 0.01 --out cov_nu3
    python benchmarks/coverage.py --experiments 40 --nu 2 --noise 0.01 --out cov_nu2
    python benchmarks/coverage.py --experiments 40 --nu 3 --noise 0.05 --out cov_n05
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # small matrices: threads only contend (2 shared cores)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

from susp_bo.calibration.evaluation import TrackRun  # noqa: E402
from susp_bo.calibration.likelihood import (  # noqa: E402
    OutputError,
    estimate_output_error,
    log_likelihood,
)
from susp_bo.calibration.loop import (  # noqa: E402
    CalibrationSettings,
    IterationReport,
    calibrate,
)
from susp_bo.calibration.paired_error import (  # noqa: E402
    PairedOutputError,
    paired_expected_log_likelihood,
    paired_log_likelihood,
)
from susp_bo.calibration.study import calibration_settings  # noqa: E402
from susp_bo.commands.demo import DEMO_RIG, demo_config  # noqa: E402
from susp_bo.data.synthetic import track_seed  # noqa: E402
from susp_bo.discrepancy.problem import LinearSimulator  # noqa: E402
from susp_bo.rig.linear import LinearisedRig  # noqa: E402
from susp_bo.rig.simulator import synthetic_track  # noqa: E402
from susp_bo.rig.spec import RigSpec, load_rig_spec  # noqa: E402
from susp_bo.rig.spectra import log_amplitude_spectra, with_noise_floor  # noqa: E402
from susp_bo.rig.track import SpeedProfile  # noqa: E402


@dataclasses.dataclass(frozen=True)
class Options:
    """What an SBC run is (stored in ``OUT/config.json``; a resume must match)."""

    nu: int
    noise: float
    seed: int
    error: str
    budget: int | None
    smoke: bool


def demo_settings(options: Options, experiment: int) -> CalibrationSettings:
    """The demo's calibration settings, seeded per experiment (and shrunk with --smoke)."""
    config = demo_config(Path("/nonexistent"), smoke=False, seed=0)
    settings = calibration_settings(config)
    seed = int(np.random.SeedSequence([options.seed, experiment, 7]).generate_state(1)[0] >> 1)
    settings = dataclasses.replace(settings, seed=seed, mcmc_seed=seed + 1)
    if options.budget is not None:
        settings = dataclasses.replace(
            settings,
            max_evaluations=options.budget,
            initial_design_size=min(settings.initial_design_size or 40, options.budget - 2),
        )
    if options.smoke:
        settings = dataclasses.replace(
            settings,
            max_evaluations=14,
            initial_design_size=10,
            check_points=2,
            batch_size=2,
            mcmc_chains=16,
            mcmc_warmup=100,
            mcmc_samples=200,
        )
    return settings


class FastPathProblem:
    """Synthetic runs of one truth and ``evaluate(W) -> log L`` on the linearised rig."""

    def __init__(self, spec: RigSpec, truth: dict[str, float], options: Options, seed: int):
        self.spec = spec
        self.names = spec.calibration_names
        self.options = options
        sim = spec.simulation
        self.rate = sim.sample_rate_hz
        true_spec = spec.with_parameters(truth)
        rig = LinearisedRig(true_spec)
        profile = SpeedProfile.constant(sim.speed_m_s, sim.warm_up_s + sim.duration_s)
        measured, tracks, n_samples = [], [], []
        for index in range(options.nu):
            geometry = synthetic_track(true_spec, seed=track_seed(seed, index))
            response = rig.response(geometry, sim.speed_m_s, time_step_s=1.0 / self.rate)
            signals = np.array(response.accelerations_m_s2, dtype=np.float64)
            if options.noise > 0:
                signals += np.random.default_rng([seed, index, 2]).normal(
                    0.0, options.noise, signals.shape
                )
            spectra = log_amplitude_spectra(signals, self.rate, response.channels, spec.spectrum)
            measured.append(spectra.log_amplitude)
            tracks.append(TrackRun(f"run{index:03d}", geometry, profile))
            n_samples.append(signals.shape[1])
        self.measured = np.stack(measured)
        self.tracks = tuple(tracks)
        self.error: PairedOutputError | OutputError
        if options.error == "paired":
            self.error = PairedOutputError(
                options.noise, self.rate, tuple(n_samples), spec.spectrum
            )
        else:
            self.error = estimate_output_error(self.measured)
        self.simulator = LinearSimulator()
        self.evaluations = 0

    def simulated(self, w: np.ndarray) -> np.ndarray:
        """(ν x C x F) simulated spectra with the noise floor, run i on track i."""
        parameters = dict(zip(self.names, np.asarray(w, dtype=float).tolist()))
        spectra = [self.simulator.spectra(self.spec, parameters, t) for t in self.tracks]
        return with_noise_floor(np.stack(spectra), self.options.noise, self.rate)

    def log_l(self, w: np.ndarray) -> float:
        """log L at one parameter vector (physical units)."""
        h = self.simulated(w)
        if isinstance(self.error, PairedOutputError):
            return float(paired_log_likelihood(self.measured, h, self.error))
        return float(log_likelihood(self.measured, h, self.error))

    def __call__(self, W: np.ndarray) -> np.ndarray:
        self.evaluations += len(W)
        out = []
        for w in np.atleast_2d(W):
            try:
                out.append(self.log_l(w))
            except (ValueError, np.linalg.LinAlgError):
                out.append(math.nan)
        return np.asarray(out, dtype=np.float64)


def run_experiment(options: Options, experiment: int) -> dict[str, Any]:
    """One SBC experiment (draw, synthesise, calibrate, score); returns its record."""
    started = time.perf_counter()
    spec = load_rig_spec(DEMO_RIG)
    names = spec.calibration_names
    bounds = spec.calibration_bounds
    rng = np.random.default_rng([options.seed, experiment, 11])
    truth = bounds[0] + rng.uniform(size=len(names)) * (bounds[1] - bounds[0])
    seed = int(np.random.SeedSequence([options.seed, experiment, 13]).generate_state(1)[0])
    problem = FastPathProblem(spec, dict(zip(names, truth.tolist())), options, seed)
    settings = demo_settings(options, experiment)

    def report(item: IterationReport) -> None:
        print(
            f"coverage: experiment {experiment}: iteration {item.iteration} [{item.phase}] "
            f"{item.n_evaluations} evaluations, best log L {item.best_log_likelihood:.1f} "
            f"({time.perf_counter() - started:.0f} s)",
            file=sys.stderr,
            flush=True,
        )

    result = calibrate(problem, bounds, names, settings, progress=False, on_iteration=report)
    draws = result.draws.reshape(-1, len(names))
    quantile = np.mean(draws < truth[None, :], axis=0)
    mean, sd = draws.mean(axis=0), draws.std(axis=0)
    interval = np.asarray(result.summary.interval95)
    tailed = np.asarray(result.summary.equal_tailed95)
    truth_log_l = problem.log_l(truth)
    expected = (
        paired_expected_log_likelihood(problem.error, problem.measured)
        if isinstance(problem.error, PairedOutputError)
        else (math.nan, math.nan)
    )
    finite = np.isfinite(result.y)
    best = int(np.flatnonzero(finite)[np.argmax(result.y[finite])])
    return {
        "experiment": experiment,
        "truth": truth.tolist(),
        "quantile": quantile.tolist(),
        "z": ((mean - truth) / sd).tolist(),
        "mean": mean.tolist(),
        "sd": sd.tolist(),
        "interval95": interval.tolist(),
        "inside95": ((interval[:, 0] <= truth) & (truth <= interval[:, 1])).tolist(),
        "inside_equal_tailed95": ((tailed[:, 0] <= truth) & (truth <= tailed[:, 1])).tolist(),
        "truth_log_l": truth_log_l,
        "best_log_l": float(result.y[best]),
        "best_w": result.X[best].tolist(),
        "expected_log_l_at_truth": list(expected),
        "r_hat_max": float(np.max(result.summary.r_hat)),
        "ess_min": float(np.min(result.summary.ess)),
        "check": None if result.check is None else result.check.verdict,
        "n_evaluations": int(result.n_evaluations),
        "stop_reason": result.stop_reason,
        "error": (
            {"model": "paired", "noise_m_s2": options.noise}
            if options.error == "paired"
            else {"model": "unpaired", "sigma": list(problem.error.sigma)}
        ),
        "seconds": time.perf_counter() - started,
    }


def _binomial_range(n: int, p: float = 0.95) -> tuple[int, int]:
    lo, hi = stats.binom.interval(0.95, n, p)
    return int(lo), int(hi)


def aggregate(records: list[dict[str, Any]], names: tuple[str, ...]) -> dict[str, Any]:
    """Every figure of the report from the experiment records."""
    quantiles = np.array([r["quantile"] for r in records])
    z = np.array([r["z"] for r in records])
    inside = np.array([r["inside95"] for r in records])
    tailed = np.array([r["inside_equal_tailed95"] for r in records])
    n = len(records)
    lo, hi = _binomial_range(n)
    pooled_lo, pooled_hi = _binomial_range(inside.size)
    gap = np.array([r["truth_log_l"] - r["best_log_l"] for r in records])
    per = {}
    for k, name in enumerate(names):
        per[name] = {
            "ks_p": float(stats.kstest(quantiles[:, k], "uniform").pvalue),
            "z_rms": float(np.sqrt(np.mean(z[:, k] ** 2))),
            "z_mean": float(np.mean(z[:, k])),
            "inside95": int(inside[:, k].sum()),
            "inside_equal_tailed95": int(tailed[:, k].sum()),
            "binomial_range": [lo, hi],
            "coverage_ok": bool(lo <= inside[:, k].sum() <= hi),
            "quantile_in_middle_half": float(
                np.mean((quantiles[:, k] >= 0.25) & (quantiles[:, k] <= 0.75))
            ),
        }
    return {
        "n_experiments": n,
        "pooled": {
            "ks_p": float(stats.kstest(quantiles.ravel(), "uniform").pvalue),
            "z_rms": float(np.sqrt(np.mean(z**2))),
            "inside95": int(inside.sum()),
            "of": int(inside.size),
            "binomial_range": [pooled_lo, pooled_hi],
            "quantile_in_middle_half": float(np.mean((quantiles >= 0.25) & (quantiles <= 0.75))),
        },
        "per_parameter": per,
        "search": {
            "truth_beats_best_evaluated": int(np.sum(gap > 0)),
            "truth_minus_best_log_l_median": float(np.median(gap)),
            "truth_minus_best_log_l_max": float(np.max(gap)),
        },
        "r_hat_max": float(max(r["r_hat_max"] for r in records)),
        "checks": {v: sum(r["check"] == v for r in records) for v in {r["check"] for r in records}},
        "seconds_per_experiment_median": float(np.median([r["seconds"] for r in records])),
    }


def rank_figure(records: list[dict[str, Any]], names: tuple[str, ...], path: Path) -> None:
    """Histograms of the truth's posterior quantile per parameter and pooled (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    quantiles = np.array([r["quantile"] for r in records])
    n = len(records)
    bins = max(4, min(10, n // 4))
    panels = [*names, "pooled"]
    cols = 4
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for ax, name in zip(axes.ravel(), panels):
        data = quantiles.ravel() if name == "pooled" else quantiles[:, names.index(name)]
        ax.hist(data, bins=bins, range=(0, 1), color="tab:blue", edgecolor="white")
        expect = data.size / bins
        band = stats.binom.interval(0.95, data.size, 1 / bins)
        ax.axhline(expect, color="k", lw=1)
        ax.axhspan(band[0], band[1], color="0.85", zorder=0)
        p = stats.kstest(data, "uniform").pvalue
        ax.set_title(f"{name}\nKS p = {p:.2g}", fontsize=8)
        ax.set_xlim(0, 1)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    fig.suptitle(
        f"SBC rank histograms: truth's posterior quantile, {n} experiments "
        "(grey: 95 % band of a uniform histogram)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Run (or resume) the SBC and write its figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--experiments", type=int, default=40)
    parser.add_argument("--nu", type=int, default=3, help="measured runs per experiment")
    parser.add_argument("--noise", type=float, default=0.01, help="sensor noise, m/s^2 rms")
    parser.add_argument("--workers", type=int, default=1, help="experiments in parallel")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--error", choices=("paired", "unpaired"), default="paired")
    parser.add_argument("--budget", type=int, default=None, help="default: the demo's")
    parser.add_argument("--smoke", action="store_true", help="tiny budgets (tests)")
    args = parser.parse_args(argv)
    for flag, value, low in (("--experiments", args.experiments, 1), ("--nu", args.nu, 1)):
        if value < low:
            parser.error(f"{flag}: got {value}; expected an integer >= {low}")
    if args.workers < 1:
        parser.error(f"--workers: got {args.workers}; expected an integer >= 1")
    if not (math.isfinite(args.noise) and args.noise >= 0):
        parser.error(f"--noise: got {args.noise}; expected a finite value >= 0 m/s^2")
    if args.error == "paired" and args.noise == 0:
        parser.error("--noise: 0 with --error paired leaves only the profiled model error")
    if args.error == "unpaired" and args.nu < 2:
        parser.error("--nu: the unpaired model estimates σ_B from >= 2 runs")
    if args.budget is not None and args.budget < 12:
        parser.error(f"--budget: got {args.budget}; expected >= 12")
    options = Options(args.nu, args.noise, args.seed, args.error, args.budget, args.smoke)
    out: Path = args.out
    folder = out / "experiments"
    folder.mkdir(parents=True, exist_ok=True)
    config_path = out / "config.json"
    if config_path.exists():
        stored = json.loads(config_path.read_text())
        if stored != dataclasses.asdict(options):
            parser.error(
                f"--out: {out} holds an SBC run with other options {stored}; "
                "choose another folder or the same options"
            )
    else:
        config_path.write_text(json.dumps(dataclasses.asdict(options), indent=1))
    names = load_rig_spec(DEMO_RIG).calibration_names
    todo = [e for e in range(args.experiments) if not (folder / f"{e:04d}.json").exists()]
    print(
        f"coverage: {args.experiments - len(todo)} of {args.experiments} experiments done, "
        f"running {len(todo)} (ν = {args.nu}, noise {args.noise} m/s², {args.error})",
        file=sys.stderr,
    )

    def save(record: dict[str, Any]) -> None:
        path = folder / f"{record['experiment']:04d}.json"
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(record, indent=1))
        tmp.replace(path)
        inside = sum(record["inside95"])
        print(
            f"coverage: experiment {record['experiment']} done in {record['seconds']:.0f} s: "
            f"{inside}/{len(names)} inside, max |z| {max(abs(v) for v in record['z']):.2f}, "
            f"truth - best log L {record['truth_log_l'] - record['best_log_l']:.2f}, "
            f"check {record['check']}",
            file=sys.stderr,
            flush=True,
        )

    if args.workers == 1:
        for e in todo:
            save(run_experiment(options, e))
    else:
        with ProcessPoolExecutor(args.workers) as pool:
            futures = [pool.submit(run_experiment, options, e) for e in todo]
            for future in as_completed(futures):
                save(future.result())
    records = [
        json.loads((folder / f"{e:04d}.json").read_text()) for e in range(args.experiments)
    ]
    figures = aggregate(records, names)
    figures["options"] = dataclasses.asdict(options)
    figures["parameters"] = list(names)
    (out / "coverage.json").write_text(json.dumps(figures, indent=1))
    rank_figure(records, names, out / "ranks.png")
    pooled = figures["pooled"]
    print(
        f"coverage: {len(records)} experiments; pooled KS p {pooled['ks_p']:.3g}, z rms "
        f"{pooled['z_rms']:.2f}, inside {pooled['inside95']}/{pooled['of']} (binomial range "
        f"{pooled['binomial_range']}); truth beat the best evaluated point in "
        f"{figures['search']['truth_beats_best_evaluated']}/{len(records)}",
        file=sys.stderr,
    )
    for name, row in figures["per_parameter"].items():
        print(
            f"  {name:32s} KS p {row['ks_p']:.3g}  z rms {row['z_rms']:.2f}  "
            f"inside {row['inside95']}/{len(records)} {row['binomial_range']}",
            file=sys.stderr,
        )
    print(f"coverage: wrote {out / 'coverage.json'} and {out / 'ranks.png'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
