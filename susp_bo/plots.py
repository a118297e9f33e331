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

The ``*_figure`` functions return the open matplotlib figure (for tests and notebooks);
the ``plot_*`` functions save and close it.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator, ScalarFormatter
from scipy.ndimage import gaussian_filter

from susp_bo.calibration.posterior import PosteriorSummary, marginal_density
from susp_bo.units import format_range, format_values, unit_scale

FIG1_NAME = "fig1_parameters.png"
FIG2_NAME = "fig2_marginals.png"
PAIRS_NAME = "pairs.png"

TRUSTED_COLOR = "#1a7f37"
NOT_TRUSTED_COLOR = "#c00000"
UNKNOWN_COLOR = "0.25"

# one look for each element, in every figure
_C_DENSITY = "tab:blue"
_C_INTERVAL = "#9ecae1"
_C_JOINT = "tab:red"
_C_ACCEPT = "tab:green"
_C_ADMISSIBLE = "0.82"

LABEL_DENSITY = "marginal posterior density"
LABEL_INTERVAL = "95 % interval"
LABEL_MARGINAL_MAP = "marginal MAP (eq. 6)"
LABEL_JOINT_MAP = "joint MAP (eq. 5)"
LABEL_REFERENCE = "reference (truth)"
LABEL_ACCEPTABLE = "acceptable band"
LABEL_ADMISSIBLE = "admissible interval C_w"
LABEL_OUTSIDE = "outside C_w"
LABEL_HPD50 = "50 % highest-density region"
LABEL_HPD90 = "90 % highest-density region"


# ----------------------------------------------------------------------------- inputs


def _check(
    summary: PosteriorSummary,
    bounds: np.ndarray,
    reference: np.ndarray | None,
    units: Sequence[str] | None = None,
    acceptable: np.ndarray | None = None,
) -> None:
    q = len(summary.names)
    if np.shape(bounds) != (2, q):
        raise ValueError(f"bounds: shape {np.shape(bounds)}, expected (2, {q})")
    if reference is not None and np.shape(reference) != (q,):
        raise ValueError(f"reference: shape {np.shape(reference)}, expected ({q},)")
    if units is not None and len(units) != q:
        raise ValueError(f"units: {len(units)} entries, expected {q}")
    if acceptable is not None and np.shape(acceptable) != (2, q):
        raise ValueError(f"acceptable: shape {np.shape(acceptable)}, expected (2, {q})")


def _units(units: Sequence[str] | None, q: int) -> list[str]:
    return [""] * q if units is None else [str(u or "") for u in units]


def _acceptable(acceptable: np.ndarray | None, q: int) -> np.ndarray:
    """(2 x q) acceptable band, NaN where a parameter has none."""
    if acceptable is None:
        return np.full((2, q), np.nan)
    return np.asarray(acceptable, dtype=np.float64)


def acceptable_bands(limits: Sequence[Sequence[float] | None]) -> np.ndarray:
    """(2 x q) array of acceptable bands from per-parameter ``(lo, hi)`` or None (NaN)."""
    out = np.full((2, len(limits)), np.nan)
    for k, band in enumerate(limits):
        if band is not None:
            out[:, k] = [float(band[0]), float(band[1])]
    return out


def pretty_name(name: str) -> str:
    """``secondary_vertical_damping`` → ``secondary vertical damping``."""
    return name.replace("_", " ")


def _wrap(text: str, width: int) -> str:
    return "\n".join(textwrap.wrap(text, width)) or text


# ----------------------------------------------------------------------------- verdict


def verdict_title(reliability: Mapping[str, Any] | Any | None) -> tuple[str, str, str]:
    """The title line, the explanatory sentence and the colour of a reliability verdict.

    Args:
        reliability: ``result.json["reliability"]`` (``verdict``, ``reasons`` with
            ``code``s, ``sentence``), an object with ``to_dict()``, or None.

    Returns:
        ``(headline, sentence, colour)``: ``"verdict: trusted"`` in green, ``"NOT TRUSTED:
        <codes>"`` in red, or ``"verdict: not computed"`` in dark grey.
    """
    if reliability is None:
        return "verdict: not computed", "", UNKNOWN_COLOR
    if not isinstance(reliability, Mapping) and hasattr(reliability, "to_dict"):
        reliability = reliability.to_dict()
    verdict = str(reliability.get("verdict", "")) if isinstance(reliability, Mapping) else ""
    sentence = str(reliability.get("sentence", "") or "") if verdict else ""
    if verdict == "trusted":
        return "verdict: trusted", sentence, TRUSTED_COLOR
    if verdict == "not_trusted":
        codes = [
            str(r.get("code", "?")) if isinstance(r, Mapping) else str(r)
            for r in reliability.get("reasons", []) or []
        ]
        head = "NOT TRUSTED" + (": " + ", ".join(codes) if codes else "")
        return head, sentence, NOT_TRUSTED_COLOR
    if verdict:
        return f"verdict: {verdict}", sentence, UNKNOWN_COLOR
    return "verdict: not computed", "", UNKNOWN_COLOR


def _suptitle(fig: Figure, what: str, reliability: Any, width: int) -> None:
    head, sentence, color = verdict_title(reliability)
    text = f"{what} — {head}"
    if sentence:
        text += "\n" + _wrap(sentence, width)
    fig.suptitle(
        text,
        color=color,
        fontsize=11,
        fontweight="bold" if color == NOT_TRUSTED_COLOR else "normal",
    )


# ----------------------------------------------------------------------------- views


@dataclass(frozen=True)
class _View:
    """How one parameter is drawn: the prefixed unit and the zoom window.

    Attributes:
        factor: divide physical values by it to get the axis' prefixed unit.
        unit: the prefixed unit (may be "").
        lo: lower end of the view, physical units.
        hi: upper end of the view, physical units.
        bounds: (lower, upper) of C_w, physical units.
    """

    factor: float
    unit: str
    lo: float
    hi: float
    bounds: tuple[float, float]

    def s(self, v: Any) -> Any:
        """Physical value(s) → axis value(s)."""
        return np.asarray(v, dtype=np.float64) / self.factor

    @property
    def share(self) -> float:
        """Fraction of C_w that the view shows."""
        lo = max(self.lo, self.bounds[0])
        hi = min(self.hi, self.bounds[1])
        return max(0.0, hi - lo) / (self.bounds[1] - self.bounds[0])


def _view(
    x: np.ndarray,
    summary: PosteriorSummary,
    k: int,
    bounds: np.ndarray,
    unit: str,
    reference: np.ndarray | None,
) -> _View:
    """Zoom window of component ``k``: 0.1–99.9 % quantiles and the MAPs/interval, padded.

    The reference joins the window when it is near (within half the window's width); a
    far reference is marked at the edge instead. The window never reaches past C_w by more
    than a sliver, so a bound in view is visible but the view is not wasted outside C_w.
    """
    lb, ub = float(bounds[0, k]), float(bounds[1, k])
    finite = x[np.isfinite(x)]
    pts = [*summary.interval95[k], summary.marginal_map[k], summary.joint_map[k]]
    if finite.size:
        pts += list(np.quantile(finite, [0.001, 0.999]))
    lo, hi = float(min(pts)), float(max(pts))
    if reference is not None and np.isfinite(reference[k]):
        r = float(reference[k])
        width = max(hi - lo, 1e-9 * (ub - lb))
        if lo - 0.5 * width <= r <= hi + 0.5 * width:
            lo, hi = min(lo, r), max(hi, r)
    width = hi - lo
    if not width > 0.0:
        width = 0.02 * (ub - lb)
        lo, hi = lo - 0.5 * width, hi + 0.5 * width
    pad = 0.12 * width
    sliver = 0.04 * (width + 2 * pad)
    lo = max(lo - pad, lb - sliver)
    hi = min(hi + pad, ub + sliver)
    factor, prefixed = unit_scale(max(abs(lo), abs(hi)), unit)
    return _View(factor, prefixed, lo, hi, (lb, ub))


def _views(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    units: Sequence[str] | None,
    reference: np.ndarray | None,
) -> list[_View]:
    q = len(summary.names)
    u = _units(units, q)
    return [_view(draws[:, k], summary, k, bounds, u[k], reference) for k in range(q)]


def _plain_axis(axis: Any) -> None:
    """Plain tick numbers: no offset text, no ×10^n (the unit carries the prefix)."""
    formatter = ScalarFormatter(useOffset=False)
    formatter.set_scientific(False)
    axis.set_major_formatter(formatter)


def _axis_label(name: str, view: _View, width: int = 0) -> str:
    label = pretty_name(name)
    if width:
        label = _wrap(label, width)
    return f"{label} [{view.unit}]" if view.unit else label


# ----------------------------------------------------------------------------- Fig. 1


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
    _check(summary, bounds, reference, units, acceptable)
    q = len(summary.names)
    unit = _units(units, q)
    band = _acceptable(acceptable, q)
    span = bounds[1] - bounds[0]

    def norm(v: Any) -> np.ndarray:
        return (np.asarray(v, dtype=np.float64) - bounds[0]) / span

    fig, ax = plt.subplots(figsize=(12.5, 0.62 * q + 2.6), constrained_layout=True)
    rows = np.arange(q)[::-1].astype(np.float64)  # first parameter on top
    interval = norm(summary.interval95.T)
    ax.barh(rows, 1.0, left=0.0, height=0.5, color=_C_ADMISSIBLE, zorder=1)
    has_band = False
    for k in range(q):
        if np.all(np.isfinite(band[:, k])):
            lo, hi = (band[:, k] - bounds[0, k]) / span[k]
            ax.barh(rows[k], hi - lo, left=lo, height=0.5, color=_C_ACCEPT, alpha=0.35, zorder=2)
            has_band = True
        ax.plot(interval[:, k], [rows[k], rows[k]], color=_C_DENSITY, lw=4, zorder=3)
    ax.plot(norm(summary.marginal_map), rows, "o", color=_C_DENSITY, ms=8, zorder=4)
    ax.plot(norm(summary.joint_map), rows + 0.2, "v", color=_C_JOINT, ms=7, zorder=5)
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
        Patch(color=_C_ADMISSIBLE, label=LABEL_ADMISSIBLE),
        Line2D([], [], color=_C_DENSITY, lw=4, label=LABEL_INTERVAL),
        Line2D([], [], color=_C_DENSITY, marker="o", ls="", ms=8, label=LABEL_MARGINAL_MAP),
        Line2D([], [], color=_C_JOINT, marker="v", ls="", ms=7, label=LABEL_JOINT_MAP),
    ]
    if reference is not None:
        handles.append(
            Line2D([], [], color="black", marker="^", ls="", ms=7, label=LABEL_REFERENCE)
        )
    if has_band:
        handles.append(Patch(color=_C_ACCEPT, alpha=0.35, label=LABEL_ACCEPTABLE))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9)
    _suptitle(fig, "Calibrated parameters (Fig. 1)", reliability, 150)
    return fig


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
    return _save(fig, path)


# ----------------------------------------------------------------------------- Fig. 2


def _draw_marginal(
    ax: Any,
    x: np.ndarray,
    summary: PosteriorSummary,
    k: int,
    view: _View,
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
    inside = (grid >= summary.interval95[k, 0]) & (grid <= summary.interval95[k, 1])
    ax.fill_between(gs, 0.0, dens, where=inside, color=_C_INTERVAL, lw=0, zorder=1)
    ax.plot(gs, dens, color=_C_DENSITY, lw=1.6, zorder=3)
    mm = float(summary.marginal_map[k])
    ax.plot(
        [view.s(mm)] * 2,
        [0.0, float(np.interp(mm, grid, dens))],
        color=_C_DENSITY,
        ls="--",
        lw=1.2,
        zorder=3,
    )
    ax.plot(view.s(summary.joint_map[k]), 0.0, "v", color=_C_JOINT, ms=8, zorder=5, clip_on=False)
    used.add(LABEL_JOINT_MAP)
    if np.all(np.isfinite(band[:, k])):
        ax.axvspan(*view.s(band[:, k]), color=_C_ACCEPT, alpha=0.15, lw=0, zorder=0)
        used.add(LABEL_ACCEPTABLE)
        a, b = view.s(band[:, k])
        if b < view.s(view.lo) or a > view.s(view.hi):  # the whole band is out of view
            right = a > view.s(view.hi)
            _edge_note(ax, f"acceptable {a:.3g}–{b:.3g} {view.unit}", right, 0.85, _C_ACCEPT)
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
            _edge_note(ax, f"reference {view.s(r):.3g} {view.unit}", r > view.hi, 0.62, "black")
    ax.set_xlim(view.s(view.lo), view.s(view.hi))
    ax.set_ylim(0.0, 1.15 * top)
    ax.set_yticks([])
    _plain_axis(ax.xaxis)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=4 if compact else 6))
    return used


def _edge_note(ax: Any, text: str, right: bool, y: float, color: str) -> None:
    """A boxed note at the left/right edge of ``ax`` for something beyond the view."""
    ax.annotate(
        f"{text} →" if right else f"← {text}",
        xy=(0.98 if right else 0.02, y),
        xycoords="axes fraction",
        ha="right" if right else "left",
        va="center",
        fontsize=7.5,
        color="black",
        bbox={"boxstyle": "round", "fc": "white", "ec": color, "lw": 1.0},
        zorder=6,
    )


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
    _check(summary, bounds, reference, units, acceptable)
    q = len(summary.names)
    draws = np.asarray(draws, dtype=np.float64).reshape(-1, q)
    comps = list(range(q)) if components is None else list(components)
    unit = _units(units, q)
    band = _acceptable(acceptable, q)
    views = _views(draws, summary, bounds, units, reference)
    ncol = min(3, len(comps))
    nrow = int(np.ceil(len(comps) / ncol))
    fig, axes = plt.subplots(
        nrow, ncol, figsize=(4.6 * ncol, 3.3 * nrow + 1.4), squeeze=False, constrained_layout=True
    )
    used: set[str] = set()
    for ax, k in zip(axes.ravel(), comps):
        view = views[k]
        used |= _draw_marginal(ax, draws[:, k], summary, k, view, reference, band)
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
    fig.legend(handles=_legend_handles(used), loc="outside lower center", ncol=4, fontsize=9)
    _suptitle(fig, "Marginal posteriors (Fig. 2)", reliability, 40 * ncol)
    return fig


def _legend_handles(used: set[str], pairs: bool = False) -> list[Any]:
    """Legend entries, in a fixed order, for the labels in ``used``.

    In the pair plot the reference is a dash-dot line on the diagonal and an open square
    below it: its entry shows both.
    """
    square = {"marker": "s", "mfc": "none", "mew": 1.5, "ms": 6} if pairs else {}
    handles = [
        Line2D([], [], color=_C_DENSITY, lw=1.6, label=LABEL_DENSITY),
        Patch(color=_C_INTERVAL, label=LABEL_INTERVAL),
        Line2D([], [], color=_C_DENSITY, ls="--", lw=1.2, label=LABEL_MARGINAL_MAP),
        Line2D([], [], color=_C_JOINT, marker="v", ls="", ms=8, label=LABEL_JOINT_MAP),
        Line2D([], [], color="black", ls="-.", lw=1.3, label=LABEL_REFERENCE, **square),
        Patch(color=_C_ACCEPT, alpha=0.15, label=LABEL_ACCEPTABLE),
        Patch(facecolor="0.9", hatch="///", edgecolor="0.6", label=LABEL_OUTSIDE),
        Patch(color="#3182bd", label=LABEL_HPD50),
        Patch(color="#c6dbef", label=LABEL_HPD90),
    ]
    out, seen = [], set()
    for h in handles:
        label = h.get_label()
        if label in used and label not in seen:
            out.append(h)
            seen.add(label)
    return out


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
    return _save(fig, path)


# ----------------------------------------------------------------------------- pairs


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


def _density2d(
    x: np.ndarray, y: np.ndarray, vx: _View, vy: _View, bins: int = 72
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed 2-D histogram of the draws on the views; (cell centres x, y, probabilities)."""
    ex = np.linspace(vx.lo, vx.hi, bins + 1)
    ey = np.linspace(vy.lo, vy.hi, bins + 1)
    h, _, _ = np.histogram2d(x, y, bins=[ex, ey])
    n = max(x.size, 1)
    # Scott's rule in 2-D (n^(-1/6)), in bins
    sx = np.std(x) * n ** (-1 / 6) / (ex[1] - ex[0]) if x.size > 1 else 1.0
    sy = np.std(y) * n ** (-1 / 6) / (ey[1] - ey[0]) if y.size > 1 else 1.0
    smooth = gaussian_filter(h, sigma=(max(sx, 0.8), max(sy, 0.8)), mode="constant")
    return 0.5 * (ex[1:] + ex[:-1]), 0.5 * (ey[1:] + ey[:-1]), smooth.T / n


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
    _check(summary, bounds, reference, units, acceptable)
    q = len(summary.names)
    d = np.asarray(draws, dtype=np.float64).reshape(-1, q)
    band = _acceptable(acceptable, q)
    views = _views(d, summary, bounds, units, reference)
    size = max(6.0, 2.1 * q + 1.2)
    fig, axes = plt.subplots(q, q, figsize=(size, size), squeeze=False, constrained_layout=True)
    used: set[str] = set()
    for i in range(q):
        for j in range(q):
            ax = axes[i, j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                used |= _draw_marginal(ax, d[:, i], summary, i, views[i], reference, band, True)
            else:
                vx, vy = views[j], views[i]
                cx, cy, p = _density2d(d[:, j], d[:, i], vx, vy)
                l90, l50 = hpd_levels(p, 1.0, (0.9, 0.5))
                top = float(p.max())
                if top > l90 > 0.0:
                    levels = sorted({l90, min(l50, top * 0.999), top * 1.0001})
                    ax.contourf(
                        vx.s(cx),
                        vy.s(cy),
                        p,
                        levels=levels,
                        colors=["#c6dbef", "#3182bd"][: len(levels) - 1],
                    )
                    ax.contour(
                        vx.s(cx), vy.s(cy), p, levels=levels[:-1], colors="#08519c", linewidths=0.7
                    )
                    used |= {LABEL_HPD50, LABEL_HPD90}
                ax.plot(
                    vx.s(summary.joint_map[j]),
                    vy.s(summary.joint_map[i]),
                    "v",
                    color=_C_JOINT,
                    ms=6,
                    zorder=5,
                )
                used.add(LABEL_JOINT_MAP)
                if reference is not None:
                    rx, ry = reference[j], reference[i]
                    if vx.lo <= rx <= vx.hi and vy.lo <= ry <= vy.hi:
                        ax.plot(
                            vx.s(rx),
                            vy.s(ry),
                            "s",
                            color="black",
                            ms=5,
                            zorder=5,
                            mfc="none",
                            mew=1.5,
                        )
                        used.add(LABEL_REFERENCE)
                ax.set_xlim(vx.s(vx.lo), vx.s(vx.hi))
                ax.set_ylim(vy.s(vy.lo), vy.s(vy.hi))
                for axis in (ax.xaxis, ax.yaxis):
                    _plain_axis(axis)
                    axis.set_major_locator(MaxNLocator(nbins=3))
            ax.tick_params(labelsize=7.5)
            if i == q - 1:
                ax.set_xlabel(_axis_label(summary.names[j], views[j], 18), fontsize=8.5)
            else:
                ax.tick_params(labelbottom=False)
            if j == 0 and i > 0:
                ax.set_ylabel(_axis_label(summary.names[i], views[i], 18), fontsize=8.5)
            elif j > 0:
                ax.tick_params(labelleft=False)
    if q == 1:
        axes[0, 0].set_xlabel(_axis_label(summary.names[0], views[0], 18), fontsize=8.5)
    fig.legend(
        handles=_legend_handles(used, pairs=True),
        loc="upper right",
        bbox_to_anchor=(0.98, 0.9),
        fontsize=9 if q > 2 else 8,
        title="pair plot: each axis zoomed to its posterior mass",
        title_fontsize=9,
    )
    _suptitle(fig, "Posterior pairs", reliability, int(14 * size))
    return fig


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
    return _save(fig, path)


# ----------------------------------------------------------------------------- files


def _save(fig: Figure, path: str | Path) -> Path:
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


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
