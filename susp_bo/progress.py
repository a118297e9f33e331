"""Progress reports on stderr: tqdm bars on a terminal, plain periodic lines elsewhere.

Every progress bar of the package is made by :func:`progress_bar`. On a terminal
it is a tqdm bar (nested bars redraw in place). When stderr is not a terminal
(a log file, CI, a notebook, a pipe) redraws would leave carriage returns and
cursor-movement escape codes (``\\x1b[A``) in the output, so the bar is a
:class:`LineProgress` instead: one plain line ``desc: n/total (p %), t s`` when
it starts, at most every ``interval_s`` seconds while it runs, and when it
ends — no escape codes, no redraws.

``SUSP_BO_PROGRESS=lines`` forces plain lines, ``SUSP_BO_PROGRESS=bar`` forces
tqdm bars; ``SUSP_BO_PROGRESS_INTERVAL_S`` sets the line interval (default 30 s).
"""

from __future__ import annotations

import os
import sys
import time
from typing import IO, Any, Protocol

DEFAULT_INTERVAL_S = 30.0


class Progress(Protocol):
    """What the package's call sites use of a bar: ``update``, ``close``, a context."""

    def update(self, n: float = 1) -> Any: ...

    def close(self) -> None: ...

    def __enter__(self) -> Progress: ...

    def __exit__(self, *exc: object) -> None: ...


class LineProgress:
    """A progress report of plain, periodic lines (for streams that are not terminals).

    Args:
        total: the count at completion (None = unknown).
        desc: what is counted, e.g. ``"simulations"``.
        unit: the unit of the count, e.g. ``"run"``.
        file: the stream (default ``sys.stderr``).
        interval_s: least time between two intermediate lines (s).
        disable: print nothing.
    """

    def __init__(
        self,
        total: float | None = None,
        desc: str = "",
        unit: str = "it",
        file: IO[str] | None = None,
        interval_s: float = DEFAULT_INTERVAL_S,
        disable: bool = False,
    ) -> None:
        self.total, self.desc, self.unit = total, desc, unit
        self.file = file if file is not None else sys.stderr
        self.interval_s = float(interval_s)
        self.disable = disable
        self.n: float = 0
        self._start = time.monotonic()
        self._last = self._start
        self._closed = False
        self._written: float | None = None  # the count of the last line printed
        self._write()

    def _write(self) -> None:
        if self.disable:
            return
        self._written = self.n
        count = f"{self.n:g}" if self.total is None else f"{self.n:g}/{self.total:g}"
        share = f" ({100.0 * self.n / self.total:.0f} %)" if self.total else ""
        elapsed = time.monotonic() - self._start
        label = f"{self.desc}: " if self.desc else ""
        print(f"{label}{count} {self.unit}{share}, {elapsed:.0f} s", file=self.file, flush=True)

    def update(self, n: float = 1) -> None:
        """Add ``n`` to the count; print a line if ``interval_s`` has passed since the last."""
        self.n += n
        now = time.monotonic()
        if now - self._last >= self.interval_s:
            self._last = now
            self._write()

    def close(self) -> None:
        """Print the final line (once; not again when the last line printed has its count)."""
        if not self._closed:
            self._closed = True
            if self._written != self.n:
                self._write()

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _is_terminal(stream: IO[str]) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def redrawn_bars(file: IO[str] | None = None) -> bool:
    """Whether redrawn bars may go to ``file`` (default stderr): a terminal, or forced.

    For third-party bars (Pyro's) that cannot be replaced by :func:`progress_bar`:
    switch them off where this is False.
    """
    mode = os.environ.get("SUSP_BO_PROGRESS", "auto")
    return mode == "bar" or (mode != "lines" and _is_terminal(file or sys.stderr))


def progress_bar(
    total: float | None = None,
    desc: str = "",
    unit: str = "it",
    disable: bool = False,
    file: IO[str] | None = None,
    **tqdm_options: Any,
) -> Progress:
    """The progress bar of one loop: tqdm on a terminal, :class:`LineProgress` otherwise.

    Args:
        total: the count at completion.
        desc: what is counted.
        unit: the unit of the count.
        disable: show nothing.
        file: the stream (default ``sys.stderr``).
        **tqdm_options: further tqdm options (terminal only), e.g. ``mininterval``.

    Returns:
        An object with ``update(n)``, ``close()`` and the context-manager protocol.
    """
    stream = file if file is not None else sys.stderr
    if not redrawn_bars(stream):
        interval = float(os.environ.get("SUSP_BO_PROGRESS_INTERVAL_S", DEFAULT_INTERVAL_S))
        return LineProgress(total, desc, unit, stream, interval, disable)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=stream, disable=disable, **tqdm_options)
