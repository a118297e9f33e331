"""Calibration on a line with curves and transitions vs tangent track (linearised fast path).

Same story as ``susp-bo demo`` (worn secondary vertical and yaw dampers, seed 2024,
ν = 3 runs, 5 mm/s² sensor noise), calibrated twice with the same budget:

* tangent track: the runs as today;
* a curved line: tangent, transition, left curve R = 7000 m with 150 mm cant,
  transition, right curve (an S-curve with the cant of a 300 km/h line);
  every run follows the design with its own irregularities.

"Measured" runs come from the PyBullet rig following the design (linear
elements, so that the fast path's model class matches: the question here is
what the curves do, not the nonlinear dampers); their spectra have the design's
quasi-static specific force removed. The model is the linearised rig's expected
spectra (:meth:`~susp_bo.rig.linear.LinearisedRig.spectra`, with ``design`` on
the curved line: operating points along the recorded stretch) plus the sensor
noise floor; the output error is estimated from the scatter of the runs, as a
study does. Prints the marginal MAPs, the 95 % intervals, whether the truth is
inside, and the ratio of the interval widths curved / tangent (target ≤ 1.2).

    python benchmarks/curved_calibration.py [--budget 40]
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from susp_bo.calibration.likelihood import (  # noqa: E402
    OutputError,
    estimate_output_error,
    log_likelihood,
)
from susp_bo.calibration.loop import calibrate  # noqa: E402
from susp_bo.calibration.settings import CalibrationSettings  # noqa: E402
from susp_bo.commands.demo import DEMO_TRUTH  # noqa: E402
from susp_bo.data.synthetic import track_seed  # noqa: E402
from susp_bo.rig.line_file import design_from_segments  # noqa: E402
from susp_bo.rig.linear import LinearisedRig  # noqa: E402
from susp_bo.rig.response import RigResponse  # noqa: E402
from susp_bo.rig.simulator import Rig, synthetic_track  # noqa: E402
from susp_bo.rig.spec import load_rig_spec  # noqa: E402
from susp_bo.rig.spectra import with_noise_floor  # noqa: E402

NAMES = ("secondary_vertical_damping", "yaw_damper_damping")
NOISE = 0.005
SEED = 2024
S_CURVE = [
    {"type": "tangent", "length_m": 400.0},
    {"type": "transition", "length_m": 250.0},
    {
        "type": "curve",
        "length_m": 1200.0,
        "radius_m": 7000.0,
        "cant_mm": 150.0,
        "direction": "left",
    },
    {"type": "transition", "length_m": 250.0},
    {
        "type": "curve",
        "length_m": 6000.0,
        "radius_m": 7000.0,
        "cant_mm": 150.0,
        "direction": "right",
    },
]


def measured_spectra(spec, design) -> np.ndarray:
    """(ν x C x F) spectra of 3 noisy PyBullet runs at the truth (quasi-static part removed)."""
    truth = spec.with_parameters(DEMO_TRUTH)
    out = []
    with Rig(truth, linear_elements=True) as rig:
        for index in range(3):
            track = synthetic_track(truth, seed=track_seed(SEED, index))
            response = rig.simulate(track, design=design)
            noise = np.random.default_rng([SEED, index, 2]).normal(
                0.0, NOISE, size=response.accelerations_m_s2.shape
            )
            noisy = RigResponse(
                response.time_s,
                response.channels,
                response.accelerations_m_s2 + noise,
                response.sample_rate_hz,
                response.settings,
                response.quasi_static_m_s2,
            )
            out.append(noisy.spectra().log_amplitude)
    return np.stack(out)


def run(spec, design, budget: int, label: str) -> dict:
    start = time.perf_counter()
    measured = measured_spectra(spec, design)
    data_s = time.perf_counter() - start
    error = OutputError(estimate_output_error(measured).sigma)
    linear = LinearisedRig(spec)
    frequencies = spec.spectrum.frequencies_hz()
    rate = spec.simulation.sample_rate_hz

    def evaluate(W: np.ndarray) -> np.ndarray:
        values = []
        for w in np.atleast_2d(W):
            model = linear.spectra(dict(zip(NAMES, w)), design=design).log_amplitude
            simulated = with_noise_floor(model[None], NOISE, rate)
            values.append(float(log_likelihood(measured, simulated, error, frequencies)))
        return np.array(values)

    bounds = spec.calibration_bounds[:, [spec.calibration_names.index(n) for n in NAMES]]
    start = time.perf_counter()
    result = calibrate(
        evaluate,
        bounds,
        NAMES,
        CalibrationSettings(
            seed=0, max_evaluations=budget, initial_design_size=16, batch_size=4, check_points=4
        ),
        progress=False,
    )
    calibration_s = time.perf_counter() - start
    summary = result.summary
    truth = np.array([DEMO_TRUTH[n] for n in NAMES])
    widths = summary.interval95[:, 1] - summary.interval95[:, 0]
    print(f"{label}: data {data_s:.0f} s, calibration {calibration_s:.0f} s ({budget} evaluations)")
    for i, name in enumerate(NAMES):
        low, high = summary.interval95[i]
        inside = low <= truth[i] <= high
        print(
            f"  {name:28s} truth {truth[i]:10.4g}  marginal MAP {summary.marginal_map[i]:10.4g}  "
            f"95% [{low:.4g}, {high:.4g}]  width {widths[i] / truth[i]:6.1%} of truth  "
            f"{'inside' if inside else 'OUTSIDE'}  r_hat {summary.r_hat[i]:.3f}"
        )
    check = result.check
    print(f"  surrogate check: {check.verdict if check is not None else None}")
    return {
        "widths": widths,
        "inside": [bool(lo <= t <= hi) for (lo, hi), t in zip(summary.interval95, truth)],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=int, default=40)
    args = parser.parse_args()
    spec = load_rig_spec("hst_trailer")
    design = design_from_segments(S_CURVE, source="S-curve R 7000 m, 150 mm")
    points = LinearisedRig(spec).operating_points(design)
    print(f"curved line: {len(points)} operating points on the recorded stretch")
    tangent = run(spec, None, args.budget, "tangent track")
    curved = run(spec, design, args.budget, "curved line")
    ratio = curved["widths"] / tangent["widths"]
    for name, r in zip(NAMES, ratio):
        print(f"interval width curved / tangent, {name}: {r:.2f} (target <= 1.20)")


if __name__ == "__main__":
    main()
