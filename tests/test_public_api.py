"""Every name of the public API resolves, and importing the package stays light."""

from __future__ import annotations

import subprocess
import sys

import susp_bo


def test_every_exported_name_resolves() -> None:
    for name in susp_bo.__all__:
        assert getattr(susp_bo, name) is not None, name


def test_import_does_not_load_torch_or_pybullet() -> None:
    code = "import sys, susp_bo; print('torch' in sys.modules, 'pybullet' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "False"]
