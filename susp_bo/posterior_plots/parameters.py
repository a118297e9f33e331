"""The paper's Fig. 1 in physical units: one row per parameter within its admissible interval."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from susp_bo.calibration.posterior import PosteriorSummary
from susp_bo.posterior_plots.common import (
    C_ACCEPT,
    C_ADMISSIBLE,
    C_DENSITY,
    C_JOINT,
    LABEL_ACCEPTABLE,
    LABEL_ADMISSIBLE,
    LABEL_INTERVAL,
    LABEL_JOINT_MAP,
    LABEL_MARGINAL_MAP,
    LABEL_REFERENCE,
    band_array,
    check_inputs,
    pretty_name,
    unit_list,
    verdict_suptitle,
)
from susp_bo.units import format_range, format_values


def parameters_figure(
    summary: PosteriorSummary,
    bounds: np.ndarray,
    reference: np.ndarray | None = None,
    units: Sequence[str] | None = None,
    *,
    acceptable: np.ndarray | None = None,
    reliability: Mapping[str, Any] | None = None,
) -> Figure:
    """The paper's Fig. 1 with physical values; returns the open figure.

    Args:
        summary: posterior summary (physical units).
        bounds: (2 x q) bounds of C_w.
        reference: (q,) reference parameters when known (synthetic data), else None.
        units: (q,) SI units of the parameters (e.g. ``"N·s/m"``), or None.
        acceptable: (2 x q) acceptable band (maintenance limits), NaN where none; or None.
        reliability: ``result.json["reliability"]`` dict, or None (not computed).
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    check_inputs(summary, bounds, reference, units, acceptable)
    q = len(summary.names)
    unit = unit_list(units, q)
    band = band_array(acceptable, q)
    span = bounds[1] - bounds[0]

    def norm(v: Any) -> np.ndarray:
        return (np.asarray(v, dtype=np.float64) - bounds[0]) / span

    fig, ax = plt.subplots(figsize=(12.5, 0.62 * q + 2.6), constrained_layout=True)
    rows = np.arange(q)[::-1].astype(np.float64)  # first parameter on top
    interval = norm(summary.interval95.T)
    ax.barh(rows, 1.0, left=0.0, height=0.5, color=C_ADMISSIBLE, zorder=1)
    has_band = False
    for k in range(q):
        if np.all(np.isfinite(band[:, k])):
            lo, hi = (band[:, k] - bounds[0, k]) / span[k]
            ax.barh(rows[k], hi - lo, left=lo, height=0.5, color=C_ACCEPT, alpha=0.35, zorder=2)
            has_band = True
        ax.plot(interval[:, k], [rows[k], rows[k]], color=C_DENSITY, lw=4, zorder=3)
    ax.plot(norm(summary.marginal_map), rows, "o", color=C_DENSITY, ms=8, zorder=4)
    ax.plot(norm(summary.joint_map), rows + 0.2, "v", color=C_JOINT, ms=7, zorder=5)
    if reference is not None:
        ax.plot(norm(reference), rows - 0.2, "^", color="black", ms=7, zorder=5)
    labels, values = [], []
    for k in range(q):
        labels.append(
            f"{pretty_name(summary.names[k])}\nC_w: {format_range(*bounds[:, k], unit[k])}"
        )
        main = [summary.marginal_map[k], *summary.interval95[k]]
        numbers, pu = format_values(main, unit[k])
        text = f"{numbers[0]} [{numbers[1]}, {numbers[2]}] {pu}".rstrip()
        extra = []
        if reference is not None:
            extra.append(f"reference {format_values([reference[k]], unit[k], like=main)[0][0]}")
        if np.all(np.isfinite(band[:, k])):
            (a, b), _ = format_values(band[:, k], unit[k], like=main)
            extra.append(f"acceptable {a}–{b}")
        if extra:
            text += "\n" + ", ".join(extra)
            text += f" {pu}" if pu else ""
        values.append(text)
    ax.set_yticks(rows, labels, fontsize=9)
    for k in range(q):
        ax.annotate(
            values[k],
            xy=(1.0, rows[k]),
            xycoords=("axes fraction", "data"),
            xytext=(10, 0),
            textcoords="offset points",
            va="center",
            fontsize=9,
        )
    ax.set_xlim(-0.03, 1.03)
    ax.set_ylim(-0.7, q - 0.3)
    ax.set_xticks([0.0, 0.25, 0.5, 0.75, 1.0], ["lower", "25 %", "50 %", "75 %", "upper"])
    ax.set_xlabel("position in the admissible interval C_w (bounds written under each name)")
    ax.set_title("marginal MAP [95 % interval] in physical units →", loc="right", fontsize=9)
    ax.grid(axis="x", alpha=0.3)
    handles = [
        Patch(color=C_ADMISSIBLE, label=LABEL_ADMISSIBLE),
        Line2D([], [], color=C_DENSITY, lw=4, label=LABEL_INTERVAL),
        Line2D([], [], color=C_DENSITY, marker="o", ls="", ms=8, label=LABEL_MARGINAL_MAP),
        Line2D([], [], color=C_JOINT, marker="v", ls="", ms=7, label=LABEL_JOINT_MAP),
    ]
    if reference is not None:
        handles.append(
            Line2D([], [], color="black", marker="^", ls="", ms=7, label=LABEL_REFERENCE)
        )
    if has_band:
        handles.append(Patch(color=C_ACCEPT, alpha=0.35, label=LABEL_ACCEPTABLE))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9)
    verdict_suptitle(fig, "Calibrated parameters (Fig. 1)", reliability)
    return fig
