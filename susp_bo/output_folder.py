"""Output folders: refuse, before any work, a path that cannot become a folder; the names
of the files a study writes into its results folder (light to import: the commands check a
results folder with them before loading torch)."""

from __future__ import annotations

from pathlib import Path

RESULT_NAME = "result.json"
CONFIG_NAME = "study.toml"
LOG_NAME = "study.log"
SAMPLES_NAME = "posterior_samples.npy"
FIGURE_NAMES = ("fig1_parameters.png", "fig2_marginals.png", "pairs.png")
"""The posterior figures of a result (:func:`susp_bo.plots.posterior_figures`)."""


def check_output_folder(path: str | Path, label: str = "--out") -> Path:
    """Return ``path`` if it is an existing folder or can be created as one.

    Args:
        path: the output folder.
        label: the flag or config key that named it, for the message.

    Raises:
        ValueError: ``path`` (or one of its parents) is an existing file, e.g.
            ``"--out: results.json is an existing file; expected a folder …"``.
    """
    folder = Path(path)
    for candidate in (folder, *folder.parents):
        if candidate.exists():
            if not candidate.is_dir():
                where = "" if candidate == folder else f" (its parent {candidate} is a file)"
                raise ValueError(
                    f"{label}: {str(folder)!r} is not allowed{where}; "
                    f"{candidate} is an existing file, expected a folder (existing or new)"
                )
            break
    return folder
