"""Figures of rig responses: acceleration time signals and log-amplitude spectra."""

from __future__ import annotations

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
    fig, axes = plt.subplots(
        n, 2, figsize=(11, 1.6 * n + 1), squeeze=False, sharex="col", constrained_layout=True
    )
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
    fig.suptitle(title)  # constrained layout keeps it clear of the column titles
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
