"""The README's table of demo seeds, from a command: run ``susp-bo demo`` on several seeds
and tabulate what each says against the truth it synthesised.

For each seed N the demo's results folder is ``OUT/demo_N``: made by ``python -m susp_bo
demo --seed N --out OUT/demo_N`` when it holds no ``result.json`` yet (one seed at a time,
in a subprocess; a killed run resumes from its store), read as it is otherwise. Each row:
the best log L, the verdict, how many of the 7 truths their 95 % interval holds and which
it misses, z = (truth − posterior mean) / posterior sd per parameter, the log L gap (best
log L minus log L at the truth on the same tracks, evaluated in a throw-away store:
:func:`coverage_pybullet.truth_log_likelihood`; twice the gap of a correct 7-D posterior
follows χ²₇, median 6.3, 97th percentile 15.5) and the draws' SHA-256 prefix (bit-identity
across machines and sessions). Writes ``OUT/demo_seeds.json`` and ``OUT/demo_seeds.md``::

    python benchmarks/demo_seeds.py --seeds 0 1 2 3 4 --out OUT

About 10 min a seed alone on a 2-core AMD EPYC Zen 4, 25–30 min two at a time (run two
processes with disjoint ``--seeds`` and the same ``--out`` to use both cores).

Measured (session 40, 2026-12-07, code ee7f7d2, AMD EPYC Zen 4, two seeds at a time)::

    seed  best log L  verdict  inside  log L gap (chi2_7 quantile)  draws SHA-256
    0     5670.624    trusted  4/7     7.84 (0.972)                 17263fd9...
    1     5630.420    trusted  7/7     0.99 (0.040)                 51b9aa0f...
    2     5603.675    trusted  7/7     1.25 (0.073)                 80b4016c...
    3     5638.817    trusted  7/7     1.48 (0.112)                 2fd1b1e1...
    4     5675.433    trusted  7/7     2.15 (0.254)                 ac458a69...

Seeds 0, 1, 3 and 4 are bit-identical to sessions 27–28's runs. Seed 2's draws moved
(9d58fafe... then) with the same best log L, verdict and count inside; a second run gave
80b4016c... again. The README's "Other seeds" has the full table.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling coverage_pybullet.py
from coverage_pybullet import truth_log_likelihood

from susp_bo.study_config import load_study_config


def demo_row(folder: Path, seed: int) -> dict[str, object]:
    """One seed's row from a finished demo folder (``result.json``, ``study.toml``,
    ``posterior_samples.npy``)."""
    result = json.loads((folder / "result.json").read_text())
    names = result["parameters"]
    truth = np.asarray(result["reference"], dtype=float)
    mean = np.asarray(result["posterior_mean"], dtype=float)
    sd = np.asarray(result["posterior_sd"], dtype=float)
    intervals = np.asarray(result["interval95"], dtype=float)
    inside = (intervals[:, 0] <= truth) & (truth <= intervals[:, 1])
    truth_log_l = truth_log_likelihood(load_study_config(folder / "study.toml"), truth)
    gap = float(result["best_log_likelihood"]) - truth_log_l
    reliability = result["reliability"]
    return {
        "seed": seed,
        "best_log_likelihood": float(result["best_log_likelihood"]),
        "verdict": reliability["verdict"],
        "reasons": [reason["code"] for reason in reliability["reasons"]],
        "inside": int(inside.sum()),
        "parameters": len(names),
        "misses": [
            {"parameter": names[i], "interval95": intervals[i].tolist(), "truth": truth[i]}
            for i in np.flatnonzero(~inside)
        ],
        "z": ((truth - mean) / sd).tolist(),
        "log_l_gap": gap,
        "gap_chi2_quantile": float(chi2.cdf(2.0 * gap, df=len(names))),
        "lack_of_fit_ratio": reliability["evidence"].get("lack_of_fit_ratio"),
        "draws_sha256": hashlib.sha256((folder / "posterior_samples.npy").read_bytes()).hexdigest(),
        "wall_time_s": float(result["wall_time_s"]),
    }


def table(rows: list[dict[str, object]]) -> str:
    """The rows as the README's markdown table."""
    lines = [
        "| seed | best log L | verdict | truths inside | misses (95 % interval, truth) | z, "
        "7 parameters | log L gap (χ²₇ quantile of 2×) | draws SHA-256 |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        misses = "; ".join(
            f"{m['parameter']} [{m['interval95'][0]:.7g}, {m['interval95'][1]:.7g}], "
            f"{m['truth']:.7g}"
            for m in row["misses"]  # type: ignore[attr-defined]
        )
        z = " ".join(f"{v:+.1f}" for v in row["z"])  # type: ignore[attr-defined]
        verdict = str(row["verdict"]) + (
            f" ({', '.join(row['reasons'])})" if row["reasons"] else ""  # type: ignore[arg-type]
        )
        lines.append(
            f"| {row['seed']} | {row['best_log_likelihood']:.3f} | `{verdict}` | "
            f"{row['inside']}/{row['parameters']} | {misses or '—'} | {z} | "
            f"{row['log_l_gap']:.2f} ({row['gap_chi2_quantile']:.3f}) | "
            f"{str(row['draws_sha256'])[:8]}… |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    parser.add_argument("--out", type=Path, required=True, help="folder of the demo folders")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:
        folder = args.out / f"demo_{seed}"
        if not (folder / "result.json").is_file():
            print(f"demo_seeds: running the demo with seed {seed} into {folder}", file=sys.stderr)
            command = [sys.executable, "-m", "susp_bo", "demo", "--seed", str(seed)]
            done = subprocess.run([*command, "--out", str(folder)], check=False)
            if done.returncode != 0:
                print(f"demo_seeds: the demo with seed {seed} exited {done.returncode}",
                      file=sys.stderr)  # fmt: skip
                return 1
    # every finished seed in OUT (other processes may have run some), in seed order
    found = sorted(
        int(path.parent.name.removeprefix("demo_"))
        for path in args.out.glob("demo_*/result.json")
        if path.parent.name.removeprefix("demo_").isdigit()
    )
    rows = [demo_row(args.out / f"demo_{seed}", seed) for seed in found]
    (args.out / "demo_seeds.json").write_text(json.dumps(rows, indent=1))
    text = table(rows)
    (args.out / "demo_seeds.md").write_text(text)
    print(text, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
