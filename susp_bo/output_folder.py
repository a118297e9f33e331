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


def check_output_files(folder: str | Path, names: tuple[str, ...], label: str = "--out") -> None:
    """Refuse, before any work, an output file name that a folder (or other non-file) holds.

    Outside probe, session 29: ``result.json`` or a figure made a folder was found only when
    written, after the whole calibration (``[Errno 21] Is a directory``); ``monitor.json``
    after every campaign.

    Args:
        folder: the output folder (it may not exist yet: then nothing blocks).
        names: the file names the command will write there.
        label: the flag or config key that named the folder, for the message.

    Raises:
        ValueError: naming the first blocked path and what to do.
    """
    for name in names:
        path = Path(folder) / name
        if path.exists() and not path.is_file():
            what = "a folder" if path.is_dir() else "not a regular file"
            raise ValueError(
                f"{label}: {path} is {what}, where the results file {name} goes; move it away "
                "(nothing was computed)"
            )
