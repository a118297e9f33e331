"""Are two result folders the same result? The check behind README "Set-up".

Compares two output folders of ``susp-bo demo`` or ``susp-bo calibrate`` (run with the
same seed and data, typically on two machines, or on one machine under different load):

- ``result.json``: every key except those that describe the run rather than the result
  (``wall_time_s``, the data path ``data``); numbers compared bit for bit, and for each
  key that differs the largest relative difference of its numbers;
- ``posterior_samples.npy``: bit for bit (SHA-256), else the largest relative difference
  in posterior sd;
- ``result.json["numerics"]["machine_independent"]`` of each side, since a run whose CPU
  code paths were not pinned (``susp_bo/numerics.py``) is not expected to match across
  machines (exit 1 unless both are true); the rest of ``numerics`` records the machine's
  environment and is not compared.

Prints a report and exits 0 when the two results are identical, 1 when they differ, 2 on
bad input::

    python benchmarks/same_result.py DIR_A DIR_B

Either side may be a ``result.json`` file instead of a folder, e.g. the kept reference of
the README's demo (``benchmarks/reference/demo_amd_epyc_zen4_result.json``); the draws are
then compared by the SHA-256 each side's folder holds, printed for both (the README gives
the reference's).

Measured (session 10, 2026-11-26): the default demo on this Intel Xeon (2 cores, Debian
12, glibc 2.36) and on a second machine of the same CPU model (16 cores, Ubuntu 24.04,
glibc 2.39): identical, draws bit-identical; the unpinned ``--smoke`` runs
(``SUSP_BO_NATIVE_NUMERICS=1``) differ in the last bits of the log L expected at the truth.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

RUN_KEYS = ("wall_time_s", "data", "numerics")
"""``result.json`` keys that describe the run (time, where the data was, the CPU code paths
in effect), not the result. ``numerics`` records the environment of the machine (on a CPU
with AVX-512 ``NPY_DISABLE_CPU_FEATURES`` is set, on one without it is not): its
``machine_independent`` is printed for each side and must be true on both for a match."""


def numbers(value: Any) -> list[float]:
    """Every number inside a JSON value, depth first (booleans excluded)."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return []
    if isinstance(value, int | float):
        return [float(value)]
    if isinstance(value, dict):
        return [x for key in sorted(value) for x in numbers(value[key])]
    if isinstance(value, list | tuple):
        return [x for item in value for x in numbers(item)]
    return []


def largest_relative_difference(a: Any, b: Any) -> float | None:
    """max |x − y| / max(|x|, |y|) over paired numbers; None where the shapes differ."""
    xs, ys = numbers(a), numbers(b)
    if len(xs) != len(ys) or not xs:
        return None
    worst = 0.0
    for x, y in zip(xs, ys, strict=True):
        if x == y or (math.isnan(x) and math.isnan(y)):
            continue
        scale = max(abs(x), abs(y))
        worst = max(worst, abs(x - y) / scale if scale > 0 else math.inf)
    return worst


def compare_results(a: dict[str, Any], b: dict[str, Any]) -> dict[str, float | None]:
    """Keys of two ``result.json`` dicts that differ → their largest relative difference
    (None: not comparable number by number). Run-describing keys (:data:`RUN_KEYS`) are
    left out; an empty dict means the same result."""
    differing: dict[str, float | None] = {}
    for key in sorted(set(a) | set(b)):
        if key in RUN_KEYS:
            continue
        if key not in a or key not in b:
            differing[key] = None
        elif json.dumps(a[key], sort_keys=True) != json.dumps(b[key], sort_keys=True):
            differing[key] = largest_relative_difference(a[key], b[key])
    return differing


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _result_path(given: Path) -> Path:
    """``given`` itself when it is a file, else ``given/result.json``."""
    return given if given.is_file() else given / "result.json"


def _samples_path(given: Path) -> Path | None:
    """The folder's ``posterior_samples.npy`` (None for a bare result.json)."""
    return None if given.is_file() else given / "posterior_samples.npy"


def _load(given: Path) -> dict[str, Any]:
    path = _result_path(given)
    if not path.is_file():
        print(
            f"same_result.py: {path}: no result.json (expected a demo/calibrate --out folder "
            "or a result.json file)",
            file=sys.stderr,
        )
        raise SystemExit(2)
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as error:
        print(f"same_result.py: {path}: not valid JSON ({error})", file=sys.stderr)
        raise SystemExit(2) from None


def main(argv: list[str] | None = None) -> int:
    """Compare two result folders; 0 identical, 1 different, 2 bad input."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path, help="first result folder (or its result.json)")
    parser.add_argument("b", type=Path, help="second result folder (or its result.json)")
    args = parser.parse_args(argv)
    a, b = _load(args.a), _load(args.b)
    for name, result in (("A", a), ("B", b)):
        numerics = result.get("numerics", {})
        pinned = numerics.get("machine_independent")
        print(
            f"{name}: numerics machine_independent = {pinned}, "
            f"torch {numerics.get('torch')}, numpy {numerics.get('numpy')}"
        )
    pinned_both = all(r.get("numerics", {}).get("machine_independent") is True for r in (a, b))
    if not pinned_both:
        print("numerics: not pinned on both sides — a match across machines is not expected")
    differing = compare_results(a, b)
    if differing:
        print(f"result.json: {len(differing)} key(s) differ")
        for key, rel in differing.items():
            print(
                f"  {key}: "
                + ("not comparable" if rel is None else f"largest relative difference {rel:.3g}")
            )
    else:
        print(f"result.json: identical (all keys but {', '.join(RUN_KEYS)})")
    same_draws = True
    found = [_samples_path(given) for given in (args.a, args.b)]
    for name, path in zip("AB", found):
        if path is not None and path.is_file():
            print(f"{name}: posterior_samples.npy SHA-256 {_sha256(path)}")
    paths = [path for path in found if path is not None and path.is_file()]
    if len(paths) == 2:
        if _sha256(paths[0]) == _sha256(paths[1]):
            print("posterior_samples.npy: bit-identical")
        else:
            same_draws = False
            x, y = (np.load(p) for p in paths)
            if x.shape != y.shape:
                print(f"posterior_samples.npy: shapes differ {x.shape} vs {y.shape}")
            else:
                gap = np.max(np.abs(x.std(axis=0) - y.std(axis=0)) / x.std(axis=0))
                print(f"posterior_samples.npy: differ; largest relative sd gap {gap:.3g}")
    else:
        print("posterior_samples.npy: not in both folders, not compared")
    return 0 if not differing and same_draws and pinned_both else 1


if __name__ == "__main__":
    sys.exit(main())
