"""Posterior figures (matplotlib, Agg backend, saved as files).

:func:`posterior_figures` writes all three as PNG files into a folder.

- :func:`plot_parameters` — the paper's Fig. 1: per component, on the
  normalised scale [0, 1] of C_w, the joint MAP (red triangle), the marginal MAP
  (blue circle) with its 95 % interval (blue line) and the reference (black square)
  when known;
- :func:`plot_marginals` — the paper's Fig. 2: marginal posterior pdfs (KDE) with the
  95 % interval bounds (dotted) and the reference (dash-dot);
- :func:`plot_pairs` — pair plot: marginal pdfs on the diagonal, 2-D histograms of
  the draws below it, joint MAP and reference marked.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from susp_bo.calibration.posterior import PosteriorSummary, marginal_density

FIG1_NAME = "fig1_parameters.png"
FIG2_NAME = "fig2_marginals.png"
PAIRS_NAME = "pairs.png"


def _normalise(v: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    return (np.asarray(v, dtype=np.float64) - bounds[0]) / (bounds[1] - bounds[0])


def _check(summary: PosteriorSummary, bounds: np.ndarray, reference: np.ndarray | None) -> None:
    q = len(summary.names)
    if np.shape(bounds) != (2, q):
        raise ValueError(f"bounds: shape {np.shape(bounds)}, expected (2, {q})")
    if reference is not None and np.shape(reference) != (q,):
        raise ValueError(f"reference: shape {np.shape(reference)}, expected ({q},)")


def plot_parameters(
    summary: PosteriorSummary,
    bounds: np.ndarray,
    path: str | Path,
    reference: np.ndarray | None = None,
) -> Path:
    """The paper's Fig. 1 on the normalised scale; returns the written path.

    Args:
        summary: posterior summary (physical units).
        bounds: (2 x q) bounds of C_w.
        path: output file (extension sets the format, e.g. .png or .pdf).
        reference: (q,) reference parameters when known (synthetic data), else None.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    _check(summary, bounds, reference)
    q = len(summary.names)
    k = np.arange(1, q + 1)
    fig, ax = plt.subplots(figsize=(max(5.0, 0.9 * q + 2.0), 4.0))
    interval = _normalise(summary.interval95.T, bounds)
    for i in range(q):
        ax.plot(
            [k[i], k[i]],
            interval[:, i],
            color="tab:blue",
            lw=2,
            label="95 % interval" if i == 0 else None,
        )
    ax.plot(
        k,
        _normalise(summary.marginal_map, bounds),
        "o",
        color="tab:blue",
        label="marginal MAP (eq. 6)",
    )
    ax.plot(
        k + 0.12,
        _normalise(summary.joint_map, bounds),
        "^",
        color="tab:red",
        label="joint MAP (eq. 5)",
    )
    if reference is not None:
        ax.plot(k - 0.12, _normalise(reference, bounds), "s", color="black", label="reference")
    ax.set_xticks(k, summary.names, rotation=30, ha="right")
    ax.set_ylim(-0.02, 1.02)
    ax.set_ylabel("normalised parameter")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def plot_marginals(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    path: str | Path,
    reference: np.ndarray | None = None,
    components: Sequence[int] | None = None,
    units: Sequence[str] | None = None,
) -> Path:
    """The paper's Fig. 2: marginal pdfs with interval bounds and reference.

    Args:
        draws: (draws x q) posterior draws, physical units.
        summary: posterior summary.
        bounds: (2 x q) bounds of C_w.
        path: output file.
        reference: (q,) reference parameters or None.
        components: indices to plot (default all).
        units: (q,) unit strings for the axis labels, or None.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    _check(summary, bounds, reference)
    draws = np.asarray(draws, dtype=np.float64).reshape(-1, len(summary.names))
    comps = list(range(len(summary.names))) if components is None else list(components)
    ncol = min(3, len(comps))
    nrow = int(np.ceil(len(comps) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.0 * ncol, 3.0 * nrow), squeeze=False)
    for ax, k in zip(axes.ravel(), comps):
        grid = np.linspace(bounds[0, k], bounds[1, k], 801)
        ax.plot(grid, marginal_density(draws[:, k], grid, bounds[:, k]), color="tab:blue")
        for edge in summary.interval95[k]:
            ax.axvline(edge, color="tab:blue", ls=":")
        if reference is not None:
            ax.axvline(reference[k], color="black", ls="-.")
        unit = f" [{units[k]}]" if units is not None and units[k] else ""
        ax.set_xlabel(f"{summary.names[k]}{unit}")
        ax.set_ylabel("posterior pdf")
    for ax in axes.ravel()[len(comps) :]:
        ax.set_visible(False)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def plot_pairs(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    path: str | Path,
    reference: np.ndarray | None = None,
) -> Path:
    """Pair plot of the posterior draws (normalised axes); returns the written path."""
    bounds = np.asarray(bounds, dtype=np.float64)
    _check(summary, bounds, reference)
    q = len(summary.names)
    u = _normalise(np.asarray(draws, dtype=np.float64).reshape(-1, q), bounds)
    jmap = _normalise(summary.joint_map, bounds)
    ref = None if reference is None else _normalise(reference, bounds)
    fig, axes = plt.subplots(q, q, figsize=(1.8 * q + 1, 1.8 * q + 1), squeeze=False)
    unit = np.array([0.0, 1.0])
    for i in range(q):
        for j in range(q):
            ax = axes[i, j]
            if j > i:
                ax.set_visible(False)
                continue
            if i == j:
                grid = np.linspace(0.0, 1.0, 401)
                ax.plot(grid, marginal_density(u[:, i], grid, unit), color="tab:blue")
                ax.set_yticks([])
            else:
                ax.hist2d(u[:, j], u[:, i], bins=60, range=[[0, 1], [0, 1]], cmap="Blues")
                ax.plot(jmap[j], jmap[i], "^", color="tab:red", ms=5)
                if ref is not None:
                    ax.plot(ref[j], ref[i], "s", color="black", ms=4)
            if i == q - 1:
                ax.set_xlabel(summary.names[j], fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(summary.names[i], fontsize=8)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def posterior_figures(
    summary: PosteriorSummary,
    draws: np.ndarray,
    bounds: np.ndarray,
    out_dir: str | Path,
    reference: np.ndarray | None = None,
    units: Sequence[str] | None = None,
) -> list[Path]:
    """Writes Fig. 1, Fig. 2 and the pair plot as PNG files into ``out_dir``.

    Args:
        summary: posterior summary (physical units).
        draws: (draws x q) posterior draws, physical units.
        bounds: (2 x q) bounds of C_w.
        out_dir: existing or new folder.
        reference: (q,) reference parameters when known, else None.
        units: (q,) units for the Fig. 2 axis labels, or None.

    Returns:
        The three paths, in the order Fig. 1, Fig. 2, pair plot.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [
        plot_parameters(summary, bounds, out / FIG1_NAME, reference),
        plot_marginals(draws, summary, bounds, out / FIG2_NAME, reference, units=units),
        plot_pairs(draws, summary, bounds, out / PAIRS_NAME, reference),
    ]
