"""One writer per results folder: an advisory lock held while a study writes into it.

Two ``susp-bo calibrate`` (or ``demo``, ``monitor``) processes writing into one
``--out`` at once both ran on one evaluation store and left a folder whose
``study.toml`` came from one run and ``result.json`` from the other (an outside
probe, session 23). :func:`hold_output_folder` takes an exclusive, non-blocking
``flock`` on ``DIR/.susp-bo.lock`` (the file records the holder's pid and command),
and a second writer is refused at once, naming the holder. The operating system
releases the lock when the holder exits, however it exits (Ctrl-C, kill -9), so a
stale lock file never blocks a later run. :func:`refuse_if_busy` checks the same
lock without taking it, for the checks that run before the folder is made.

Where ``fcntl`` does not exist (Windows) the lock is skipped.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".susp-bo.lock"


class OutputFolderBusy(ValueError):
    """Another process is writing into the results folder."""


def _holder(path: Path) -> str:
    try:
        text = path.read_text(encoding="utf-8").strip()
    except OSError:
        text = ""
    return text or "another process"


def _busy(folder: Path, path: Path) -> OutputFolderBusy:
    return OutputFolderBusy(
        f"out: {folder} is in use by {_holder(path)}, which is writing its study there now; "
        "wait for it to finish (then --resume extends it), or choose another output folder "
        "(nothing was changed)"
    )


def refuse_if_busy(folder: Path) -> None:
    """Raise :class:`OutputFolderBusy` when another process holds ``folder``'s lock.

    Takes and releases the lock at once; does nothing when the folder or its lock file
    does not exist.
    """
    path = Path(folder) / LOCK_NAME
    if fcntl is None or not path.is_file():
        return
    try:
        with path.open("r") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise _busy(Path(folder), path) from None
            fcntl.flock(handle, fcntl.LOCK_UN)
    except OSError:  # unreadable lock file: the real attempt will say
        return


@contextlib.contextmanager
def hold_output_folder(folder: Path) -> Iterator[None]:
    """Hold ``folder``'s lock for the ``with`` block (the folder must exist).

    Raises:
        OutputFolderBusy: another process holds it (nothing is written).
    """
    if fcntl is None:  # pragma: no cover - Windows
        yield
        return
    path = Path(folder) / LOCK_NAME
    handle = path.open("a+", encoding="utf-8")
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise _busy(Path(folder), path) from None
        handle.seek(0)
        handle.truncate()
        program = " ".join([Path(sys.argv[0]).name, *sys.argv[1:2]]) if sys.argv else "python"
        handle.write(f"process {os.getpid()} ({program})\n")
        handle.flush()
        yield
    finally:
        handle.close()  # releases the lock
