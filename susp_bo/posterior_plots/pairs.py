"""Pair plot: 1-D marginals on the diagonal, 50 % and 90 % highest-density regions below."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from scipy.ndimage import gaussian_filter

from susp_bo.calibration.posterior import PosteriorSummary
from susp_bo.posterior_plots.common import (
    C_JOINT,
    HPD50_COLOR,
    HPD90_COLOR,
    LABEL_HPD50,
    LABEL_HPD90,
    LABEL_JOINT_MAP,
    LABEL_OUTSIDE,
    LABEL_REFERENCE,
    PAIR_TICKS,
    View,
    axis_label,
    band_array,
    check_inputs,
    draws_matrix,
    legend_handles,
    plain_axis,
    verdict_suptitle,
    views_of,
)
from susp_bo.posterior_plots.marginals import draw_marginal


def hpd_levels(density: np.ndarray, total: float, masses: Sequence[float]) -> list[float]:
    """Density thresholds whose super-level sets hold ``masses`` of the probability.

    Args:
        density: cell probabilities (any shape), summing to at most ``total``.
        total: the whole probability (cells outside the grid count in it).
        masses: e.g. (0.5, 0.9).

    Returns:
        One threshold per mass (higher mass → lower threshold).
    """
    p = np.sort(np.asarray(density, dtype=np.float64).ravel())[::-1]
    cum = np.cumsum(p) / total
    out = []
    for m in masses:
        i = min(int(np.searchsorted(cum, m)), p.size - 1)
        out.append(float(p[i]))
    return out


def _padded(h: np.ndarray, axis: int, width: int, reflect: tuple[bool, bool]) -> np.ndarray:
    """``h`` padded by ``width`` cells on both ends of ``axis``: mirrored at a C_w bound
    (so the smoothing keeps the mass inside C_w), zeros elsewhere."""
    h = np.moveaxis(h, axis, 0)
    width = min(width, h.shape[0])
    zeros = np.zeros((width, *h.shape[1:]))
    left = h[:width][::-1] if reflect[0] else zeros
    right = h[-width:][::-1] if reflect[1] else zeros
    return np.moveaxis(np.concatenate([left, h, right]), 0, axis)


def density2d(
    x: np.ndarray, y: np.ndarray, vx: View, vy: View, bins: int = 72
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed 2-D histogram of the draws within the views and C_w.

    Gaussian smoothing with Scott's bandwidth (sd · n^(-1/6) per axis), reflected at the
    bounds of C_w that are in view.

    Args:
        x: (n,) draws of the horizontal parameter, physical units.
        y: (n,) draws of the vertical parameter.
        vx: view of the horizontal parameter.
        vy: view of the vertical parameter.
        bins: cells per axis.

    Returns:
        ``(cx, cy, p)``: (bins,) cell centres of each axis (physical units) and the
        (bins x bins) cell probabilities (rows: y), as a fraction of all n draws.
    """
    (x0, x1), (y0, y1) = vx.inner, vy.inner
    ex = np.linspace(x0, x1, bins + 1)
    ey = np.linspace(y0, y1, bins + 1)
    h, _, _ = np.histogram2d(x, y, bins=[ex, ey])
    n = max(x.size, 1)
    sx = max(0.8, float(np.std(x)) * n ** (-1 / 6) / (ex[1] - ex[0])) if n > 1 else 1.0
    sy = max(0.8, float(np.std(y)) * n ** (-1 / 6) / (ey[1] - ey[0])) if n > 1 else 1.0
    px, py = int(np.ceil(4 * sx)) + 1, int(np.ceil(4 * sy)) + 1
    h = _padded(h, 0, px, (x0 <= vx.bounds[0], x1 >= vx.bounds[1]))
    h = _padded(h, 1, py, (y0 <= vy.bounds[0], y1 >= vy.bounds[1]))
    smooth = gaussian_filter(h, sigma=(sx, sy), mode="constant", truncate=4.0)
    smooth = smooth[px : px + bins, py : py + bins]
    return 0.5 * (ex[1:] + ex[:-1]), 0.5 * (ey[1:] + ey[:-1]), smooth.T / n


def _draw_pair(
    ax: Any,
    x: np.ndarray,
    y: np.ndarray,
    jmap: tuple[float, float],
    vx: View,
    vy: View,
    reference: tuple[float, float] | None,
) -> set[str]:
    """One 2-D panel: 50/90 % HPD regions, joint MAP, reference; returns the labels used."""
    used = {LABEL_JOINT_MAP}
    cx, cy, p = density2d(x, y, vx, vy)
    l90, l50 = hpd_levels(p, 1.0, (0.9, 0.5))
    top = float(p.max())
    if top > l90 > 0.0:
        levels = sorted({l90, min(l50, top * 0.999), top * 1.0001})
        colors = [HPD90_COLOR, HPD50_COLOR][: len(levels) - 1]
        ax.contourf(vx.s(cx), vy.s(cy), p, levels=levels, colors=colors)
        ax.contour(vx.s(cx), vy.s(cy), p, levels=levels[:-1], colors="#08519c", linewidths=0.7)
        used |= {LABEL_HPD50, LABEL_HPD90}
    for view, span in ((vx, ax.axvspan), (vy, ax.axhspan)):
        for outside in ((view.lo, view.bounds[0]), (view.bounds[1], view.hi)):
            if outside[1] > outside[0]:
                span(*view.s(outside), facecolor="0.9", hatch="///", edgecolor="0.6", lw=0)
                used.add(LABEL_OUTSIDE)
    ax.plot(vx.s(jmap[0]), vy.s(jmap[1]), "v", color=C_JOINT, ms=6, zorder=5)
    if reference is not None:
        rx, ry = reference
        if vx.lo <= rx <= vx.hi and vy.lo <= ry <= vy.hi:
            ax.plot(vx.s(rx), vy.s(ry), "s", color="black", ms=5, zorder=5, mfc="none", mew=1.5)
            used.add(LABEL_REFERENCE)
    ax.set_xlim(vx.s(vx.lo), vx.s(vx.hi))
    ax.set_ylim(vy.s(vy.lo), vy.s(vy.hi))
    for axis in (ax.xaxis, ax.yaxis):
        plain_axis(axis)
        axis.set_major_locator(MaxNLocator(nbins=PAIR_TICKS))
    return used


def pairs_figure(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    reference: np.ndarray | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> Figure:
    """Pair plot: 1-D marginals on the diagonal, 50/90 % HPD regions below; the open figure.

    Args:
        draws: (draws x q) posterior draws, physical units.
        summary: posterior summary.
        bounds: (2 x q) bounds of C_w.
        reference: (q,) reference parameters or None.
        units: (q,) SI units of the parameters, or None.
        acceptable: (2 x q) acceptable band, NaN where none; or None (shaded on the diagonal).
        reliability: ``result.json["reliability"]`` dict, or None.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    check_inputs(summary, bounds, reference, units, acceptable)
    q = len(summary.names)
    d = draws_matrix(draws, summary.names)
    band = band_array(acceptable, q)
    views = views_of(d, summary, bounds, units, reference)
    size = max(7.0, 2.1 * q + 1.2)
    fig, axes = plt.subplots(q, q, figsize=(size, size), squeeze=False, constrained_layout=True)
    used: set[str] = set()
    for i in range(q):
        for j in range(q):
            ax = axes[i, j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                used |= draw_marginal(ax, d[:, i], summary, i, views[i], reference, band, True)
            else:
                ref = None if reference is None else (reference[j], reference[i])
                jmap = (summary.joint_map[j], summary.joint_map[i])
                used |= _draw_pair(ax, d[:, j], d[:, i], jmap, views[j], views[i], ref)
            ax.tick_params(labelsize=7.5)
            if i == q - 1:
                ax.set_xlabel(axis_label(summary.names[j], views[j], 18), fontsize=8.5)
            else:
                ax.tick_params(labelbottom=False)
            if j == 0 and i > 0:
                ax.set_ylabel(axis_label(summary.names[i], views[i], 18), fontsize=8.5)
            elif j > 0:
                ax.tick_params(labelleft=False)
    if q == 1:
        axes[0, 0].set_xlabel(axis_label(summary.names[0], views[0], 18), fontsize=8.5)
    handles = legend_handles(used, pairs=True)
    if q > 1:  # in the empty upper triangle
        legend = axes[0, q - 1].legend(
            handles=handles,
            loc="upper right",
            borderaxespad=0.0,
            fontsize=8.5,
            title="axes zoomed to the posterior mass",
            title_fontsize=8.5,
        )
        legend.set_in_layout(False)  # may reach into the empty cells; keep the grid even
    else:
        fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=8.5)
    verdict_suptitle(fig, "Posterior pairs", reliability)
    return fig
