"""Curved line vs tangent track through the command line (synth → calibrate), PyBullet rig.

The issue-14 target: a calibration on synthetic data from a line with curves and
transitions recovers the demo's worn dampers with intervals as narrow (within ± 20 %)
as on tangent track, with the reliability verdict ``trusted``.

For each of ``tangent`` and ``curved`` (the S-curve ``benchmarks/s_curve_7000.toml``:
tangent, transition, R 7000 m / 150 mm cant left, transition, right curve), this runs
what a user runs:

1. ``susp-bo synth RIG --truth truth.toml --nu 3 --seed 2024 --noise 0.005 [--line …]``
   on a copy of ``hst_trailer`` with 16 s records (4 s warm-up), the demo's truth
   (secondary vertical damping 28 kN·s/m, yaw damper 3.7 MN·s/m);
2. ``susp-bo calibrate study.toml`` with q = 2 (those two dampers), the paired output
   error and the local phase (``[search] local = true``), the budget ``--budget``
   (design 16, batches of 4, 4 check points, seeds 0/1);

then prints, per case and parameter, the marginal MAP, the 95 % interval, whether it
holds the truth, the verdict with its reasons, and the ratio of the interval widths
curved / tangent. Everything lands in ``OUT/<case>/`` (data, results folder); a rerun
with the same ``OUT`` reuses finished steps (``result.json`` of the same budget) and
resumes from the evaluation store otherwise (an interrupted run, or ``--budget`` raised
as a verdict asks: the evaluations already made are replayed, not rerun).

    python benchmarks/curved_study.py --out curved_study [--budget 40] [--workers 2]

Measured (2026-11-25, 2 shared cores, load 3–4; ``--budget 40``, then ``--budget 80`` on
the same ``--out``):

    budget 40   tangent  not_trusted (not_converged, search_box_edge)  yaw damper 3.692
                         [3.676, 3.696] MN·s/m: OUTSIDE (truth 3.7)
                curved   not_trusted (not_converged, search_box_edge)  both inside
    budget 80   tangent  trusted, converged at 56 evaluations (216 PyBullet runs)
                         28.000 [27.995, 28.006] kN·s/m, 3.691 [3.675, 3.708] MN·s/m
                curved   trusted, converged at 56 evaluations (216 PyBullet runs)
                         28.000 [27.995, 28.006] kN·s/m, 3.692 [3.676, 3.708] MN·s/m
    width curved / tangent: 1.00 (secondary vertical damping), 0.97 (yaw damper)

About 6 min per command here (each calibration 160–175 s of study wall time).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

from susp_bo.commands.demo import DEMO_TRUTH
from susp_bo.rig.catalog import rig_path

LINE = Path(__file__).with_name("s_curve_7000.toml")
NAMES = ("secondary_vertical_damping", "yaw_damper_damping")


def short_rig(out: Path) -> Path:
    """The shipped hst_trailer with 16 s records and a 4 s warm-up (the README story)."""
    text = rig_path("hst_trailer").read_text()
    text, n_duration = re.subn(r"(?m)^duration_s = [0-9.]+", "duration_s = 16.0", text)
    text, n_warm = re.subn(r"(?m)^warm_up_s = [0-9.]+", "warm_up_s = 4.0", text)
    if n_duration != 1 or n_warm != 1:
        raise SystemExit("curved_study: hst_trailer.toml no longer has one duration_s/warm_up_s")
    path = out / "hst_trailer_16s.toml"
    path.write_text(text)
    return path


def run(command: list[str]) -> None:
    """Run a susp-bo command, its stderr passed through; stop on failure."""
    print("$ " + " ".join(command), file=sys.stderr, flush=True)
    subprocess.run(command, check=True)


def case(out: Path, rig: Path, curved: bool, budget: int, workers: int) -> dict:
    """synth + calibrate one case; returns its result.json."""
    name = "curved" if curved else "tangent"
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    data = folder / "data"
    results = folder / "result"
    done = results / "result.json"
    if done.exists() and json.loads(done.read_text())["reliability"]["evidence"]["budget"] != (
        budget
    ):
        done.unlink()  # a larger (or smaller) budget: resume from the store
    if not done.exists():
        if not data.exists():
            truth = folder / "truth.toml"
            truth.write_text("".join(f"{k} = {v!r}\n" for k, v in DEMO_TRUTH.items()))
            synth = [sys.executable, "-m", "susp_bo", "synth", str(rig), "--out", str(data)]
            synth += ["--truth", str(truth), "--nu", "3", "--seed", "2024", "--noise", "0.005"]
            run(synth + (["--line", str(LINE)] if curved else []))
        study = folder / "study.toml"
        study.write_text(
            f'rig = "{rig}"\ndata = "data"\nout = "result"\n'
            f"parameters = {json.dumps(list(NAMES))}\n\n"
            f"[budget]\nmax_evaluations = {budget}\ninitial_design = 16\n"
            "batch_size = 4\ncheck_points = 4\n\n"
            "[seeds]\ncalibration = 0\nmcmc = 1\n\n"
            f"[executor]\nworkers = {workers}\n\n"
            '[output_error]\nmodel = "paired"\n\n[search]\nlocal = true\n'
        )
        command = [sys.executable, "-m", "susp_bo", "calibrate", str(study)]
        run(command + (["--resume"] if (results / "evaluations.sqlite").exists() else []))
    return json.loads((results / "result.json").read_text())


def main(argv: list[str] | None = None) -> int:
    """Both cases, then the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--budget", type=int, default=40)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rig = short_rig(args.out)
    started = time.perf_counter()
    results = {
        label: case(args.out, rig, label == "curved", args.budget, args.workers)
        for label in ("tangent", "curved")
    }
    widths = {}
    for label, result in results.items():
        reliability = result["reliability"]
        codes = ", ".join(r["code"] for r in reliability["reasons"]) or "-"
        print(
            f"{label}: verdict {reliability['verdict']} ({codes}); "
            f"{result['n_simulations']} PyBullet runs, {result['wall_time_s']:.0f} s"
        )
        names = result["parameters"]
        for i, name in enumerate(names):
            low, high = result["interval95"][i]
            truth = DEMO_TRUTH[name]
            widths[label, name] = high - low
            print(
                f"  {name:28s} truth {truth:10.4g}  MAP {result['marginal_map'][i]:10.5g}  "
                f"95% [{low:.5g}, {high:.5g}]  {'inside' if low <= truth <= high else 'OUTSIDE'}"
            )
    for name in NAMES:
        ratio = widths["curved", name] / widths["tangent", name]
        print(f"interval width curved / tangent, {name}: {ratio:.2f} (target <= 1.2)")
    print(f"total {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
