"""Held-out check of the surrogate posterior against direct log L evaluations.

The surrogate's own uncertainty can be wrong: with few evaluations a long fitted
lengthscale makes the GP confidently extrapolate a bowl that is too steep along a
weakly identified direction, and the posterior comes out too narrow (seen on the
reference rig's yaw damper at 120 evaluations). The GP cannot see this; only new
evaluations can.

The check spends the last ``n`` evaluations of the budget at the edges of the
current surrogate posterior: along its principal directions (largest spread
first), at posterior draws whose projection sits at the 2.5 % and 97.5 % quantiles
(the ends of a 95 % interval; among the draws near each quantile, the one of
highest surrogate density, so a curved posterior is checked on its ridge, not at
an empty corner). It then compares the true log L there with what the surrogate
predicted *before* seeing them:

    error_i = log L(w_i) − log L̃(w_i)     (nats)

A positive error means the true likelihood is higher at the edge than the
surrogate said, i.e. the posterior is really wider there (surrogate
overconfident); negative, narrower. The verdict is ``"ok"`` when every |error| is
within the tolerance (default 1 nat: a factor e in density at the interval's end),
otherwise ``"overconfident"`` or ``"underconfident"`` by the sign of the largest
error. The checked points then join the data, so the final surrogate uses them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import torch

Verdict = Literal["ok", "overconfident", "underconfident"]
_EDGE_QUANTILES = (0.025, 0.16, 0.3)
"""Lower quantiles of the successive rounds over the q directions (upper = 1 − lower):
the 95 % interval's ends first, then ±1 sd, then inner points when n > 2 q."""
_WINDOW = 0.05  # half-width of the projection window at a quantile, in projected sd


@dataclass(frozen=True)
class SurrogateCheck:
    """Outcome of the held-out check.

    Attributes:
        points_unit: (n x q) checked points in the unit cube.
        predicted: (n,) surrogate log L̃ predicted before the evaluations (nats).
        predicted_sd: (n,) the GP's standard deviation of log L̃ there (nats).
        observed: (n,) log L evaluated there (NaN = failed run).
        tolerance_nats: largest |observed − predicted| still called "ok".
    """

    points_unit: np.ndarray
    predicted: np.ndarray
    predicted_sd: np.ndarray
    observed: np.ndarray
    tolerance_nats: float

    @property
    def errors(self) -> np.ndarray:
        """(n,) observed − predicted log L (nats); NaN where the run failed."""
        return self.observed - self.predicted

    @property
    def max_abs_error(self) -> float:
        """Largest |error| over the successful points (nats; NaN if none succeeded)."""
        e = self.errors[np.isfinite(self.errors)]
        return float(np.max(np.abs(e))) if e.size else math.nan

    @property
    def verdict(self) -> Verdict:
        """Either "ok" or the direction of the largest error beyond the tolerance."""
        e = self.errors[np.isfinite(self.errors)]
        if e.size == 0 or np.max(np.abs(e)) <= self.tolerance_nats:
            return "ok"
        return "overconfident" if e[np.argmax(np.abs(e))] > 0 else "underconfident"

    def line(self) -> str:
        """One-line summary for logs."""
        return (
            f"surrogate check at {len(self.observed)} posterior-edge points: {self.verdict}"
            f" (max |log L − predicted| {self.max_abs_error:.2f} nats,"
            f" tolerance {self.tolerance_nats:g})"
        )

    def to_dict(self, bounds: np.ndarray) -> dict[str, Any]:
        """JSON-ready summary; points in physical units given the (2 x q) ``bounds``."""
        lo, hi = bounds[0], bounds[1]
        return {
            "verdict": self.verdict,
            "max_abs_error_nats": self.max_abs_error,
            "tolerance_nats": self.tolerance_nats,
            "points": (lo + self.points_unit * (hi - lo)).tolist(),
            "predicted_log_likelihood": self.predicted.tolist(),
            "predicted_sd": self.predicted_sd.tolist(),
            "observed_log_likelihood": self.observed.tolist(),
        }


def edge_points(draws: torch.Tensor, log_density: torch.Tensor, n: int) -> torch.Tensor:
    """Posterior-edge points along the principal directions of ``draws``.

    Args:
        draws: (m x q) posterior draws (unit cube).
        log_density: (m,) surrogate log density of the draws (picks the ridge point).
        n: number of points wanted (>= 1); pairs of ends along the first ⌈n/2⌉
            directions, largest variance first (an odd n drops the last upper end);
            beyond 2 q points further rounds use the 16/84 % and then 30/70 % quantiles.

    Returns:
        (n x q) distinct draws at the projected quantiles (within
        0.05 projected sd; the one of highest ``log_density`` there).
    """
    if n < 1:
        raise ValueError(f"n: {n} must be >= 1")
    x = torch.as_tensor(draws, dtype=torch.float64)
    m, q = x.shape
    centred = x - x.mean(0)
    cov = centred.T @ centred / max(1, m - 1)
    eigval, eigvec = torch.linalg.eigh(cov)
    order = torch.argsort(eigval, descending=True)
    chosen: list[int] = []
    taken = torch.zeros(m, dtype=torch.bool)  # draws equal to a chosen one (MH repeats draws)
    for k in range(math.ceil(n / 2)):
        proj = centred @ eigvec[:, order[k % q]]
        window = _WINDOW * proj.std()
        lower = _EDGE_QUANTILES[min(k // q, len(_EDGE_QUANTILES) - 1)]
        for qt in (lower, 1.0 - lower):
            if len(chosen) == n:
                break
            distance = (proj - torch.quantile(proj, qt)).abs()
            distance[taken] = math.inf
            near = torch.nonzero(distance <= window).reshape(-1)
            if near.numel() == 0:
                near = torch.argmin(distance).reshape(1)
            pick = int(near[torch.argmax(log_density[near])])
            chosen.append(pick)
            taken |= torch.all(x == x[pick], dim=1)
    return x[chosen]
