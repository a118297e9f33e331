"""The peers of ``posterior_accuracy.py``: PyVBMC and ELFI's BOLFI on the same target.

Each runner takes (target, budget, seed) and returns (draws in physical units,
evaluations used, None): the same contract as the tool's runner there, on the same
unit-cube log density, bounds and budget. PyVBMC and ELFI are imported when run, so
the benchmark runs without them (their rows are then skipped).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from susp_bo.calibration.design import from_unit
from susp_bo.calibration.test_functions import NoisyTarget, Target


def run_pyvbmc(target: Target, budget: int, seed: int) -> tuple[np.ndarray, int, None]:
    """PyVBMC on the unit-cube log density with the same budget; returns draws, evaluations.

    On a :class:`NoisyTarget` PyVBMC is told the noise sd (``specify_target_noise``,
    each evaluation returns (log L, sd)): its documented set-up for noisy log densities,
    and more than this tool gets (it learns the noise level).
    """
    from pyvbmc import VBMC

    q = target.dim
    np.random.seed(seed)  # noqa: NPY002  (PyVBMC draws from numpy's global generator)
    noise_sd = target.noise_sd if isinstance(target, NoisyTarget) else 0.0

    def log_density(u: np.ndarray) -> float | tuple[float, float]:
        value = float(target.log_likelihood(from_unit(np.atleast_2d(u), target.bounds))[0])
        return (value, noise_sd) if noise_sd > 0.0 else value

    lb, ub = np.zeros((1, q)), np.ones((1, q))
    plb, pub = np.full((1, q), 0.05), np.full((1, q), 0.95)
    x0 = np.full((1, q), 0.5)
    options = {"max_fun_evals": budget, "display": "off"}
    if noise_sd > 0.0:
        options["specify_target_noise"] = True
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vbmc = VBMC(log_density, x0, lb, ub, plb, pub, options=options)
        vp, results = vbmc.optimize()
        draws, _ = vp.sample(100_000)
    return from_unit(draws, target.bounds), int(results["func_count"]), None


def run_bolfi(target: Target, budget: int, seed: int) -> tuple[np.ndarray, int, None]:
    """ELFI's BOLFI (Gutmann & Corander 2016) with the same budget; returns draws, evaluations.

    Settings, all ELFI defaults unless said otherwise:

    - parameters: the unit cube with uniform priors (the box's uniform prior, mapped
      affinely as for PyVBMC). ELFI's default GP kernel is an isotropic RBF plus a bias
      whose hyperprior scales come from the bounds, so physical units (0.1 to 5e5 here)
      would make it meaningless;
    - discrepancy: the deterministic d = log(−log L) (log discrepancy, as ELFI's docs
      advise for BOLFI). Raw −log L spans 12 to 5000 over the boxes and the GP fitted to
      it degenerates (noise sd ≈ 19; MMTV 0.39 instead of 0.15 on banana_2d at 100
      evaluations). Needs log L < 0 on the box: true for all targets (max −12 to −400);
    - acquisition: LCBSC (exploration rate 10), sequential (batch_size 1),
      ``initial_evidence`` = the same design size as this tool (5 q, at least 10), GP
      hyperparameters refitted every 10 evidence points (ELFI warns that it recommends
      2^q + 1 initial points, 129 in 7-D, more than a quarter budget); ``n_evidence`` =
      budget, and every call of log L is counted;
    - posterior: ELFI's ``BolfiPosterior``, prior × Φ((h − μ(θ))/σ(θ)) with μ, σ the GP
      mean and predictive sd of d. It is an ABC (uniform-kernel) posterior, not
      exp(log L): with a deterministic discrepancy σ is only the GP's uncertainty, so it
      tends to the uniform density on the level set {log L > max log L − ε}. ELFI has no
      option that treats the discrepancy as a log-likelihood, and no threshold gives
      exp(log L). ELFI's default threshold (the minimum of μ) collapses it onto the mode;
      we take h = log(exp(min μ) + ε) with ε = (q + 2)/2, for which the level set of a
      Gaussian likelihood (an ellipsoid) has exactly the posterior covariance. With the
      exact log L instead of the GP this threshold posterior still scores MMTV ≈ 0.15
      (banana_2d), 0.13 (oscillator_2d) and 0.05 (both 7-D targets): a floor of the
      method, not of the budget;
    - draws: ELFI's own samplers do not cope with this flat-topped, hard-edged density
      (NUTS fails to find a step size, the pure-Python Metropolis takes minutes), so
      ``posterior.logpdf`` is sampled with emcee (vectorised, 8 q walkers started at the
      best evidence points), 20 000 draws after burn-in and thinning.
    """
    import logging

    import elfi  # not installed in the project venv (see the module docstring)
    import emcee

    from susp_bo.calibration.design import default_design_size

    q = target.dim
    np.random.seed(seed)  # noqa: NPY002  (GPy and emcee draw from numpy's global generator)
    logging.getLogger("elfi").setLevel(logging.WARNING)
    count = [0]

    def discrepancy(*u: np.ndarray) -> np.ndarray:
        units = np.column_stack([np.asarray(x, dtype=np.float64).reshape(-1) for x in u])
        count[0] += units.shape[0]
        neg_log_l = -target.log_likelihood(from_unit(units, target.bounds))
        if np.any(neg_log_l <= 0.0):
            raise ValueError("run_bolfi: log(−log L) needs log L < 0 on the box")
        return np.log(neg_log_l)

    model = elfi.ElfiModel(name=f"bolfi_{target.name}")
    names = [f"u{k}" for k in range(q)]
    priors = [elfi.Prior("uniform", 0.0, 1.0, model=model, name=n) for n in names]
    elfi.Operation(discrepancy, *priors, model=model, name="d")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bolfi = elfi.BOLFI(
            model,
            "d",
            batch_size=1,
            initial_evidence=default_design_size(q),
            update_interval=10,
            bounds={n: (0.0, 1.0) for n in names},
            seed=seed,
        )
        d_min = float(bolfi.fit(n_evidence=budget, bar=False).threshold)  # min of GP mean
        threshold = math.log(math.exp(d_min) + (q + 2) / 2)
        posterior = bolfi.extract_posterior(threshold)

        def log_density(u: np.ndarray) -> np.ndarray:
            out = np.asarray(posterior.logpdf(u), dtype=np.float64).reshape(-1)
            return np.where(np.isfinite(out), out, -np.inf)

        n_walkers, thin, n_draws = 8 * q, 10, 20_000
        evidence = bolfi.target_model.X[np.argsort(bolfi.target_model.Y[:, 0])]
        start = evidence[np.arange(n_walkers) % len(evidence)]
        jitter = 1e-4 * np.random.default_rng(seed).standard_normal(start.shape)
        start = np.clip(start + jitter, 0.0, 1.0)
        sampler = emcee.EnsembleSampler(n_walkers, q, log_density, vectorize=True)
        burn = 2000
        sampler.run_mcmc(start, burn + n_draws * thin // n_walkers)
        draws = sampler.get_chain(discard=burn, thin=thin, flat=True)
    return from_unit(draws, target.bounds), count[0], None
