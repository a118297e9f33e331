"""``python -m susp_bo`` is the ``susp-bo`` command line."""

from __future__ import annotations

from susp_bo.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
