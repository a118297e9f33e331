"""Where rig files live: by name in the shipped ``rigs/`` folder, or by path.

Rigs are data (TOML). In a source checkout they sit in ``<repo>/rigs``; in an
installed wheel they are shipped as ``susp_bo/rigs`` (see pyproject.toml).
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent.parent


def rig_directories() -> tuple[Path, ...]:
    """Folders searched for rig files, installed copy first.

    Returns:
        Existing folders, in search order.
    """
    candidates = (_PACKAGE_DIR / "rigs", _PACKAGE_DIR.parent / "rigs")
    return tuple(p for p in candidates if p.is_dir())


def available_rigs() -> tuple[str, ...]:
    """Names of the shipped rigs (file stems of ``rigs/*.toml``), sorted."""
    names: set[str] = set()
    for folder in rig_directories():
        names.update(p.stem for p in folder.glob("*.toml"))
    return tuple(sorted(names))


def rig_path(name_or_path: str | Path) -> Path:
    """Resolve a rig name (``"hst_trailer"``) or a path to a rig TOML file.

    Args:
        name_or_path: a shipped rig's name, with or without ``.toml``, or a path
            to a TOML file.

    Returns:
        The path of the rig file.

    Raises:
        FileNotFoundError: naming the rig and listing the rigs that exist.
    """
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" and candidate.is_file():
        return candidate
    stem = candidate.stem if candidate.suffix == ".toml" else str(name_or_path)
    for folder in rig_directories():
        path = folder / f"{stem}.toml"
        if path.is_file():
            return path
    raise FileNotFoundError(
        f"rig: no rig named {str(name_or_path)!r}; shipped rigs are "
        f"{', '.join(available_rigs()) or '(none)'}, or give a path to a .toml file"
    )
