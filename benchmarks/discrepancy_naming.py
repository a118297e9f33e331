"""Discrepancy workflow: naming accuracy over hidden-effect cases, smallest named amplitude.

Fast path (linearised rig on seeded tracks) on the maintainer's base rig, band
0.3–40 Hz, ν = 3 runs of 20 s. Prints, all measured in this run:

* per case (effect × speed × noise × seed): named effect, score margin, gap before/after;
* naming accuracy over all hidden cases, gap ratio per effect (median);
* false alarms on null data: share of null data sets with any flagged band and the
  mean share of flagged bins (expected <= q = 0.05 and ~0);
* per effect, the smallest amplitude (scale of the effect's strength) still named.

    python benchmarks/discrepancy_naming.py            # full sweep (~10 min on 1 core)
    python benchmarks/discrepancy_naming.py --quick    # one seed, one noise level
"""

from __future__ import annotations

import argparse
import statistics
import time

from susp_bo.discrepancy.problem import LinearSimulator
from susp_bo.discrepancy.scenarios import scenario_spec, synthesize_problem
from susp_bo.discrepancy.workflow import run_workflow

NOMINAL = {
    "carbody_bending": {"frequency_hz": 10.0},
    "wheel_out_of_roundness": {"amplitude_m": 3.0e-4},
    "yaw_damper_series_stiffness": {"stiffness": 5.0e6},
    "lateral_bump_stop": {"gap_m": 0.003},
    "air_spring_reservoir": {"stiffness_ratio": 3.0},
}
# strength ladders, strongest first (the amplitude of each effect)
LADDERS = {
    "carbody_bending": ("damping_ratio", [0.02, 0.04, 0.06, 0.08]),
    "wheel_out_of_roundness": ("amplitude_m", [3e-4, 1e-4, 5e-5, 2e-5, 1e-5]),
    "yaw_damper_series_stiffness": ("stiffness", [5e6, 1e7, 1.5e7, 2e7, 3e7]),
    "lateral_bump_stop": ("gap_m", [0.003, 0.005, 0.007, 0.009, 0.012]),
    "air_spring_reservoir": ("stiffness_ratio", [3.0, 2.0, 1.5, 1.0, 0.5]),
}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    spec = scenario_spec(duration_s=20.0, warm_up_s=4.0)
    simulator = LinearSimulator()
    seeds = [1] if args.quick else [1, 2, 3]
    noises = [0.02] if args.quick else [0.01, 0.05]
    speeds = [55.56, 83.33]
    started = time.perf_counter()
    hits, total, ratios = 0, 0, {}
    print(f"{'effect':28s} speed noise seed  {'named':28s} margin  gap before -> after")
    for name, values in NOMINAL.items():
        for speed in speeds:
            for noise in noises:
                for seed in seeds:
                    problem = synthesize_problem(spec, (name, values), nu=3, seed=seed,
                                                 noise_m_s2=noise, speed_m_s=speed)  # fmt: skip
                    report = run_workflow(problem, simulator)
                    doc = report.to_dict()
                    total += 1
                    hits += doc["named_effect"] == name
                    ratios.setdefault(name, []).append(report.gap_ratio)
                    margin = doc["margin"] if doc["margin"] is not None else float("nan")
                    before, after = report.gap_before["value"], report.gap_after["value"]
                    print(f"{name:28s} {speed:5.1f} {noise:5.2f} {seed:4d}  "
                          f"{doc['named_effect']!s:28s} {margin:7.1f}  "
                          f"{before:8.3g} -> {after:.3g}")  # fmt: skip
    print(f"\nnaming accuracy: {hits}/{total} = {hits / total:.3f}")
    for name, values in ratios.items():
        print(f"  gap ratio after/before, {name:28s} median {statistics.median(values):.3g} "
              f"max {max(values):.3g}")  # fmt: skip
    null_any, null_bins, n_null = 0, [], 0
    for speed in speeds:
        for noise in noises:
            for seed in [*seeds, 7, 8]:
                problem = synthesize_problem(spec, None, nu=3, seed=100 + seed,
                                             noise_m_s2=noise, speed_m_s=speed)  # fmt: skip
                report = run_workflow(problem, simulator)
                n_null += 1
                null_any += bool(report.before.bands) or report.named_effect is not None
                null_bins.append(report.before.flagged_fraction)
    print(f"\nnull data sets with a flag or a name: {null_any}/{n_null} "
          f"(BH q = 0.05); mean flagged-bin share {statistics.mean(null_bins):.4f}")  # fmt: skip
    print("\nsmallest amplitude still named (83.33 m/s, noise 0.02, seed 1):")
    for name, (key, ladder) in LADDERS.items():
        smallest = None
        for value in ladder:
            values = {**NOMINAL[name], key: value}
            problem = synthesize_problem(spec, (name, values), nu=3, seed=1, noise_m_s2=0.02,
                                         speed_m_s=83.33)  # fmt: skip
            report = run_workflow(problem, simulator)
            if report.named_effect != name:
                break
            smallest = value
        print(f"  {name:28s} {key} = {smallest} (ladder {ladder})")
    print(f"\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
