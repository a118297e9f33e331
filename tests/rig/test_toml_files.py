"""Reading the tool's TOML files: not UTF-8 or not TOML is refused naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from susp_bo.rig.toml_files import TomlFileError, read_toml


def test_a_utf8_document_is_read(tmp_path: Path) -> None:
    path = tmp_path / "a.toml"
    path.write_text('name = "Kö"\n[t]\nx = 1.5\n', encoding="utf-8")
    assert read_toml(path) == {"name": "Kö", "t": {"x": 1.5}}


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        (b"\xff\xfe\x00", r"not a UTF-8 text file \(byte 0xff at position 0 is not UTF-8\)"),
        ('x = "é"'.encode("latin-1"), r"byte 0xe9 at position 5"),
        (b"x = [1,\n", r"not valid TOML"),
    ],
)
def test_bad_bytes_or_syntax_are_refused_naming_the_file(
    tmp_path: Path, raw: bytes, message: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_bytes(raw)
    with pytest.raises(TomlFileError, match=message) as raised:
        read_toml(path)
    assert str(raised.value).startswith(f"{path}: ")
    assert isinstance(raised.value, ValueError)  # the commands turn it into exit code 2
