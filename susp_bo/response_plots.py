"""Figures of rig responses: acceleration time signals and log-amplitude spectra."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

if TYPE_CHECKING:
    from susp_bo.rig.simulator import RigResponse
    from susp_bo.rig.spectra import Spectra


def plot_response(
    response: RigResponse, spectra: Spectra, path: Path, title: str = "", seconds: float = 10.0
) -> Path:
    """Save a two-column figure: time signals (first ``seconds`` s) and spectra per channel.

    Args:
        response: the rig response (channels x time).
        spectra: its log-amplitude spectra.
        path: output PNG.
        title: figure title.
        seconds: length of the time window shown (s).

    Returns:
        ``path``.
    """
    n = len(response.channels)
    fig, axes = plt.subplots(n, 2, figsize=(11, 1.6 * n + 1), squeeze=False, sharex="col")
    keep = response.time_s <= response.time_s[0] + seconds
    for row, channel in enumerate(response.channels):
        axes[row, 0].plot(response.time_s[keep], response.accelerations_m_s2[row, keep], lw=0.6)
        axes[row, 0].set_ylabel(f"{channel}\nm/s²", fontsize=7)
        axes[row, 1].semilogx(spectra.frequencies_hz, spectra.channel(channel), lw=1.0)
        axes[row, 1].set_ylabel("ln ASD", fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    axes[-1, 1].set_xlabel("frequency (Hz)")
    axes[0, 0].set_title("accelerations")
    axes[0, 1].set_title("log-amplitude spectra, ln((m/s²)/√Hz)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_spectra_comparison(
    frequencies_hz: Sequence[float],
    channels: Sequence[str],
    curves: dict[str, object],
    path: Path,
    title: str = "",
) -> Path:
    """Overlay spectra sets (label -> (C x F) array) channel by channel; save to ``path``."""
    import numpy as np

    n = len(channels)
    cols = 2
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(10, 2.2 * rows + 0.8), squeeze=False)
    for index, channel in enumerate(channels):
        ax = axes[index // cols, index % cols]
        for label, values in curves.items():
            ax.semilogx(frequencies_hz, np.asarray(values)[index], lw=1.0, label=label)
        ax.set_title(channel, fontsize=8)
        ax.set_xlabel("Hz", fontsize=7)
    for index in range(n, rows * cols):
        axes[index // cols, index % cols].axis("off")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
