"""The paper's Fig. 2: marginal posterior pdfs, each zoomed to where its mass is."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from susp_bo.calibration.posterior import PosteriorSummary, marginal_density
from susp_bo.posterior_plots.common import (
    C_ACCEPT,
    C_DENSITY,
    C_INTERVAL,
    C_JOINT,
    LABEL_ACCEPTABLE,
    LABEL_DENSITY,
    LABEL_INTERVAL,
    LABEL_JOINT_MAP,
    LABEL_MARGINAL_MAP,
    LABEL_OUTSIDE,
    LABEL_REFERENCE,
    PAIR_TICKS,
    View,
    band_array,
    check_inputs,
    draws_matrix,
    edge_note,
    legend_handles,
    plain_axis,
    pretty_name,
    unit_list,
    verdict_suptitle,
    views_of,
)
from susp_bo.units import format_quantity, format_range, format_values


def draw_marginal(
    ax: Any,
    x: np.ndarray,
    summary: PosteriorSummary,
    k: int,
    view: View,
    reference: np.ndarray | None,
    band: np.ndarray,
    compact: bool = False,
) -> set[str]:
    """One marginal pdf in its zoom window; returns the legend labels it used."""
    used = {LABEL_DENSITY, LABEL_INTERVAL, LABEL_MARGINAL_MAP}
    lb, ub = view.bounds
    grid = np.linspace(max(view.lo, lb), min(view.hi, ub), 601)
    dens = marginal_density(x, grid, (lb, ub)) * view.factor  # per prefixed unit
    gs = view.s(grid)
    top = float(np.max(dens)) if dens.size and np.max(dens) > 0 else 1.0
    notes: list[tuple[str, bool, str]] = []  # things beyond the view: text, right?, colour
    inside = (grid >= summary.interval95[k, 0]) & (grid <= summary.interval95[k, 1])
    ax.fill_between(gs, 0.0, dens, where=inside, color=C_INTERVAL, lw=0, zorder=1)
    ax.plot(gs, dens, color=C_DENSITY, lw=1.6, zorder=3)
    mm = float(summary.marginal_map[k])
    ax.plot(
        [view.s(mm)] * 2,
        [0.0, float(np.interp(mm, grid, dens))],
        color=C_DENSITY,
        ls="--",
        lw=1.2,
        zorder=3,
    )
    ax.plot(view.s(summary.joint_map[k]), 0.0, "v", color=C_JOINT, ms=8, zorder=5, clip_on=False)
    used.add(LABEL_JOINT_MAP)
    if np.all(np.isfinite(band[:, k])):
        ax.axvspan(*view.s(band[:, k]), color=C_ACCEPT, alpha=0.15, lw=0, zorder=0)
        used.add(LABEL_ACCEPTABLE)
        a, b = band[:, k]
        if b < view.lo or a > view.hi:  # the whole band is out of view
            text = f"acceptable {format_range(a, b, view.base_unit)}"
            notes.append((text, a > view.hi, C_ACCEPT))
    for edge, outside in ((lb, (view.lo, lb)), (ub, (ub, view.hi))):
        if outside[1] > outside[0]:
            ax.axvspan(*view.s(outside), facecolor="0.9", hatch="///", edgecolor="0.6", lw=0)
            ax.axvline(view.s(edge), color="0.4", lw=1.0)
            used.add(LABEL_OUTSIDE)
    if reference is not None and np.isfinite(reference[k]):
        used.add(LABEL_REFERENCE)
        r = float(reference[k])
        if view.lo <= r <= view.hi:
            ax.axvline(view.s(r), color="black", ls="-.", lw=1.3, zorder=4)
        else:
            text = f"reference {format_quantity(r, view.base_unit)}"
            notes.append((text, r > view.hi, "black"))
    ax.set_xlim(view.s(view.lo), view.s(view.hi))
    for n, (text, right, color) in enumerate(notes):  # above the curve: it ends at 0.6
        edge_note(ax, text, right, 0.92 - 0.14 * n, color)
    ax.set_ylim(0.0, (1.65 if notes else 1.15) * top)
    ax.set_yticks([])
    plain_axis(ax.xaxis)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=PAIR_TICKS if compact else 6))
    return used


def marginals_figure(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    reference: np.ndarray | None = None,
    components: Sequence[int] | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> Figure:
    """The paper's Fig. 2, each marginal zoomed to its mass; returns the open figure.

    Args:
        draws: (draws x q) posterior draws, physical units.
        summary: posterior summary.
        bounds: (2 x q) bounds of C_w.
        reference: (q,) reference parameters or None.
        components: indices to plot (default all).
        units: (q,) SI units of the parameters, or None.
        acceptable: (2 x q) acceptable band, NaN where none; or None.
        reliability: ``result.json["reliability"]`` dict, or None.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    check_inputs(summary, bounds, reference, units, acceptable)
    q = len(summary.names)
    draws = draws_matrix(draws, summary.names)
    comps = list(range(q)) if components is None else list(components)
    unit = unit_list(units, q)
    band = band_array(acceptable, q)
    views = views_of(draws, summary, bounds, units, reference)
    ncol = min(3, len(comps))
    nrow = int(np.ceil(len(comps) / ncol))
    fig, axes = plt.subplots(
        nrow, ncol, figsize=(4.6 * ncol, 3.3 * nrow + 1.4), squeeze=False, constrained_layout=True
    )
    used: set[str] = set()
    for ax, k in zip(axes.ravel(), comps):
        view = views[k]
        used |= draw_marginal(ax, draws[:, k], summary, k, view, reference, band)
        numbers, pu = format_values([summary.marginal_map[k], *summary.interval95[k]], unit[k])
        ax.set_title(
            f"{pretty_name(summary.names[k])}\nMAP {numbers[0]} [{numbers[1]}, {numbers[2]}] {pu}",
            fontsize=9.5,
        )
        ax.set_xlabel(
            f"[{view.unit}]   C_w: {format_range(*view.bounds, unit[k])}"
            f" ({100 * view.share:.0f} % in view)"
            if view.unit
            else f"C_w: {format_range(*view.bounds, '')} ({100 * view.share:.0f} % in view)",
            fontsize=8.5,
        )
    for ax in axes.ravel()[len(comps) :]:
        ax.set_visible(False)
    fig.legend(handles=legend_handles(used), loc="outside lower center", ncol=4, fontsize=9)
    verdict_suptitle(fig, "Marginal posteriors (Fig. 2)", reliability)
    return fig
