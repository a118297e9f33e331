"""How far another CPU's last bits can move the demo's answer: a tolerance, measured.

Across CPU families the pinned numerics do not give the same bits (README "Set-up": an
Intel Xeon and an AMD EPYC gave the same verdict and 7/7 but draws that differ in their
last bits). Which code path still differs was not found, so this benchmark measures what
such a difference does instead of what causes it: it reruns the README demo (same seed,
same data) with every log-likelihood value the surrogate sees moved by one unit in the
last place (``np.nextafter``, up or down by a hash of the perturbation seed and the
value) — a change of ≈ 1e-12 nats, the size of the GP's last-bit differences between
machines — and reports how far each printed figure moves from the unperturbed run:

- per parameter, the largest move of the 95 % interval's ends and of the posterior mean,
  as a fraction of the unperturbed interval's width;
- per run, the references inside, the verdict, the best log L, R-hat and ESS, and the
  draws' SHA-256 (each perturbed run is expected to differ from the baseline in its bits).

::

    python benchmarks/last_bit_sensitivity.py --perturbations 3 --jobs 2 --out OUT
    python benchmarks/last_bit_sensitivity.py --smoke --perturbations 2 --out OUT  # minutes

``--baseline DIR`` reuses an unperturbed demo folder (its ``result.json``) instead of
running one; a run whose folder already holds a ``result.json`` is not run again (a killed
benchmark continues). ``--compare LABEL=RESULT_JSON`` (repeatable) adds the same demo's
``result.json`` from another machine (e.g. ``benchmarks/reference/
demo_amd_epyc_zen3_session17_result.json``): its moves are reported beside the perturbations'.
Writes ``OUT/summary.json``, ``OUT/intervals.png`` (each run's 95 % intervals in physical
units, truth marked) and each run's demo folder ``OUT/run_K``. Bad arguments exit 2
before anything runs.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import susp_bo  # noqa: F401  (first: pins the numerics before NumPy loads, as the demo)

# isort: split
import numpy as np

FIGURES = ("interval_low", "interval_high", "posterior_mean")


def nudge(value: float, seed: int) -> float:
    """``value`` moved one unit in the last place, up or down by a hash of seed and value."""
    if not np.isfinite(value):
        return value
    digest = hashlib.sha256(seed.to_bytes(8, "little") + np.float64(value).tobytes()).digest()
    return float(np.nextafter(value, np.inf if digest[0] & 1 else -np.inf))


def _run_perturbed_demo(out: Path, seed: int, smoke: bool) -> int:
    """Child process: the demo with every log L the loop sees nudged (seed < 0: none)."""
    from susp_bo.calibration.evaluation import LikelihoodEvaluator
    from susp_bo.commands.demo import run_demo

    if seed >= 0:
        original = LikelihoodEvaluator.log_likelihood_of

        def log_likelihood_of(self: Any, H: np.ndarray, exact: bool = False) -> np.ndarray:
            values = original(self, H, exact=exact)
            return np.array([nudge(float(v), seed) for v in values], dtype=np.float64)

        LikelihoodEvaluator.log_likelihood_of = log_likelihood_of  # type: ignore[method-assign]
    return run_demo(out=out, smoke=smoke)


def figures(result: dict[str, Any]) -> dict[str, Any]:
    """The printed figures of one demo's ``result.json``."""
    low, high = np.asarray(result["interval95"], dtype=np.float64).T
    truth = np.asarray(result["reference"], dtype=np.float64)
    return {
        "interval_low": low.tolist(),
        "interval_high": high.tolist(),
        "posterior_mean": list(map(float, result["posterior_mean"])),
        "inside": int(np.sum((truth >= low) & (truth <= high))),
        "verdict": result["reliability"]["verdict"],
        "reasons": result["reliability"]["reasons"],
        "best_log_likelihood": result["best_log_likelihood"],
        "r_hat_max": max(result["mcmc"]["r_hat"]),
        "ess_min": min(result["mcmc"]["ess"]),
    }


def moves(baseline: dict[str, Any], runs: list[dict[str, Any]]) -> dict[str, list[float]]:
    """Per figure, per parameter: the largest |run − baseline| / baseline interval width."""
    width = np.subtract(baseline["interval_high"], baseline["interval_low"])
    return {
        name: np.max(
            [np.abs(np.subtract(run[name], baseline[name])) / width for run in runs], axis=0
        ).tolist()
        for name in FIGURES
    }


def _draws_sha(folder: Path) -> str | None:
    path = folder / "posterior_samples.npy"
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def _plot(
    out: Path, names: list[str], units: list[str], truth: list[float], runs: dict[str, Any]
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(names), 1, figsize=(7.5, 1.25 * len(names) + 1.0))
    labels = list(runs)
    for index, (ax, name, unit) in enumerate(zip(axes, names, units)):
        for row, label in enumerate(labels):
            run = runs[label]
            low, high = run["interval_low"][index], run["interval_high"][index]
            colour = {"baseline": "black"}.get(label, "tab:blue" if "ulp" in label else "grey")
            ax.plot([low, high], [row, row], color=colour, lw=3, solid_capstyle="butt")
            ax.plot(run["posterior_mean"][index], row, "|", color="white", ms=8)
        ax.axvline(truth[index], color="tab:red", lw=1, label="truth")
        ax.set_yticks(range(len(labels)), labels, fontsize=7)
        ax.set_ylim(-0.7, len(labels) - 0.3)
        ax.set_title(f"{name} [{unit}]", fontsize=8, loc="left")
        ax.tick_params(axis="x", labelsize=7)
        ax.ticklabel_format(axis="x", useOffset=False, style="plain")
        if index == 0:
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.suptitle(
        "95 % intervals: the demo here (black), with log L moved by 1 ulp (blue), "
        "other machines (grey)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--perturbations", type=int, default=3, help="perturbed runs (>= 1)")
    parser.add_argument("--jobs", type=int, default=1, help="demos run at once (>= 1)")
    parser.add_argument("--smoke", action="store_true", help="the demo's --smoke budgets")
    parser.add_argument("--baseline", type=Path, help="an unperturbed demo folder to reuse")
    parser.add_argument(
        "--compare",
        action="append",
        default=[],
        metavar="LABEL=RESULT_JSON",
        help="the same demo's result.json from another machine (repeatable)",
    )
    parser.add_argument("--child-seed", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child_seed is not None:
        return _run_perturbed_demo(args.out, args.child_seed, args.smoke)
    if args.perturbations < 1:
        parser.error(f"--perturbations {args.perturbations}: must be >= 1")
    if args.jobs < 1:
        parser.error(f"--jobs {args.jobs}: must be >= 1")
    if args.baseline is not None and not (args.baseline / "result.json").is_file():
        parser.error(f"--baseline {args.baseline}: no result.json there (a demo output folder)")
    compared: dict[str, Path] = {}
    for item in args.compare:
        label, _, path = item.partition("=")
        if not label or not Path(path).is_file():
            parser.error(f"--compare {item!r}: expected LABEL=RESULT_JSON with an existing file")
        compared[label] = Path(path)
    args.out.mkdir(parents=True, exist_ok=True)

    seeds = ([] if args.baseline else [-1]) + list(range(args.perturbations))
    folders = {seed: args.out / ("baseline" if seed < 0 else f"run_{seed}") for seed in seeds}
    pending = [seed for seed in seeds if not (folders[seed] / "result.json").is_file()]
    for seed in sorted(set(seeds) - set(pending)):
        print(f"last_bit_sensitivity: {folders[seed].name} done before, reused", file=sys.stderr)
    running: dict[int, tuple[subprocess.Popen[bytes], Any]] = {}
    started = time.perf_counter()
    while pending or running:
        while pending and len(running) < args.jobs:
            seed = pending.pop(0)
            folder = folders[seed]
            command = [sys.executable, __file__, "--out", str(folder), "--child-seed", str(seed)]
            log = open(args.out / f"{folder.name}.log", "w")  # noqa: SIM115 (closed below)
            running[seed] = (
                subprocess.Popen(
                    command + (["--smoke"] if args.smoke else []), stdout=log, stderr=log
                ),
                log,
            )
            print(f"last_bit_sensitivity: started {folder.name}", file=sys.stderr)
        time.sleep(2.0)
        for seed, (process, log) in list(running.items()):
            if process.poll() is not None:
                log.close()
                del running[seed]
                print(
                    f"last_bit_sensitivity: {folders[seed].name} finished (exit "
                    f"{process.returncode}), {time.perf_counter() - started:.0f} s",
                    file=sys.stderr,
                )
                if process.returncode != 0:
                    print(
                        f"last_bit_sensitivity: see {args.out / folders[seed].name}.log",
                        file=sys.stderr,
                    )
                    return 1

    base_folder = args.baseline or folders[-1]
    base_result = json.loads((base_folder / "result.json").read_text())
    runs = {"baseline": figures(base_result) | {"draws_sha256": _draws_sha(base_folder)}}
    for seed in range(args.perturbations):
        result = json.loads((folders[seed] / "result.json").read_text())
        runs[f"ulp seed {seed}"] = figures(result) | {"draws_sha256": _draws_sha(folders[seed])}
    perturbed = [run for label, run in runs.items() if label != "baseline"]
    others = {label: figures(json.loads(path.read_text())) for label, path in compared.items()}
    summary = {
        "command": " ".join(sys.argv),
        "baseline": str(base_folder),
        "parameters": base_result["parameters"],
        "largest_move_in_interval_widths": moves(runs["baseline"], perturbed),
        "other_machines_move_in_interval_widths": {
            label: moves(runs["baseline"], [run]) for label, run in others.items()
        },
        "runs": runs,
        "other_machines": {
            label: run | {"result": str(compared[label])} for label, run in others.items()
        },
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    _plot(
        args.out / "intervals.png",
        base_result["parameters"],
        base_result["units"],
        base_result["reference"],
        runs | others,
    )
    print("parameter                      largest move / interval width: low  high  mean")
    largest = summary["largest_move_in_interval_widths"]
    for index, name in enumerate(base_result["parameters"]):
        row = "  ".join(f"{largest[f][index]:.3f}" for f in FIGURES)
        print(f"{name:<32}{row}")
    for label, largest_other in summary["other_machines_move_in_interval_widths"].items():
        worst = max(max(values) for values in largest_other.values())
        print(f"{label}: largest move of any figure {worst:.3f} interval widths")
    for label, run in (runs | others).items():
        draws = run.get("draws_sha256") or "-"
        print(
            f"{label:<12} inside {run['inside']}/{len(base_result['parameters'])}, "
            f"{run['verdict']}, best log L {run['best_log_likelihood']:.3f}, R-hat <= "
            f"{run['r_hat_max']:.3f}, ESS >= {run['ess_min']:.0f}, draws "
            f"{draws[:8]}"
        )
    print(f"last_bit_sensitivity: wrote {args.out / 'summary.json'} and intervals.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
