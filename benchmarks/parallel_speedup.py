"""Wall time of one batch of rig simulations with 1 and 2 worker processes, same run.

Prints the speed-up of 2 workers over 1 (target >= 1.7x on 2 cores). Both
pools are started and warmed up (each worker builds its PyBullet rig once)
before the timed batch, as in a study where the pool lives for many batches.

    python benchmarks/parallel_speedup.py [--runs 8] [--duration 10]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from susp_bo.calibration.evaluation import simulate_spectra
from susp_bo.data.synthetic import track_seed
from susp_bo.execution import make_executor, run_tasks
from susp_bo.rig.simulator import synthetic_track
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.track import SpeedProfile


def batch_seconds(workers: int, tasks: list[tuple], warm: list[tuple]) -> tuple[float, list]:
    """Wall time (s) of ``tasks`` on a pool of ``workers`` processes, after a warm-up batch."""
    with make_executor(workers=workers) as executor:
        run_tasks(executor, simulate_spectra, warm, progress=False)
        start = time.perf_counter()
        outcomes = run_tasks(executor, simulate_spectra, tasks, desc=f"{workers} worker(s)")
        return time.perf_counter() - start, outcomes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8, help="simulations in the batch")
    parser.add_argument("--duration", type=float, default=10.0, help="recorded seconds per run")
    args = parser.parse_args()
    spec = load_rig_spec("hst_trailer").with_simulation(duration_s=args.duration)
    settings = spec.simulation
    speed = SpeedProfile.constant(settings.speed_m_s, settings.warm_up_s + settings.duration_s)
    bounds = spec.calibration_bounds
    rng = np.random.default_rng(0)
    tasks = []
    for index in range(args.runs):
        w = bounds[0] + rng.random(bounds.shape[1]) * (bounds[1] - bounds[0])
        geometry = synthetic_track(spec, seed=track_seed(0, index))
        tasks.append((spec, spec.parameters_from_vector(w), geometry, speed))
    warm = tasks[:2]
    one, outcomes_one = batch_seconds(1, tasks, warm)
    two, outcomes_two = batch_seconds(2, tasks, warm)
    same = all(
        a.ok and b.ok and np.array_equal(a.value, b.value)
        for a, b in zip(outcomes_one, outcomes_two)
    )
    print(f"batch of {args.runs} runs x {args.duration:.0f} s simulated")
    print(f"1 worker : {one:7.2f} s wall")
    print(f"2 workers: {two:7.2f} s wall")
    print(f"speed-up : {one / two:5.2f}x  (target >= 1.7x on 2 cores)")
    print(f"identical spectra from both pools: {same}")


if __name__ == "__main__":
    main()
