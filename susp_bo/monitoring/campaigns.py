"""Measurement campaigns: the measured runs of one vehicle on one date.

A monitoring folder holds one sub-folder per campaign (at any depth); a
campaign folder is a folder that directly holds measured runs (``*.h5`` /
``*.hdf5``, the format of :mod:`susp_bo.data.measured`). Its identity —
vehicle, date and (optionally) line — comes from

1. a ``campaign.toml`` manifest in the folder, if present::

       vehicle = "CR400-0042"   # vehicle (car) identifier
       date = 2026-03-14        # TOML date, or "2026-03-14"
       line = "Beijing-Shanghai"  # optional

2. else the runs' metadata (keys ``vehicle``, ``date``, ``line``; every run of
   the folder must agree).

Discovery fails with one clear message (naming the folder and what to fix) on a
missing vehicle or date, runs of different vehicles or dates in one campaign,
a manifest that contradicts its runs, or two campaigns of the same vehicle on
the same date (or of two vehicles whose names give the same results folder, e.g.
``etc`` and ``../../etc``).
"""

from __future__ import annotations

import datetime as dt
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from susp_bo.data.measured import RUN_SUFFIXES, MeasuredDataError, load_run, run_paths

MANIFEST_NAME = "campaign.toml"
_MANIFEST_KEYS = ("vehicle", "date", "line")


class CampaignError(ValueError):
    """A monitoring folder whose campaigns cannot be identified unambiguously."""


@dataclass(frozen=True)
class Campaign:
    """One measurement campaign.

    Attributes:
        vehicle: vehicle identifier.
        date: date of the measurement.
        folder: the folder of its measured runs.
        line: the line it ran on ("" when unknown).
        n_runs: number of measured runs.
        truth: true parameter values when every run is synthetic with the same
            truth (known-answer scenarios), else None.
    """

    vehicle: str
    date: dt.date
    folder: Path
    line: str = ""
    n_runs: int = 0
    truth: Mapping[str, float] | None = None

    @property
    def campaign_id(self) -> str:
        """``<vehicle>/<date>``: unique in a monitoring folder, used as the result sub-folder."""
        return f"{safe_name(self.vehicle)}/{self.date.isoformat()}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "id": self.campaign_id,
            "vehicle": self.vehicle,
            "date": self.date.isoformat(),
            "line": self.line,
            "folder": str(self.folder),
            "n_runs": self.n_runs,
            "truth": None if self.truth is None else dict(self.truth),
        }


def safe_name(text: str) -> str:
    """``text`` as a file-name component (letters, digits, ``-``, ``_``, ``.``)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "_"


def parse_date(value: object, where: str) -> dt.date:
    """A date from a TOML date, a ``datetime`` or an ISO ``YYYY-MM-DD`` string.

    Raises:
        CampaignError: naming ``where`` and the value.
    """
    if isinstance(value, dt.datetime):
        return value.date()
    if isinstance(value, dt.date):
        return value
    if isinstance(value, str):
        try:
            return dt.date.fromisoformat(value.strip()[:10])
        except ValueError:
            pass
    raise CampaignError(f"{where}: date {value!r} is not a date; expected YYYY-MM-DD")


def _manifest(folder: Path) -> dict[str, Any] | None:
    path = folder / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as error:
        raise CampaignError(f"{path}: not valid TOML ({error})") from None
    unknown = sorted(set(data) - set(_MANIFEST_KEYS))
    if unknown:
        raise CampaignError(
            f"{path}: unknown keys {unknown}; allowed keys: {', '.join(_MANIFEST_KEYS)}"
        )
    return data


def _agreed(values: dict[Path, object], key: str, folder: Path) -> object:
    """The one value every run gives for ``key`` (None if no run gives it)."""
    given = {path: value for path, value in values.items() if value not in (None, "")}
    distinct = sorted({str(v) for v in given.values()})
    if len(distinct) > 1:
        detail = ", ".join(f"{p.name}: {v}" for p, v in sorted(given.items()))
        what = {"vehicle": "vehicles", "date": "dates", "line": "lines"}[key]
        raise CampaignError(
            f"{folder}: runs of different {what} in one campaign ({detail}); a campaign is one "
            f"vehicle on one date — put each {key} in its own folder"
        )
    if given and len(given) < len(values):
        missing = sorted(p.name for p in values if p not in given)
        raise CampaignError(
            f"{folder}: runs {missing} have no {key!r} in their metadata while the others "
            f"give {distinct[0]!r}; add it, or write a {MANIFEST_NAME}"
        )
    return next(iter(given.values()), None)


def read_campaign(folder: str | Path) -> Campaign:
    """The campaign of one folder of measured runs.

    Raises:
        CampaignError: no runs, unreadable runs, missing vehicle or date,
            disagreeing runs, or a manifest that contradicts the runs.
    """
    folder = Path(folder)
    paths = run_paths(folder)
    if not paths:
        raise CampaignError(f"{folder}: holds no measured runs (*.h5, *.hdf5)")
    metadata: dict[Path, Mapping[str, Any]] = {}
    for path in paths:
        try:
            metadata[path] = load_run(path, allow_nan=True).metadata or {}
        except MeasuredDataError as error:
            raise CampaignError(f"{folder}: {error}") from None
    from_runs = {
        key: _agreed({p: m.get(key) for p, m in metadata.items()}, key, folder)
        for key in _MANIFEST_KEYS
    }
    manifest = _manifest(folder)
    values = dict(from_runs)
    if manifest is not None:
        for key, value in manifest.items():
            ours = from_runs[key]
            if key == "date" and ours is not None:
                same = parse_date(value, str(folder / MANIFEST_NAME)) == parse_date(
                    ours, f"{folder}: run metadata"
                )
            else:
                same = ours is None or str(ours) == str(value)
            if not same:
                raise CampaignError(
                    f"{folder / MANIFEST_NAME}: {key} = {value!r} contradicts the runs' "
                    f"metadata ({key} = {ours!r})"
                )
            values[key] = value
    hint = (
        f'give it in {folder / MANIFEST_NAME} (vehicle = "…", date = YYYY-MM-DD) '
        "or in the runs' metadata"
    )
    if values["vehicle"] in (None, ""):
        raise CampaignError(f"{folder}: no vehicle for this campaign; {hint}")
    if values["date"] in (None, ""):
        raise CampaignError(f"{folder}: no date for this campaign; {hint}")
    truths = [m.get("truth") for m in metadata.values()]
    truth = truths[0] if all(t == truths[0] and isinstance(t, dict) for t in truths) else None
    return Campaign(
        vehicle=str(values["vehicle"]),
        date=parse_date(values["date"], str(folder)),
        folder=folder,
        line=str(values["line"] or ""),
        n_runs=len(paths),
        truth=None if truth is None else {str(k): float(v) for k, v in truth.items()},
    )


def discover_campaigns(folder: str | Path) -> list[Campaign]:
    """Every campaign under ``folder``, sorted by vehicle then date.

    Raises:
        CampaignError: no campaign at all, a campaign that cannot be identified,
            or two campaigns of the same vehicle on the same date (or of two vehicles
            whose names give the same results folder: both named as given).
    """
    root = Path(folder)
    if not root.is_dir():
        raise CampaignError(f"{root}: not a folder (expected a monitoring folder of campaigns)")
    folders = sorted(
        {p.parent for p in root.rglob("*") if p.is_file() and p.suffix in RUN_SUFFIXES}
    )
    if not folders:
        raise CampaignError(
            f"{root}: holds no campaign (no folder with measured runs *.h5, *.hdf5)"
        )
    campaigns = [read_campaign(f) for f in folders]
    seen: dict[str, Campaign] = {}
    for campaign in campaigns:
        other = seen.get(campaign.campaign_id)
        if other is not None and other.vehicle != campaign.vehicle:
            raise CampaignError(
                f"{root}: vehicle {other.vehicle!r} ({other.folder}) and vehicle "
                f"{campaign.vehicle!r} ({campaign.folder}) on {campaign.date.isoformat()} "
                f"would share the same results folder {campaign.campaign_id!r} (a vehicle's "
                "results folder keeps only letters, digits, '-', '_' and '.'); rename one of "
                f"the vehicles in its {MANIFEST_NAME} or run metadata"
            )
        if other is not None:
            raise CampaignError(
                f"{root}: two campaigns of vehicle {campaign.vehicle!r} on "
                f"{campaign.date.isoformat()}: {other.folder} and {campaign.folder}; merge "
                "their runs into one folder (one campaign = one vehicle on one date)"
            )
        seen[campaign.campaign_id] = campaign
    return sorted(campaigns, key=lambda c: (c.vehicle, c.date))
