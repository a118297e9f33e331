"""Posterior summaries of MCMC draws: joint MAP (eq. 5), marginal MAP (eq. 6), intervals.

- joint MAP: argmax of the (surrogate) posterior density over C_w, started from the
  best MCMC draws and polished by L-BFGS-B on the surrogate (eq. 5);
- marginal MAP: argmax of a kernel density estimate of each marginal (eq. 6);
- the paper's 95 % interval [w_marg − δ, w_marg + δ] with δ the 95 % quantile of
  |W_k − w_marg| (so it holds 95 % of the marginal mass; clipped to C_w, which
  changes nothing as there is no mass outside);
- equal-tailed 95 % intervals (2.5 % and 97.5 % quantiles);
- split R-hat and ESS per component (Pyro's diagnostics).

The KDE is a Gaussian kernel (Silverman bandwidth) evaluated on a fine binned grid,
with reflection at the bounds of C_w so that mass piled against a bound is not lost.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from scipy import optimize
from scipy.ndimage import gaussian_filter1d

from susp_bo.calibration.design import from_unit
from susp_bo.calibration.mcmc import chain_diagnostics
from susp_bo.rig.schema import repeated, repeated_phrase

_BINS = 2048


def kde_bandwidth(x: np.ndarray) -> float:
    """Silverman's rule 0.9 min(sd, IQR/1.34) n^(−1/5) (> 0 even for constant x).

    Constant draws (a pinned parameter, sd 0) take a spread of 1e-6 of the value's
    magnitude (at least 1e-6). Draws so narrow that the rule's bandwidth is not resolvable
    in float64 around their value (sd of a few ulps, e.g. from rounding in the mean) get
    the least resolvable bandwidth instead, so that the binned KDE's grid
    (:func:`marginal_density`) has distinct bins.
    """
    x = np.asarray(x, dtype=np.float64)
    sd = float(np.std(x))
    iqr = float(np.subtract(*np.percentile(x, [75, 25])))
    spread = min(sd, iqr / 1.34) if iqr > 0 else sd
    if not spread > 0:
        spread = max(abs(float(np.mean(x))), 1.0) * 1e-6
    return max(0.9 * spread * x.size ** (-0.2), _resolvable_bandwidth(x))


def _resolvable_bandwidth(x: np.ndarray) -> float:
    """The least bandwidth whose binned KDE grid (12 h over ``_BINS`` bins around ``x``)
    has bins 16 ulps of the values wide; narrower ones are not distinct in float64."""
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    return 16.0 * float(np.spacing(scale)) * _BINS / 12.0


def marginal_density(
    samples: np.ndarray, grid: np.ndarray, bounds: Sequence[float], bandwidth: float | None = None
) -> np.ndarray:
    """Reflected Gaussian KDE of one marginal, evaluated on ``grid``.

    Args:
        samples: (n,) draws of one component, physical units.
        grid: (g,) evaluation points.
        bounds: (lower, upper) of the component; the density is 0 outside.
        bandwidth: kernel standard deviation; default Silverman's rule.

    Returns:
        (g,) density values (integrates to 1 over the bounds).
    """
    x = np.asarray(samples, dtype=np.float64)
    lo_b, hi_b = float(bounds[0]), float(bounds[1])
    h = kde_bandwidth(x) if bandwidth is None else float(bandwidth)
    lo = max(lo_b, float(x.min()) - 6.0 * h)
    hi = min(hi_b, float(x.max()) + 6.0 * h)
    if hi <= lo:
        hi = lo + 12.0 * h
    counts, edges = np.histogram(x, bins=_BINS, range=(lo, hi))
    width = edges[1] - edges[0]
    pad = min(_BINS, int(np.ceil(6.0 * h / width)) + 1)
    left = counts[:pad][::-1] if lo <= lo_b else np.zeros(pad)
    right = counts[-pad:][::-1] if hi >= hi_b else np.zeros(pad)
    padded = np.concatenate([left, counts, right]).astype(np.float64)
    smooth = gaussian_filter1d(padded, sigma=h / width, mode="constant", truncate=6.0)[pad:-pad]
    centres = 0.5 * (edges[1:] + edges[:-1])
    if not smooth.sum() > 0.0:  # no draw inside the bounds
        return np.zeros_like(np.asarray(grid, dtype=np.float64))
    dens = smooth / (smooth.sum() * width)
    g = np.asarray(grid, dtype=np.float64)
    out = np.interp(g, centres, dens, left=dens[0], right=dens[-1])
    out[(g < lo) | (g > hi)] = 0.0
    return out


def marginal_map(samples: np.ndarray, bounds: Sequence[float]) -> float:
    """Mode of the marginal KDE (eq. 6), on a 4001-point grid over the sample range."""
    x = np.asarray(samples, dtype=np.float64)
    h = kde_bandwidth(x)
    grid = np.linspace(max(bounds[0], x.min() - 3 * h), min(bounds[1], x.max() + 3 * h), 4001)
    return float(grid[np.argmax(marginal_density(x, grid, bounds, h))])


@dataclass(frozen=True)
class PosteriorSummary:
    """Summary of the posterior in physical units.

    Attributes:
        names: (q,) parameter names.
        joint_map: (q,) joint MAP, eq. 5.
        marginal_map: (q,) marginal MAPs, eq. 6.
        interval95: (q x 2) the paper's interval [w_marg − δ, w_marg + δ] (95 % of the mass).
        equal_tailed95: (q x 2) 2.5 % and 97.5 % quantiles.
        mean: (q,) posterior mean.
        sd: (q,) posterior standard deviation.
        r_hat: (q,) split R-hat.
        ess: (q,) effective sample size.
    """

    names: tuple[str, ...]
    joint_map: np.ndarray
    marginal_map: np.ndarray
    interval95: np.ndarray
    equal_tailed95: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    r_hat: np.ndarray
    ess: np.ndarray

    def __post_init__(self) -> None:
        q = len(self.names)
        for name in ("joint_map", "marginal_map", "mean", "sd", "r_hat", "ess"):
            if np.shape(getattr(self, name)) != (q,):
                raise ValueError(f"{name}: shape {np.shape(getattr(self, name))}, expected ({q},)")
        for name in ("interval95", "equal_tailed95"):
            if np.shape(getattr(self, name)) != (q, 2):
                raise ValueError(
                    f"{name}: shape {np.shape(getattr(self, name))}, expected ({q}, 2)"
                )
            bounds = np.asarray(getattr(self, name), dtype=np.float64)
            inverted = [n for n, (lo, hi) in zip(self.names, bounds, strict=True) if not lo <= hi]
            if inverted:  # also NaN: an interval must have ordered, comparable ends
                raise ValueError(
                    f"{name}: not an interval (lower > upper, or NaN) for {', '.join(inverted)}; "
                    "expected rows (lower, upper) with lower <= upper"
                )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of plain lists (physical units)."""
        return {
            "parameters": list(self.names),
            "joint_map": [float(v) for v in self.joint_map],
            "marginal_map": [float(v) for v in self.marginal_map],
            "interval95": [[float(a), float(b)] for a, b in self.interval95],
            "equal_tailed95": [[float(a), float(b)] for a, b in self.equal_tailed95],
            "mean": [float(v) for v in self.mean],
            "sd": [float(v) for v in self.sd],
            "r_hat": [float(v) for v in self.r_hat],
            "ess": [float(v) for v in self.ess],
        }


def joint_map(
    draws_unit: np.ndarray,
    log_density: Callable[[torch.Tensor], torch.Tensor],
    n_starts: int = 8,
) -> np.ndarray:
    """Joint MAP in the unit cube (eq. 5): best draws polished by L-BFGS-B.

    Args:
        draws_unit: (n x q) draws in the unit cube.
        log_density: unit-cube (m x q) tensor -> (m,) log posterior density (differentiable).
        n_starts: number of best draws used as starting points.

    Returns:
        (q,) maximiser in the unit cube.
    """
    x = torch.as_tensor(draws_unit, dtype=torch.float64)
    with torch.no_grad():
        values = torch.cat([log_density(chunk) for chunk in torch.split(x, 65536)])
    starts = x[torch.argsort(values, descending=True)[:n_starts]].numpy()
    q = x.shape[1]

    def fun(u: np.ndarray) -> tuple[float, np.ndarray]:
        t = torch.tensor(u[None, :], dtype=torch.float64, requires_grad=True)
        with torch.enable_grad():
            v = -log_density(t)[0]
            v.backward()
        return v.item(), t.grad.detach().numpy()[0].astype(np.float64)

    best_u, best_v = starts[0], float(-values.max())
    for s in starts:
        res = optimize.minimize(fun, s, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * q)
        if np.isfinite(res.fun) and res.fun < best_v:
            best_u, best_v = res.x, float(res.fun)
    return np.clip(best_u, 0.0, 1.0)


def summarize(
    draws_unit: np.ndarray,
    bounds: np.ndarray,
    names: Sequence[str],
    log_density: Callable[[torch.Tensor], torch.Tensor] | None = None,
) -> PosteriorSummary:
    """Posterior summary from MCMC draws.

    Args:
        draws_unit: (n_chains x n_draws x q) draws in the unit cube.
        bounds: (2 x q) physical bounds.
        names: (q,) parameter names.
        log_density: unit-cube log posterior for the joint MAP; without it the best of the
            draws is not known and the joint MAP is taken as the draw mean's nearest draw.

    Returns:
        The :class:`PosteriorSummary` in physical units. A constant component (a pinned
        parameter) is summarised as that value; its R-hat and ESS are NaN.

    Raises:
        ValueError: shapes that disagree, fewer than 4 draws per chain (the split R-hat),
            draws outside [0, 1] or NaN, or a repeated name.
    """
    d = np.asarray(draws_unit, dtype=np.float64)
    bounds = np.asarray(bounds, dtype=np.float64)
    check_names(names)
    if d.ndim != 3 or bounds.ndim != 2 or d.shape[2] != bounds.shape[1] or len(names) != d.shape[2]:
        raise ValueError(f"draws_unit: shape {d.shape}, expected (chains x draws x {len(names)})")
    if d.shape[1] < 4:
        raise ValueError(
            f"draws_unit: {d.shape[1]} draws per chain is not allowed; expected >= 4 (the split "
            "R-hat halves every chain)"
        )
    if not np.all((d >= 0.0) & (d <= 1.0)):  # NaN fails both
        bad = d[~((d >= 0.0) & (d <= 1.0))]
        raise ValueError(
            f"draws_unit: {bad.size} values outside the unit cube [0, 1] (e.g. "
            f"{float(bad[0])!r}) are not allowed; expected unit-cube draws (physical ones map "
            "to it by the bounds)"
        )
    q = d.shape[2]
    flat = from_unit(d.reshape(-1, q), bounds)
    r_hat, ess = chain_diagnostics(torch.as_tensor(d))
    if log_density is not None:
        jmap = from_unit(joint_map(d.reshape(-1, q), log_density), bounds)
    else:
        centre = flat.mean(0)
        sd = flat.std(0)
        sd = np.where(sd > 0.0, sd, 1.0)  # a constant parameter adds 0 to every distance
        jmap = flat[np.argmin(np.sum(((flat - centre) / sd) ** 2, axis=1))]
    mmap = np.array([marginal_map(flat[:, k], bounds[:, k]) for k in range(q)])
    delta = np.quantile(np.abs(flat - mmap), 0.95, axis=0)
    interval = np.column_stack(
        [np.maximum(mmap - delta, bounds[0]), np.minimum(mmap + delta, bounds[1])]
    )
    equal = np.quantile(flat, [0.025, 0.975], axis=0).T
    return PosteriorSummary(
        names=tuple(names),
        joint_map=jmap,
        marginal_map=mmap,
        interval95=interval,
        equal_tailed95=equal,
        mean=flat.mean(0),
        sd=flat.std(0),
        r_hat=r_hat.numpy(),
        ess=ess.numpy(),
    )


def check_names(names: Sequence[str], argument: str = "names") -> None:
    """Refuses parameter names that are not non-empty strings, or that repeat (each names one
    variable of the results: a column of the summary, a key of ``result.json``).

    Raises:
        ValueError: naming ``argument`` and the first bad or repeated name.
    """
    for name in names:
        if not isinstance(name, str) or not name.strip():
            raise ValueError(
                f"{argument}: {list(names)!r} is not allowed: {name!r} is not a parameter "
                "name; expected non-empty strings"
            )
    twice = repeated(names)
    if twice:
        raise ValueError(
            f"{argument}: {list(names)!r} is not allowed: {repeated_phrase(twice)} given more "
            "than once; expected distinct parameter names"
        )


def to_inference_data(draws: np.ndarray, names: Sequence[str]) -> Any:
    """ArviZ ``InferenceData`` with one posterior variable per parameter.

    Args:
        draws: (n_chains x n_draws x q) draws in physical units.
        names: (q,) parameter names.

    Returns:
        ``arviz.InferenceData`` (requires the optional ``arviz`` dependency).

    Raises:
        ValueError: a shape that disagrees with ``names``, or a repeated name (ArviZ would
            keep one variable of two named alike).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # arviz announces its refactor on import
        import arviz as az

        d = np.asarray(draws, dtype=np.float64)
        check_names(names)
        if d.ndim != 3 or d.shape[2] != len(names):
            raise ValueError(f"draws: shape {d.shape}, expected (chains x draws x {len(names)})")
        return az.from_dict(posterior={name: d[:, :, k] for k, name in enumerate(names)})
