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

Discovery fails with one clear message (naming the folder or file and what to fix)
on a missing vehicle or date, a vehicle id with leading or trailing whitespace,
runs of different vehicles or dates in one campaign, a manifest that contradicts
its runs, a ``campaign.toml`` in a folder without measured runs (an empty or
not yet imported campaign — CSV/MATLAB files get the ``susp-bo import`` hint — or
a manifest in a parent folder: a manifest applies only to the runs in its own
folder), two campaigns of the same vehicle on the same date, or two vehicle ids
that differ only in letter case or whose names give the same results folder
(e.g. ``etc`` and ``../../etc``): two vehicles never share a campaign id or a
results folder.
"""

from __future__ import annotations

import datetime as dt
import logging
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from susp_bo.calibration.study_inputs import import_hint
from susp_bo.data.measured import MeasuredDataError
from susp_bo.data.run_files import RUN_SUFFIXES, load_run, run_paths
from susp_bo.rig.toml_files import TomlFileError, read_toml

logger = logging.getLogger(__name__)

MANIFEST_NAME = "campaign.toml"
_MANIFEST_KEYS = ("vehicle", "date", "line")
_IMPORTED = (".csv", ".mat")  # what ``susp-bo import`` converts to measured runs


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


def _shown(value: object) -> str:
    """A value as a user wrote it: a date as YYYY-MM-DD (not ``datetime.date(…)``)."""
    return value.isoformat() if isinstance(value, dt.date) else repr(value)


def _manifest(folder: Path) -> dict[str, Any] | None:
    path = folder / MANIFEST_NAME
    if path.exists() and not path.is_file():  # a folder read as "no vehicle" (probe, s. 29)
        raise CampaignError(f"{path}: not a file; expected the campaign's settings (TOML)")
    if not path.is_file():
        return None
    try:
        data = read_toml(path)
    except TomlFileError as error:  # not UTF-8 text, or not valid TOML: names the file
        raise CampaignError(str(error)) from None
    unknown = sorted(set(data) - set(_MANIFEST_KEYS))
    if unknown:
        raise CampaignError(
            f"{path}: unknown keys {unknown}; allowed keys: {', '.join(_MANIFEST_KEYS)}"
        )
    return data


def _import_hint(folder: Path, name: str = "it") -> str:
    """``susp-bo calibrate``'s import hint, importing into the campaign folder itself (the
    runs go next to its ``campaign.toml``), else ``""``."""
    return import_hint(folder, name, out=folder)


def _check_manifest_folders(root: Path, run_folders: list[Path]) -> None:
    """Refuse a ``campaign.toml`` in a folder that holds no measured runs.

    Raises:
        CampaignError: naming the manifest, what it lacks and what to do — for a
            manifest above campaign folders, those folders (it is not inherited).
    """
    with_runs = set(run_folders)
    for manifest in sorted(root.rglob(MANIFEST_NAME)):
        folder = manifest.parent
        if not manifest.is_file() or folder in with_runs:
            continue
        below = [f for f in run_folders if folder in f.parents]
        if below:
            listed = ", ".join(str(f) for f in below[:3]) + (", …" if len(below) > 3 else "")
            raise CampaignError(
                f"{manifest}: a {MANIFEST_NAME} applies only to the measured runs in its own "
                f"folder, and {folder} holds none (*.h5, *.hdf5); it is not inherited by the "
                f"campaign folders below it ({listed}){_import_hint(folder)}; move it into the "
                "campaign folder it describes (one per campaign) or delete it"
            )
        raise CampaignError(
            f"{folder}: has a {MANIFEST_NAME} but holds no measured runs (*.h5, *.hdf5)"
            f"{_import_hint(folder)}; put the campaign's runs next to its {MANIFEST_NAME}, "
            "or remove the folder if the campaign does not exist"
        )


def _check_vehicle(value: object, where: str) -> None:
    """Refuse a vehicle id with leading or trailing whitespace.

    Raises:
        CampaignError: naming ``where``, the value and what is allowed.
    """
    text = str(value)
    if text != text.strip():
        expected = (
            f"write it without the whitespace ({text.strip()!r})"
            if text.strip()
            else "expected a vehicle id"
        )
        raise CampaignError(
            f"{where}: vehicle {text!r} has leading or trailing whitespace, which is not "
            f"allowed (it would be another vehicle with the same results folder); {expected}"
        )


def _vehicle_source(campaign: Campaign) -> str:
    """Where the vehicle of ``campaign`` is given: its manifest, or its runs' metadata."""
    manifest = _manifest(campaign.folder)
    if manifest is not None and "vehicle" in manifest:
        return str(campaign.folder / MANIFEST_NAME)
    return f"{campaign.folder}, run metadata"


def _check_vehicle_names(root: Path, campaigns: list[Campaign]) -> None:
    """Refuse two vehicle ids equal once letter case is ignored, or with one results folder.

    Raises:
        CampaignError: naming both vehicles and where each is given.
    """
    first: dict[str, Campaign] = {}
    for campaign in sorted(campaigns, key=lambda c: (c.vehicle, c.date)):
        first.setdefault(campaign.vehicle, campaign)
    by_case: dict[str, Campaign] = {}
    by_folder: dict[str, Campaign] = {}
    for vehicle, campaign in first.items():
        case_key, folder_key = vehicle.casefold(), safe_name(vehicle).casefold()
        other = by_case.get(case_key) or by_folder.get(folder_key)
        if other is not None:
            both = (
                f"vehicle {other.vehicle!r} ({_vehicle_source(other)}) and vehicle "
                f"{vehicle!r} ({_vehicle_source(campaign)})"
            )
            if other.vehicle.casefold() == case_key:
                problem = (
                    "differ only in letter case, which is not allowed: two vehicles must not "
                    f"share campaign ids and results folders ({safe_name(other.vehicle)!r} and "
                    f"{safe_name(vehicle)!r} are one folder where case is not told apart)"
                )
            else:
                problem = (
                    f"would share the results folder {safe_name(vehicle)!r} and its campaign "
                    f"ids '{safe_name(vehicle)}/<date>' (a vehicle's results folder keeps only "
                    "letters, digits, '-', '_' and '.')"
                )
            raise CampaignError(
                f"{root}: {both} {problem}; if they are one vehicle, spell it the same way "
                f"everywhere, else rename one of them in its {MANIFEST_NAME} or run metadata"
            )
        by_case[case_key] = campaign
        by_folder[folder_key] = campaign


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
        CampaignError: no runs, unreadable runs, missing vehicle or date, a vehicle
            with leading or trailing whitespace, disagreeing runs, or a manifest that
            contradicts the runs.
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
    if manifest is not None and manifest.get("vehicle") not in (None, ""):
        _check_vehicle(manifest["vehicle"], str(folder / MANIFEST_NAME))
    if from_runs["vehicle"] not in (None, ""):
        _check_vehicle(
            from_runs["vehicle"],
            f"{folder}: run metadata of {', '.join(p.name for p in paths)}",
        )
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
                    f"{folder / MANIFEST_NAME}: {key} = {_shown(value)} contradicts the runs' "
                    f"metadata ({key} = {_shown(ours)})"
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
        CampaignError: no campaign at all, a ``campaign.toml`` in a folder without
            measured runs, a campaign that cannot be identified, two campaigns of the
            same vehicle on the same date, or two vehicles whose ids differ only in
            letter case or give the same results folder (both named as given).
    """
    root = Path(folder)
    if not root.is_dir():
        raise CampaignError(f"{root}: not a folder (expected a monitoring folder of campaigns)")
    folders = sorted(
        {p.parent for p in root.rglob("*") if p.is_file() and p.suffix in RUN_SUFFIXES}
    )
    _check_manifest_folders(root, folders)
    if not folders:
        unimported = sorted(
            {p.parent for p in root.rglob("*") if p.is_file() and p.suffix.lower() in _IMPORTED}
        )
        raise CampaignError(
            f"{root}: holds no campaign (no folder with measured runs *.h5, *.hdf5)"
            + (_import_hint(unimported[0], str(unimported[0])) if unimported else "")
        )
    campaigns = [read_campaign(f) for f in folders]
    _check_vehicle_names(root, campaigns)
    seen: dict[str, Campaign] = {}
    for campaign in campaigns:
        other = seen.get(campaign.campaign_id)
        if other is not None:
            raise CampaignError(
                f"{root}: two campaigns of vehicle {campaign.vehicle!r} on "
                f"{campaign.date.isoformat()}: {other.folder} and {campaign.folder}; merge "
                "their runs into one folder (one campaign = one vehicle on one date)"
            )
        seen[campaign.campaign_id] = campaign
    _warn_future_dates(campaigns)
    return sorted(campaigns, key=lambda c: (c.vehicle, c.date))


def _warn_future_dates(campaigns: list[Campaign], today: dt.date | None = None) -> None:
    """A warning (not a refusal: a result must not depend on the day it is computed) for
    campaigns dated after ``today``: a mistyped year would put a campaign last in its
    vehicle's history, where it sets the alarm state."""
    today = dt.date.today() if today is None else today
    for campaign in campaigns:
        if campaign.date > today:
            logger.warning(
                "%s: campaign date %s is after today (%s): a mistyped date? Campaigns are "
                "followed in date order, so this one counts as %s's latest",
                campaign.folder,
                campaign.date.isoformat(),
                today.isoformat(),
                campaign.vehicle,
            )
