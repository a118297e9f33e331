"""The paired residual y_i − h(x_i, w_true) on the fast path, against both error models.

For ``--seeds`` x 3 runs of the demo's truth on the linearised rig (the generator of
``benchmarks/coverage.py``) with white sensor noise, prints per noise level:

- the paired residual's rms per channel, and the replicate-scatter σ_B of eq. 4
  (first 3 runs) with the mean of (r/σ_B)² — 1 if σ_B described the paired residual;
- the residual standardised by the paired model's Welch noise variance (diagonal):
  mean square overall, per quarter of the band and per channel; its mean;
- the correlation of neighbouring bands, measured and predicted;
- the mean square after projection onto the range of R and whitening with the full
  covariance, with the χ² mean and variance per run and channel (expected D, 2D);
- log L at the truth against :func:`expected_log_likelihood_at_truth` (in sd).

Example (the figures of ``susp_bo/calibration/paired_error.py``'s docstring)::

    python benchmarks/paired_residuals.py --noise 0.005 0.01 0.05 --seeds 6
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from susp_bo.calibration.likelihood import (
    estimate_output_error,
    expected_log_likelihood_at_truth,
)
from susp_bo.calibration.paired_error import (
    PairedOutputError,
    paired_log_likelihood,
    whitened_residuals,
)
from susp_bo.calibration.welch_noise import noise_residual_moments
from susp_bo.commands.demo import DEMO_RIG, DEMO_TRUTH
from susp_bo.data.synthetic import track_seed
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.simulator import synthetic_track
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.spectra import log_amplitude_spectra, with_noise_floor


def measure(noise: float, seeds: int) -> None:
    """Print the figures of one noise level (m/s² rms)."""
    spec = load_rig_spec(DEMO_RIG)
    true_spec = spec.with_parameters(DEMO_TRUTH)
    sim = true_spec.simulation
    rate = sim.sample_rate_hz
    rig = LinearisedRig(true_spec)
    ys, hs = [], []
    for seed in range(seeds):
        for index in range(3):
            geometry = synthetic_track(true_spec, seed=track_seed(seed, index))
            response = rig.response(geometry, sim.speed_m_s, time_step_s=1.0 / rate)
            s = np.array(response.accelerations_m_s2)
            n = np.random.default_rng([seed, index, 2]).normal(0.0, noise, s.shape)
            ys.append(log_amplitude_spectra(s + n, rate, response.channels, spec.spectrum))
            clean = log_amplitude_spectra(s, rate, response.channels, spec.spectrum)
            hs.append(with_noise_floor(clean.log_amplitude, noise, rate))
    y = np.stack([v.log_amplitude for v in ys])
    h = np.stack(hs)
    r = y - h
    n_samples = s.shape[1]
    print(f"noise {noise} m/s², {len(y)} runs", file=sys.stderr)
    print(f"  paired r rms per channel: {np.sqrt((r**2).mean(axis=(0, 2))).round(4)}")
    sigma_b = np.array(estimate_output_error(y[:3]).sigma)
    print(f"  replicate σ_B (3 runs): {sigma_b.round(3)}")
    print(f"  mean (r/σ_B)² = {np.mean((r / sigma_b[None, :, None]) ** 2):.4f}")
    error = PairedOutputError(noise, rate, (n_samples,) * 3, spec.spectrum)
    r_full, _ = error.projection(0)
    mean, cov = noise_residual_moments(h, error.noise_psd, r_full)
    var = np.diagonal(cov, axis1=-2, axis2=-1)
    z = (r - mean) / np.sqrt(var)
    quarters = [float(np.mean(z[..., a : a + 12] ** 2)) for a in (0, 12, 24, 36)]
    print(
        f"  diagonal-standardised: mean square {np.mean(z**2):.3f}, quarters "
        f"{np.round(quarters, 3)}, per channel {np.mean(z**2, axis=(0, 2)).round(2)}, "
        f"mean {np.mean(z):.3f}"
    )
    measured_corr = [
        float(
            np.mean(z[..., b] * z[..., b + 1])
            / np.sqrt(np.mean(z[..., b] ** 2) * np.mean(z[..., b + 1] ** 2))
        )
        for b in range(12)
    ]
    predicted_corr = np.mean(
        cov[..., np.arange(12), np.arange(1, 13)] / np.sqrt(var[..., :12] * var[..., 1:13]),
        axis=(0, 1),
    )
    print(f"  neighbouring-band correlation, bands 0-12: measured {np.round(measured_corr, 2)}")
    print(f"                                          predicted {predicted_corr.round(2)}")
    chi2, standard, values = [], [], []
    for start in range(0, len(y), 3):
        yy, hh = y[start : start + 3], h[start : start + 3]
        zz, lam = whitened_residuals(yy, hh, error)
        per_run = (zz**2 / lam).reshape(zz.shape[0], 3, -1).sum(axis=-1)
        chi2.extend(per_run.ravel())
        standard.append(np.mean(zz**2 / lam))
        m, sd = expected_log_likelihood_at_truth(error, yy)
        values.append((paired_log_likelihood(yy, hh, error) - m) / sd)
    d = zz.shape[-1] // 3
    print(
        f"  full-covariance whitened: mean square {np.mean(standard):.3f}; χ² per run and "
        f"channel: mean {np.mean(chi2):.1f}, variance {np.var(chi2):.0f} (D = {d}: {d}, {2 * d})"
    )
    print(f"  log L at the truth − expected, in sd, per 3-run set: {np.round(values, 2)}")


def main(argv: list[str] | None = None) -> int:
    """Measure at each requested noise level."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--noise", type=float, nargs="+", default=[0.005, 0.01, 0.05])
    parser.add_argument("--seeds", type=int, default=6, help="sets of 3 runs")
    args = parser.parse_args(argv)
    if args.seeds < 1 or any(not n > 0 for n in args.noise):
        parser.error("--seeds must be >= 1 and every --noise > 0 m/s^2")
    for noise in args.noise:
        measure(noise, args.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
