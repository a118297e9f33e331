"""``susp-bo monitor`` through the real stack: kill and resume, new campaigns, alarms, figures."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomli_w

import susp_bo
from susp_bo.cli import main
from susp_bo.monitoring.alarms import p_outside

pytestmark = pytest.mark.slow

PARAMETERS = ["secondary_vertical_damping", "yaw_damper_damping"]  # as in monitor.toml
A, B, C = "TRAIN-1/2026-01-10", "TRAIN-1/2026-02-10", "TRAIN-1/2026-03-10"
SIMULATIONS_PER_CAMPAIGN = 8 * 2  # 8 evaluations x 2 measured runs


def _rows(store: Path) -> list[tuple[str, str]]:
    try:
        db = sqlite3.connect(f"file:{store}?mode=ro", uri=True)
        try:
            return db.execute("SELECT key, created_at FROM evaluations ORDER BY id").fetchall()
        finally:
            db.close()
    except sqlite3.DatabaseError:
        return []


def _monitor_cli(folder: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "susp_bo",
            "monitor",
            str(folder),
            "--out",
            str(out),
            "--workers",
            "1",
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=900,
    )


def _snapshot(out: Path, campaign: str) -> dict[str, Any]:
    folder = out / campaign
    result = folder / "result.json"
    return {
        "rows": _rows(folder / "evaluations.sqlite"),
        "result": result.read_bytes() if result.exists() else None,
        "mtime": result.stat().st_mtime_ns if result.exists() else None,
    }


@pytest.fixture(scope="module")
def monitored(
    fast_rig: Path,
    tmp_path_factory: pytest.TempPathFactory,
    campaign_adder: Any,
    monitor_config_writer: Any,
) -> dict[str, Any]:
    """Kill a monitoring run in its second campaign, resume it, then add a third campaign."""
    root = tmp_path_factory.mktemp("monitoring")
    folder, out = root / "campaigns", root / "out"
    campaign_adder(folder, fast_rig, "TRAIN-1", "2026-01-10", seed=1)
    campaign_adder(folder, fast_rig, "TRAIN-1", "2026-02-10", seed=2)
    monitor_config_writer(folder, fast_rig)
    seen: dict[str, Any] = {"folder": folder, "out": out}
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "susp_bo",
            "monitor",
            str(folder),
            "--out",
            str(out),
            "--workers",
            "1",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    store_b = out / B / "evaluations.sqlite"
    deadline = time.monotonic() + 600
    try:
        while time.monotonic() < deadline and len(_rows(store_b)) < 3:
            assert process.poll() is None, "the monitoring run ended before it could be killed"
            time.sleep(0.05)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=30)
    seen["killed"] = {c: _snapshot(out, c) for c in (A, B)}
    seen["resumed_run"] = _monitor_cli(folder, out)
    seen["resumed"] = {c: _snapshot(out, c) for c in (A, B)}
    campaign_adder(folder, fast_rig, "TRAIN-1", "2026-03-10", seed=3)
    seen["added_run"] = _monitor_cli(folder, out)
    seen["added"] = {c: _snapshot(out, c) for c in (A, B, C)}
    return seen


def test_a_killed_monitoring_run_continues_without_recomputing(monitored: dict[str, Any]) -> None:
    killed, resumed = monitored["killed"], monitored["resumed"]
    assert killed[A]["result"] is not None, "the first campaign had finished before the kill"
    assert killed[B]["result"] is None and 3 <= len(killed[B]["rows"]) < SIMULATIONS_PER_CAMPAIGN
    run = monitored["resumed_run"]
    assert run.returncode == 0, run.stderr[-3000:]
    assert "2 campaigns of 1 vehicles: finished 1, interrupted 1, new 0" in run.stderr
    # the finished campaign is read back, never recomputed: same file, same store
    assert resumed[A] == killed[A]
    # the killed one continues from its store: earlier simulations kept, not re-run
    before = dict(killed[B]["rows"])
    after = dict(resumed[B]["rows"])
    assert len(after) == SIMULATIONS_PER_CAMPAIGN
    assert all(after[key] == created for key, created in before.items())
    payload = json.loads(resumed[B]["result"])
    assert payload["n_simulations"] == SIMULATIONS_PER_CAMPAIGN


def test_a_new_campaign_adds_only_its_own_work(monitored: dict[str, Any]) -> None:
    run = monitored["added_run"]
    assert run.returncode == 0, run.stderr[-3000:]
    assert "finished 2, interrupted 0, new 1" in run.stderr
    added, resumed = monitored["added"], monitored["resumed"]
    assert added[A] == resumed[A] and added[B] == resumed[B]
    assert len(added[C]["rows"]) == SIMULATIONS_PER_CAMPAIGN
    report = json.loads((monitored["out"] / "monitor.json").read_text())
    assert [c["id"] for c in report["campaigns"]] == [A, B, C]
    assert report["n_simulations"] == 3 * SIMULATIONS_PER_CAMPAIGN
    assert [c["status_before_this_run"] for c in report["campaigns"]] == [
        "finished",
        "finished",
        "new",
    ]
    for name in PARAMETERS:
        assert (monitored["out"] / f"trend_{name}.png").stat().st_size > 10_000


def test_alarms_follow_trusted_verdicts_and_the_posterior_draws(
    monitored: dict[str, Any], fast_rig: Path, tmp_path: Path
) -> None:
    """Depends on the reliability contract: sets ``result.json["reliability"]`` only if absent."""
    out = tmp_path / "out"
    shutil.copytree(monitored["out"], out)
    for campaign in (A, C):  # trusted; B keeps what the study wrote (no verdict on older code)
        path = out / campaign / "result.json"
        payload = json.loads(path.read_text())
        payload.setdefault(
            "reliability", {"verdict": "trusted", "reasons": [], "sentence": "set by the test"}
        )
        path.write_text(json.dumps(payload))
    trusted = {
        c: json.loads((out / c / "result.json").read_text()).get("reliability") for c in (A, B, C)
    }
    # a band that excludes the truth (30 kN·s/m): the worn damper must be called
    document = tomllib.loads(fast_rig.read_text())
    for entry in document["calibration"]["parameters"]:
        if entry["name"] == "secondary_vertical_damping":
            entry["acceptable"] = [35.0e3, 70.0e3]
    rig = tmp_path / "hst_trailer_fast.toml"
    rig.write_text(tomli_w.dumps(document))
    stores = {c: _rows(out / c / "evaluations.sqlite") for c in (A, B, C)}
    report = susp_bo.monitor(monitored["folder"], out, rig=str(rig), progress=False)
    assert {c: _rows(out / c / "evaluations.sqlite") for c in (A, B, C)} == stores
    for row in report["campaigns"]:
        draws = np.load(out / row["id"] / "posterior_samples.npy")
        damper = row["parameters"]["secondary_vertical_damping"]
        assert damper["p_outside"] == pytest.approx(p_outside(draws[:, 0], (35.0e3, 70.0e3)))
        is_trusted = (trusted[row["id"]] or {}).get("verdict") == "trusted"
        assert row["trusted"] is is_trusted
        assert damper["used_for_alarm"] is is_trusted
        if not is_trusted:
            assert "not used for alarms" in row["alarm_note"]
    # the alarm rule, replayed: a trusted campaign sets the state, an untrusted one carries it
    state = False
    for row in report["campaigns"]:
        damper = row["parameters"]["secondary_vertical_damping"]
        if row["trusted"]:
            state = damper["p_outside"] > 0.9
        assert damper["alarm"] is state, row["id"]
        assert damper["truth_outside"] is True  # truth 30 kN·s/m, band 35-70 kN·s/m
    alarms = [m for m in report["maintenance"] if m["parameter"] == "secondary_vertical_damping"]
    assert bool(alarms) is state
    if not trusted[B] or trusted[B].get("verdict") != "trusted":
        b = next(r for r in report["campaigns"] if r["id"] == B)
        assert b["alarm_note"].startswith("not used for alarms")


def test_bad_input_exits_2_with_a_message_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["monitor", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert main(["monitor", str(tmp_path), "--out", str(tmp_path / "o"), "--budget", "1"]) == 2
    assert "argument --budget: '1' is not allowed" in capsys.readouterr().err
    assert main(["monitor", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "holds no campaign" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_the_next_campaign_starts_from_the_previous_trusted_posterior(
    monitored: dict[str, Any], tmp_path: Path
) -> None:
    """A trusted campaign B: C's design starts at B's posterior median (warm start), and
    ``--cold-start`` / ``warm_start=False`` does not; an untrusted B gives a cold start."""
    out = tmp_path / "out"
    shutil.copytree(monitored["out"], out)
    shutil.rmtree(out / C)
    path = out / B / "result.json"
    payload = json.loads(path.read_text())
    payload["reliability"] = {"verdict": "trusted", "reasons": [], "sentence": "set by the test"}
    path.write_text(json.dumps(payload))
    median = np.median(np.load(out / B / "posterior_samples.npy"), axis=0)
    # with a warm budget (session 28): the warm campaign's, C runs on 6, the cold B kept its 8
    report = susp_bo.monitor(monitored["folder"], out, progress=False, figures=False, warm_budget=6)
    row = next(r for r in report["campaigns"] if r["id"] == C)
    assert row["warm_start"]["from_campaign"] == B and row["n_evaluations"] <= 6
    budgets = {r["id"]: r["budget"] for r in report["campaigns"]}  # as each campaign ran
    assert budgets[C] == 6 and budgets[A] == 8
    assert (
        json.loads((out / C / "result.json").read_text())["reliability"]["evidence"]["budget"] == 6
    )
    assert tomllib.loads((out / C / "study.toml").read_text())["budget"]["max_evaluations"] == 6
    assert tomllib.loads((out / B / "study.toml").read_text())["budget"]["max_evaluations"] == 8
    assert json.loads((out / C / "result.json").read_text())["warm_start"] == row["warm_start"]
    db = sqlite3.connect(out / C / "evaluations.sqlite")
    rows = [json.loads(r[0]) for r in db.execute("SELECT parameters_json FROM evaluations")]
    db.close()
    evaluated = np.array(rows)  # w in calibration order
    assert np.min(np.max(np.abs(evaluated / median - 1.0), axis=1)) < 1e-12  # B's median ran
    # B's own row: it was a cold start (A had no trusted verdict when B ran)
    assert next(r for r in report["campaigns"] if r["id"] == B)["warm_start"] is None
    # cold on request, and after an untrusted campaign
    for cold_out, trusted in ((tmp_path / "cold", True), (tmp_path / "untrusted", False)):
        shutil.copytree(out, cold_out)
        shutil.rmtree(cold_out / C)
        if not trusted:
            payload["reliability"] = {"verdict": "not_trusted", "reasons": [], "sentence": "x"}
            (cold_out / B / "result.json").write_text(json.dumps(payload))
        cold = susp_bo.monitor(
            monitored["folder"], cold_out, progress=False, figures=False, warm_start=not trusted
        )
        assert next(r for r in cold["campaigns"] if r["id"] == C)["warm_start"] is None
