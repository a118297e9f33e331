"""The known-answer scenario writer: arguments checked before anything is written; manifests
that read back as written. No simulation runs here (the writers are replaced by recorders)."""

from __future__ import annotations

import datetime as dt
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from susp_bo.data.measured import MeasuredRun
from susp_bo.monitoring import scenario
from susp_bo.monitoring.campaigns import read_campaign
from susp_bo.rig.catalog import rig_path
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.track import SpeedProfile, TrackGeometry

JAN, FEB, MAR = dt.date(2026, 1, 15), dt.date(2026, 2, 15), dt.date(2026, 3, 15)


@pytest.fixture(scope="module")
def spec() -> RigSpec:
    """The reference rig (only read: nothing is simulated)."""
    return load_rig_spec(rig_path("hst_trailer"))


@pytest.fixture
def written(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """The campaigns :func:`scenario.write_scenario` asks for, recorded instead of simulated."""
    calls: list[dict[str, Any]] = []

    def record(spec: RigSpec, folder: Path, **kwargs: Any) -> Path:
        calls.append({"folder": folder, **kwargs})
        return folder

    monkeypatch.setattr(scenario, "write_campaign", record)
    return calls


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"n_campaigns": 2, "dates": [FEB, JAN]}, r"dates: \['2026-02-15', '2026-01-15'\] are not"),
        (
            {"n_campaigns": 3, "dates": [JAN, FEB, FEB]},
            r"not strictly increasing \(2026-02-15 then",
        ),
        ({"n_campaigns": 2, "dates": ["2026-01-15", FEB]}, r"dates: '2026-01-15' is not allowed"),
        ({"n_campaigns": 2, "dates": [JAN, dt.datetime(2026, 2, 1)]}, r"datetime.date values"),
        ({"vehicles": ("TRAIN-A", "TRAIN-A")}, r"vehicles: \['TRAIN-A'\] given more than once"),
        ({"vehicles": ("TRAIN-A", "train-a")}, r"given more than once \(letter case ignored\)"),
        ({"vehicles": ()}, r"vehicles: got an empty sequence; expected 1 or more vehicle ids"),
        ({"vehicles": "AB"}, r"vehicles: got 'AB'; expected a sequence of vehicle ids"),
        ({"vehicles": ("TRAIN-A", "../B")}, r"vehicles: '\.\./B' is not allowed; expected a"),
        ({"vehicles": ("TRAIN-A ",)}, r"vehicles: 'TRAIN-A ' is not allowed"),
        ({"n_campaigns": 0}, r"n_campaigns: got 0; expected an integer >= 2"),
        ({"n_campaigns": 1}, r"n_campaigns: got 1; expected an integer >= 2"),
        (
            {"n_campaigns": 2, "dates": [JAN, FEB, MAR]},
            r"dates: 3 given for n_campaigns = 2; expected one date per",
        ),
        ({"final": 1.0e9}, r"final: parameter secondary_vertical_damping: got 1000000000.0"),
        ({"nu": 0}, r"nu: got 0; expected an integer in 1 … 1000"),
        ({"nu": 100_000}, r"nu: got 100000; expected an integer in 1 … 1000"),  # probe, s. 29
        ({"seed": -1}, r"seed: got -1; expected an integer >= 0"),
        ({"noise_m_s2": float("nan")}, r"noise_m_s2: got nan; expected a finite value in 0 … 100"),
        ({"noise_m_s2": 1e9}, r"noise_m_s2: got 1000000000\.0; expected a finite value in 0"),
    ],
)
def test_write_scenario_refuses_inconsistent_arguments_before_writing(
    spec: RigSpec,
    tmp_path: Path,
    written: list[dict[str, Any]],
    arguments: dict[str, Any],
    message: str,
) -> None:
    with pytest.raises(ValueError, match=message):
        scenario.write_scenario(spec, tmp_path / "campaigns", **arguments)
    assert written == [] and not (tmp_path / "campaigns").exists()
    # the same call with consistent arguments writes one campaign per vehicle and date
    truth = scenario.write_scenario(spec, tmp_path / "campaigns", n_campaigns=2, dates=[JAN, FEB])
    assert [(c["vehicle"], c["date"]) for c in written] == [
        ("TRAIN-A", JAN),
        ("TRAIN-A", FEB),
        ("TRAIN-B", JAN),
        ("TRAIN-B", FEB),
    ]
    assert truth["truth"]["TRAIN-A"] == [40.0e3, 21.0e3]


def _fake_runs(spec: RigSpec, truth: object, *, nu: int, **_: object) -> list[MeasuredRun]:
    """``nu`` small runs in place of :func:`~susp_bo.data.synthetic.synthesize_runs`."""
    rng = np.random.default_rng(0)
    return [
        MeasuredRun(
            geometry=TrackGeometry.synthetic("low", length_m=100.0, seed=index),
            speed=SpeedProfile.constant(20.0, 4.0),
            channels=("a",),
            accelerations_m_s2=rng.normal(0.0, 0.3, size=(1, 400)),
            sample_rate_hz=100.0,
            units=("m/s^2",),
            metadata={"truth": dict(truth)},  # type: ignore[call-overload]
        )
        for index in range(nu)
    ]


def test_write_campaign_writes_a_manifest_that_reads_back_as_given(
    spec: RigSpec, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Quotes, backslashes and new lines in the vehicle or line made an f-string invalid TOML."""
    monkeypatch.setattr(scenario, "synthesize_runs", _fake_runs)
    vehicle, line = 'CR400 "42" \\ B', 'Beijing "South"\\Shanghai\nHongqiao'
    folder = scenario.write_campaign(
        spec,
        tmp_path / "c",
        vehicle=vehicle,
        date=MAR,
        truth={"secondary_vertical_damping": 30.0e3},
        nu=1,
        seed=0,
        noise_m_s2=0.0,
        line=line,
    )
    manifest = tomllib.loads((folder / "campaign.toml").read_text(encoding="utf-8"))
    assert manifest == {"vehicle": vehicle, "date": MAR, "line": line}
    campaign = read_campaign(folder)
    assert (campaign.vehicle, campaign.date, campaign.line) == (vehicle, MAR, line)
