"""Result files: numpy values become plain JSON, non-finite numbers become null."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from susp_bo.json_files import json_ready, write_json


def test_json_ready_converts_numpy_and_non_finite_values(tmp_path: Path) -> None:
    value = {"a": np.array([1.0, np.nan]), 3: (np.float64(np.inf), np.int64(2)), "s": "x"}
    assert json_ready(value) == {"a": [1.0, None], "3": [None, 2], "s": "x"}
    write_json(tmp_path / "r.json", json_ready(value))
    assert json.loads((tmp_path / "r.json").read_text())["a"] == [1.0, None]
    assert not (tmp_path / "r.json.tmp").exists()


def test_write_json_refuses_nan_rather_than_writing_invalid_json(tmp_path: Path) -> None:
    with pytest.raises(ValueError):
        write_json(tmp_path / "bad.json", {"x": float("nan")})
    assert not (tmp_path / "bad.json").exists()
