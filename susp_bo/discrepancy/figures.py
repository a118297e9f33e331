"""Figures of the discrepancy workflow: the channel × frequency heat map and before/after."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from susp_bo.discrepancy.detection import DB_PER_NEPER, Detection
from susp_bo.discrepancy.report import DiagnosisReport


def _z_limit(*detections: Detection) -> float:
    """Colour-scale limit shared by heat maps drawn against one colour bar."""
    return max(4.0, *(float(np.nanmax(np.abs(d.z))) for d in detections))


def _heat_map(
    ax: object, detection: Detection, edges_hz: np.ndarray, title: str, limit: float | None = None
) -> object:
    """Z (channels × frequency) with flagged bins outlined; returns the image.

    ``limit`` is the colour-scale limit (default: this map's own, at least 4).
    """
    limit = _z_limit(detection) if limit is None else limit
    rows = np.arange(len(detection.channels) + 1) - 0.5
    image = ax.pcolormesh(  # type: ignore[attr-defined]
        edges_hz, rows, detection.z, cmap="RdBu_r", vmin=-limit, vmax=limit, shading="flat"
    )
    c_idx, f_idx = np.nonzero(detection.flagged)
    ax.scatter(  # type: ignore[attr-defined]
        np.sqrt(edges_hz[f_idx] * edges_hz[f_idx + 1]), c_idx, marker="s", s=10,
        facecolors="none", edgecolors="k", linewidths=0.8, label="flagged band (BH)",
    )  # fmt: skip
    ax.set_xscale("log")  # type: ignore[attr-defined]
    ax.set_yticks(range(len(detection.channels)))  # type: ignore[attr-defined]
    ax.set_yticklabels(detection.channels, fontsize=7)  # type: ignore[attr-defined]
    ax.set_xlabel("frequency (Hz)")  # type: ignore[attr-defined]
    ax.set_title(title, fontsize=9, loc="left")  # type: ignore[attr-defined]
    if c_idx.size:  # the markers' legend above the map's right corner, clear of the data
        ax.legend(  # type: ignore[attr-defined]
            loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False,
            borderaxespad=0.1, handletextpad=0.2,
        )  # fmt: skip
    return image


def heat_map_figure(
    detection: Detection, edges_hz: np.ndarray, path: Path | None = None, note: str = ""
) -> object:
    """The channel × frequency map of standardised residuals Z; saved when ``path`` is given
    (``note`` heads it in red, see :func:`before_after_figure`)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4), constrained_layout=True)
    image = _heat_map(ax, detection, edges_hz, f"standardised residual Z (BH q = {detection.q})")
    fig.colorbar(image, ax=ax, label="Z (+: model too little energy)")
    if note:
        fig.suptitle(note, fontsize=9, color="C3")
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


def before_after_figure(
    report: DiagnosisReport, path: Path | None = None, note: str = ""
) -> object:
    """Heat maps before/after adding the named effect and the worst channel's spectra.

    ``note`` (e.g. that the run was forced on a calibration that is not trusted) heads the
    figure in red, so that the file read alone does not contradict the verdict.
    """
    import matplotlib.pyplot as plt

    edges = report.problem.spec.spectrum.band_edges_hz()
    after = report.after if report.after is not None else report.before
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    limit = _z_limit(report.before, after)  # one colour bar for both maps
    _heat_map(
        axes[0], report.before, edges,
        f"before ({report.verdict}): gap {report.gap_before['value']:.3g}", limit,
    )  # fmt: skip
    label = report.named_effect or "nothing added"
    title = f"after ({label}): gap {report.gap_after['value']:.3g}"
    if report.after is None:
        title = f"{report.verdict}: nothing added, base model kept"
    elif not report.accepted:
        title += " — not better: base model kept"
    image = _heat_map(axes[1], after, edges, title, limit)
    fig.colorbar(image, ax=axes[:2], label="Z (+: model too little energy)")
    caption = "gap: mean Z² on the bins flagged before (≈ 1 or less: consistent with B)"
    if report.before.offsets:  # a level error shows as a uniform row: say it is one
        caption += "; whole channel level off: " + ", ".join(
            o.label() for o in report.before.offsets
        )
    if note:
        caption = f"{note} — {caption}"
    fig.suptitle(caption, fontsize=9, color="C3" if note else "0.2")
    channels = report.problem.spec.channels
    worst = (
        channels.index(report.before.bands[0].channel)
        if report.before.bands
        else channels.index(report.before.offsets[0].channel)
        if report.before.offsets
        else 0
    )
    f = report.before.frequencies_hz
    ax = axes[2]
    for i, run in enumerate(report.problem.measured):
        ax.plot(
            f, DB_PER_NEPER * run[worst], color="0.6", lw=0.8, label="measured" if i == 0 else None
        )
    before_mean = report.problem.measured.mean(axis=0)[worst] - report.before.residual[worst]
    ax.plot(f, DB_PER_NEPER * before_mean, "C3", lw=1.5, label="base model")
    if report.after is not None:
        after_mean = report.problem.measured.mean(axis=0)[worst] - report.after.residual[worst]
        ax.plot(f, DB_PER_NEPER * after_mean, "C0--", lw=1.5, label=f"with {label}")
    ax.set_xscale("log")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("dB re 1 (m/s²)/√Hz")
    ax.set_title(report.problem.spec.channels[worst], fontsize=9)
    ax.legend(fontsize=7)
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


def write_figures(report: DiagnosisReport, out: Path, note: str = "") -> list[Path]:
    """``discrepancy_heatmap.png`` and ``discrepancy_before_after.png`` in ``out`` (``note``:
    see :func:`before_after_figure`, also on the heat map)."""
    edges = report.problem.spec.spectrum.band_edges_hz()
    paths = [out / "discrepancy_heatmap.png", out / "discrepancy_before_after.png"]
    heat_map_figure(report.before, edges, paths[0], note)
    before_after_figure(report, paths[1], note)
    return paths
