"""Maximum-likelihood refits and their Laplace posteriors (the fast path of the workflow).

With every measured run paired with its own track, ``log L`` of eq. 4 is
dominated by the paired term, ``-½ Σ_i ‖(y_i − h(x_i, w)) / σ_B‖²`` + const, a
nonlinear least-squares problem: trust-region reflective least squares
(:func:`scipy.optimize.least_squares`, bounds = C_w mapped to the unit cube,
finite-difference Jacobian) finds the maximum from a few starts, and the
Gauss–Newton matrix ``JᵀJ`` at the maximum gives the Laplace approximation of
the posterior (uniform prior on C_w, draws clipped to the box). With a paired
output error (:attr:`~.problem.DiagnosisProblem.paired`) the σ_B optimum is refined
on the paired scale (:func:`~.detection_scale.paired_scale`, weights frozen at the σ_B
optimum), whose Jacobian gives the Laplace posterior: as wide as the paired data
allow. The score reported is eq. 4 itself at the maximum.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from susp_bo.calibration.likelihood import log_likelihood
from susp_bo.discrepancy.problem import DiagnosisProblem, Simulator
from susp_bo.rig.spec import RigSpec

FloatArray = np.ndarray

PAIRED_REWEIGHTS = 4
"""Most reweighting rounds of a paired refit (:func:`fit_model`)."""


@dataclass(frozen=True)
class Fit:
    """A fitted model: maximum-likelihood parameters and a Laplace posterior.

    Attributes:
        spec: the rig (effects included).
        names: fitted parameter names (q,).
        bounds: (2 x q) admissible box.
        w: (q,) maximum-likelihood (= joint MAP under the uniform prior) values.
        log_likelihood: eq. 4 at ``w``.
        covariance_unit: (q x q) Laplace covariance in unit-cube coordinates.
        n_evaluations: simulator evaluations used (each = ν runs).
    """

    spec: RigSpec
    names: tuple[str, ...]
    bounds: FloatArray
    w: FloatArray
    log_likelihood: float
    covariance_unit: FloatArray
    n_evaluations: int

    @property
    def sd(self) -> FloatArray:
        """(q,) posterior standard deviations, physical units."""
        span = self.bounds[1] - self.bounds[0]
        return np.sqrt(np.clip(np.diag(self.covariance_unit), 0.0, None)) * span

    def draws(self, n: int, seed: int) -> FloatArray:
        """``n`` posterior draws (n x q), physical units; the first is ``w`` itself."""
        rng = np.random.default_rng(seed)
        span = self.bounds[1] - self.bounds[0]
        u0 = (self.w - self.bounds[0]) / span
        u = rng.multivariate_normal(u0, self.covariance_unit, size=n, method="eigh")
        u[0] = u0
        return self.bounds[0] + np.clip(u, 0.0, 1.0) * span

    def parameters(self) -> dict[str, float]:
        """``{name: value}`` at the maximum."""
        return dict(zip(self.names, (float(v) for v in self.w)))


def fit_model(
    problem: DiagnosisProblem,
    simulator: Simulator,
    spec: RigSpec,
    names: Sequence[str],
    bounds: FloatArray,
    starts: Sequence[FloatArray],
    max_iterations: int = 15,
    local_starts: int = 1,
) -> Fit:
    """Maximise log L over ``names`` within ``bounds`` from the best of ``starts``.

    Args:
        problem: data and tracks.
        simulator: ``h(x, w)``.
        spec: the rig to fit (its other parameters fixed).
        names: parameters to fit (q,).
        bounds: (2 x q) box.
        starts: candidate starting points (physical units); each costs one evaluation,
            the ``local_starts`` best are refined.
        max_iterations: least-squares iterations per local start.
        local_starts: number of refined starts.
    """
    names = tuple(names)
    bounds = np.asarray(bounds, dtype=np.float64)
    span = bounds[1] - bounds[0]
    sigma = problem.sigma[None, :, None]
    count = [0]

    def simulate(u: FloatArray) -> FloatArray:
        count[0] += 1
        return problem.simulate(simulator, spec, names, bounds[0] + np.clip(u, 0.0, 1.0) * span)

    def residual(u: FloatArray) -> FloatArray:
        return ((problem.measured - simulate(u)) / sigma).ravel()

    def solve(function, start: FloatArray, step: float = 1e-3):
        return least_squares(
            function,
            start,
            bounds=(0.0, 1.0),
            diff_step=step,
            max_nfev=max_iterations,
            x_scale=1.0,
            ftol=1e-6,
            xtol=1e-6,
        )

    units = [np.clip((np.asarray(s, dtype=np.float64) - bounds[0]) / span, 0, 1) for s in starts]
    costs = [float(np.sum(residual(u) ** 2)) for u in units]
    order = np.argsort(costs)[: max(1, local_starts)]
    best = None
    for index in order:
        result = solve(residual, units[index])
        if best is None or result.cost < best.cost:
            best = result
    assert best is not None
    if problem.paired is not None:
        # σ_B weighs every band of a channel alike; paired data are judged band by band on
        # the sensor-noise scale (+ τ_c), whose weights differ by orders of magnitude, so the
        # σ_B optimum can lie many paired sd from the paired one (measured: 0.3–0.8 % off
        # against sd 0.03–0.17 %). Refined on that scale by reweighted least squares: the
        # scale (it depends on h and on the residuals through τ_c) frozen at the current
        # point, solved, recomputed there, PAIRED_REWEIGHTS times at most.
        for _ in range(PAIRED_REWEIGHTS):
            scale = problem.detection_scale(simulate(best.x))
            sd = np.sqrt(scale.variance)

            def paired_residual(u: FloatArray, scale=scale, sd=sd) -> FloatArray:
                return ((problem.measured - simulate(u) - scale.offset) / sd).ravel()

            # the paired posterior is ~1e-4 of the box wide: a 1e-3 difference step would
            # straddle it
            start = best.x
            best = solve(paired_residual, start, step=1e-6)
            if np.max(np.abs(best.x - start)) < 1e-6:
                break
    jac = np.asarray(best.jac, dtype=np.float64)
    information = jac.T @ jac
    covariance = np.linalg.pinv(information + 1e-9 * np.eye(len(names)))
    w = bounds[0] + np.clip(best.x, 0.0, 1.0) * span
    simulated = problem.simulate(simulator, spec, names, w)
    count[0] += 1
    value = float(log_likelihood(problem.measured, simulated, problem.error))
    return Fit(spec, names, bounds, w, value, covariance, count[0])
