"""Posterior figures for a railway engineer (matplotlib, Agg backend, saved as files).

:func:`posterior_figures` writes all three as PNG files into a folder. Every figure carries
the reliability verdict in its title (red when the result is not trusted), shows physical
values in SI-prefixed units (:mod:`susp_bo.units`) and has a legend for every line and marker.

- :func:`plot_parameters` — the paper's Fig. 1: one row per parameter on the normalised
  scale of its admissible interval C_w (grey bar, bounds written in physical units), with
  the 95 % interval, the marginal MAP (eq. 6), the joint MAP (eq. 5), the acceptable band
  (green) where the rig defines one and the reference when known; the values are written
  beside each row in physical units;
- :func:`plot_marginals` — the paper's Fig. 2: each marginal posterior pdf zoomed to where
  its mass is (0.1–99.9 % quantiles, padded), with the 95 % interval shaded, both MAPs, the
  reference, the acceptable band and the part of the view outside C_w; the C_w range and the
  share of it in view are written under each panel;
- :func:`plot_pairs` — pair plot: 1-D marginals on the diagonal, 2-D posterior densities
  below it as filled 50 % and 90 % highest-density regions, joint MAP and reference marked.

The ``*_figure`` functions (:mod:`susp_bo.posterior_plots`) return the open matplotlib
figure, for tests and notebooks; the ``plot_*`` functions save and close it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.calibration.posterior import PosteriorSummary
from susp_bo.output_folder import FIGURE_NAMES
from susp_bo.posterior_plots.common import (
    LABEL_ACCEPTABLE,
    LABEL_ADMISSIBLE,
    LABEL_DENSITY,
    LABEL_HPD50,
    LABEL_HPD90,
    LABEL_INTERVAL,
    LABEL_JOINT_MAP,
    LABEL_MARGINAL_MAP,
    LABEL_OUTSIDE,
    LABEL_REFERENCE,
    acceptable_bands,
    save,
    verdict_title,
)
from susp_bo.posterior_plots.marginals import marginals_figure
from susp_bo.posterior_plots.pairs import pairs_figure
from susp_bo.posterior_plots.parameters import parameters_figure

__all__ = [
    "FIG1_NAME",
    "FIG2_NAME",
    "LABEL_ACCEPTABLE",
    "LABEL_ADMISSIBLE",
    "LABEL_DENSITY",
    "LABEL_HPD50",
    "LABEL_HPD90",
    "LABEL_INTERVAL",
    "LABEL_JOINT_MAP",
    "LABEL_MARGINAL_MAP",
    "LABEL_OUTSIDE",
    "LABEL_REFERENCE",
    "PAIRS_NAME",
    "acceptable_bands",
    "marginals_figure",
    "pairs_figure",
    "parameters_figure",
    "plot_marginals",
    "plot_pairs",
    "plot_parameters",
    "posterior_figures",
    "verdict_title",
]

FIG1_NAME, FIG2_NAME, PAIRS_NAME = FIGURE_NAMES


def plot_parameters(
    summary: PosteriorSummary,
    bounds: np.ndarray,
    path: str | Path,
    reference: np.ndarray | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> Path:
    """The paper's Fig. 1 (see :func:`parameters_figure`) saved to ``path``; returns it."""
    fig = parameters_figure(
        summary, bounds, reference, units, acceptable=acceptable, reliability=reliability
    )
    return save(fig, path)


def plot_marginals(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    path: str | Path,
    reference: np.ndarray | None = None,
    components: Sequence[int] | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> Path:
    """The paper's Fig. 2 (see :func:`marginals_figure`) saved to ``path``; returns it."""
    fig = marginals_figure(
        draws,
        summary,
        bounds,
        reference,
        components,
        units,
        acceptable=acceptable,
        reliability=reliability,
    )
    return save(fig, path)


def plot_pairs(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    path: str | Path,
    reference: np.ndarray | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> Path:
    """Pair plot (see :func:`pairs_figure`) saved to ``path``; returns it."""
    fig = pairs_figure(
        draws, summary, bounds, reference, units, acceptable=acceptable, reliability=reliability
    )
    return save(fig, path)


def posterior_figures(
    summary: PosteriorSummary,
    draws: np.ndarray,
    bounds: np.ndarray,
    out_dir: str | Path,
    reference: np.ndarray | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Writes Fig. 1, Fig. 2 and the pair plot as PNG files into ``out_dir``.

    Args:
        summary: posterior summary (physical units).
        draws: (draws x q) posterior draws, physical units.
        bounds: (2 x q) bounds of C_w.
        out_dir: existing or new folder.
        reference: (q,) reference parameters when known, else None.
        units: (q,) SI units of the parameters (e.g. ``"N·s/m"``), or None.
        acceptable: (2 x q) acceptable band (maintenance limits), NaN where a parameter has
            none; or None.
        reliability: ``result.json["reliability"]`` (``verdict``, ``reasons``, ``sentence``)
            or None (the titles then say "verdict: not computed").

    Returns:
        The three paths, in the order Fig. 1, Fig. 2, pair plot.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    extra = {"acceptable": acceptable, "reliability": reliability}
    return [
        plot_parameters(summary, bounds, out / FIG1_NAME, reference, units, **extra),
        plot_marginals(draws, summary, bounds, out / FIG2_NAME, reference, units=units, **extra),
        plot_pairs(draws, summary, bounds, out / PAIRS_NAME, reference, units, **extra),
    ]
