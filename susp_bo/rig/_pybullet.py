"""PyBullet without its banners: the module and DIRECT clients, with C-level output silenced.

PyBullet prints ``pybullet build time: …`` when imported and ``argv[0]=`` when a
client connects, from C (``printf``), so Python's ``sys.stdout``/``sys.stderr``
redirection cannot stop them and they end up in every log. Here the import and
the connection run with the process's file descriptors 1 and 2 pointed at
``/dev/null`` (``os.dup2``), C's stdio buffers flushed before they are restored.
Import ``pybullet`` from this module (not directly) so the banner never prints.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator


def _flush_c_stdio() -> None:
    """``fflush(NULL)``: write out what C code left in its stdio buffers (best effort)."""
    with contextlib.suppress(OSError, AttributeError, TypeError):  # no libc symbols (Windows)
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def silenced_c_output() -> Iterator[None]:
    """Point file descriptors 1 and 2 at ``/dev/null`` for the block (Python streams flushed)."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, ValueError, OSError):
            stream.flush()
    try:
        saved = [os.dup(fd) for fd in (1, 2)]
    except OSError:  # no such descriptors (some embedded interpreters): nothing to silence
        yield
        return
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            os.dup2(null, fd)
        yield
    finally:
        _flush_c_stdio()
        for fd, copy in zip((1, 2), saved):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)


with silenced_c_output():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient


def direct_client() -> BulletClient:
    """A new PyBullet DIRECT client, connected without the ``argv[0]=`` banner."""
    with silenced_c_output():
        return BulletClient(connection_mode=pybullet.DIRECT)


__all__ = ["BulletClient", "direct_client", "pybullet", "silenced_c_output"]
