"""Is the reliability verdict honest? Verdicts against known truths, from SBC runs.

Reads the experiments of one or more ``benchmarks/coverage.py`` output folders (each
experiment: a truth drawn from the prior, synthetic data, a full calibration) and
tabulates, per verdict, how many experiments got it and how many of their 95 %
intervals hold the truth. The promise the tool makes is one-sided: a ``trusted``
result must not exclude the truth more often than a 95 % interval allows (binomial
range over its intervals); a ``not_trusted`` result may be anything — it said so.

Usage::

    python benchmarks/verdict_honesty.py OUT [OUT ...]

Prints one table per folder and writes ``OUT/verdict_honesty.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

from scipy import stats


def binomial_range(n: int, p: float = 0.95) -> tuple[int, int]:
    """Central 95 % range of the number of intervals holding the truth, out of n."""
    return int(stats.binom.ppf(0.025, n, p)), int(stats.binom.ppf(0.975, n, p))


def tabulate(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Per verdict: experiments, intervals holding the truth, experiments with a miss."""
    out: dict[str, Any] = {}
    for verdict in ("trusted", "not_trusted", None):
        chosen = [r for r in records if r.get("verdict") == verdict]
        if not chosen:
            continue
        inside = sum(sum(r["inside95"]) for r in chosen)
        total = sum(len(r["inside95"]) for r in chosen)
        low, high = binomial_range(total)
        out[str(verdict)] = {
            "experiments": len(chosen),
            "intervals_inside": inside,
            "intervals": total,
            "binomial_range": [low, high],
            "consistent": low <= inside,
            "experiments_with_a_miss": sum(not all(r["inside95"]) for r in chosen),
            "reasons": dict(Counter(c for r in chosen for c in r.get("reasons", []))),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    """Tabulate every folder given."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="+", type=Path)
    args = parser.parse_args(argv)
    for folder in args.folders:
        files = sorted((folder / "experiments").glob("*.json"))
        if not files:
            print(f"verdict_honesty: {folder} holds no experiments/*.json", file=sys.stderr)
            return 2
        records = [json.loads(f.read_text()) for f in files]
        table = tabulate(records)
        (folder / "verdict_honesty.json").write_text(json.dumps(table, indent=1))
        print(f"{folder}: {len(records)} experiments")
        for verdict, row in table.items():
            print(
                f"  {verdict:12s} {row['experiments']:3d} experiments, "
                f"{row['intervals_inside']}/{row['intervals']} intervals hold the truth "
                f"(binomial {row['binomial_range'][0]}–{row['binomial_range'][1]}), "
                f"{row['experiments_with_a_miss']} with a miss; reasons {row['reasons']}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
