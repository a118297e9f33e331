"""Degradation scenario: when does the alarm rise, and does a healthy train stay quiet?

Two vehicles measured monthly over ``--campaigns`` dates: on TRAIN-A the secondary
vertical damper loses damping linearly from its nominal 40 kN·s/m to ``--final``
(acceptable domain 28–56 kN·s/m, so the truth leaves the band part-way); TRAIN-B
stays nominal. Each campaign: ``--nu`` synthetic runs on fresh tracks, calibrated with
``susp-bo monitor`` (q = 2: the degrading damper and the yaw damper) on a shortened
version of the reference rig (``--duration`` s records, 4 s Welch segments,
0.5–20 Hz). Prints, per vehicle and parameter, the campaign at which the truth left
the acceptable domain, the campaign at which the alarm rose (P(outside) > 0.9) and
the false alarms — twice: with the reliability contract (a calibration without a
trusted verdict never raises an alarm) and on the calibrations alone (every campaign
taken as trusted), so that the figure exists on a branch without reliability verdicts.

Resumable: rerun the same command and finished campaigns are read back.

    python benchmarks/monitoring_degradation.py --out /tmp/degradation [--workers 1]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from pathlib import Path

import tomli_w

from susp_bo.monitoring.alarms import apply_alarms
from susp_bo.monitoring.runner import monitor
from susp_bo.monitoring.scenario import score_scenario, write_scenario
from susp_bo.rig.catalog import rig_path
from susp_bo.rig.spec import load_rig_spec

PARAMETER = "secondary_vertical_damping"
CALIBRATED = ["secondary_vertical_damping", "yaw_damper_damping"]


def scenario_rig(folder: Path, duration_s: float) -> Path:
    """The reference rig with ``duration_s`` records after 2 s warm-up, 4 s segments."""
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    document["rig"]["name"] = "hst_trailer_monitoring"
    document["simulation"].update(duration_s=duration_s, warm_up_s=2.0)
    document["spectrum"].update(segment_s=4.0, f_min_hz=0.5, n_frequencies=32)
    path = folder / "hst_trailer_monitoring.toml"
    path.write_text(tomli_w.dumps(document))
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--campaigns", type=int, default=10)
    parser.add_argument("--final", type=float, default=21.0e3, help="N·s/m at the last campaign")
    parser.add_argument("--nu", type=int, default=2)
    parser.add_argument("--duration", type=float, default=16.0)
    parser.add_argument("--budget", type=int, default=30)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()
    root = args.out
    data = root / "campaigns"
    data.mkdir(parents=True, exist_ok=True)
    rig = scenario_rig(root, args.duration)
    started = time.perf_counter()
    truth = write_scenario(
        load_rig_spec(rig),
        data,
        parameter=PARAMETER,
        final=args.final,
        n_campaigns=args.campaigns,
        nu=args.nu,
        seed=2026,
    )
    print(f"scenario written in {time.perf_counter() - started:.0f} s", file=sys.stderr)
    (data / "monitor.toml").write_text(
        tomli_w.dumps(
            {
                "rig": str(rig),
                "parameters": CALIBRATED,
                "budget": {
                    "max_evaluations": args.budget,
                    "initial_design": max(8, args.budget // 3),
                    "batch_size": 4,
                    "check_points": 4,
                },
                "seeds": {"calibration": 0, "mcmc": 1},
                "mcmc": {"chains": 128, "draws": 1000, "warmup": 300},
            }
        )
    )
    payload = monitor(data, root / "monitor", workers=args.workers)
    wall = time.perf_counter() - started
    contract = score_scenario(payload, PARAMETER)
    # the same campaigns, every calibration taken as trusted (no reliability verdicts here)
    everything = json.loads(json.dumps(payload))
    for row in everything["campaigns"]:
        row["trusted"] = True
    from susp_bo.monitoring.alarms import CampaignRecord

    records = [
        CampaignRecord(
            r["id"],
            r["vehicle"],
            r["date"],
            True,
            "taken as trusted",
            {
                n: (s["median"], tuple(s["interval95"]), s["p_outside"], s["direction"])
                for n, s in r["parameters"].items()
            },
            r["truth"],
        )
        for r in everything["campaigns"]
    ]
    acceptable = dict(
        zip(payload["parameters"], (None if a is None else tuple(a) for a in payload["acceptable"]))
    )
    states = apply_alarms(records, acceptable)
    for row in everything["campaigns"]:
        row["parameters"] = {n: s.to_dict() for n, s in states[row["id"]].items()}
    calibration_only = score_scenario(everything, PARAMETER)
    report = {
        "truth": truth,
        "with_reliability_contract": contract,
        "every_calibration_taken_as_trusted": calibration_only,
        "n_simulations": payload["n_simulations"],
        "wall_time_s": wall,
        "settings": vars(args) | {"out": str(args.out)},
    }
    (root / "scenario_score.json").write_text(json.dumps(report, indent=2))
    for view, score in (("contract", contract), ("calibration only", calibration_only)):
        print(f"== {view}")
        for vehicle, per in score.items():
            for name, s in per.items():
                p = ", ".join("-" if v is None else f"{v:.2f}" for v in s["p_outside"])
                print(
                    f"{vehicle} {name}: truth left band at campaign {s['truth_left_band_at']}, "
                    f"alarm at {s['alarm_raised_at']}, delay {s['delay_campaigns']}, "
                    f"false alarms {len(s['false_alarms'])}; P(outside) = [{p}]"
                )
    print(f"simulator runs {payload['n_simulations']}, wall {wall:.0f} s")


if __name__ == "__main__":
    main()
