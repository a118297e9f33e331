"""Rig files are found by name (shipped with the package) or by path."""

from __future__ import annotations

from pathlib import Path

import pytest

from susp_bo.rig.catalog import available_rigs, rig_path


def test_reference_rig_is_shipped() -> None:
    assert "hst_trailer" in available_rigs()
    assert rig_path("hst_trailer").name == "hst_trailer.toml"
    assert rig_path("hst_trailer.toml") == rig_path("hst_trailer")


def test_path_to_a_file_is_accepted(tmp_path: Path) -> None:
    path = tmp_path / "my_rig.toml"
    path.write_text("name = 'x'\n")
    assert rig_path(path) == path


def test_unknown_rig_names_the_rig_and_the_alternatives() -> None:
    with pytest.raises(FileNotFoundError, match=r"'no_such_rig'.*hst_trailer"):
        rig_path("no_such_rig")
