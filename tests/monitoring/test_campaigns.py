"""Campaign discovery: vehicle, date and line from manifests or run metadata; clear errors."""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from susp_bo.data.measured import MeasuredRun, save_run
from susp_bo.monitoring.campaigns import CampaignError, discover_campaigns, read_campaign
from susp_bo.rig.track import SpeedProfile, TrackGeometry


def _run(seed: int, **metadata: object) -> MeasuredRun:
    rng = np.random.default_rng(seed)
    return MeasuredRun(
        geometry=TrackGeometry.synthetic("low", length_m=100.0, seed=seed),
        speed=SpeedProfile.constant(20.0, 4.0),
        channels=("a", "b"),
        accelerations_m_s2=rng.normal(0.0, 0.3, size=(2, 400)),
        sample_rate_hz=100.0,
        units=("m/s^2", "m/s^2"),
        metadata=dict(metadata),
    )


def _campaign(folder: Path, *metadata: dict, manifest: str | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for index, meta in enumerate(metadata):
        save_run(_run(index, **meta), folder / f"run_{index:03d}.h5")
    if manifest is not None:
        (folder / "campaign.toml").write_text(manifest)
    return folder


def test_campaigns_from_metadata_and_manifests_sorted_by_vehicle_then_date(tmp_path: Path) -> None:
    meta = {"vehicle": "B-7", "date": "2026-03-01", "line": "L1", "truth": {"x": 1.0}}
    _campaign(tmp_path / "b" / "march", meta, meta)
    _campaign(tmp_path / "a_feb", {}, manifest='vehicle = "A 1"\ndate = 2026-02-01\n')
    _campaign(tmp_path / "a_jan", {}, manifest='vehicle = "A 1"\ndate = "2026-01-10"\n')
    campaigns = discover_campaigns(tmp_path)
    assert [(c.vehicle, c.date) for c in campaigns] == [
        ("A 1", dt.date(2026, 1, 10)),
        ("A 1", dt.date(2026, 2, 1)),
        ("B-7", dt.date(2026, 3, 1)),
    ]
    assert campaigns[0].campaign_id == "A_1/2026-01-10"
    assert campaigns[2].line == "L1" and campaigns[2].n_runs == 2
    assert campaigns[2].truth == {"x": 1.0}
    assert campaigns[0].truth is None


def test_missing_date_names_the_folder_and_the_fix(tmp_path: Path) -> None:
    folder = _campaign(tmp_path / "c", {"vehicle": "A"})
    with pytest.raises(CampaignError, match=r"no date for this campaign; give it in") as caught:
        read_campaign(folder)
    assert str(folder) in str(caught.value) and "campaign.toml" in str(caught.value)


def test_missing_vehicle_is_refused(tmp_path: Path) -> None:
    with pytest.raises(CampaignError, match="no vehicle"):
        read_campaign(_campaign(tmp_path / "c", {"date": "2026-01-01"}))


def test_mixed_vehicles_in_one_campaign_are_refused(tmp_path: Path) -> None:
    folder = _campaign(
        tmp_path / "c",
        {"vehicle": "A", "date": "2026-01-01"},
        {"vehicle": "B", "date": "2026-01-01"},
    )
    with pytest.raises(CampaignError, match=r"runs of different vehicles in one campaign.*A.*B"):
        read_campaign(folder)


def test_mixed_dates_and_partial_metadata_are_refused(tmp_path: Path) -> None:
    mixed = _campaign(
        tmp_path / "m",
        {"vehicle": "A", "date": "2026-01-01"},
        {"vehicle": "A", "date": "2026-01-02"},
    )
    with pytest.raises(CampaignError, match="different dates"):
        read_campaign(mixed)
    partial = _campaign(tmp_path / "p", {"vehicle": "A", "date": "2026-01-01"}, {"vehicle": "A"})
    with pytest.raises(CampaignError, match=r"run_001.h5'\] have no 'date'"):
        read_campaign(partial)


def test_a_manifest_that_contradicts_the_runs_is_refused(tmp_path: Path) -> None:
    folder = _campaign(
        tmp_path / "c",
        {"vehicle": "A", "date": "2026-01-01"},
        manifest='vehicle = "A"\ndate = 2026-01-02\n',
    )
    # the date as written, not as Python's repr (datetime.date(2026, 1, 2))
    with pytest.raises(
        CampaignError,
        match=r"date = 2026-01-02 contradicts the runs' metadata \(date = '2026-01-01'\)",
    ):
        read_campaign(folder)
    (folder / "campaign.toml").write_text('vehicle = "A"\ndate = 2026-01-01\nspeed = 3\n')
    with pytest.raises(CampaignError, match=r"unknown keys \['speed'\]"):
        read_campaign(folder)
    (folder / "campaign.toml").write_text('vehicle = "A"\ndate = "yesterday"\n')
    with pytest.raises(CampaignError, match=r"'yesterday' is not a date; expected YYYY-MM-DD"):
        read_campaign(folder)


def test_two_campaigns_of_one_vehicle_on_one_date_are_refused(tmp_path: Path) -> None:
    meta = {"vehicle": "A", "date": "2026-01-01"}
    _campaign(tmp_path / "one", meta)
    _campaign(tmp_path / "two", meta)
    with pytest.raises(CampaignError, match=r"two campaigns of vehicle 'A' on 2026-01-01"):
        discover_campaigns(tmp_path)


def test_two_vehicles_whose_names_make_one_results_folder_are_both_named(tmp_path: Path) -> None:
    """'etc' and '../../etc' are different vehicles with the same results sub-folder 'etc'."""
    first = _campaign(tmp_path / "a", {}, manifest='vehicle = "etc"\ndate = 2026-01-01\n')
    second = _campaign(tmp_path / "b", {}, manifest='vehicle = "../../etc"\ndate = 2026-01-01\n')
    with pytest.raises(CampaignError) as raised:
        discover_campaigns(tmp_path)
    message = str(raised.value)
    assert f"vehicle 'etc' ({first / 'campaign.toml'})" in message
    assert f"vehicle '../../etc' ({second / 'campaign.toml'})" in message
    assert "would share the results folder 'etc'" in message
    assert "merge their runs" not in message  # two vehicles: renaming one is the fix


def test_an_empty_folder_holds_no_campaign(tmp_path: Path) -> None:
    with pytest.raises(CampaignError, match="holds no campaign"):
        discover_campaigns(tmp_path)
    with pytest.raises(CampaignError, match="not a folder"):
        discover_campaigns(tmp_path / "missing")


def test_replace_keeps_campaign_frozen(tmp_path: Path) -> None:
    campaign = read_campaign(_campaign(tmp_path / "c", {"vehicle": "A", "date": "2026-01-01"}))
    with pytest.raises(dataclasses.FrozenInstanceError):
        campaign.vehicle = "B"  # type: ignore[misc]


def test_two_vehicles_with_one_results_folder_are_refused_on_different_dates(
    tmp_path: Path,
) -> None:
    """'etc' and '../../etc' on two dates: one results folder 'etc' for two vehicles."""
    first = _campaign(tmp_path / "a", {}, manifest='vehicle = "etc"\ndate = 2026-01-01\n')
    second = _campaign(tmp_path / "b", {}, manifest='vehicle = "../../etc"\ndate = 2026-02-01\n')
    with pytest.raises(CampaignError) as raised:
        discover_campaigns(tmp_path)
    message = str(raised.value)
    assert str(first / "campaign.toml") in message and str(second / "campaign.toml") in message
    assert "would share the results folder 'etc'" in message


@pytest.mark.parametrize("vehicle", ["TRAIN-A ", " TRAIN-A", "TRAIN-A\t", "  "])
def test_a_vehicle_with_surrounding_whitespace_in_a_manifest_is_refused(
    tmp_path: Path, vehicle: str
) -> None:
    manifest = tomli_w.dumps({"vehicle": vehicle, "date": dt.date(2026, 4, 15)})
    folder = _campaign(tmp_path / "c", {}, manifest=manifest)
    with pytest.raises(CampaignError, match="leading or trailing whitespace") as raised:
        read_campaign(folder)
    message = str(raised.value)
    assert message.startswith(f"{folder / 'campaign.toml'}: vehicle {vehicle!r}")


def test_a_vehicle_with_surrounding_whitespace_in_run_metadata_is_refused(tmp_path: Path) -> None:
    folder = _campaign(tmp_path / "c", {"vehicle": "TRAIN-A ", "date": "2026-04-15"})
    with pytest.raises(CampaignError, match="leading or trailing whitespace") as raised:
        read_campaign(folder)
    message = str(raised.value)
    assert str(folder) in message and "run_000.h5" in message and "'TRAIN-A '" in message
    assert "without the whitespace ('TRAIN-A')" in message


def test_the_testers_three_spellings_of_one_vehicle_are_refused(tmp_path: Path) -> None:
    """'TRAIN-A', 'TRAIN-A ' and 'train-a' were three vehicles, two sharing id and folder."""
    spellings = (("TRAIN-A", "2026-03-15"), ("TRAIN-A ", "2026-04-15"), ("train-a", "2026-05-15"))
    for index, (name, date) in enumerate(spellings):
        _campaign(
            tmp_path / f"v{index}" / date, {}, manifest=f'vehicle = "{name}"\ndate = {date}\n'
        )
    with pytest.raises(CampaignError, match=r"vehicle 'TRAIN-A ' has leading or trailing"):
        discover_campaigns(tmp_path)


def test_vehicle_ids_equal_but_for_letter_case_are_refused(tmp_path: Path) -> None:
    upper = _campaign(
        tmp_path / "A" / "march", {}, manifest='vehicle = "TRAIN-A"\ndate = 2026-03-15\n'
    )
    lower = _campaign(tmp_path / "a" / "april", {"vehicle": "train-a", "date": "2026-04-15"})
    with pytest.raises(CampaignError, match="differ only in letter case") as raised:
        discover_campaigns(tmp_path)
    message = str(raised.value)
    assert f"vehicle 'TRAIN-A' ({upper / 'campaign.toml'})" in message
    assert f"vehicle 'train-a' ({lower}, run metadata)" in message


def test_a_campaign_toml_without_runs_is_refused(tmp_path: Path) -> None:
    """An empty campaign next to a real one was silently left out."""
    _campaign(tmp_path / "TRAIN-A" / "2026-03-15", {"vehicle": "TRAIN-A", "date": "2026-03-15"})
    empty = tmp_path / "TRAIN-A" / "2026-04-15"
    empty.mkdir(parents=True)
    (empty / "campaign.toml").write_text('vehicle = "TRAIN-A"\ndate = 2026-04-15\n')
    with pytest.raises(CampaignError) as raised:
        discover_campaigns(tmp_path)
    message = str(raised.value)
    assert message.startswith(f"{empty}: has a campaign.toml but holds no measured runs")
    assert "susp-bo import" not in message


def test_a_campaign_of_csv_files_not_yet_imported_gets_the_import_hint(tmp_path: Path) -> None:
    _campaign(tmp_path / "TRAIN-A" / "2026-03-15", {"vehicle": "TRAIN-A", "date": "2026-03-15"})
    raw = tmp_path / "TRAIN-A" / "2026-04-15"
    raw.mkdir(parents=True)
    (raw / "campaign.toml").write_text('vehicle = "TRAIN-A"\ndate = 2026-04-15\n')
    for role in ("accelerations", "geometry"):
        (raw / f"run1_{role}.csv").write_text("x\n")
    with pytest.raises(CampaignError) as raised:
        discover_campaigns(tmp_path)
    message = str(raised.value)
    assert message.startswith(f"{raw}: has a campaign.toml but holds no measured runs")
    assert "it holds 2 .csv files: convert them to the HDF5 measured-run format first" in message
    assert f"susp-bo import csv {raw} --out {raw} --rig RIG" in message


def test_a_folder_of_csv_files_only_gets_the_import_hint(tmp_path: Path) -> None:
    raw = tmp_path / "TRAIN-A" / "2026-04-15"
    raw.mkdir(parents=True)
    (raw / "run1_accelerations.csv").write_text("x\n")
    with pytest.raises(CampaignError, match="holds no campaign") as raised:
        discover_campaigns(tmp_path)
    assert f"{raw} holds 1 .csv files: convert them" in str(raised.value)


@pytest.mark.parametrize("parent", [".", "TRAIN-A"])
def test_a_campaign_toml_in_a_parent_folder_is_refused(tmp_path: Path, parent: str) -> None:
    """A manifest is not inherited: one above the campaign folders is refused, not ignored."""
    campaign = _campaign(
        tmp_path / "TRAIN-A" / "2026-03-15", {"vehicle": "TRAIN-A", "date": "2026-03-15"}
    )
    stray = tmp_path / parent / "campaign.toml"
    stray.write_text('vehicle = "TRAIN-A"\n')
    with pytest.raises(CampaignError) as raised:
        discover_campaigns(tmp_path)
    message = str(raised.value)
    assert message.startswith(f"{stray}: a campaign.toml applies only to the measured runs")
    assert f"not inherited by the campaign folders below it ({campaign})" in message


def test_a_campaign_dated_after_today_is_warned_about_not_refused(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A mistyped year (2062 for 2026) would make a campaign its vehicle's latest, where it
    sets the alarm state. Not refused: a result must not depend on the day it is computed."""
    _campaign(tmp_path / "ok", {}, manifest='vehicle = "A"\ndate = 2020-02-01\n')
    _campaign(tmp_path / "typo", {}, manifest='vehicle = "A"\ndate = 9999-02-01\n')
    with caplog.at_level("WARNING", logger="susp_bo.monitoring.campaigns"):
        campaigns = discover_campaigns(tmp_path)
    assert [c.date.year for c in campaigns] == [2020, 9999]
    warned = [r.getMessage() for r in caplog.records]
    assert len(warned) == 1 and "campaign date 9999-02-01 is after today" in warned[0]
    assert "typo" in warned[0] and "mistyped" in warned[0]


def test_a_campaign_toml_that_is_not_utf8_text_is_named(tmp_path: Path) -> None:
    folder = _campaign(tmp_path / "c", {"vehicle": "A", "date": "2026-01-01"})
    manifest = folder / "campaign.toml"
    manifest.write_bytes('vehicle = "Zürich 1"\n'.encode("utf-16"))  # a UTF-16 export
    with pytest.raises(CampaignError) as raised:
        read_campaign(folder)
    assert str(raised.value).startswith(f"{manifest}: not a UTF-8 text file (byte 0xff at")


def test_a_campaign_toml_that_is_a_folder_is_named(tmp_path: Path) -> None:
    """Outside probe, session 29: a folder named campaign.toml was read as "no vehicle"."""
    folder = _campaign(tmp_path / "c", {"vehicle": "A", "date": "2026-01-01"})
    manifest = folder / "campaign.toml"
    manifest.unlink(missing_ok=True)
    manifest.mkdir()
    with pytest.raises(CampaignError, match=f"{manifest}: not a file; expected the campaign"):
        read_campaign(folder)
