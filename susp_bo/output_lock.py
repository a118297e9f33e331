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

A process that holds a folder may take it again (``demo`` holds its folder from the
synthesis of its runs to the study's last file, and the study takes it again); the
inner hold is then a no-op. Where ``fcntl`` does not exist (Windows) the lock is
skipped.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".susp-bo.lock"
_ATTEMPTS = 10
_PAUSE_S = 0.01
"""A busy lock is tried this often, this far apart: :func:`refuse_if_busy` takes it for an
instant, and a writer starting in that instant must not be refused for it."""
_HELD: set[Path] = set()
"""Folders this process holds (resolved paths)."""


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
        "wait for it to finish, then run yours again (calibrate: with --resume, which extends "
        "that study), or choose another output folder (nothing was changed)"
    )


def _lock(handle: IO[str], folder: Path, path: Path) -> None:
    for attempt in range(_ATTEMPTS):
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if attempt + 1 == _ATTEMPTS:
                raise _busy(folder, path) from None
            time.sleep(_PAUSE_S)


def refuse_if_busy(folder: Path) -> None:
    """Raise :class:`OutputFolderBusy` when another process holds ``folder``'s lock.

    Takes and releases the lock at once; does nothing when the folder or its lock file
    does not exist.
    """
    path = Path(folder) / LOCK_NAME
    if fcntl is None or not path.is_file() or Path(folder).resolve() in _HELD:
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
    key = Path(folder).resolve()
    if fcntl is None or key in _HELD:  # Windows; or held already by this process
        yield
        return
    path = Path(folder) / LOCK_NAME
    try:
        handle = path.open("a+", encoding="utf-8")
    except OSError as error:  # e.g. a lock file left by another user
        raise OutputFolderBusy(
            f"out: {path} cannot be opened ({error.strerror or error}); it marks the folder "
            "that one process writes at a time: make it writable, or choose another output "
            "folder (nothing was changed)"
        ) from None
    try:
        _lock(handle, Path(folder), path)
        _HELD.add(key)
        handle.seek(0)
        handle.truncate()
        program = " ".join([Path(sys.argv[0]).name, *sys.argv[1:2]]) if sys.argv else "python"
        handle.write(f"process {os.getpid()} ({program})\n")
        handle.flush()
        yield
    finally:
        _HELD.discard(key)
        handle.close()  # releases the lock
