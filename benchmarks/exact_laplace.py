"""The exact-likelihood Laplace posterior of an SBC experiment (no surrogate), for
``coverage.py``: ``--reference-only`` replaces the calibration by it, ``--laplace`` adds it
to every finished experiment. It tests the paired output error B alone, separately from
the surrogate search (``coverage.py``'s docstring has the measured figures).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from fast_path import FastPathProblem, Options, sbc_draw
from scipy import stats

from susp_bo.calibration.paired_error import PairedOutputError, paired_log_likelihood
from susp_bo.commands.demo import DEMO_RIG
from susp_bo.rig.spec import load_rig_spec


def reference_experiment(options: Options, experiment: int) -> dict[str, Any]:
    """One SBC experiment of the exact-likelihood Laplace posterior only (no surrogate).

    Gauss–Newton starts at the truth (the mode is within a few posterior sd of it), so
    this tests the error model B alone, at a small fraction of the cost.
    """
    started = time.perf_counter()
    spec = load_rig_spec(DEMO_RIG)
    bounds = spec.calibration_bounds
    u_true, _ = sbc_draw(options.seed, experiment, bounds.shape[1])
    truth = bounds[0] + u_true * (bounds[1] - bounds[0])
    lap = laplace_reference(
        options, {"experiment": experiment, "truth": truth.tolist(), "best_w": truth.tolist()}
    )
    z = np.asarray(lap["z"])
    return {
        "experiment": experiment,
        "truth": truth.tolist(),
        "quantile": lap["quantile"],
        "z": lap["z"],
        "mean": lap["mode"],
        "sd": lap["sd"],
        "inside95": lap["inside95"],
        "inside_equal_tailed95": lap["inside95"],
        "truth_log_l": lap["log_l_truth"],
        "best_log_l": lap["log_l_mode"],
        "best_w": lap["mode"],
        "r_hat_max": math.nan,
        "ess_min": math.nan,
        "check": None,
        "laplace": lap,
        "reference_only": True,
        "max_abs_z": float(np.max(np.abs(z))),
        "seconds": time.perf_counter() - started,
    }


def laplace_reference(options: Options, record: dict[str, Any]) -> dict[str, Any]:
    """The exact-likelihood posterior of one experiment, by Laplace (no surrogate).

    Gauss–Newton with the paired model's whitening (sensor-noise covariance and profiled
    τ_c held fixed within an iteration), started at the best evaluated point, gives the
    mode and the Fisher covariance (JᵀJ)⁻¹ in the unit cube. The posterior is hundreds
    to thousands of times narrower than C_w here, so the Gaussian is accurate; its truth
    quantiles, z and 95 % intervals test the *error model* alone, separately from the
    surrogate search.
    """
    from susp_bo.calibration.paired_error import profile_model_error, whitened_residuals
    from susp_bo.calibration.welch_noise import noise_residual_moments

    spec = load_rig_spec(DEMO_RIG)
    names = spec.calibration_names
    lower, upper = spec.calibration_bounds
    span = upper - lower
    truth = np.asarray(record["truth"])
    _, seed = sbc_draw(options.seed, record["experiment"], len(names))
    problem = FastPathProblem(spec, dict(zip(names, truth.tolist())), options, seed)
    error = problem.error
    if not isinstance(error, PairedOutputError):
        raise ValueError("laplace_reference: the paired error model only")
    y = problem.measured

    def log_l(h: np.ndarray) -> float:
        return float(paired_log_likelihood(y, h, error))

    def whitening(h: np.ndarray) -> list[np.ndarray]:
        """Per run (C x F' x F) maps of y − h − m to unit-variance coordinates, fixed at h."""
        z, lam = whitened_residuals(y, h, error)
        _, t = profile_model_error(z, lam)
        maps = []
        for i in range(y.shape[0]):
            r_full, basis = error.projection(i)
            _, cov = noise_residual_moments(h[i], error.noise_psd, r_full)
            cov_p = basis.T @ cov @ basis + t[:, None, None] * np.eye(basis.shape[1])
            values, vectors = np.linalg.eigh(cov_p)
            maps.append(np.swapaxes(vectors, -1, -2) @ basis.T / np.sqrt(values)[..., None])
        return maps

    def jacobian(u: np.ndarray, maps: list[np.ndarray], step: float = 1e-5) -> np.ndarray:
        columns = []
        for k in range(u.size):
            up, down = u.copy(), u.copy()
            up[k], down[k] = min(u[k] + step, 1.0), max(u[k] - step, 0.0)  # inside C_w
            dh = (problem.simulated(lower + up * span) - problem.simulated(lower + down * span)) / (
                up[k] - down[k]
            )
            columns.append(
                np.concatenate([(m @ dh[i][..., None]).ravel() for i, m in enumerate(maps)])
            )
        return np.stack(columns, axis=1)  # d(whitened h)/du

    def whitened(h: np.ndarray, maps: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([(m @ (y[i] - h[i])[..., None]).ravel() for i, m in enumerate(maps)])

    u = (np.asarray(record["best_w"]) - lower) / span
    h = problem.simulated(lower + u * span)
    value = log_l(h)
    for _ in range(10):
        maps = whitening(h)
        jac = jacobian(u, maps)
        info = jac.T @ jac
        step = np.linalg.solve(info, jac.T @ whitened(h, maps))
        step = np.clip(u + step, 0.0, 1.0) - u  # projected step: the prior is C_w
        for _ in range(30):
            h_new = problem.simulated(lower + (u + step) * span)
            value_new = log_l(h_new)
            if value_new >= value:
                break
            step = step / 2
        else:
            break
        u, h, value = u + step, h_new, value_new
        if np.all(np.abs(step) < 0.01 * np.sqrt(np.diag(np.linalg.inv(info)))):  # converged
            break
    maps = whitening(h)
    jac = jacobian(u, maps)
    cov = np.linalg.inv(jac.T @ jac)
    sd = np.sqrt(np.diag(cov)) * span
    mode = lower + u * span
    z = (mode - truth) / sd
    return {
        "mode": mode.tolist(),
        "sd": sd.tolist(),
        "z": z.tolist(),
        "quantile": stats.norm.cdf((truth - mode) / sd).tolist(),
        "inside95": (np.abs(z) <= 1.959964).tolist(),
        "log_l_mode": value,
        "log_l_truth": problem.log_l(truth),
        "sd_fraction_of_range": (sd / span).tolist(),
    }
