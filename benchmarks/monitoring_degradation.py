"""Degradation scenario: when does the alarm rise, and does a healthy train stay quiet?

Two vehicles measured monthly over ``--campaigns`` dates: on TRAIN-A the secondary
vertical damper loses damping linearly from its nominal 40 kN·s/m to ``--final``
(acceptable domain 28–56 kN·s/m, so the truth leaves the band part-way); TRAIN-B
stays nominal. Each campaign: ``--nu`` synthetic runs on fresh tracks, calibrated by
:func:`susp_bo.monitor` (q = 2: the degrading damper and the yaw damper) on a
shortened version of the reference rig (``--duration`` s records, 4 s Welch
segments, 0.5–20 Hz), ``--budget`` likelihood evaluations per campaign. Prints, per
vehicle and parameter, the campaign at which the truth left the acceptable domain,
the campaign at which the alarm rose (P(outside) > 0.9) and the false alarms —
twice: with the reliability contract (a calibration without a trusted verdict never
raises an alarm) and on the calibrations alone (every campaign taken as trusted), so
that the figure exists on a branch without reliability verdicts.

Resumable: rerun the same command and finished campaigns are read back.

    python benchmarks/monitoring_degradation.py --out /tmp/degradation [--workers 1]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from susp_bo.monitoring.scenario import run_scenario


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--campaigns", type=int, default=10)
    parser.add_argument("--final", type=float, default=21.0e3, help="N·s/m at the last campaign")
    parser.add_argument("--nu", type=int, default=2)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--budget", type=int, default=20)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()
    started = time.perf_counter()
    report = run_scenario(
        args.out,
        n_campaigns=args.campaigns,
        final=args.final,
        nu=args.nu,
        duration_s=args.duration,
        budget=args.budget,
        workers=args.workers,
    )
    wall = time.perf_counter() - started
    payload = report.pop("monitor")
    report |= {
        "n_simulations": payload["n_simulations"],
        "wall_time_s": wall,
        "settings": vars(args) | {"out": str(args.out)},
    }
    (args.out / "scenario_score.json").write_text(json.dumps(report, indent=2))
    for view in ("with_reliability_contract", "every_calibration_taken_as_trusted"):
        print(f"== {view}")
        for vehicle, per in report[view].items():
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
