"""Posterior mass the search cannot see at first: is it found, or is the result refused?

Targets on [0, 1]² whose exact answer is known (the outside probes of sessions 24–25):

- ``needle``: two equal-mass Gaussian modes, the second 5x narrower (sd 0.08 and 0.016);
  statistic: the share of the draws within 0.1 of the narrow mode (exact 0.5);
- ``spike_slab``: a spike (sd 0.015) holding 78.4 % of the mass and a slab (sd 0.3) whose
  peak is 7 nats lower; statistic: the share within 0.08 of the spike (exact 0.784);
- ``gauss``: one Gaussian (sd 0.05, 0.08); statistic: the share below its mean (0.5);
- ``cauchy``: independent Cauchy marginals of scale 1e-3; statistic: the width of the
  reported 95 % interval of x over the exact one (1.0).

Each run is ``calibrate`` with 200 evaluations, the default settings or
``trust_region=True``. A result is *trusted and wrong* when its verdict is ``trusted`` and
the statistic is off by more than 0.15 (the width ratio by more than 15 %); that count must
be zero. Usage::

    python benchmarks/hidden_mass.py --targets needle spike_slab gauss cauchy \\
        --settings default trust_region --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from susp_bo.calibration.loop import calibrate
from susp_bo.calibration.settings import CalibrationSettings

NARROW, SPIKE = np.array([0.8, 0.75]), np.array([0.78, 0.72])
CAUCHY_CENTRE, CAUCHY_SCALE = np.array([0.43, 0.61]), 1e-3


def needle(w: np.ndarray) -> np.ndarray:
    broad = -0.5 * np.sum(((w - [0.3, 0.3]) / 0.08) ** 2, axis=1) - 2 * np.log(0.08)
    narrow = -0.5 * np.sum(((w - NARROW) / 0.016) ** 2, axis=1) - 2 * np.log(0.016)
    return np.logaddexp(broad, narrow)


def spike_slab(w: np.ndarray) -> np.ndarray:
    spike = -0.5 * np.sum(((w - SPIKE) / 0.015) ** 2, axis=1)
    slab = -7.0 - 0.5 * np.sum(((w - [0.35, 0.4]) / 0.3) ** 2, axis=1)
    return np.logaddexp(spike, slab)


def gauss(w: np.ndarray) -> np.ndarray:
    return -0.5 * np.sum(((w - [0.4, 0.6]) / [0.05, 0.08]) ** 2, axis=1)


def cauchy(w: np.ndarray) -> np.ndarray:
    return -np.sum(np.log1p(((w - CAUCHY_CENTRE) / CAUCHY_SCALE) ** 2), axis=1)


def _cauchy_width(samples: np.ndarray) -> float:
    lo, hi = np.quantile(samples[:, 0], [0.025, 0.975])
    return float((hi - lo) / (2 * CAUCHY_SCALE * math.tan(math.pi * 0.475)))


TARGETS: dict[str, tuple[Callable[[np.ndarray], np.ndarray], Callable, float]] = {
    "needle": (
        needle,
        lambda s: float(np.mean(np.linalg.norm(s - NARROW, axis=1) < 0.1)),
        0.5,
    ),
    "spike_slab": (
        spike_slab,
        lambda s: float(np.mean(np.linalg.norm(s - SPIKE, axis=1) < 0.08)),
        0.784,
    ),
    "gauss": (gauss, lambda s: float(np.mean(s[:, 0] < 0.4)), 0.5),
    "cauchy": (cauchy, _cauchy_width, 1.0),
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--targets", nargs="+", choices=sorted(TARGETS), default=sorted(TARGETS))
    parser.add_argument(
        "--settings", nargs="+", choices=("default", "trust_region"), default=["default"]
    )
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    args = parser.parse_args(argv)
    bounds = np.array([[0.0, 0.0], [1.0, 1.0]])
    wrong = 0
    for name in args.targets:
        log_l, statistic, exact = TARGETS[name]
        for which in args.settings:
            for seed in args.seeds:
                start = time.time()
                settings = CalibrationSettings(
                    seed=seed, max_evaluations=200, trust_region=which == "trust_region"
                )
                result = calibrate(log_l, bounds, ["x", "y"], settings, progress=False)
                value = statistic(result.samples)
                audits = sum(h.phase == "explore" for h in result.history)
                rel = result.reliability
                bad = rel is not None and rel.trusted and abs(value - exact) > 0.15
                wrong += bad
                print(
                    f"{name:10s} {which:12s} seed {seed}: {result.n_evaluations} evaluations "
                    f"({audits} audits), statistic {value:.3f} (exact {exact}), "
                    f"{rel.verdict if rel else '-'} {list(rel.codes) if rel else ''}"
                    f"{'  TRUSTED AND WRONG' if bad else ''}, {time.time() - start:.0f} s",
                    flush=True,
                )
    print(f"trusted and wrong: {wrong}")
    return 1 if wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
