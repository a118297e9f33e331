"""What the posterior figures share: inputs, the verdict title, zoom windows, legend entries.

Physical values are drawn in SI-prefixed units (:mod:`susp_bo.units`): a :class:`View` holds
the factor and prefixed unit of one parameter and the window it is drawn in.
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
from matplotlib.ticker import ScalarFormatter

from susp_bo.calibration.posterior import PosteriorSummary
from susp_bo.units import unit_scale

TRUSTED_COLOR = "#1a7f37"
NOT_TRUSTED_COLOR = "#c00000"
UNKNOWN_COLOR = "0.25"

# one look for each element, in every figure
C_DENSITY = "tab:blue"
C_INTERVAL = "#9ecae1"
C_JOINT = "tab:red"
C_ACCEPT = "tab:green"
C_ADMISSIBLE = "0.82"
PAIR_TICKS = 4
"""Most tick intervals on a pair-plot axis (the diagonal and the 2-D panels alike)."""
HPD50_COLOR = "#3182bd"
HPD90_COLOR = "#c6dbef"

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


def check_inputs(
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


def unit_list(units: Sequence[str] | None, q: int) -> list[str]:
    return [""] * q if units is None else [str(u or "") for u in units]


def band_array(acceptable: np.ndarray | None, q: int) -> np.ndarray:
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


def wrap(text: str, width: int) -> str:
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


def verdict_suptitle(fig: Figure, what: str, reliability: Any) -> None:
    """``what — <verdict>`` and the verdict's sentence as the figure title, in its colour.

    Wrapped to the figure's width (about 9 bold 11-pt characters per inch).
    """
    head, sentence, color = verdict_title(reliability)
    width = max(30, int(9 * fig.get_figwidth()))
    text = wrap(f"{what} — {head}", width)
    if sentence:
        text += "\n" + wrap(sentence, width)
    fig.suptitle(
        text,
        color=color,
        fontsize=11,
        fontweight="bold" if color == NOT_TRUSTED_COLOR else "normal",
    )


# ----------------------------------------------------------------------------- views


@dataclass(frozen=True)
class View:
    """How one parameter is drawn: the prefixed unit and the zoom window.

    Attributes:
        factor: divide physical values by it to get the axis' prefixed unit.
        unit: the prefixed unit (may be "").
        lo: lower end of the view, physical units.
        hi: upper end of the view, physical units.
        bounds: (lower, upper) of C_w, physical units.
        base_unit: the parameter's SI unit without prefix (e.g. ``N·s/m``).
    """

    factor: float
    unit: str
    lo: float
    hi: float
    bounds: tuple[float, float]
    base_unit: str = ""

    def s(self, v: Any) -> Any:
        """Physical value(s) → axis value(s)."""
        return np.asarray(v, dtype=np.float64) / self.factor

    @property
    def inner(self) -> tuple[float, float]:
        """The part of the view inside C_w, physical units."""
        return max(self.lo, self.bounds[0]), min(self.hi, self.bounds[1])

    @property
    def share(self) -> float:
        """Fraction of C_w that the view shows."""
        lo = max(self.lo, self.bounds[0])
        hi = min(self.hi, self.bounds[1])
        return max(0.0, hi - lo) / (self.bounds[1] - self.bounds[0])


def view_of(
    x: np.ndarray,
    summary: PosteriorSummary,
    k: int,
    bounds: np.ndarray,
    unit: str,
    reference: np.ndarray | None,
) -> View:
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
    return View(factor, prefixed, lo, hi, (lb, ub), unit)


def views_of(
    draws: np.ndarray,
    summary: PosteriorSummary,
    bounds: np.ndarray,
    units: Sequence[str] | None,
    reference: np.ndarray | None,
) -> list[View]:
    q = len(summary.names)
    u = unit_list(units, q)
    return [view_of(draws[:, k], summary, k, bounds, u[k], reference) for k in range(q)]


def plain_axis(axis: Any) -> None:
    """Plain tick numbers: no offset text, no ×10^n (the unit carries the prefix)."""
    formatter = ScalarFormatter(useOffset=False)
    formatter.set_scientific(False)
    axis.set_major_formatter(formatter)


def axis_label(name: str, view: View, width: int = 0) -> str:
    label = pretty_name(name)
    if width:
        label = wrap(label, width)
    return f"{label} [{view.unit}]" if view.unit else label


def edge_note(ax: Any, text: str, right: bool, y: float, color: str) -> None:
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


def legend_handles(used: set[str], pairs: bool = False) -> list[Any]:
    """Legend entries, in a fixed order, for the labels in ``used``.

    In the pair plot the reference is a dash-dot line on the diagonal and an open square
    below it: its entry shows both.
    """
    square = {"marker": "s", "mfc": "none", "mew": 1.5, "ms": 6} if pairs else {}
    handles = [
        Line2D([], [], color=C_DENSITY, lw=1.6, label=LABEL_DENSITY),
        Patch(color=C_INTERVAL, label=LABEL_INTERVAL),
        Line2D([], [], color=C_DENSITY, ls="--", lw=1.2, label=LABEL_MARGINAL_MAP),
        Line2D([], [], color=C_JOINT, marker="v", ls="", ms=8, label=LABEL_JOINT_MAP),
        Line2D([], [], color="black", ls="-.", lw=1.3, label=LABEL_REFERENCE, **square),
        Patch(color=C_ACCEPT, alpha=0.15, label=LABEL_ACCEPTABLE),
        Patch(facecolor="0.9", hatch="///", edgecolor="0.6", label=LABEL_OUTSIDE),
        Patch(color=HPD50_COLOR, label=LABEL_HPD50),
        Patch(color=HPD90_COLOR, label=LABEL_HPD90),
    ]
    out, seen = [], set()
    for h in handles:
        label = h.get_label()
        if label in used and label not in seen:
            out.append(h)
            seen.add(label)
    return out


def save(fig: Figure, path: str | Path) -> Path:
    """Save and close ``fig``; returns the file written (``.png`` added when no suffix)."""
    out = Path(path)
    if not out.suffix:  # matplotlib would add .png itself, and the returned name not exist
        out = out.with_name(out.name + ".png")
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def draws_matrix(draws: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Posterior draws as a (n x q) float64 matrix, refusing any other layout.

    Args:
        draws: (n x q) or (chains x n x q) draws in physical units.
        names: the q parameter names (named in the message).

    Raises:
        ValueError: the last axis is not q (e.g. transposed (q x n) draws, which a plain
            reshape would scramble), no draws, or non-finite draws.
    """
    array = np.asarray(draws, dtype=np.float64)
    q = len(names)
    if array.ndim not in (2, 3) or array.shape[-1] != q or array.size == 0:
        raise ValueError(
            f"draws: shape {array.shape}; expected (draws x {q}) or (chains x draws x {q}), "
            f"the last axis over the parameters {list(names)}"
        )
    if not np.all(np.isfinite(array)):
        raise ValueError(f"draws: {int(np.sum(~np.isfinite(array)))} non-finite values")
    return array.reshape(-1, q)
