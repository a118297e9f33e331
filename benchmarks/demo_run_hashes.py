"""Fingerprint a demo's simulator runs, to find where two machines' demos part.

Reads ``OUT/evaluations.sqlite`` and ``OUT/posterior_samples.npy`` of ``susp-bo demo --out
OUT`` (or of a study) and writes, per simulator run in evaluation order, SHA-256 prefixes
of the parameter vector and of the simulated spectra as stored, plus the draws' SHA-256::

    python benchmarks/demo_run_hashes.py demo_out --out runs.json --machine "Intel Xeon ..."

Two such files from two CPUs show the first run whose parameters or spectra differ: a
different spectrum at the same parameters points at the simulator (PyBullet, NumPy), the
same spectra with different next parameters at the surrogate/acquisition (torch, BLAS).
Reference (session 19, AMD EPYC Zen 3, pinned numerics, the README demo on a fresh clone of
commit a0891f1, whose whole calibration runs BLAS on one thread): ``benchmarks/reference/
demo_amd_epyc_zen3_runs.json`` and ``..._result.json``, draws SHA-256 5b672c75…; its first
321 runs equal session 18's (``..._session18_runs.json``, commit 33a9088, 04cf3ea8…), whose
local phase ran the main process's products on two threads. Before 33a9088 the Intel Xeon
runs of sessions 10–16 had 63cef1cb…, the AMD EPYC 00bb65a1….
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sqlite3
import sys
from pathlib import Path


def _prefix(data: bytes | None) -> str:
    return hashlib.sha256(data or b"").hexdigest()[:16]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a demo or study output folder")
    parser.add_argument("--out", type=Path, required=True, help="JSON file to write")
    parser.add_argument("--machine", default="", help="a description of the machine")
    args = parser.parse_args(argv)
    store, draws = args.folder / "evaluations.sqlite", args.folder / "posterior_samples.npy"
    for path in (store, draws):
        if not path.is_file():
            print(f"demo_run_hashes: {path}: no such file (folder: a demo output)", file=sys.stderr)
            return 2
    with sqlite3.connect(f"file:{store}?mode=ro", uri=True) as connection:
        rows = connection.execute(
            "SELECT id, parameters, track_id, spectra FROM evaluations ORDER BY id"
        ).fetchall()
    document = {
        "machine": args.machine,
        "posterior_samples_sha256": hashlib.sha256(draws.read_bytes()).hexdigest(),
        "runs": [
            {
                "id": i,
                "track_id": track,
                "parameters_sha256": _prefix(p),
                "spectra_sha256": _prefix(s),
            }
            for i, p, track, s in rows
        ],
    }
    args.out.write_text(json.dumps(document, indent=0))
    print(f"demo_run_hashes: {len(rows)} runs -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
