"""Local phase of the calibration loop: a trust-region Gauss–Newton search on the spectra.

Why. log L(w) = ℓ(h(w)) is a cheap, known function ℓ (the output-error model B, eq. 4
or the paired model) of the simulated spectra h(w) (n runs x C channels x F bands).
Treated as a black box, log L is hard: with paired data its peak is 10⁻⁴–10⁻³ of C_w
wide while it falls by 10³–10⁴ nats across C_w, and the kriging search alone stopped
tens to hundreds of nats below the true maximum (benchmarks/coverage.py, issue 10).
Treated as ℓ ∘ h, it is easy: h is smooth in w, so the model

    m(δ) = ℓ(h(u) + J δ),   J = ∂h/∂u by forward differences (q simulator runs),

is accurate near u (unit coordinates of C_w) for *every* B, nonlinear ℓ included
(the mixture of eq. 4, the profiled model error of the paired model). This is the
model-based trust-region method of derivative-free least squares (DFO-GN, POUNDERS)
with the exact outer function instead of a sum of squares.

One iteration: maximise m over δ with |δ|∞ ≤ r inside [0, 1]^q (L-BFGS-B on the cheap
m, no simulation), run the simulator at u + δ (one evaluation), accept when the actual
gain is at least ``accept`` of the predicted one, grow r after a good step at the
radius and shrink it after a poor one, and re-difference J at an accepted point
(q evaluations). It stops when an accepted step predicts less than ``tolerance``
nats (or the model's maximum lies inside the radius and gains less than that: no
evaluation is spent on it), on the radius falling below ``min_radius`` or on its
evaluation cap.

Output for the loop: every simulator run (the trial points and the differencing
points) joins the kriging data, and the Laplace approximation at the best point — the
mode and the covariance (−∇²m)⁻¹ by central differences of the cheap m — defines the
search box the surrogate, the refinement, the held-out check and the MCMC then work in
(:mod:`.trust_region`). The final posterior stays the kriging/MCMC one of the paper;
the Laplace covariance is also reported, as a cross-check of its width.

Determinism: m is evaluated in float64 with the evaluator's own determinism; proposed
points are rounded to 1e-10 of C_w (``_ROUND``) so that last-bit differences of the
optimiser between machines do not change the points that get simulated.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.optimize import minimize

from susp_bo.numerics import one_blas_thread

logger = logging.getLogger(__name__)

_ROUND = 10  # decimals of proposed unit-cube coordinates


@runtime_checkable
class SpectraEvaluator(Protocol):
    """An ``evaluate`` that also exposes the spectra log L is computed from.

    ``evaluate(W) == log_likelihood_of(spectra(W))`` (NaN where a run failed).
    """

    def __call__(self, W: np.ndarray) -> np.ndarray:
        """(b,) log L of the rows of W (physical units), NaN where a run failed."""
        ...

    def spectra(self, W: np.ndarray) -> np.ndarray:
        """(b x n x C x F) simulated spectra of the b rows of W (physical units), NaN rows
        where a simulation failed; each call runs (or looks up) the simulator."""
        ...

    def log_likelihood_of(self, H: np.ndarray, exact: bool = False) -> np.ndarray:
        """(b,) log L of (b x n x C x F) spectra, no simulation. ``exact``: no rounding
        (for derivatives of the local model)."""
        ...


@dataclass(frozen=True)
class LocalSearchSettings:
    """Settings of :func:`local_search` (unit-cube coordinates of C_w).

    Args:
        initial_radius: first trust radius (∞-norm), in (0, 1].
        min_radius: stop when the radius falls below this.
        tolerance: stop when an accepted step predicted less than this gain (nats).
        accept: accept a step when actual gain >= ``accept`` x predicted gain.
        difference_step: forward-difference step as a fraction of the radius, clipped to
            [``min_difference_step``, ``max_difference_step``].
    """

    initial_radius: float = 0.1
    min_radius: float = 1e-7
    tolerance: float = 0.05
    accept: float = 0.1
    difference_step: float = 0.05
    min_difference_step: float = 1e-6
    max_difference_step: float = 1e-2

    def __post_init__(self) -> None:
        if not 0.0 < self.initial_radius <= 1.0:
            raise ValueError(f"initial_radius: {self.initial_radius} must be in (0, 1]")
        if not 0.0 < self.min_radius < self.initial_radius:
            raise ValueError(f"min_radius: {self.min_radius} must be in (0, initial_radius)")
        if not self.tolerance > 0.0:
            raise ValueError(f"tolerance: {self.tolerance} must be > 0 nats")
        if not 0.0 < self.accept < 1.0:
            raise ValueError(f"accept: {self.accept} must be in (0, 1)")
        if not 0.0 < self.min_difference_step <= self.max_difference_step < 0.5:
            raise ValueError("min/max_difference_step: need 0 < min <= max < 0.5")


@dataclass(frozen=True)
class LocalSearchResult:
    """What the local phase found (unit-cube coordinates of C_w).

    Attributes:
        mode: (q,) best point found.
        log_likelihood: log L there (nats).
        covariance: (q x q) Laplace covariance (−∇²m)⁻¹ at the mode, unit cube; a
            direction without curvature gets variance 1 (the whole of C_w).
        n_evaluations: simulator evaluations the phase used.
        stop_reason: "converged", "radius", "budget" or "failed".
        iterations: trust-region iterations run.
    """

    mode: np.ndarray
    log_likelihood: float
    covariance: np.ndarray
    n_evaluations: int
    stop_reason: str
    iterations: int

    @property
    def sd(self) -> np.ndarray:
        """(q,) Laplace posterior sd per coordinate (unit cube)."""
        return np.sqrt(np.diag(self.covariance))

    def box(self, half_width_sd: float, best: np.ndarray | None = None) -> np.ndarray:
        """(2 x q) unit-cube box: mode ± ``half_width_sd`` sd, holding ``best``, in [0, 1]."""
        half = half_width_sd * self.sd
        lo, hi = self.mode - half, self.mode + half
        if best is not None:
            lo, hi = np.minimum(lo, best), np.maximum(hi, best)
        return np.stack([np.clip(lo, 0.0, 1.0), np.clip(hi, 0.0, 1.0)])


def _round(u: np.ndarray) -> np.ndarray:
    return np.clip(np.round(np.asarray(u, dtype=np.float64), _ROUND), 0.0, 1.0)


class _Model:
    """m(δ) = ℓ(h0 + J δ) and its finite-difference derivatives (no simulation)."""

    def __init__(self, head: Callable[[np.ndarray], np.ndarray], h0: np.ndarray, jac: np.ndarray):
        self.head = head
        self.h0 = h0  # n x C x F
        self.jac = jac  # q x n x C x F
        self.q = jac.shape[0]

    def values(self, deltas: np.ndarray) -> np.ndarray:
        d = np.atleast_2d(deltas)
        with one_blas_thread():  # exact log L: its bits must not depend on the core count
            h = self.h0[None] + np.tensordot(d, self.jac, axes=(1, 0))
        return np.asarray(self.head(h), dtype=np.float64)

    def value_and_gradient(self, delta: np.ndarray, eps: np.ndarray) -> tuple[float, np.ndarray]:
        e = np.diag(eps)
        rows = np.vstack([delta[None], delta + e, delta - e])
        v = self.values(rows)
        grad = (v[1 : self.q + 1] - v[self.q + 1 :]) / (2.0 * eps)
        return float(v[0]), grad

    def hessian(self, delta: np.ndarray, eps: np.ndarray) -> np.ndarray:
        """Central-difference Hessian at ``delta`` with per-coordinate steps ``eps``."""
        q = self.q
        rows, index = [delta], {}
        for k in range(q):
            for s in (2, -2):
                index[k, s] = len(rows)
                step = np.zeros(q)
                step[k] = s * eps[k]
                rows.append(delta + step)
        for k in range(q):
            for m in range(k + 1, q):
                for sk in (1, -1):
                    for sm in (1, -1):
                        index[k, m, sk, sm] = len(rows)
                        step = np.zeros(q)
                        step[k], step[m] = sk * eps[k], sm * eps[m]
                        rows.append(delta + step)
        v = self.values(np.array(rows))
        hess = np.empty((q, q))
        for k in range(q):
            hess[k, k] = (v[index[k, 2]] - 2.0 * v[0] + v[index[k, -2]]) / (4.0 * eps[k] ** 2)
            for m in range(k + 1, q):
                mixed = (
                    v[index[k, m, 1, 1]]
                    - v[index[k, m, 1, -1]]
                    - v[index[k, m, -1, 1]]
                    + v[index[k, m, -1, -1]]
                ) / (4.0 * eps[k] * eps[m])
                hess[k, m] = hess[m, k] = mixed
        return hess

    def maximise(self, u0: np.ndarray, radius: float) -> tuple[np.ndarray, float]:
        """argmax of m over |δ|∞ ≤ radius, 0 ≤ u0 + δ ≤ 1: (δ, predicted gain)."""
        lo = np.maximum(-radius, -u0)
        hi = np.minimum(radius, 1.0 - u0)
        scale = np.maximum(hi - lo, 1e-300)
        eps = np.maximum(1e-7 * scale, 1e-12)
        m0 = float(self.values(np.zeros((1, self.q)))[0])

        def objective(t: np.ndarray) -> tuple[float, np.ndarray]:
            value, grad = self.value_and_gradient(lo + t * scale, eps)
            if not math.isfinite(value):
                return 1e300, np.zeros_like(t)
            return -(value - m0), -grad * scale

        start = np.clip(-lo / scale, 0.0, 1.0)
        found = minimize(
            objective,
            start,
            jac=True,
            method="L-BFGS-B",
            bounds=[(0.0, 1.0)] * self.q,
            options={"maxiter": 200, "ftol": 1e-12, "gtol": 1e-9},
        )
        delta = lo + np.clip(found.x, 0.0, 1.0) * scale
        gain = float(self.values(delta[None])[0]) - m0
        if not (math.isfinite(gain) and gain > 0.0):
            return np.zeros(self.q), 0.0
        return delta, gain


def _laplace_covariance(model: _Model, radius: float) -> np.ndarray:
    """(−∇²m)⁻¹ at δ = 0, steps adapted to the curvature; variance 1 where m is flat."""
    q = model.q
    eps = np.full(q, max(1e-3 * radius, 1e-8))
    cov = np.eye(q)
    for _ in range(2):
        neg = -model.hessian(np.zeros(q), eps)
        neg = 0.5 * (neg + neg.T)
        values, vectors = np.linalg.eigh(neg)
        floor = 1.0  # curvature of a unit-variance direction: flatter ones are capped at C_w
        values = np.maximum(values, floor)
        cov = (vectors / values) @ vectors.T
        eps = np.clip(0.5 * np.sqrt(np.diag(cov)), 1e-9, 0.05)
    return cov


def local_search(
    evaluator: SpectraEvaluator,
    bounds: np.ndarray,
    start: np.ndarray,
    max_evaluations: int,
    settings: LocalSearchSettings | None = None,
    on_evaluations: Callable[[np.ndarray, np.ndarray, float], None] | None = None,
) -> LocalSearchResult:
    """Trust-region Gauss–Newton ascent of log L from ``start`` (see the module docstring).

    Args:
        evaluator: the study's evaluator (spectra and the cheap log L of spectra).
        bounds: (2 x q) bounds of C_w, physical units.
        start: (q,) start point, physical units (e.g. the best evaluated one).
        max_evaluations: simulator evaluations this phase may use (>= q + 2 to do anything).
        settings: search settings (defaults if None).
        on_evaluations: called with (W (b x q) physical units, log L (b,), predicted gain)
            after every batch of simulator evaluations, so the caller records them.

    Returns:
        The :class:`LocalSearchResult` (unit-cube coordinates).
    """
    settings = settings or LocalSearchSettings()
    b = np.asarray(bounds, dtype=np.float64)
    span = b[1] - b[0]
    q = b.shape[1]

    def head(h: np.ndarray) -> np.ndarray:
        return evaluator.log_likelihood_of(h, exact=True)

    used = 0

    def simulate(U: np.ndarray, gain: float) -> tuple[np.ndarray, np.ndarray]:
        nonlocal used
        W = b[0] + U * span
        H = np.asarray(evaluator.spectra(W), dtype=np.float64)
        ok = np.all(np.isfinite(H.reshape(len(W), -1)), axis=1)
        y = np.full(len(W), np.nan)
        if ok.any():
            y[ok] = np.asarray(evaluator.log_likelihood_of(H[ok]), dtype=np.float64)
        used += len(W)
        if on_evaluations is not None:
            on_evaluations(W, y, gain)
        return H, y

    def difference(u: np.ndarray, h: np.ndarray, radius: float) -> np.ndarray | None:
        """(q x n x C x F) forward-difference J at u (q runs), None if a run failed."""
        step = np.clip(
            settings.difference_step * radius,
            settings.min_difference_step,
            settings.max_difference_step,
        )
        direction = np.where(u + step <= 1.0, 1.0, -1.0)  # forward, or backward at 1
        U = _round(u[None] + np.diag(direction * step))
        H, _ = simulate(U, math.nan)
        if not np.all(np.isfinite(H)):
            return None
        du = (U - u[None])[np.arange(q), np.arange(q)]
        return (H - h[None]) / du[:, None, None, None]

    u = np.clip((np.asarray(start, dtype=np.float64) - b[0]) / span, 0.0, 1.0)
    # the start point was evaluated already: its spectra are looked up (at exactly the
    # evaluated w, so that a store finds them), not counted
    w_start = np.asarray(start, dtype=np.float64)
    h = np.asarray(evaluator.spectra(w_start[None]), dtype=np.float64)[0]
    if not np.all(np.isfinite(h)):
        return LocalSearchResult(u, math.nan, np.eye(q), 0, "failed", 0)
    value = float(evaluator.log_likelihood_of(h[None])[0])
    radius = settings.initial_radius
    jac: np.ndarray | None = None
    stop = "budget"
    iterations = 0
    while True:
        if jac is None:
            if used + q + 1 > max_evaluations:
                stop = "budget"
                break
            jac = difference(u, h, radius)
            if jac is None:
                radius /= 4.0
                if radius < settings.min_radius:
                    stop = "failed"
                    break
                continue
        iterations += 1
        model = _Model(head, h, jac)
        delta, predicted = model.maximise(u, radius)
        at_radius = bool(np.max(np.abs(delta)) >= 0.99 * radius)
        if (
            predicted <= 0.0
            or not np.any(delta)
            or (predicted < settings.tolerance and not at_radius)
        ):
            stop = "converged"  # the model's maximum is inside the radius and within tolerance
            break
        if used + 1 > max_evaluations:
            stop = "budget"
            break
        u_new = _round(u + delta)
        H, y = simulate(u_new[None], predicted)
        actual = float(y[0]) - value if math.isfinite(y[0]) else -math.inf
        ratio = actual / predicted
        logger.info(
            "local step %d: radius %.3g predicted %+.4g actual %+.4g nats",
            iterations,
            radius,
            predicted,
            actual,
        )
        if ratio >= settings.accept:
            u, h, value = u_new, H[0], float(y[0])
            jac = None
            if ratio > 0.75 and at_radius:
                radius = min(2.0 * radius, 1.0)
            elif ratio < 0.25:
                radius = max(np.max(np.abs(delta)) / 4.0, settings.min_radius)
            if predicted < settings.tolerance:
                stop = "converged"
                break
        else:
            radius = np.max(np.abs(delta)) / 4.0
            if radius < settings.min_radius:
                stop = "radius"
                break
    if jac is None and used + q <= max_evaluations:
        jac = difference(u, h, radius)  # the mode moved after the last differencing
    covariance = np.eye(q) if jac is None else _laplace_covariance(_Model(head, h, jac), radius)
    return LocalSearchResult(u, value, covariance, used, stop, iterations)
